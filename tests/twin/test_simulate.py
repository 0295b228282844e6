"""Tests of the physics twin: rdea_lab.twin.simulate and rdea_lab.twin.curves.

The references are independent of the code under test: the SU stress and
C0 written out by hand, the viscoelastic ODE (44) integrated by
scipy.integrate.solve_ivp, and analytic limits (no branches, very slow rate).

Reference: Prechtl et al., Smart Mater. Struct. (2021), doi:10.1088/1361-665X/ac34be.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.physics.result import SLACK, StretchBelowOneError
from rdea_lab.specs import load_params, load_specimen
from rdea_lab.twin import quasi_static_curves, simulate

ROOT = Path(__file__).resolve().parents[2]
MM, UM = 1e-3, 1e-6
#: Vacuum permittivity, CODATA 2018 [F/m]; scipy >= 1.15 uses CODATA 2022,
#: 6.8e-10 relative away, hence REL_EPS0 on anything proportional to eps0.
EPS0 = 8.8541878128e-12
REL_EPS0 = 1e-9

# Table 3 of the paper as corrected in ERRATA.md
C10, C20, C30, EPS_R = 242e3, -69e3, 47e3, 2.8
K_V1, ETA_V1 = 8271e3, 86e3
TAU = ETA_V1 / K_V1  # 10.4 ms
# Table 1, specimen 2
L1, L2, L3, L1E = 34 * MM, 99 * MM, 48 * UM, 29 * MM
#: The rolled cross-section equals the flat one: pi (Ro^2 - Ri^2) = 2 L2 L3
#: (volume balance (53)-(55) of the Appendix; two membranes of thickness L3).
AREA = 2 * L2 * L3


@pytest.fixture(scope="module")
def card():
    return load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")


@pytest.fixture(scope="module")
def table3():
    return load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")


def tensile(period=10.0, duration=20.0, rate_hz=100.0):
    """Time [s] and stretch of the 0 V tensile history, 1 + 0.25 (1 - cos(2 pi t / period))."""
    t = np.arange(round(duration * rate_hz) + 1) / rate_hz
    return t, 1.0 + 0.25 * (1.0 - np.cos(2.0 * np.pi * t / period))


def su_stress_hand(l):
    """Reversible SU stress at 0 V, eq. (39): 2 l^2 W'(x) (1 - l^-3), x = l^2 + 2/l - 3."""
    x = l**2 + 2.0 / l - 3.0
    return 2.0 * l**2 * (C10 + 2.0 * C20 * x + 3.0 * C30 * x**2) * (1.0 - l**-3)


def branch_strain_ivp(t, stretch, tau):
    """q = lambda1 - xi of one Maxwell branch, eq. (44), by solve_ivp.

    dq/dt = s(t) - q / tau with s the slope of the linearly interpolated
    stretch. s jumps at every sample, so each interval is integrated on its
    own (an adaptive step across the jumps would lose the accuracy asked for).
    """
    slopes = np.diff(stretch) / np.diff(t)
    q = np.zeros_like(t)
    for i, s in enumerate(slopes):
        sol = solve_ivp(lambda _, y, s=s: s - y / tau, (t[i], t[i + 1]), [q[i]],
                        method="RK45", rtol=1e-10, atol=1e-14)
        q[i + 1] = sol.y[0, -1]
    return q


@pytest.fixture(scope="module")
def tensile_run(card, table3):
    t, lam = tensile()
    return t, lam, simulate(card, table3, t, lam, 0.0, model="su")


def test_area_is_volume_balance(card):
    # independent check of the area used below: Appendix volume balance
    assert geometry_from_card(card).area == pytest.approx(AREA, rel=1e-12)  # float rounding of radii


def test_dataset_schema(tensile_run):
    t, lam, ds = tensile_run
    units = {"stretch": "1", "voltage": "V", "force": "N", "capacitance": "F", "sigma1": "Pa", "sigma1_irr": "Pa"}
    for name, unit in units.items():
        assert name in ds.data_vars, name
        assert ds[name].attrs["units"] == unit, name
        assert ds[name].attrs["long_name"], name
        assert ds[name].dims == ("time",)
    for name in ds.data_vars:  # every variable, not only the six above
        assert {"units", "long_name"} <= set(ds[name].attrs), name
    assert ds["time"].attrs["units"] == f"seconds since {ds.attrs['created']}"  # CF 1.8
    np.testing.assert_array_equal(ds["time"], t)
    np.testing.assert_array_equal(ds["stretch"], lam)
    np.testing.assert_array_equal(ds["voltage"], 0.0)


