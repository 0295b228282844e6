"""The hard cases of the physics core, each a named test."""

from types import SimpleNamespace

import numpy as np
import pytest

from rdea_lab.physics.geometry import RollGeometry
from rdea_lab.physics.models import solve, three_ring
from rdea_lab.physics.models._common import HOOP_STRETCH_CAP, kappa
from rdea_lab.physics.result import (BAD_INPUT, LIMIT_POINT, OK, OUTSIDE_RANGE, SLACK, SNAPPED,
                                     StretchBelowOneError)

from physics_cases import RIZZELLO, TABLE3, core

MODELS = ("su", "1r", "3r")
SPECIMEN2 = (0.0, 0.6026e-3, 1.6211e-3, 1.7393e-3)  # our appendix radii of specimen 2


def test_Ri_zero_specimen2_stays_uniaxial_at_paper_voltage_and_opens_at_high_voltage():
    """Ri = 0: at 2.6 kV the 3R state is the SU state (r_i = 0); at 8 kV the inner
    hole opens (the pitchfork of ERRATA), with lower enthalpy than the saddle r_i = 0."""
    geom = core(SPECIMEN2, L1e=29e-3)
    l1 = np.linspace(1.0, 1.5, 26)
    r3 = solve("3r", geom, TABLE3, l1, 2600.0)
    assert np.all(r3.r_i == 0.0)
    np.testing.assert_allclose(r3.sigma1, solve("su", geom, TABLE3, l1, 2600.0).sigma1, rtol=0, atol=1e-6)
    # the bifurcation voltage falls with stretch (it is 8.8 kV at lambda1 = 1 for the
    # Section 3.4 material on this geometry): at 8 kV the hole is open from 1.2 on
    l1 = np.linspace(1.2, 1.5, 16)
    hi = solve("3r", geom, TABLE3, l1, 8000.0)
    assert hi.all_converged and np.all(hi.r_i > 0)
    assert np.all(three_ring.enthalpy(geom, TABLE3, l1, 8000.0, hi.r_i)
                  < three_ring.enthalpy(geom, TABLE3, l1, 8000.0, 0.0))


@pytest.mark.parametrize("v", [0.0, 3500.0])
def test_ring_a_vanishing(v):
    """Ri -> Rie: the solution tends continuously to the one without ring a."""
    l1 = np.linspace(1.0, 1.75, 16)
    limit = solve("3r", core((0.88e-3, 0.88e-3, 1.76e-3, 1.8e-3)), RIZZELLO, l1, v)
    assert limit.all_converged and np.all(np.isnan(limit.lambda2a))
    for gap in (1e-3, 1e-6, 1e-9, 1e-12):
        geom = core((0.88e-3 * (1 - gap), 0.88e-3, 1.76e-3, 1.8e-3))
        r = solve("3r", geom, RIZZELLO, l1, v)
        assert r.all_converged
        # ring a carries a fraction eta_a (~0.6 gap) of the volume; what it changes is
        # bounded by eta_a times the stress scale (1.24 MPa at lambda1 = 1.75)
        assert np.max(np.abs(r.sigma1 - limit.sigma1)) <= 1.24e6 * geom.eta_a + 1e-6


@pytest.mark.parametrize("v", [0.0, 3500.0])
def test_ring_c_vanishing(v):
    """Roe -> Ro: likewise, for the outer passive ring."""
    l1 = np.linspace(1.0, 1.75, 16)
    for Ri in (0.0, 0.86e-3):
        limit = solve("3r", core((Ri, 0.88e-3, 1.8e-3, 1.8e-3)), RIZZELLO, l1, v)
        assert limit.all_converged and np.all(np.isnan(limit.lambda2c))
        near = solve("3r", core((Ri, 0.88e-3, 1.8e-3 * (1 - 1e-10), 1.8e-3)), RIZZELLO, l1, v)
        assert near.all_converged
        np.testing.assert_allclose(near.sigma1, limit.sigma1, rtol=0, atol=1e-2)  # eta_c ~ 2e-10


