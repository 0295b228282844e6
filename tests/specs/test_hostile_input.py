"""Input built to hang or crash the parsers (issue 11): refused with one line, in well under a second."""

import time
from pathlib import Path

import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import SpecError, parse_quantity, protocol_from_yaml, specimen_from_yaml

ROOT = Path(__file__).resolve().parents[2]
CARD = (ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml").read_text()

#: "billion laughs": nine levels of nine aliases, 9**9 = 387 million strings once expanded
BOMB = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
    f"{c}: &{c} [" + ",".join([f"*{p}"] * 9) + "]\n" for p, c in zip("abcdefgh", "bcdefghi"))


@pytest.mark.parametrize("parse", [specimen_from_yaml, protocol_from_yaml], ids=["card", "protocol"])
@pytest.mark.parametrize("text, words", [
    (BOMB + "id: x\n", "expands to more than"),
    ("id: x\nL1: " + "[" * 500 + "]" * 500 + "\n", "nested"),
    ("id: x\nloop: &l [*l]\n", "recursive"),
])
def test_yaml_built_to_explode_is_refused_quickly(parse, text, words):
    t0 = time.perf_counter()
    with pytest.raises(SpecError, match=words):
        parse(text)
    assert time.perf_counter() - t0 < 1.0  # a bomb took 56-90 s before


def test_the_bomb_through_the_cli_is_exit_2(tmp_path, capsys):
    path = tmp_path / "bomb.yaml"
    path.write_text(BOMB + "name: p\nkind: custom\n")
    assert run_cli(cli, ["protocol", "show", str(path)]) == 2
    err = capsys.readouterr().err
    assert "expands to more than" in err and len(err.strip().splitlines()) == 1


def test_a_unit_is_never_evaluated_as_an_expression():
    t0 = time.perf_counter()
    with pytest.raises(SpecError, match="no arithmetic"):
        parse_quantity("3 kV*10**10**10", "voltage", source="p.yaml", field="limits.max_voltage")
    assert time.perf_counter() - t0 < 0.5


@pytest.mark.parametrize("old, new, words", [
    ("L3: 48 um", "L3: 1e-300 um", "smaller than any real one"),
    ("L3: 48 um", "L3: 48 mm", "must be <= 10000 um, got 48000 um; check the unit"),
    ("L1: 34 mm", "L1: 34 km", "check the unit"),
])
def test_lengths_off_by_a_unit_are_named(old, new, words):
    with pytest.raises(SpecError, match=words) as info:
        specimen_from_yaml(CARD.replace(old, new))
    assert info.value.field == "membrane." + old.split(":")[0]


@pytest.mark.parametrize("name", ["..", ".", ".hidden", "a/b"])
def test_ids_are_names_not_paths(name):
    with pytest.raises(SpecError, match="not a valid name"):
        specimen_from_yaml(CARD.replace("id: specimen-2", f"id: {name!r}"))
