"""The corpus of malformed protocols in tests/protocols/bad/: each file's first
line is ``# field: <expected field>``; reading, expanding and checking it (with
the paper's L3 = 48 um) must raise one `SpecError` naming the file and field."""

from pathlib import Path

import pytest

from rdea_lab.protocols import expand, first_violation, load_plan
from rdea_lab.specs import SpecError, load_protocol

BAD = Path(__file__).resolve().parent / "bad"
BAD_FILES = sorted(BAD.glob("*.yaml"))
L3 = 48e-6  # [m]

#: problems the brief asks the corpus to cover, by file
COVERED = [
    "unknown_top_key", "unknown_segment_key", "missing_duration", "missing_kind", "unknown_segment_kind",
    "voltage_in_kg", "voltage_bare_number", "duration_bare_number", "negative_duration", "zero_frequency",
    "negative_sample_rate", "nan_value", "empty_stretch", "top_level_list", "broken_yaml", "preset_and_channels",
    "no_waveform", "unknown_preset", "unknown_setting", "durations_differ", "stretch_literal_below_one",
    "sine_dips_below_one", "voltage_above_limit", "field_above_limit", "stretch_above_max", "measure_unknown",
    "measure_empty", "kind_not_allowed", "too_many_samples", "bad_name",
]
#: files that load: the problem is found by the plan check
PLAN_LEVEL = {
    "sine_dips_below_one", "voltage_above_limit", "field_above_limit", "stretch_above_max",
    "preset_above_max_stretch", "negative_voltage_above_limit", "probe_above_voltage_limit",
}


def _expected_field(path: Path) -> str:
    first = path.read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith("# field: "), f"{path.name}: first line must be '# field: ...'"
    return first.removeprefix("# field: ").strip()


def test_the_corpus_covers_the_brief():
    names = {p.stem for p in BAD_FILES}
    assert len(BAD_FILES) >= 30
    assert set(COVERED) <= names and PLAN_LEVEL <= names


@pytest.mark.parametrize("path", BAD_FILES, ids=[p.name for p in BAD_FILES])
def test_bad_file(path):
    if path.stem in PLAN_LEVEL:
        plan = load_plan(path)  # loads and expands fine
        with pytest.raises(SpecError) as info:
            first_violation(plan, L3=L3)
    else:
        with pytest.raises(SpecError) as info:
            first_violation(expand(load_protocol(path)), L3=L3)
    err, text = info.value, str(info.value)
    assert "\n" not in text
    assert path.name in text and err.source == str(path)
    assert err.field == _expected_field(path)
    # the document as a whole names no field: "x.yaml: not valid YAML: ..."
    assert text == (f"{path}: {err.message}" if err.field == "<document>" else f"{path}: {err.field}: {err.message}")