def test_thin_shell():
    """Ri close to Ro (a 0.1 mm wall at 1.8 mm): a thin shell is a rolled strip, so 3R
    follows 1R closely, and agrees with the per-sample fsolve reference."""
    from rdea_lab.reports.baseline_3r_fsolve import solve_3r_fsolve

    radii = (1.70e-3, 1.705e-3, 1.795e-3, 1.8e-3)
    geom = core(radii)
    l1 = np.linspace(1.0, 1.75, 16)
    v = np.full(16, 3500.0)
    r3 = solve("3r", geom, RIZZELLO, l1, v, slack=False)  # the equations, as fsolve solves them
    r1 = solve("1r", geom, RIZZELLO, l1, v, slack=False)
    assert r3.all_converged and r1.all_converged
    assert np.max(np.abs(r3.sigma1 - r1.sigma1)) < 0.01 * np.max(np.abs(r1.sigma1))
    base = solve_3r_fsolve(l1, v, Ri=radii[0], Rie=radii[1], Roe=radii[2], Ro=radii[3], L3=48e-6, alpha_e1=1.0,
                           C10=RIZZELLO.C10, C20=RIZZELLO.C20, C30=RIZZELLO.C30, eps_r=2.8)
    np.testing.assert_allclose(r3.sigma1, base["sigma1"], rtol=0, atol=1e-8 * np.max(np.abs(r3.sigma1)))


@pytest.mark.parametrize("model", MODELS)
def test_stretch_exactly_one_and_one_plus_1e_12(model, any_core):
    """At rest the stress is exactly 0; at 1 + e (e = 1e-12, exact as l1 - 1) it is the
    small-strain value 6 C10 e (Young's modulus 3 mu = 6 C10) to 1e-6: the invariants' arrangement
    (`yeoh._invariant_terms`) keeps the digits the naive formula loses."""
    assert solve(model, any_core, TABLE3, 1.0, 0.0).sigma1 == 0.0
    l1 = 1.0 + 1e-12
    e = l1 - 1.0
    assert solve(model, any_core, TABLE3, l1, 0.0).sigma1 == pytest.approx(6 * TABLE3.C10 * e, rel=1e-6, abs=0)
    r = solve(model, any_core, TABLE3, np.array([1.0, l1]), 2600.0, slack=False)  # compressive under voltage
    assert r.all_converged and np.all(r.sigma1 < 0)
    # ... which a roll cannot carry: it is slack, in its free state at a larger stretch with zero stress
    s = solve(model, any_core, TABLE3, np.array([1.0, l1]), 2600.0)
    assert np.all(s.status == SLACK) and np.all(s.force == 0.0) and np.all(s.sigma1 == 0.0)
    np.testing.assert_array_equal(s.tension, r.sigma1)
    assert np.all(s.free_stretch > np.array([1.0, l1]))
    free = solve(model, any_core, TABLE3, s.free_stretch, 2600.0, slack=False)
    assert np.all(np.abs(free.sigma1) <= 1e-6 * np.abs(r.sigma1))  # the free state carries no stress
    np.testing.assert_allclose(s.capacitance, free.capacitance, rtol=1e-9)
    np.testing.assert_allclose(s.lambda2b, free.lambda2b, rtol=1e-9)


@pytest.mark.parametrize("model", MODELS)
def test_stretch_three(model, any_core):
    l1 = np.linspace(1.0, 3.0, 41)
    for v in (0.0, 3500.0):
        r = solve(model, any_core, TABLE3, l1, v, slack=False)
        assert r.all_converged
        assert np.all(np.diff(r.sigma1) > 0)  # stress grows with stretch over the whole range
    r0 = [solve(m, any_core, TABLE3, 3.0, 0.0).sigma1 for m in MODELS]
    assert r0[1] == pytest.approx(r0[0], rel=1e-9, abs=0) and r0[2] == pytest.approx(r0[0], rel=1e-9, abs=0)


# A weakly stiffening material (admissible: C20^2 < 3 C10 C30 keeps dW/dI1 > 0) whose
# 1R branch folds at a few kV and re-stabilizes; a neo-Hookean one whose branch has an
# asymptote (no fold); and a softening one without C30, whose branch folds for good.
WEAK = SimpleNamespace(C10=242e3, C20=-20e3, C30=1e3, eps_r=2.8)
NEO = SimpleNamespace(C10=242e3, C20=0.0, C30=0.0, eps_r=2.8)
SOFT = SimpleNamespace(C10=242e3, C20=-20e3, C30=0.0, eps_r=2.8)


