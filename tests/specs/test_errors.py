"""Tests of rdea_lab.specs.errors: one-line SpecError, YAML reading, and every
malformed file in tests/specs/bad/ (first line of each: ``# field: <expected>``)."""

import pickle
from pathlib import Path

import pytest

from rdea_lab.specs import SpecError, load_params, load_specimen
from rdea_lab.specs.errors import parse_yaml_mapping, read_yaml_mapping

BAD = Path(__file__).resolve().parent / "bad"
BAD_FILES = sorted(BAD.glob("*.yaml"))


def _expected_field(path: Path) -> str:
    first = path.read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith("# field: "), f"{path.name}: first line must be '# field: ...'"
    return first.removeprefix("# field: ").strip()


def test_there_are_enough_bad_files():
    names = [p.name for p in BAD_FILES]
    assert sum(n.startswith("specimen_") for n in names) >= 10
    assert sum(n.startswith("params_") for n in names) >= 10


@pytest.mark.parametrize("path", BAD_FILES, ids=[p.name for p in BAD_FILES])
def test_bad_file(path):
    load = load_specimen if path.name.startswith("specimen_") else load_params
    with pytest.raises(SpecError) as info:
        load(path)
    err, text = info.value, str(info.value)
    assert "\n" not in text
    assert path.name in text and err.source == str(path)
    assert err.field == _expected_field(path)
    # the document as a whole names no field: "x.yaml: not valid YAML: ..."
    assert text == (f"{path}: {err.message}" if err.field == "<document>" else f"{path}: {err.field}: {err.message}")


def test_spec_error_is_one_line_and_a_value_error():
    err = SpecError("a.yaml", "membrane.L3", "first line\nsecond   line")
    assert isinstance(err, ValueError)
    assert str(err) == "a.yaml: membrane.L3: first line second line"
    assert (err.source, err.field, err.message) == ("a.yaml", "membrane.L3", "first line second line")


def test_spec_error_pickles():
    # calibration may run in worker processes
    err = pickle.loads(pickle.dumps(SpecError("a.yaml", "yeoh.C10", "must be > 0 kPa")))
    assert (err.source, err.field, str(err)) == ("a.yaml", "yeoh.C10", "a.yaml: yeoh.C10: must be > 0 kPa")


def test_with_source():
    err = SpecError("<python>", "eps_r", "x").with_source("p.yaml")
    assert str(err) == "p.yaml: eps_r: x"


@pytest.mark.parametrize(
    "text, match",
    [
        ("a: [1\n", r"^<string>: not valid YAML: .*\(line 2, column 1\)$"),
        ("a: 1\na: 2\n", r"^<string>: not valid YAML: duplicate key 'a' \(line 2, column 1\)$"),
        ("", r"^<string>: the document is empty"),
        ("# only a comment\n", r"the document is empty"),
        ("42\n", r"^<string>: top level is a int \(42\); expected a mapping of keys$"),
        ("!!python/object:os.system {}\n", r"not valid YAML: could not determine a constructor"),
    ],
)
def test_parse_yaml_mapping_errors(text, match):
    with pytest.raises(SpecError, match=match):
        parse_yaml_mapping(text)


def test_nested_duplicate_key_is_refused():
    with pytest.raises(SpecError, match=r"duplicate key 'L3'"):
        parse_yaml_mapping("membrane:\n  L3: 48 um\n  L3: 50 um\n")


def test_read_yaml_mapping_errors(tmp_path):
    with pytest.raises(SpecError, match=r"missing\.yaml: file not found$"):
        read_yaml_mapping(tmp_path / "missing.yaml")
    with pytest.raises(SpecError, match=r": is a directory; expected a YAML file$"):
        read_yaml_mapping(tmp_path)
    latin1 = tmp_path / "latin1.yaml"
    latin1.write_bytes("id: caf\xe9\n".encode("latin-1"))
    with pytest.raises(SpecError, match=r"latin1\.yaml: not UTF-8 text"):
        read_yaml_mapping(latin1)
    good = tmp_path / "good.yaml"
    good.write_text("id: s\n", encoding="utf-8")
    assert read_yaml_mapping(good) == ({"id": "s"}, str(good))
