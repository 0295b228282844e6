"""The committed reference report (reports/paper2021/, the output of `rdea-lab reproduce`).

A regression baseline: its Table 4 (errors, roles, extrapolation flags, file
hashes) must be what the code's twin and validation report give now on the
datasets it was made from (committed as datasets/paper2021/: the same files)
with the parameters it calibrated (committed). A change to the models, the
twin, the envelope or the error measures that moves a number fails here until
the report is regenerated (``rdea-lab reproduce``, then copy its datasets to
datasets/paper2021/) and committed in a commit that says why. A change to the
emulator or the calibration shows only when the report is regenerated: both
inputs are committed files.
"""

import csv
from pathlib import Path

import pytest

from rdea_lab.reports.validation import validation_report

ROOT = Path(__file__).resolve().parents[2]
REF = ROOT / "reports" / "paper2021"
SHIPPED = ROOT / "datasets" / "paper2021"
MEASURES = ("max_rel_error", "rms_rel_error", "p99_rel_error")


def committed_rows():
    with open(REF / "validation" / "table4.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_the_reference_report_is_complete():
    for name in ("index.html", "params/calibrated.yaml", "validation/index.html", "validation/table4.md",
                 "validation/table4.csv", "validation/table4.tex", "speed/speed.md", "models/models.md"):
        assert (REF / name).is_file(), name
    pngs = sorted(REF.rglob("*.png"))
    assert len(pngs) >= 10
    # a few MB: its datasets are committed once, as datasets/paper2021/ (see .gitignore)
    assert sum(p.stat().st_size for p in REF.rglob("*") if p.is_file() and "datasets" not in p.parts) < 15e6


def test_its_table4_is_what_the_code_gives_on_the_shipped_datasets(tmp_path):
    rows = committed_rows()
    assert len(rows) == 12
    report = validation_report(REF / "params" / "calibrated.yaml", SHIPPED, tmp_path, model="su", figures=False)
    now = {(r["specimen"], r["protocol"]): r for r in report["rows"]}
    assert len(now) == 12
    for row in rows:
        r = now[(row["specimen"], row["protocol"])]
        for key in MEASURES:
            assert float(row[key]) == pytest.approx(r[key], rel=1e-9, abs=1e-15), (row["specimen"], row["protocol"], key)
        assert int(row["samples"]) == r["samples"]
        # the same files: the fitted runs are found by their hashes, so roles and flags are the report's
        assert (row["sha256"], row["role"], row["beyond_calibration"]) == (r["sha256"], r["role"],
                                                                          r["beyond_calibration"])
    roles = sorted(r["role"] for r in rows)
    assert roles.count("calibration run") == 2 and roles.count("held out (same specimen)") == 2
    assert sum("beyond" in r["beyond_calibration"] for r in rows) == 3  # the blocking runs' 15 s hold


def test_its_datasets_link_goes_somewhere():
    assert "datasets/" in (REF / "index.html").read_text(encoding="utf-8")
    assert (REF / "datasets" / "README.md").is_file()