def reference_1r(geom, mat, l1):
    """Independent of the solver: along the 1R equilibria the voltage is explicit,
    v(l2)^2 = psi_2 / (2 l2 kappa l1^2) (eq. 33), on a grid over the admissible range.
    Returns the grid's v and the indices of its local maxima (folds) and minima."""
    l2 = np.linspace(l1**-0.5, HOOP_STRETCH_CAP * l1**-0.5, 2_000_001)
    x = l1**2 + l2**2 + (l1 * l2) ** -2 - 3
    W1 = mat.C10 + 2 * mat.C20 * x + 3 * mat.C30 * x**2
    psi_2 = W1 * (2 * l2 - 2 * l1**-2 * l2**-3)
    with np.errstate(invalid="ignore"):
        v = np.sqrt(np.maximum(psi_2, 0) / (2 * l2 * kappa(geom, mat) * l1**2))
    d = np.diff(v)
    maxima = np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0)) + 1
    minima = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0)) + 1
    return v, maxima, minima


@pytest.mark.parametrize("l1", [1.0, 1.2, 1.5])
def test_fold_snap_and_the_end_of_the_solved_range(l1):
    """WEAK folds at v_c and re-stabilizes: past v_c the ramp snaps to the expanded branch
    (SNAPPED, critical voltage = the fold's); past the voltage at the range's end the state
    is outside the solved range (no fold reported: the range is not a limit point)."""
    geom = core("hollow")
    v, maxima, minima = reference_1r(geom, WEAK, l1)
    assert maxima.size == 1 and minima.size == 1  # one fold pair: an S-shaped branch
    v_c, v_end = v[maxima[0]], v[-1]
    below = solve("1r", geom, WEAK, l1, v_c * (1 - 1e-4), slack=False)
    assert below.status == OK and np.isfinite(below.sigma1)
    past = solve("1r", geom, WEAK, l1, np.array([v_c * (1 + 1e-4), 1.5 * v_c, 0.999 * v_end]), slack=False)
    assert np.all(past.status == SNAPPED)
    assert np.all(past.critical_voltage == pytest.approx(v_c, rel=1e-7, abs=0))  # grid step ~5e-6 in l2
    out = solve("1r", geom, WEAK, l1, 1.001 * v_end, slack=False)
    assert out.status == OUTSIDE_RANGE and np.isnan(out.critical_voltage) and np.isnan(out.sigma1)
    assert float(out.range_voltage) == pytest.approx(v_end, rel=1e-9)
    assert "outside solved range" in out.summary() and "past limit point" not in out.summary()


def test_a_fold_with_nothing_beyond_is_a_limit_point():
    """SOFT (no strain stiffening) folds and never re-stabilizes: past the fold, pull-in."""
    geom = core("hollow")
    l1 = 1.2
    v, maxima, _ = reference_1r(geom, SOFT, l1)
    v_c = v[maxima[0]]
    r = solve("1r", geom, SOFT, l1, np.array([0.99 * v_c, 1.01 * v_c, 3 * v_c]), slack=False)
    assert r.status[0] == OK and np.all(r.status[1:] == LIMIT_POINT)
    assert np.all(r.critical_voltage[1:] == pytest.approx(v_c, rel=1e-7, abs=0))
    assert np.all(np.isnan(r.sigma1[1:])) and "past limit point" in r.summary()


def test_neo_hookean_has_no_equilibrium_above_its_asymptote():
    """Neo-Hookean 1R: K(l2) = C10 (1 - l1^-2 l2^-4) rises to C10 without a fold, so no
    equilibrium exists above v* = sqrt(C10 / kappa) / l1. That is not a limit point: the
    result says the state is outside the solved range, which ends at
    v* sqrt(1 - l1^-2 cap^-4) (the hoop stretch cap / sqrt(l1))."""
    geom = core("hollow")
    l1 = 1.2
    v_star = np.sqrt(NEO.C10 / kappa(geom, NEO)) / l1
    r = solve("1r", geom, NEO, l1, np.array([0.9 * v_star, 1.01 * v_star]), slack=False)
    assert r.status[0] == OK and r.status[1] == OUTSIDE_RANGE and np.isnan(r.critical_voltage[1])
    cap = HOOP_STRETCH_CAP / np.sqrt(l1)
    assert r.range_voltage[1] == pytest.approx(v_star * np.sqrt(1 - l1**-2 * cap**-4), rel=1e-12, abs=0)


