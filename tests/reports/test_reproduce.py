"""`rdea-lab reproduce` end to end on a shortened campaign (issue 6)."""

import csv
from pathlib import Path

import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import load_params
from rdea_lab.store import open_run

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow  # ~50 s on one core, a quarter of the default suite's wall time; CI runs it with the slow step
def test_reproduce_on_a_short_campaign(capsys, tmp_path, read_page):
    campaign = tmp_path / "short.yaml"
    campaign.write_text(f"""name: short
root: {ROOT}
backend: emulator
truth: truth/paper2021.yaml
seed: 7
out: datasets/short
specimens: [specimens/specimen2.yaml, specimens/specimen1.yaml]
protocols: [protocols/tensile_ramp_sine_0V.yaml, protocols/tensile_ramp_sine_2.6kV.yaml, \
protocols/capacitance_sweep.yaml]
""")
    out = tmp_path / "rep"
    rc = run_cli(cli, ["reproduce", "--campaign", str(campaign), "--out", str(out), "--no-speed", "--quiet"])
    stdout = capsys.readouterr().out
    assert rc == 0, stdout
    datasets = sorted((out / "datasets").rglob("*.nc"))
    assert len(datasets) == 6
    for path in datasets:
        ds = open_run(path)
        assert ds.attrs["status"] == "complete" and ds.attrs["emulated"] == 1
    # calibrated on specimen 2: the emulator's truth is C10 = 242 kPa behind radii off by up to 2 %
    params = load_params(out / "params" / "calibrated.yaml")
    assert params.C10 == pytest.approx(242e3, rel=0.05)
    with open(out / "validation" / "table4.csv") as fh:
        rows = list(csv.DictReader(fh))
    # one row per run: force for the tensile tests, capacitance for the two sweeps (Table 4's rows)
    assert len(rows) == 6 and sum("capacitance" in r["experiment"] for r in rows) == 2
    assert (out / "validation" / "index.html").stat().st_size > 1000
    assert (out / "models" / "models.md").exists() and not (out / "speed").exists()
    assert not list(out.rglob("*.pdf"))  # PNG only, unless --pdf
    assert "Table 4 analogue" in stdout and "EMULATOR" in stdout and "index.html" in stdout
    # the top-level index links the calibration, the validation report, the models and the datasets,
    # every link to something that exists, and its tables fit the page
    page = read_page(out / "index.html")
    for target in ("params/calibrated.yaml", "params/calibrated.history.csv", "validation/index.html",
                   "validation/table4.csv", "models/models.md", "datasets/"):
        assert target in page.links, target
    for href in page.links:
        if not href.startswith("#"):
            assert (out / href).exists(), href
    assert "models/figure5_hollow-core.png" in page.attrs and not any("speed" in h for h in page.links)
    assert len(page.longest_unbreakable()) <= 24, page.longest_unbreakable()
    assert "index.html" in stdout.split("outputs:")[1].splitlines()[1]
    # every force error of this emulator campaign stays small once calibrated (a few percent at most)
    for row in rows:
        if "force" in row["experiment"]:
            assert float(row["max_rel_error"]) < 0.05, row


def test_reproduce_refuses_a_campaign_without_specimen_2(capsys, tmp_path):
    campaign = tmp_path / "c.yaml"
    campaign.write_text(f"""name: c
root: {ROOT}
backend: emulator
out: datasets/c
specimens: [specimens/specimen1.yaml]
protocols: [protocols/tensile_ramp_sine_0V.yaml]
""")
    rc = run_cli(cli, ["reproduce", "--campaign", str(campaign), "--out", str(tmp_path / "r"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and "specimen-2" in err and len(err.strip().splitlines()) == 1