def test_tensile_force_against_ivp(tensile_run):
    t, lam, ds = tensile_run
    q = branch_strain_ivp(t, lam, TAU)
    visc = K_V1 * q
    # solve_ivp at rtol 1e-10 agrees with the exact exponential update to
    # ~3e-7 Pa on a 13.5 kPa peak; errors decay with exp(-dt/tau) and do not
    # accumulate. 1e-8 of the peak leaves a margin of ~500.
    np.testing.assert_allclose(ds["sigma1_irr"], visc, rtol=0, atol=1e-8 * np.max(np.abs(visc)))
    expected = (su_stress_hand(lam) + visc) * AREA / lam
    # back near stretch 1 the overstress is compressive and exceeds the elastic stress:
    # the roll would push, so it goes slack (force 0, status slack) instead
    pushes = expected < 0
    assert 10 < pushes.sum() < 100
    np.testing.assert_array_equal(ds["model_status"].values[pushes], SLACK)
    expected = np.maximum(expected, 0.0)
    # force ~4 N; the hand formula and the library differ by float rounding
    # (~1e-14 relative) and the IVP by ~1e-12 N: 1e-9 of the peak is ample
    np.testing.assert_allclose(ds["force"], expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    # the rate effect is visible: hysteresis of ~13 kPa, i.e. not a trivial zero
    assert np.max(np.abs(visc)) > 1e4


def test_geometry_object_gives_same_run(card, table3, tensile_run):
    t, lam, ds = tensile_run
    other = simulate(geometry_from_card(card), table3, t, lam, 0.0, model="su")
    np.testing.assert_array_equal(other["force"], ds["force"])


def test_without_branches_force_is_quasi_static(card, table3):
    t, lam = tensile()
    elastic = table3.replace(branches=())
    ds = simulate(card, elastic, t, lam, 0.0, model="su")
    np.testing.assert_array_equal(ds["sigma1_irr"], 0.0)
    curve = quasi_static_curves(card, elastic, "su", lam, [0.0]).curves[0]
    # same stress and the same arithmetic: exactly equal
    np.testing.assert_array_equal(ds["force"], curve.force)
    # and equal to the hand formula up to float rounding (1e-14 relative; abs 1e-12 N at lambda1 = 1)
    np.testing.assert_allclose(ds["force"], su_stress_hand(lam) * AREA / lam, rtol=1e-10, atol=1e-12)


def test_rizzello_params_have_no_viscous_part(card):
    params = load_params(ROOT / "rdea_lab" / "data" / "params" / "rizzello2020.yaml")
    t, lam = tensile()
    ds = simulate(card, params, t, lam, 0.0, model="su")
    np.testing.assert_array_equal(ds["sigma1_irr"], 0.0)


def test_slow_rate_is_quasi_static(card, table3):
    t, lam = tensile(period=1e5, duration=1e5, rate_hz=0.02)  # 2001 samples over one cycle
    ds = simulate(card, table3, t, lam, 0.0, model="su")
    irr = np.abs(ds["sigma1_irr"].values)
    peak = np.max(np.abs(ds["sigma1"].values))
    assert np.max(irr) < 1e-3 * peak
    # analytic bound of a Maxwell branch starting relaxed: |q| <= tau max|dlambda/dt|,
    # so |sigma_irr| <= eta max|dlambda/dt| = 86 kPa s * 0.25 * 2 pi / 1e5 s = 1.35 Pa
    rate_max = 0.25 * 2 * np.pi / 1e5
    assert np.max(irr) <= ETA_V1 * rate_max


def test_capacitance_su_and_1r(card, table3):
    geom = geometry_from_card(card)
    # eq. (41) by hand from the radii; alpha_e1 = L1e / L1
    C0 = EPS0 * EPS_R * (L1E / L1) * L1 * math.pi * (geom.Roe**2 - geom.Rie**2) / L3**2
    t, lam = tensile()
    t, lam = t[:501], lam[:501]  # the rising half-cycle is enough
    su = simulate(card, table3, t, lam, 0.0, model="su")
    np.testing.assert_allclose(su["capacitance"], C0 * lam, rtol=REL_EPS0, atol=0)
    one_ring = simulate(card, table3, t, lam, 0.0, model="1r")
    # at 0 V, 1R sits on the uniaxial state lambda2 = lambda1^-1/2, so
    # C0 lambda1^2 lambda2^2 (eq. 34) = C0 lambda1; the eps0 revision dominates
    np.testing.assert_allclose(one_ring["capacitance"], C0 * lam, rtol=REL_EPS0, atol=0)


def test_nan_stretch_flags_one_sample(card, table3, tensile_run):
    t, lam, clean = tensile_run
    lam = lam.copy()
    lam[700] = np.nan
    ds = simulate(card, table3, t, lam, 0.0, model="su")  # must not raise
    converged = ds["converged"].values
    assert converged[700] == 0
    assert np.all(np.delete(converged, 700) == 1)
    # samples before the gap depend only on earlier samples: bit-identical to
    # the clean run
    np.testing.assert_array_equal(ds["force"][:700], clean["force"][:700])
    assert np.isnan(ds["force"][700])
    # after it the branches carry on as if the stretch were linear across the
    # gap: the stretch error is at most lambda'' (2 dt)^2 / 8 (lambda'' <= 0.25
    # (2 pi 0.1)^2 for this cosine), so the overstress moves by at most k times
    # that, and the force by that times area / stretch
    dt = t[1] - t[0]
    d_stretch = 0.25 * (2 * np.pi * 0.1) ** 2 * (2 * dt) ** 2 / 8
    bound = table3.branches[0].k * d_stretch * np.pi * (1.7393e-3) ** 2
    after = slice(701, None)
    assert np.all(np.isfinite(ds["force"][after]))
    assert np.max(np.abs(ds["force"][after] - clean["force"][after])) <= bound


def test_stretch_below_one_raises(card, table3):
    t, lam = tensile()
    lam = lam.copy()
    lam[300] = 0.99
    with pytest.raises(StretchBelowOneError, match="tension"):
        simulate(card, table3, t, lam, 0.0, model="su")


@pytest.mark.parametrize("model", ["su", "1r", "3r"])
def test_quasi_static_curves_shape(card, table3, model):
    stretch = np.linspace(1.0, 1.5, 7)
    voltages = [0.0, 1000.0, 2600.0]
    out = quasi_static_curves(card, table3, model, stretch, voltages)
    assert out.model == model
    assert out.specimen == "specimen-2" and out.parameters == table3.name
    assert [c.voltage for c in out.curves] == voltages
    for c in out.curves:
        for k in ("stretch", "sigma1", "force", "lambda2b", "capacitance", "converged"):
            assert np.shape(getattr(c, k)) == stretch.shape, k
    # at 0 V every model is on the uniaxial state: the hand SU stress;
    # 1e-8 covers the iterative solvers' stopping tolerance, abs for lambda1 = 1
    np.testing.assert_allclose(out.curves[0].sigma1, su_stress_hand(stretch), rtol=1e-8, atol=1e-3)
    # the same numbers as one table, a row per (voltage, stretch) in the order given
    table = out.table
    assert list(table.columns) == ["voltage", "stretch", "sigma1", "force", "lambda2b", "capacitance", "converged"]
    assert list(table["voltage"]) == [v for v in voltages for _ in stretch]
    np.testing.assert_array_equal(table["force"], np.concatenate([c.force for c in out.curves]))


@pytest.mark.parametrize("branches", [True, False])
def test_time_axis_is_checked_whatever_the_parameters(card, table3, branches):
    params = table3 if branches else table3.replace(branches=())
    lam = np.array([1.0, 1.1, 1.2])
    with pytest.raises(ValueError, match=r"strictly increasing; t\[2\] = 0.5 follows t\[1\] = 1.0"):
        simulate(card, params, [0.0, 1.0, 0.5], lam, 0.0)
    with pytest.raises(ValueError, match="1-D arrays of one length"):
        simulate(card, params, [0.0, 1.0], lam, 0.0)
    with pytest.raises(ValueError, match="time must be finite"):
        simulate(card, params, [0.0, np.nan, 2.0], lam, 0.0)


def test_parameters_are_the_yaml_every_run_writes(card, table3):
    """One encoding of ``parameters`` (issue 14): `simulate` writes what a twin run writes, `dump_params`'s
    YAML, and it reads back as the same parameter set (law and branches included)."""
    from rdea_lab.specs import dump_params, params_from_yaml

    t = np.linspace(0.0, 1.0, 11)
    ds = simulate(card, table3, t, 1.0 + 0.1 * t, 0.0)
    assert ds.attrs["parameters"] == dump_params(table3)
    back = params_from_yaml(ds.attrs["parameters"], "parameters")
    assert back.law == table3.law and back.branches == table3.branches and back.C10 == table3.C10


def test_status_variables_are_cf_flags(card, table3):
    """``model_status`` and ``converged`` name their codes in ``flag_values``/``flag_meanings`` (CF 1.8
    section 3.5), taken from the status codes of `rdea_lab.physics.result`, not spelled in ``long_name``."""
    from rdea_lab.physics.result import STATUS_NAMES

    t = np.linspace(0.0, 1.0, 11)
    ds = simulate(card, table3, t, 1.0 + 0.1 * t, 0.0)
    status = ds["model_status"].attrs
    assert status["flag_values"].dtype == np.int8 and list(status["flag_values"]) == sorted(STATUS_NAMES)
    meanings = status["flag_meanings"].split()
    assert meanings[SLACK] == "slack" and meanings[0] == "ok" and len(meanings) == len(STATUS_NAMES)
    assert ds["converged"].attrs["flag_meanings"] == "no_stable_equilibrium stable_equilibrium"
    assert "time" in ds.coords and ds["time"].encoding["_FillValue"] is None