def test_3r_fold_matches_brute_force_enthalpy():
    """3R on the weak material: just below the reported critical voltage a local minimum of
    g exists near the unloaded state (found on a grid), just above the branch is gone."""
    geom = core("hollow")
    l1 = 1.2
    r = solve("3r", geom, WEAK, l1, 6e3, slack=False)
    assert r.status == SNAPPED
    v_c = float(r.critical_voltage)
    xs = np.linspace(geom.Ri / np.sqrt(l1), 3 * geom.Ro, 400_001)

    def first_local_min(v):
        g = three_ring.enthalpy(geom, WEAK, l1, v, xs)
        i = np.flatnonzero((g[1:-1] <= g[:-2]) & (g[1:-1] <= g[2:]))
        return xs[i[0] + 1] if i.size else np.inf

    before = solve("3r", geom, WEAK, l1, 0.99 * v_c, slack=False)
    assert before.status == OK
    assert first_local_min(0.99 * v_c) == pytest.approx(float(before.r_i), abs=2 * (xs[1] - xs[0]))
    assert first_local_min(1.01 * v_c) > 1.2 * float(before.r_i)  # the nearby minimum has vanished
    # ... and the snapped state is the first minimum beyond it
    assert first_local_min(1.01 * v_c) == pytest.approx(
        float(solve("3r", geom, WEAK, l1, 1.01 * v_c, slack=False).r_i), abs=2 * (xs[1] - xs[0]))


@pytest.mark.parametrize("model", MODELS)
def test_negative_C20(model):
    """Table 3 has C20 = -69 kPa; a stronger softening C20 = -150 kPa (still admissible
    with C30 = 40 kPa: C20^2 = 2.25e10 < 3 C10 C30 = 2.9e10) keeps every model well posed.
    (Its uniaxial stress need not rise monotonically: dW/dI1 > 0 only makes it positive.)"""
    soft = SimpleNamespace(C10=242e3, C20=-150e3, C30=40e3, eps_r=2.8)
    l1 = np.linspace(1.0, 3.0, 81)
    for geom in (core("hollow"), core("passive")):
        r0 = solve(model, geom, soft, l1, 0.0)
        assert r0.all_converged and np.all(r0.sigma1[1:] > 0)
        # at 0 V the three models coincide; compare with SU's closed form
        np.testing.assert_allclose(r0.sigma1, solve("su", geom, soft, l1, 0.0).sigma1, rtol=1e-9, atol=1e-6)
        r = solve(model, geom, soft, l1, 2600.0)
        assert r.all_converged and np.all(np.isfinite(r.sigma1))


@pytest.mark.parametrize("model", MODELS)
def test_nan_in_the_input_is_flagged_not_fatal(model):
    geom = core("active")
    l1 = np.array([1.1, np.nan, 1.3, 1.4, np.inf])
    v = np.array([3500.0, 3500.0, np.nan, 3500.0, 0.0])
    r = solve(model, geom, RIZZELLO, l1, v)
    assert list(r.status == BAD_INPUT) == [False, True, True, False, True]
    assert np.all(np.isnan(r.sigma1[r.status == BAD_INPUT]))
    clean = solve(model, geom, RIZZELLO, l1[[0, 3]], v[[0, 3]])
    np.testing.assert_array_equal(r.sigma1[[0, 3]], clean.sigma1)
    assert "NaN or infinite input" in r.summary()


@pytest.mark.parametrize("model", MODELS)
def test_stretch_below_one_is_a_clear_error(model):
    with pytest.raises(StretchBelowOneError, match=r"stretch 0\.99 at sample 1 is below 1.*tension"):
        solve(model, core("passive"), RIZZELLO, np.array([1.0, 0.99, 1.2]), 0.0)


