"""The validation report on the shared VHB 4910 files (../shared/data), calibrated on part of them.

Fitted: 0d01_1d5 and 0d05_1d5_1 (rates 0.01 and 0.05 1/s to stretch 1.5, as their names say, see the data
folder's README); held out: 0d03_1d5_1 (inside that envelope: rate 0.03, stretch 1.5) and the two runs to
stretch 3.0 (beyond it). Expected roles and flags come from the file names and the hashes of the files,
not from the report. 1R with a small evaluation budget: the test is of the report, not of the fit.
"""

import csv
import hashlib
import re
from pathlib import Path

import pytest
import yaml
from vhb_data import needs_vhb

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli

ROOT = Path(__file__).resolve().parents[2]
pytestmark = needs_vhb
FITTED = ("0d01_1d5", "0d05_1d5_1")
HELD_OUT = ("0d03_1d5_1", "0d01_3d0", "0d05_3d0")
CREDIT = "Chongran-Zhao/VHB4910_data (GitHub)"  # as the imported fixture gives it to rdea-lab import


def stretch_of(name: str) -> float:
    """The nominal maximum stretch in a file name ``0dRR_SdS[_k]``."""
    m = re.fullmatch(r"0d\d\d_(\d)d(\d)(_\d+)?", name)
    return float(f"{m.group(1)}.{m.group(2)}")


@pytest.fixture(scope="module")
def report(imported, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("vhb_report")
    rec = tmp / "vhb.yaml"
    argv = ["calibrate", str(imported), "--model", "1r", "--max-evals", "200", "--quiet", "--out", str(rec)]
    argv += [a for name in HELD_OUT for a in ("--holdout", str(imported / f"{name}.nc"))]
    assert run_cli(cli, argv) == 0
    out = tmp / "report"
    assert run_cli(cli, ["report", "validation", "--params", str(rec), "--datasets", str(imported), "--model", "1r",
                         "--out", str(out), "--no-figures"]) == 0
    with open(out / "table4.csv", newline="") as fh:
        rows = {r["name"]: r for r in csv.DictReader(fh)}
    return rec, out, rows


def test_every_row_says_calibration_run_or_held_out(report, imported):
    rec, _, rows = report
    assert sorted(rows) == sorted(FITTED + HELD_OUT)
    assert {n: rows[n]["role"] for n in rows} == {**{n: "calibration run" for n in FITTED},
                                                  **{n: "held out (same specimen)" for n in HELD_OUT}}
    # the roles rest on the record's hashes: those of the fitted files, byte for byte
    fitted = yaml.safe_load(rec.read_text())["calibration"]["runs"]
    assert sorted(r["sha256"] for r in fitted) == sorted(
        hashlib.sha256((imported / f"{n}.nc").read_bytes()).hexdigest() for n in FITTED)


def test_the_runs_beyond_the_calibrated_stretch_are_flagged(report):
    _, _, rows = report
    for name, r in rows.items():
        if stretch_of(name) > 1.5:
            assert "stretch 3.0 beyond the calibrated 1.5" in r["beyond_calibration"], (name, r["beyond_calibration"])
        else:
            assert r["beyond_calibration"] == "—", (name, r["beyond_calibration"])  # 0d03: inside rate and stretch
        assert float(r["max_stretch"]) == pytest.approx(stretch_of(name), abs=0.01)
        assert r["origin"] == "import" and r["source_file"] == f"{name}.csv"


def test_the_data_credit_and_origin_are_on_the_page(report, read_page):
    _, out, _ = report
    page = read_page(out / "index.html")
    banner = re.search(r'<p class="banner">(.*?)</p>', (out / "index.html").read_text()).group(1)
    assert "5 of 5 runs are measurements imported from other files" in banner and CREDIT in banner
    assert "do not say they are emulated" not in banner
    squeeze = "".join(f"credit: {CREDIT}".split())  # cells as text with their break opportunities taken out
    assert sum(squeeze in "".join(c.split()) for c in page.cells) == 5  # each run's provenance row
    assert "the record's calibration.validation.envelope" in page.text
    assert CREDIT in (out / "table4.md").read_text()
