"""Calibrating on imported real data (issue 7): the VHB 4910 files of ../shared/data."""

from pathlib import Path

import numpy as np
import pytest
from vhb_data import needs_vhb

from rdea_lab.calibration import load_run
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import load_params
from rdea_lab.store import open_run

ROOT = Path(__file__).resolve().parents[2]
pytestmark = needs_vhb


def test_noise_below_stretch_1_is_left_out_and_counted(imported):
    path = imported / "0d01_1d5.nc"
    ds = open_run(path)
    lam = ds["stretch"].values
    below = int(np.sum(lam < 1.0))
    assert below > 0 and lam.min() > 0.999  # real encoder noise at zero load
    run = load_run(path)
    assert run.excluded == below and run.n == lam.size - below
    np.testing.assert_array_equal(run.stretch, lam[run.index])
    assert np.all(run.stretch >= 1.0)


@pytest.mark.slow
def test_calibrate_on_one_rate_of_real_data(capsys, imported, tmp_path):
    out = tmp_path / "vhb.yaml"
    rc = run_cli(cli, ["calibrate", str(imported / "0d01_1d5.nc"), "--model", "1r", "--quiet", "--out", str(out)])
    stdout = capsys.readouterr().out
    assert rc == 0, stdout
    p = load_params(out)
    # VHB 4910's initial shear modulus is some tens of kPa (mu = 2 C10): a plausible range, not a fit target
    assert 5e3 < p.C10 < 100e3
    assert "excluded_samples" in out.read_text()