# ------------------------------------------------------------- overflow and empty input (issue 12, item 5)
def test_a_stretch_whose_stress_overflows_is_flagged_never_ok():
    """Past about 1e51 the Yeoh energy (which grows as lambda1**2 to the cube) overflows double precision:
    the answer is no number with its own status, never an inf or NaN flagged ok."""
    import numpy as np

    from rdea_lab.physics.geometry import RollGeometry
    from rdea_lab.physics.models import solve
    from rdea_lab.physics.result import OVERFLOW, VALID
    from rdea_lab.specs import ParameterSet

    geom = RollGeometry(0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3, L1=34e-3, L1e=34e-3, L3=48e-6)
    material = ParameterSet(name="t", C10=242e3, C20=-69e3, C30=47e3, eps_r=2.8)
    stretch = np.array([1.5, 1e52, 1e300])
    for model in ("su", "1r", "3r"):
        with np.errstate(all="ignore"):
            res = solve(model, geom, material, stretch, 0.0)
        assert res.status[0] in VALID and np.isfinite(res.force[0])
        assert list(res.status[1:]) == [OVERFLOW, OVERFLOW], model
        assert np.all(np.isnan(res.force[1:])) and not res.converged[1:].any()


def test_viscoelastic_stress_of_empty_or_all_nan_input():
    import numpy as np

    from rdea_lab.physics.viscoelastic import branch_strains, overstress

    assert overstress([], [], [1e5], [1e5], 10.0).shape == (0,)
    assert branch_strains([], [], [1.0, 2.0]).shape == (2, 0)
    sigma = overstress([0.0, 1.0], [np.nan, np.nan], [1e5], [1e5], 10.0)
    assert sigma.shape == (2,) and np.all(np.isnan(sigma))


# ------------------------------------------------------------- a hollow micro-core's fold (issue 30, item 1)
#: A hollow roll with a 40 nm hole (Ri/Ro = 2e-5) and a 2.2 um ring a, on a softening Yeoh material: h rises
#: from 0 at r_i = Ri l1**-0.5 and folds at r_i ~ 0.6 um, 1/3500 of the range's first regular scan node.
MICRO = RollGeometry(40e-9, 2.2e-6, 0.56e-3, 2e-3, L1=30e-3, L1e=30e-3, L3=50e-6)
MICRO_MAT = SimpleNamespace(C10=180e3, C20=-37e3, C30=6.3e3, eps_r=4.0)


@pytest.mark.parametrize("l1", [1.0, 1.1])
def test_hollow_micro_core_fold_is_seen(l1):
    """Below the fold (0.5, 0.9, 0.999 of its voltage) the state is the near minimum; past it (1.001,
    1.5) the roll snapped to the far one, critical voltage the fold's. Against brute force, on the rising
    ramp rule and on a rising path. (The scan, graded toward the core only for solid rolls, stepped over
    the fold: the far state, 2.8x out at 0.999, was returned as OK, and past the fold OK for SNAPPED.)"""
    import brute_force as bf

    land = bf.landscape("3r", MICRO, MICRO_MAT, l1)
    assert land.fold_index is not None and land.fold_y * MICRO.Ro < 1e-6  # the fold, within 1 um of the axis
    v_f = np.sqrt(land.fold_h)
    v = v_f * np.array([0.5, 0.9, 0.999, 1.001, 1.5])
    ref = [land.rising_state(x) for x in v]
    assert [s.expected for s in ref] == [OK, OK, OK, SNAPPED, SNAPPED] and not any(s.ambiguous for s in ref)
    ramp = solve("3r", MICRO, MICRO_MAT, np.full(v.size, l1), v, slack=False)
    path = solve("3r", MICRO, MICRO_MAT, np.full(v.size, l1), v, slack=False, path=True)
    assert list(ramp.status) == [OK, OK, OK, SNAPPED, SNAPPED]
    assert list(path.status) == [OK, OK, OK, SNAPPED, OK]  # a path flags the snap where it happens
    for res in (ramp, path):
        for k, s in enumerate(ref):
            assert abs(float(res.r_i[k]) - s.r_i) <= s.tol * MICRO.Ro, (k, float(res.r_i[k]), s.r_i)
    for res in (ramp, path):
        assert float(res.critical_voltage[3]) == pytest.approx(v_f, rel=1e-6, abs=0)
