"""The three quasi-static models against the free energy, each other, and Section 3.4."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rdea_lab.physics.geometry import RollGeometry
import functools

from rdea_lab.physics.models import one_ring, su, three_ring
from rdea_lab.physics.models import solve as _solve
from rdea_lab.physics.result import OK, SNAPPED

from physics_cases import RIZZELLO, TABLE3, core

from rdea_lab.reports.baseline_3r_fsolve import solve_3r_fsolve  # independent reference

#: These tests check the models' equations (the paper's, Assumption 1 taken as given):
#: the equilibrium at the given stretch, a negative stress included (slack: test_hard_cases).
solve = functools.partial(_solve, slack=False)

L1_GRID = np.linspace(1.0, 1.75, 76)  # the lambda1 range of Figures 5-7


def equilibrium_enthalpy(model, geom, mat, l1, v):
    """g at the solved equilibrium: the free enthalpy the model minimizes."""
    res = solve(model, geom, mat, l1, v)
    if model == "su":
        return su.enthalpy(geom, mat, l1, v)
    if model == "1r":
        return one_ring.enthalpy(geom, mat, l1, v, res.lambda2b)
    return three_ring.enthalpy(geom, mat, l1, v, res.r_i)


@st.composite
def rolls(draw):
    """Random admissible roll geometries, Ri from 0 up to a thin shell."""
    Ro = 1.8e-3
    Roe = draw(st.floats(0.5, 1.0)) * Ro
    Rie = draw(st.floats(1e-3, 0.95)) * Roe
    Ri = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(0.0, 1.0)) * Rie
    return RollGeometry(Ri, Rie, Roe, Ro, L1=34e-3, L1e=draw(st.floats(0.5, 1.0)) * 34e-3, L3=48e-6)


@settings(max_examples=60, deadline=None)
@given(rolls(), st.floats(1.0, 3.0))
def test_models_coincide_at_zero_volts(geom, l1):
    """At 0 V every ring is uniaxial (lambda2 = lambda1^-1/2 minimizes each ring's Yeoh
    energy), so SU, 1R and 3R are the same model: equal to rounding."""
    s = [solve(m, geom, TABLE3, l1, 0.0) for m in ("su", "1r", "3r")]
    for r in s:
        assert r.all_converged
        assert r.lambda2b == pytest.approx(l1**-0.5, rel=1e-12, abs=0)
    assert s[1].sigma1 == pytest.approx(s[0].sigma1, rel=1e-9, abs=1e-6)
    assert s[2].sigma1 == pytest.approx(s[0].sigma1, rel=1e-9, abs=1e-6)


@pytest.mark.parametrize("v", [0.0, 1000.0, 2600.0, 3500.0, 5000.0])
def test_3r_with_a_single_active_ring_equals_1r(v):
    """Rings a and c of zero volume (Ri = Rie, Roe = Ro): 3R has the 1R energy."""
    geom = RollGeometry(0.5e-3, 0.5e-3, 1.8e-3, 1.8e-3, L1=34e-3, L1e=30e-3, L3=48e-6)
    r1 = solve("1r", geom, RIZZELLO, L1_GRID, v)
    r3 = solve("3r", geom, RIZZELLO, L1_GRID, v)
    assert r1.all_converged and r3.all_converged
    np.testing.assert_allclose(r3.sigma1, r1.sigma1, rtol=1e-9, atol=1e-4)  # 1e-4 Pa: stress ~1e6 Pa
    np.testing.assert_allclose(r3.lambda2b, r1.lambda2b, rtol=1e-10)
    np.testing.assert_allclose(r3.capacitance, r1.capacitance, rtol=1e-10)


@pytest.mark.parametrize("model", ["su", "1r", "3r"])
@pytest.mark.parametrize("name", ["hollow", "active", "passive"])
@pytest.mark.parametrize("v", [0.0, 2600.0, 3500.0])
def test_stress_is_lambda1_times_derivative_of_free_enthalpy(model, name, v):
    """sigma1 = lambda1 dg/dlambda1 (ERRATA), g re-minimized at each stretch: central
    differences with h = 1e-5 (truncation ~h^2 * 1e7 Pa ~ 1e-3 Pa, rounding ~
    eps * 1e6 Pa / h ~ 1e-5 Pa); tolerance 0.5 Pa against stresses of ~1e6 Pa."""
    geom = core(name)
    l1 = np.array([1.1, 1.3, 1.5, 1.7])
    h = 1e-5
    fd = l1 * (equilibrium_enthalpy(model, geom, RIZZELLO, l1 + h, v)
               - equilibrium_enthalpy(model, geom, RIZZELLO, l1 - h, v)) / (2 * h)
    res = solve(model, geom, RIZZELLO, l1, v)
    assert res.all_converged
    np.testing.assert_allclose(res.sigma1, fd, rtol=0, atol=0.5)


def test_3r_equilibrium_is_the_enthalpy_minimum_by_brute_force():
    """A slow straightforward reference: g on a fine grid of r_i, for each core."""
    for name in ("hollow", "active", "passive"):
        geom = core(name)
        for l1 in (1.0, 1.3, 1.75):
            res = solve("3r", geom, RIZZELLO, l1, 3500.0)
            grid = np.linspace(geom.Ri / np.sqrt(l1), 1.5 * geom.Ro, 200_001)
            g = three_ring.enthalpy(geom, RIZZELLO, l1, 3500.0, grid)
            best = g.min()
            # our r_i is at least as low as the grid minimum (up to rounding of g ~ 1e-9 Pa)
            assert three_ring.enthalpy(geom, RIZZELLO, l1, 3500.0, res.r_i) <= best + 1e-9
            assert abs(res.r_i - grid[np.argmin(g)]) < 2e-5 * geom.Ro  # grid step 1.4e-8 m; flat minimum


@pytest.mark.parametrize("radii", [(0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3), (0.3e-3, 0.6e-3, 1.615e-3, 1.732e-3),
                                   (0.0, 0.81e-3, 1.76e-3, 1.8e-3)])
def test_3r_agrees_with_six_equation_fsolve_baseline(radii):
    """The corrected system (27) solved per sample by fsolve (benchmarks/), where its
    stationary point is the physical one: agreement to 1e-9 of the peak stress."""
    rng = np.random.default_rng(3)
    l1, v = rng.uniform(1.0, 1.75, 60), rng.uniform(0.0, 3500.0, 60)
    geom = core(radii)
    base = solve_3r_fsolve(l1, v, Ri=radii[0], Rie=radii[1], Roe=radii[2], Ro=radii[3], L3=48e-6,
                           alpha_e1=1.0, C10=RIZZELLO.C10, C20=RIZZELLO.C20, C30=RIZZELLO.C30, eps_r=2.8)
    res = solve("3r", geom, RIZZELLO, l1, v)
    assert base["converged"].all() and res.all_converged
    np.testing.assert_allclose(res.sigma1, base["sigma1"], rtol=0, atol=1e-9 * np.abs(base["sigma1"]).max())
    np.testing.assert_allclose(res.lambda2b, base["lambda2b"], rtol=1e-9)


def test_3r_avoids_the_uniaxial_saddle_that_fsolve_finds_on_the_active_core():
    """ERRATA: with Ri = 0 the uniaxial state is always stationary. On the active core
    at 3.5 kV it is not the minimum: fsolve (started at the uniaxial point) stays there,
    our solver opens the inner hole, and its enthalpy is strictly lower."""
    geom = core("active")
    l1 = np.array([1.2, 1.5, 1.75])
    base = solve_3r_fsolve(l1, 3500.0 * np.ones(3), Ri=0.0, Rie=0.088e-3, Roe=1.76e-3, Ro=1.8e-3, L3=48e-6,
                           alpha_e1=1.0, C10=RIZZELLO.C10, C20=RIZZELLO.C20, C30=RIZZELLO.C30, eps_r=2.8,
                           guess="su")
    assert np.allclose(base["lambda2b"], l1**-0.5, rtol=1e-9)  # fsolve: the saddle
    res = solve("3r", geom, RIZZELLO, l1, 3500.0)
    assert np.all(res.r_i > 0.05e-3)  # the hole is open (0.06-0.065 mm)
    g_saddle = three_ring.enthalpy(geom, RIZZELLO, l1, 3500.0, 0.0)
    g_ours = three_ring.enthalpy(geom, RIZZELLO, l1, 3500.0, res.r_i)
    assert np.all(g_ours < g_saddle)


def _max_dev(geom, model, v=3500.0):
    ref = solve("3r", geom, RIZZELLO, L1_GRID, v)
    other = solve(model, geom, RIZZELLO, L1_GRID, v)
    assert ref.all_converged and other.all_converged
    return np.max(np.abs(other.sigma1 - ref.sigma1))


# Section 3.4 (ERRATA lists the findings). The paper reads its figures "about"; we assert
# within +-25 % of the paper's value over lambda1 in [1, 1.75] at 3.5 kV and state ours.
def test_section_3_4_hollow_core_su_deviates_about_0_1_MPa():
    dev = _max_dev(core("hollow"), "su")
    assert 0.075e6 <= dev <= 0.125e6  # we get 0.0876 MPa
    assert _max_dev(core("hollow"), "1r") < 0.01e6  # 1R tracks 3R: 0.0010 MPa


def test_section_3_4_active_core_1r_deviates_about_0_1_MPa():
    dev = _max_dev(core("active"), "1r")
    assert 0.075e6 <= dev <= 0.125e6  # we get 0.0900 MPa
    assert _max_dev(core("active"), "su") < 0.01e6  # SU tracks 3R: 0.0040 MPa


def test_section_3_4_passive_core_1r_deviates_about_0_055_MPa():
    dev = _max_dev(core("passive"), "1r")
    assert 0.041e6 <= dev <= 0.069e6  # we get 0.0486 MPa
    # r_i stays exactly 0, so 3R is the SU state; the stresses differ only by the
    # rounding of two formula paths (~1e-16 of 1e6 Pa terms)
    assert np.all(solve("3r", core("passive"), RIZZELLO, L1_GRID, 3500.0).r_i == 0.0)
    assert _max_dev(core("passive"), "su") < 1e-6


@pytest.mark.parametrize("name", ["hollow", "active", "passive"])
def test_section_3_4_all_three_coincide_at_zero_volts(name):
    for model in ("su", "1r"):
        assert _max_dev(core(name), model, v=0.0) < 1e-3  # Pa, against stresses up to 1.24 MPa


def test_figure_8_sweep_moves_from_1r_to_su_behaviour():
    """Figure 8: Rie = 0.6, Roe = 1.21, Ro = 1.33 mm, Ri = 0.1..0.9 Rie. Large Ri: 1R is
    closer to 3R than SU is; small Ri: SU is closer. The transition is smooth."""
    su_dev, r1_dev = [], []
    for f in np.arange(1, 10) / 10:
        geom = core((f * 0.6e-3, 0.6e-3, 1.21e-3, 1.33e-3))
        su_dev.append(_max_dev(geom, "su"))
        r1_dev.append(_max_dev(geom, "1r"))
    assert su_dev[-1] > r1_dev[-1] and su_dev[0] < r1_dev[0]
    assert np.all(np.diff(su_dev) > 0) and np.all(np.diff(r1_dev) < 0)


def test_3r_tends_to_su_as_the_passive_core_shrinks():
    """Ri = 0, Rie -> 0+: the shrinking core ring resists the hole ever more (its hoop
    stretch ~ r_i / Rie), so 3R tends to SU (Section 3.4: 'the roll behaves as a single
    solid uniaxial cylinder'); Rie below 1e-6 Ro is refused rather than half-modelled."""
    devs = []
    for f in (1e-2, 1e-4, 1e-6):
        geom = core((0.0, f * 1.8e-3, 1.35e-3, 1.8e-3))
        l1 = np.array([1.5, 2.0])
        devs.append(np.max(np.abs(solve("3r", geom, TABLE3, l1, 3500.0).sigma1
                                  - solve("su", geom, TABLE3, l1, 3500.0).sigma1)))
    assert devs[0] > devs[1] > devs[2] and devs[2] < 5.0  # Pa; we get 832, 84, 2.6 Pa
    with pytest.raises(ValueError, match="tends to the SU model"):
        core((0.0, 1e-10, 1.35e-3, 1.8e-3))


def test_capacitance_laws():
    """(41): C = C0 lambda1 for SU; (34), (29): C0 lambda1^2 lambda2^2."""
    geom = core("hollow")
    C0 = geom.C0(RIZZELLO.eps_r)
    r = solve("su", geom, RIZZELLO, L1_GRID, 3500.0)
    np.testing.assert_allclose(r.capacitance, C0 * L1_GRID, rtol=1e-14)
    for m in ("1r", "3r"):
        r = solve(m, geom, RIZZELLO, L1_GRID, 3500.0)
        np.testing.assert_allclose(r.capacitance, C0 * (L1_GRID * r.lambda2b) ** 2, rtol=1e-14)


def test_arrays_of_any_shape_and_broadcasting():
    geom = core("passive")
    l1 = np.linspace(1, 1.5, 12).reshape(3, 4)
    for m in ("su", "1r", "3r"):
        r = solve(m, geom, RIZZELLO, l1, np.array([0.0, 1e3, 2e3, 3e3]))
        assert r.sigma1.shape == (3, 4) and r.converged.shape == (3, 4)
        assert np.isin(r.status, (OK, SNAPPED)).all()


def test_unknown_model_is_refused():
    with pytest.raises(ValueError, match="unknown model '4r'; allowed: su, 1r, 3r"):
        solve("4r", core("hollow"), RIZZELLO, 1.2, 0.0)
