"""The inverse twin: the planned voltage drives the forward twin to its force target.

Independent check: `simulate` (the forward twin, path-following, viscoelastic
history from t[0]) on the voltage `voltage_for_force` returns, compared with
the target. SU is closed form (agreement to rounding); 1R, 3R and CR bisect
in v**2 (60 halvings: agreement far below 1e-6).
"""

import numpy as np
import pytest

from rdea_lab.specs import load_params
from rdea_lab.twin import as_geometry, simulate
from rdea_lab.twin.inverse import voltage_for_force

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]
GEOM = as_geometry(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
PARAMS = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
RATE = 500.0  # Hz: fast against the 10 ms branch, so the overstress matters in the ramp


def history(n=1501):
    """Approach ramp to 1.5 in 1 s (no target), then a force target that moves at 1 Hz."""
    t = np.arange(n) / RATE
    stretch = np.where(t < 1.0, 1.0 + 0.5 * t, 1.5)
    force = np.where(t < 1.2, np.nan, 4.05 + 0.1 * np.sin(2 * np.pi * t))
    return t, stretch, force


@pytest.mark.parametrize("model", ["su", "1r", "3r", "cr"])
def test_planned_voltage_drives_the_twin_to_its_target(model):
    t, stretch, force = history(1001 if model == "su" else 801)
    inv = voltage_for_force(GEOM, PARAMS, t, stretch, force, model, max_voltage=3000.0)
    assert inv.reachable.all()
    out = simulate(GEOM, PARAMS, t, stretch, inv.voltage, model)
    m = np.isfinite(force)
    # the requirement is 1e-6; SU is exact to rounding, the bisection to 2**-60 of (3 kV)**2
    assert np.max(np.abs(out["force"].values[m] / force[m] - 1.0)) < 1e-6
    assert np.all(inv.voltage[~m] == 0.0) and np.all(inv.voltage[m] > 0.0)


def test_moving_stretch_includes_the_overstress():
    """A stretch that moves: the overstress (voltage-independent) is part of what the voltage must balance.
    The target is the forward twin's own force under a known voltage: the inverse gives that voltage back."""
    t = np.arange(1001) / RATE
    stretch = 1.3 + 0.05 * np.sin(2 * np.pi * 2.0 * t)
    known = 1500.0 + 500.0 * np.sin(2 * np.pi * 3.0 * t)
    force = simulate(GEOM, PARAMS, t, stretch, known, "su")["force"].values
    inv = voltage_for_force(GEOM, PARAMS, t, stretch, force, "su", max_voltage=3000.0)
    assert inv.reachable.all()
    np.testing.assert_allclose(inv.voltage, known, rtol=1e-9)  # v**2 from a difference of stresses: 1e-9
    out = simulate(GEOM, PARAMS, t, stretch, inv.voltage, "su")
    np.testing.assert_allclose(out["force"].values, force, rtol=1e-12)
    static = voltage_for_force(GEOM, PARAMS.model_copy(update={"branches": ()}), t, stretch, force, "su",
                               max_voltage=3000.0)
    assert np.nanmax(np.abs(static.voltage - known)) > 10.0  # without the overstress the plan is off by volts


def test_out_of_reach_is_flagged_with_the_reachable_range():
    t, stretch, force = history(601)
    force = np.where(np.isfinite(force), 3.5, np.nan)  # below what 3 kV gives at stretch 1.5 (3.91 N)
    inv = voltage_for_force(GEOM, PARAMS, t, stretch, force, "su", max_voltage=3000.0)
    m = np.isfinite(force)
    assert not inv.reachable[m].any() and np.isnan(inv.voltage[m]).all()
    # reachable range at 1.5 (eq. 39, hand check with the numbers of the SU forward model at 0 V and 3 kV)
    out = simulate(GEOM, PARAMS, t, stretch, np.where(m, 3000.0, 0.0), "su")
    np.testing.assert_allclose(inv.force_min[m], out["force"].values[m], rtol=1e-12)
    assert np.all(inv.force_max[m] > inv.force_min[m]) and not inv.fold.any()


def test_the_fold_caps_the_reachable_voltage():
    """The active core (3R) snaps at about 3.0 kV at stretch 1: the branch from 0 V ends there,
    below a 5 kV limit, and the usable voltage is the fold's."""
    geom = as_geometry(ROOT / "rdea_lab" / "data" / "specimens" / "active_core.yaml")
    t = np.arange(3) / RATE
    inv = voltage_for_force(geom, PARAMS, t, np.ones(3), np.full(3, 0.01), "3r", max_voltage=5000.0)
    assert inv.fold.all() and not inv.reachable.any()
    assert 2900.0 < inv.voltage_max[0] < 3100.0
