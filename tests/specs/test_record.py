"""The calibration record (rdea_lab.specs.record): the one reader and writer of a parameter file's
``calibration:`` section. The committed record of the paper's campaign is the reference: read and written
again, it is the same text to the byte."""

import math
from pathlib import Path

import pytest
import yaml

from rdea_lab.specs import CalibrationRecord, SpecError, load_params
from rdea_lab.specs.record import add_record_section

ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "reports" / "paper2021" / "params" / "calibrated.yaml"
TABLE3 = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"


def test_the_committed_record_reads_and_writes_back_byte_for_byte():
    text = COMMITTED.read_text()
    record = CalibrationRecord.of_file(COMMITTED)
    head = text[: text.index("calibration:\n")]
    assert head + record.block() == text
    assert record.model == "su" and record.statistics.nvarys == 6 and record.statistics.nfree == 10796
    assert [r.specimen for r in record.runs] == ["specimen-2", "specimen-2"]
    assert record.parameters["C10"].value == "239.132 kPa" and record.correlation.names[0] == "C10"
    assert load_params(COMMITTED).name  # a record is part of a loadable parameter file


def test_a_file_without_a_record_has_none(tmp_path):
    assert CalibrationRecord.of_file(TABLE3) is None
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: [\n")
    assert CalibrationRecord.of_file(bad) is None


def test_a_record_field_of_the_wrong_kind_names_the_file_and_the_field(tmp_path):
    path = tmp_path / "cal.yaml"
    path.write_text(TABLE3.read_text() + yaml.safe_dump({"calibration": {"runs": [{"samples": "many"}]}}))
    with pytest.raises(SpecError, match=rf"^{path}: calibration\.runs\[0\]\.samples: ") as info:
        CalibrationRecord.of_file(path)
    assert "\n" not in str(info.value)


def test_what_a_newer_record_adds_is_kept_after_the_known_keys():
    record = CalibrationRecord.from_mapping({"extra": {"x": 1}, "model": "su", "aic": None})
    assert list(record.mapping()) == ["model", "extra", "aic"] and record.mapping()["aic"] is None


def test_validation_is_appended_under_the_record_as_text_or_rewritten(tmp_path):
    section = {"held_out": [{"file": "a.nc", "rms_error_N": 0.5, "beyond_calibration": []}],
               "envelope": {"stretch": [1.0, 1.5], "rate_per_s": [None, 0.1], "voltage_V": [0.0, 0.0], "hold_s": 0.0},
               "measures": "legend"}
    path = tmp_path / "cal.yaml"
    path.write_text(COMMITTED.read_text())
    add_record_section(path, section)
    assert path.read_text().startswith(COMMITTED.read_text())  # appended: the record's text kept
    assert CalibrationRecord.of_file(path).validation.envelope["stretch"] == [1.0, 1.5]
    nan = dict(section, held_out=[{"file": "a.nc", "rms_error_N": math.nan}])  # nan != nan: written again
    path.write_text(COMMITTED.read_text())
    add_record_section(path, nan)
    assert math.isnan(CalibrationRecord.of_file(path).validation.held_out[0]["rms_error_N"])
    with pytest.raises(ValueError, match="no calibration section"):
        add_record_section(TABLE3, section)
    with pytest.raises(SpecError, match=r"calibration\.validation\.envelope: "):
        CalibrationRecord.from_mapping({"model": "su"}).with_section("validation", {"envelope": [1]})
