"""The shipped campaign's 2.6 kV tensile runs: a roll that would push is slack.

Assumption 1 of the paper: a roll is only ever in tension. Clamped shorter
than its free length under voltage it buckles and the load cell reads its own
offset and noise, nothing compressive. The bound below comes from the truth
file's instrument (independent of the physics): offset - 5 sigma.
"""

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from rdea_lab.specs import load_truth

ROOT = Path(__file__).resolve().parents[2]
RUNS = sorted((ROOT / "datasets" / "paper2021").glob("*/tensile_ramp_sine_2.6kV.nc"))


@pytest.mark.parametrize("path", RUNS, ids=lambda p: p.parent.name)
def test_no_compressive_force_beyond_the_load_cell_noise(path):
    inst = load_truth(ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml").instrument
    with xr.open_dataset(path) as ds:
        force = ds["force"].values
        assert ds.attrs["status"] == "complete"
    force = force[np.isfinite(force)]
    assert force.min() >= inst.force_offset - 5 * inst.force_noise
    # the slack samples are there (the 2.6 kV runs start at stretch 1, where the roll would push):
    # a plateau of readings at the offset, half of it below (a taut roll reads above the offset)
    plateau = np.abs(force - inst.force_offset) < 3 * inst.force_noise
    assert plateau.sum() > 0.1 * force.size
    assert np.sum(force < inst.force_offset) > 0.04 * force.size
