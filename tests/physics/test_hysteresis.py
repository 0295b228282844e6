"""History-aware (path) equilibria: ``solve(..., path=True)`` against a sequential reference.

Under voltage control the 1R and 3R rolls can have two stable states at one
voltage; which one the roll is in depends on where it came from. A voltage
going up and back down therefore traces a hysteresis loop, with a
snap-through at each end of the window of bistability. ``path=True`` treats
the samples as a time series (each from the previous sample's state);
``path=False`` keeps the rule of a rising ramp from 0 V for every sample,
which on the way down drops back to the lower branch at once (the bug this
checks: 1R, hollow core, Yeoh 100/-10/0.5 kPa, stretch 1.2, 0 -> 3.38 kV -> 0
in 700 + 700 samples: 205 of the 700 falling samples, 2.14-3.13 kV, off the
physical path by up to 1.56 MPa).

The reference (``sequential_reference.py``) walks downhill in the free
enthalpy from the previous state, one sample at a time, from nothing but the
models' ``enthalpy`` functions. Tolerances (justified by what the reference
reaches against the package's rising-ramp solver, analytic derivatives, on
the rising halves: stresses within 3e-11 of their scale, fold voltages
within 5e-11 relative, coordinates as below):

* coordinates (lambda2, r_i) ``Y_RTOL = 1e-9`` relative, plus ``ERR_FACTOR``
  times the reference's own error bound for that minimum (``RefPath.y_err``:
  measured rounding noise and truncation of its dg/dy, over g''): on the
  short branch of a narrow bistable window (the active core's open hole,
  above all next to its fold) the minimum is shallow and energy-only
  arithmetic fixes it only to about 1e-9 to 1e-8 relative (6e-7 five
  millivolts from the fold). The package's solvers (analytic derivatives)
  and the reference differ by at most 1.0 y_err on every compared sample,
  and by less than 5e-11 relative on the hollow core;
* stress ``SIG_RTOL = 1e-8`` of the path's largest |sigma1| (the stress moves
  by up to a few times its scale per unit relative change of the coordinate),
  plus ``ERR_FACTOR`` times what y_err moves it by;
* fold voltages ``CV_RTOL = 1e-8`` relative: well below anything a
  physically different fold (or the fold at another stretch) would give, and
  100x the reference's error.

Where the roll would push at the given stretch (sigma1 < 0), the package may
report it slack (status 7) with the fields of a free state at a larger
stretch: those samples' fields are not compared (the snap events are). The
cases at stretch 2.5 (hollow core) and 1.05/1.2 (active core) are taut over
the whole loop, so every sample is compared there.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import brentq

from rdea_lab.physics.models import solve

from physics_cases import RIZZELLO, TABLE3, core
from sequential_reference import H_TOL, Reference

OK, SNAPPED, SLACK = 0, 4, 7
#: Soft Yeoh material of the bug report (eps_r 2.8: with it the folds are at 3.13 and 2.14 kV).
SOFT = SimpleNamespace(C10=100e3, C20=-10e3, C30=0.5e3, eps_r=2.8)

Y_RTOL = 1e-9
SIG_RTOL = 1e-8
ERR_FACTOR = 4.0
CV_RTOL = 1e-8
#: Tension counted as positive / negative beyond this fraction of the stress scale.
TAUT_RTOL = 1e-7
#: No sample may lie closer than this to a fold voltage [V] (the rule is ill-posed right at a fold).
FOLD_MARGIN = 1e-3


def _grid(*parts):
    return np.unique(np.concatenate([np.atleast_1d(np.asarray(p, float)) for p in parts]))


@dataclass(frozen=True)
class Case:
    model: str
    core: str
    material: object
    stretch: float
    up: tuple      # rising voltages; the loop is up followed by up reversed
    taut: bool     # tensile (sigma1 > 0) at every sample of the loop

    @property
    def voltage(self):
        up = np.array(self.up)
        return np.concatenate([up, up[::-1]])

    @property
    def n_up(self):
        return len(self.up)

    @property
    def geom(self):
        return core(self.core)


CASES = {
    # the bug report: the upper branch pushes at stretch 1.2 (about -1 to -1.7 MPa)
    "1r-hollow-1.2": Case("1r", "hollow", SOFT, 1.2, tuple(np.linspace(0.0, 3380.0, 700)), False),
    "1r-hollow-2.5": Case("1r", "hollow", SOFT, 2.5,
                          tuple(_grid(np.linspace(0, 1000, 21), 1000 + 2.5 * np.arange(49))), True),
    "3r-hollow-1.2": Case("3r", "hollow", SOFT, 1.2, tuple(np.linspace(0.0, 3300.0, 111)), False),
    "3r-hollow-2.5": Case("3r", "hollow", SOFT, 2.5,
                          tuple(_grid(np.linspace(0, 1000, 21), 1000 + 2.5 * np.arange(45))), True),
    # active core (Ri = 0): the hole opens at a subcritical pitchfork and closes at a fold.
    # At stretch 1 every loaded sample pushes (about -45 kPa): events only.
    "3r-active-RZ-1.0": Case("3r", "active", RIZZELLO, 1.0,
                             tuple(_grid(np.linspace(0, 2990, 14), 2990 + 0.5 * np.arange(7),
                                         2993 + 0.05 * np.arange(101), 2998 + 0.5 * np.arange(5), 3005)), False),
    "3r-active-RZ-1.05": Case("3r", "active", RIZZELLO, 1.05,
                              tuple(_grid(np.linspace(0, 2845, 14), 2845 + 0.5 * np.arange(11),
                                          2850 + 0.05 * np.arange(31), 2851.5 + 0.5 * np.arange(6), 2860)), True),
    "3r-active-T3-1.0": Case("3r", "active", TABLE3, 1.0,
                             tuple(_grid(np.linspace(0, 2900, 15), 2900 + 2.0 * np.arange(56))), False),
    "3r-active-T3-1.2": Case("3r", "active", TABLE3, 1.2,
                             tuple(_grid(np.linspace(0, 2400, 13), 2400 + 0.5 * np.arange(81))), True),
}
TAUT = [name for name, c in CASES.items() if c.taut]
BLOCK_CASES = ["1r-hollow-2.5", "3r-active-RZ-1.05", "3r-hollow-1.2"]


@functools.lru_cache(maxsize=None)
def reference(name):
    c = CASES[name]
    ref = Reference(c.model, c.geom, c.material)
    return ref, ref.path(c.stretch, c.voltage)


@functools.lru_cache(maxsize=None)
def package(name, path, slack=True):
    """The package's loop: ``path=True``, or the old rule (solve's default, called without ``path``);
    ``slack=False``: the equilibrium at the given stretch even where the roll would push."""
    c = CASES[name]
    kw = {} if slack else {"slack": False}
    if path:
        kw["path"] = True
    return solve(c.model, c.geom, c.material, c.stretch, c.voltage, **kw)


def folds(name):
    """``(k_up, k_down, v_up, v_down)``: the reference's two snap samples and fold voltages."""
    _, rp = reference(name)
    k = np.flatnonzero(rp.status == SNAPPED)
    assert k.size == 2, f"{name}: the loop should cross each fold once, reference snaps at {k}"
    return int(k[0]), int(k[1]), float(rp.critical_voltage[k[0]]), float(rp.critical_voltage[k[1]])


def coordinate(model, res):
    return res.lambda2b if model == "1r" else res.r_i


def ref_coordinate(model, rp):
    return rp.lambda2b if model == "1r" else rp.r_i


def y_atol(case):
    # r_i of a closed hole is exactly 0 in the reference; allow rounding far below any open state
    return 1e-12 * case.geom.Ro if case.model == "3r" else 0.0


def y_err(case, rp):
    """The reference's resolution of the coordinate compared (lambda2, or r_i in metres)."""
    return rp.y_err * (case.geom.Ro if case.model == "3r" else 1.0)


def resolution_at(case, ref, stretch, voltage, y):
    """The reference's resolution (in the compared coordinate) of minima the package returned."""
    scale = case.geom.Ro if case.model == "3r" else 1.0
    out = np.zeros(len(y))
    for k, (l1, v, yk) in enumerate(zip(np.broadcast_to(stretch, len(y)), voltage, y)):
        if not (ref.pitchfork and yk == 0.0):
            out[k] = ref.resolution(l1, v, yk / scale)[0] * scale
    return out


def assert_close(actual, desired, tol, what):
    off = ~(np.abs(actual - desired) <= tol)
    if np.any(off):
        i = int(np.flatnonzero(off)[np.argmax((np.abs(actual - desired) / tol)[off])])
        raise AssertionError(f"{what}: {off.sum()} of {off.size} samples off; worst [{i}]: {actual[i]!r} "
                             f"vs {desired[i]!r} (difference {abs(actual[i] - desired[i]):.3g}, "
                             f"tolerance {tol[i]:.3g})")


def tension_classes(rp):
    scale = np.max(np.abs(rp.sigma1))
    return rp.sigma1 > TAUT_RTOL * scale, rp.sigma1 < -TAUT_RTOL * scale


def assert_states_match(case, res, rp, sel, what):
    assert np.any(sel), f"{what}: nothing to compare"
    y_ref = ref_coordinate(case.model, rp)[sel]
    assert_close(coordinate(case.model, res)[sel], y_ref,
                 Y_RTOL * np.abs(y_ref) + ERR_FACTOR * y_err(case, rp)[sel] + y_atol(case), f"{what}: coordinate")
    if case.model == "3r":
        assert_close(res.lambda2b[sel], rp.lambda2b[sel],
                     Y_RTOL * rp.lambda2b[sel] + ERR_FACTOR * rp.lambda2b_err[sel], f"{what}: lambda2b")
    assert_close(res.sigma1[sel], rp.sigma1[sel],
                 SIG_RTOL * np.max(np.abs(rp.sigma1)) + ERR_FACTOR * rp.sigma1_err[sel], f"{what}: sigma1")


# -- the reference on its own -----------------------------------------------------------------

@pytest.mark.parametrize("model, name, material", [("1r", "hollow", SOFT), ("3r", "hollow", SOFT),
                                                   ("3r", "active", RIZZELLO), ("3r", "active", TABLE3)])
def test_enthalpy_is_psi_minus_v_squared_c(model, name, material):
    """The reference splits g = psi - v**2 c from g at 0 V and at V_REF: g must be exactly quadratic in v."""
    ref = Reference(model, core(name), material)
    rng = np.random.default_rng(7)
    for l1 in (1.0, 1.2, 2.5):
        lo, hi = ref.bounds(l1)
        y = rng.uniform(lo, 0.5 * hi, 50)
        psi, c = ref.psi_c(l1, y)
        assert np.all(c > 0)
        for v in (1.0, 2345.6, 8000.0):
            g = ref.g(l1, v, y)
            np.testing.assert_allclose(g, psi - v * v * c, rtol=0, atol=1e-12 * np.max(np.abs(psi) + v * v * c))


@pytest.mark.parametrize("name", list(CASES))
def test_case_is_well_posed(name):
    """Each loop crosses the up fold once on the way up and the down fold once on the way down; no
    sample sits within FOLD_MARGIN of a fold; the taut cases are tensile everywhere; fold events are
    far from the reference's threshold on both sides (h monotone on every continuous step)."""
    c = CASES[name]
    ref, rp = reference(name)
    k_up, k_dn, v_up, v_dn = folds(name)
    v = c.voltage
    assert k_up < c.n_up <= k_dn
    assert v[k_up - 1] < v_up < v[k_up] and v[k_dn] < v_dn < v[k_dn - 1]
    assert v_dn < v_up
    assert np.min(np.abs(v[:, None] - np.array([v_up, v_dn]))) > FOLD_MARGIN
    if ref.pitchfork:  # the hole opens where h(0+) = v**2: the subcritical pitchfork
        assert v_up == pytest.approx(np.sqrt(ref.h_boundary(c.stretch)), rel=1e-12)
    other = np.ones(v.size, bool)
    other[[k_up, k_dn]] = False
    assert np.max(rp.violation[other]) <= 1e-2 * H_TOL
    assert np.min(rp.violation[~other]) >= 1e2 * H_TOL
    # the other criterion agrees: a snap travels farther than any continuous step
    travel = np.abs(np.diff(np.concatenate([[ref.unloaded(c.stretch)], rp.y])))
    assert np.min(travel[~other]) > np.max(travel[other])
    if c.taut:
        assert np.min(rp.sigma1) > 0


def test_reference_reproduces_the_bug_report():
    """1R, hollow core, stretch 1.2, 0 -> 3.38 kV -> 0 (700 + 700): on the way down 205 of the 700
    samples, 2.14-3.13 kV, are off the rising-ramp state by up to 1.56 MPa; lambda2 1.384 (rising rule)
    against 3.625 (path); at 3.0 kV both 1.2404 and 3.5737 are stable minima."""
    c = CASES["1r-hollow-1.2"]
    ref, rp = reference("1r-hollow-1.2")
    l1, n = c.stretch, c.n_up
    down = c.voltage[n:]
    # the rising-ramp rule at the falling samples' voltages is the path's rising half reversed (a
    # rising path is a rising ramp); checked on every 7th sample and around both folds
    k_up, k_dn, _, _ = folds("1r-hollow-1.2")
    some = np.unique(np.concatenate([np.arange(0, n, 7), np.arange(k_up - 3, k_up + 3), 2 * n - 1 - k_dn
                                     + np.arange(-3, 3)]))
    ramp = ref.rising_rule(l1, c.voltage[some])
    np.testing.assert_allclose(rp.y[some], ramp.y, rtol=1e-10)
    y_ramp, s_ramp = rp.y[:n][::-1], rp.sigma1[:n][::-1]
    off = np.abs(rp.y[n:] - y_ramp) > 1e-6 * y_ramp
    assert off.sum() == 205
    assert round(down[off].min() / 1e3, 2) == 2.14 and round(down[off].max() / 1e3, 2) == 3.13
    dsig = np.abs(rp.sigma1[n:] - s_ramp)
    assert dsig.max() / 1e6 == pytest.approx(1.56, abs=0.005)
    assert np.max(dsig[~off]) < 1e-6 * dsig.max()
    y0 = l1**-0.5
    assert ref.descend(l1, 3000.0, y0) == pytest.approx(1.2404, abs=5e-5)
    assert ref.descend(l1, 3000.0, 5.0) == pytest.approx(3.5737, abs=5e-5)
    v_star = brentq(lambda v: ref.descend(l1, v, y0) - 1.384, 3000.0, 3130.0, xtol=1e-6)
    assert ref.descend(l1, v_star, 5.0) == pytest.approx(3.625, abs=5e-4)


# -- the package against the reference ----------------------------------------------------------

@pytest.mark.parametrize("name", list(CASES))
def test_rising_half_of_reference_equals_the_rising_ramp_rule(name):
    """Validates the reference on the old rule (path=False, at the given stretch: slack=False): on a
    rising voltage the path is the rising-ramp state at every sample, and the fold crossed on the way
    up is the one path=False reports for a state reached through it."""
    c = CASES[name]
    _, rp = reference(name)
    old = package(name, False, slack=False)
    n = c.n_up
    rising = np.arange(c.voltage.size) < n
    assert np.all(np.isin(old.status[:n], (OK, SNAPPED)))
    assert_states_match(c, old, rp, rising, f"{name} rising half, path=False")
    k_up, _, v_up, _ = folds(name)
    assert old.status[k_up] == SNAPPED and np.all(old.status[:k_up] == OK)
    assert old.critical_voltage[k_up] == pytest.approx(v_up, rel=CV_RTOL)


@pytest.mark.parametrize("name", list(CASES))
def test_path_matches_the_sequential_reference(name):
    c = CASES[name]
    _, rp = reference(name)
    res = package(name, True)
    taut, _ = tension_classes(rp)
    event = rp.status == SNAPPED
    # tensile samples are valid states, OK or (at the reference's events) SNAPPED
    assert np.all(res.status[taut & ~event] == OK)
    # slack only where the roll would push
    assert not np.any((res.status == SLACK) & taut)
    if c.taut:
        assert taut.all()
    # every tensile sample, and every sample the package calls OK, is the reference's state
    sel = taut | (res.status == OK)
    assert_states_match(c, res, rp, sel, f"{name} path=True")


@pytest.mark.parametrize("name", [name for name, c in CASES.items() if not c.taut])
def test_path_at_the_given_stretch_matches_the_reference_at_every_sample(name):
    """With ``slack=False`` the package returns the equilibrium at the given stretch even where the
    roll would push: then every sample of the loops that push (the bug report's included) is the
    reference's state, with status 4 exactly at its events and 0 elsewhere."""
    c = CASES[name]
    _, rp = reference(name)
    res = package(name, True, slack=False)
    np.testing.assert_array_equal(res.status, rp.status)
    assert_states_match(c, res, rp, np.ones(c.voltage.size, bool), f"{name} path=True slack=False")
    k = np.flatnonzero(rp.status == SNAPPED)
    np.testing.assert_allclose(res.critical_voltage[k], rp.critical_voltage[k], rtol=CV_RTOL)
    assert np.all(np.isnan(np.delete(res.critical_voltage, k)))


def test_old_rule_at_the_given_stretch_is_the_reported_bug():
    """The bug as reported (stress at the given stretch, negative where the roll pushes): with the old
    rule, on the way down 205 of the 700 samples (2.14-3.13 kV) are off the path, by up to 1.56 MPa."""
    c = CASES["1r-hollow-1.2"]
    _, rp = reference("1r-hollow-1.2")
    old = package("1r-hollow-1.2", False, slack=False)
    n = c.n_up
    assert np.all(np.isin(old.status, (OK, SNAPPED)))
    down = c.voltage[n:]
    off = np.abs(old.lambda2b[n:] - rp.lambda2b[n:]) > 1e-6 * rp.lambda2b[n:]
    assert off.sum() == 205
    assert round(down[off].min() / 1e3, 2) == 2.14 and round(down[off].max() / 1e3, 2) == 3.13
    assert np.max(np.abs(old.sigma1[n:] - rp.sigma1[n:])) / 1e6 == pytest.approx(1.56, abs=0.005)
    # and nowhere else
    rest = np.ones(c.voltage.size, bool)
    rest[n:] = ~off
    assert_states_match(c, old, rp, rest, "old rule off the window")


@pytest.mark.parametrize("name", list(CASES))
def test_snap_events_and_fold_voltages(name):
    """Status 4 exactly at the samples where the reference's state jumped across a fold, with that
    fold's voltage; critical_voltage NaN at every other valid sample."""
    c = CASES[name]
    _, rp = reference(name)
    res = package(name, True)
    k_ref = np.flatnonzero(rp.status == SNAPPED)
    np.testing.assert_array_equal(np.flatnonzero(res.status == SNAPPED), k_ref)
    np.testing.assert_allclose(res.critical_voltage[k_ref], rp.critical_voltage[k_ref], rtol=CV_RTOL)
    valid_other = np.isin(res.status, (OK, SLACK))
    assert np.all(np.isnan(res.critical_voltage[valid_other]))
    k_up, k_dn, _, _ = folds(name)
    # hysteresis in the events: the roll snaps back at a lower voltage than it snapped over
    assert res.critical_voltage[k_dn] < res.critical_voltage[k_up]
    assert c.voltage[k_dn] < c.voltage[k_up]


@pytest.mark.parametrize("name", TAUT)
def test_up_and_down_branches_differ_in_the_window(name):
    """Hysteresis in the states: at a voltage between the two folds the falling path is on the other
    branch than the rising one; outside the window both are on the same branch."""
    c = CASES[name]
    _, rp = reference(name)
    res = package(name, True)
    _, _, v_up, v_dn = folds(name)
    n = c.n_up
    y = coordinate(c.model, res)
    y_up, y_dn = y[:n], y[n:][::-1]
    up = np.array(c.up)
    window = (up > v_dn) & (up < v_up)
    assert window.sum() >= 5
    gap = np.abs(y_dn - y_up)
    assert np.all(gap[window] > 0.1 * np.maximum(np.abs(y_up), np.abs(y_dn))[window])
    err = y_err(c, rp)
    tol = Y_RTOL * np.abs(y_up) + ERR_FACTOR * (err[:n] + err[n:][::-1]) + y_atol(c)
    assert_close(y_dn[~window], y_up[~window], tol[~window], f"{name}: up and down outside the window")


@pytest.mark.parametrize("name", TAUT + ["1r-hollow-1.2"])
def test_old_rule_differs_from_the_path_on_the_way_down(name):
    """Documents the bug: path=False answers every sample from a rising ramp, so on the way down
    through the window it is on the lower branch while the roll is still on the upper one."""
    c = CASES[name]
    _, rp = reference(name)
    old = package(name, False)
    _, _, v_up, v_dn = folds(name)
    n = c.n_up
    v = c.voltage
    window = np.zeros(v.size, bool)
    window[n:] = (v[n:] > v_dn) & (v[n:] < v_up)
    cmp = window & (old.status == OK)
    assert cmp.sum() >= (100 if name == "1r-hollow-1.2" else 5)
    y_old, y_ref = coordinate(c.model, old), ref_coordinate(c.model, rp)
    assert np.all(np.abs(y_old[cmp] - y_ref[cmp]) > 0.1 * np.abs(y_ref[cmp]))
    assert np.all(np.abs(old.sigma1[cmp] - rp.sigma1[cmp]) > 1e3 * SIG_RTOL * np.max(np.abs(rp.sigma1)))
    # outside the window on the way down the old rule is right
    taut, _ = tension_classes(rp)
    out = np.zeros(v.size, bool)
    out[n:] = ~window[n:] & taut[n:] & (old.status[n:] == OK)
    assert_states_match(c, old, rp, out, f"{name} path=False outside the window")


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
@pytest.mark.parametrize("name", BLOCK_CASES)
def test_blocks_continue_with_start_equal_one_call(name, kernel):
    """The loop in three blocks, each started from the previous block's end: identical to one call
    (of the same kernel: ``auto`` may take the compiled path for the whole and the numpy one for a short
    block, which agree to 1e-12). The second block starts exactly at the sample where the roll snaps
    over; the third inside the window on the way down."""
    if kernel == "numba":
        pytest.importorskip("numba")
    c = CASES[name]
    k_up, k_dn, _, _ = folds(name)
    cut1, cut2 = k_up, (c.n_up + k_dn) // 2
    assert c.n_up < cut2 < k_dn
    whole = solve(c.model, c.geom, c.material, c.stretch, c.voltage, path=True, kernel=kernel)
    v = c.voltage
    parts, start = [], None
    for a, b in ((0, cut1), (cut1, cut2), (cut2, v.size)):
        r = solve(c.model, c.geom, c.material, c.stretch, v[a:b], path=True, start=start, kernel=kernel)
        parts.append(r)
        start = r.end
    for field in ("status", "critical_voltage", "sigma1", "force", "lambda2b", "r_i", "capacitance"):
        np.testing.assert_array_equal(np.concatenate([getattr(p, field) for p in parts]), getattr(whole, field),
                                      err_msg=field)


def _monotone_series(name, kind):
    _, _, v_up, v_dn = folds(name)
    mid = 0.5 * (v_up + v_dn)
    if kind == "rising-into-window":
        return np.linspace(0.0, mid, 60)
    if kind == "falling-from-window":
        return np.linspace(mid, 0.0, 60)
    if kind == "falling-below-window":
        return np.linspace(0.98 * v_dn, 0.0, 40)
    raise ValueError(kind)


@pytest.mark.parametrize("kind", ["rising-into-window", "falling-from-window", "falling-below-window"])
@pytest.mark.parametrize("name", TAUT)
def test_monotone_path_without_fold_equals_the_old_rule(name, kind):
    """A path that crosses no fold (the first sample from the unloaded roll by the rising-ramp rule,
    then monotone) is the rising-ramp state at every sample, with no snap event."""
    c = CASES[name]
    ref, _ = reference(name)
    v = _monotone_series(name, kind)
    new = solve(c.model, c.geom, c.material, c.stretch, v, path=True)
    old = solve(c.model, c.geom, c.material, c.stretch, v)
    assert np.all(new.status == OK) and np.all(old.status == OK)
    assert np.all(np.isnan(new.critical_voltage))
    _assert_package_states_agree(c, ref, v, new, old)


@pytest.mark.parametrize("name", TAUT)
def test_rising_through_the_fold_is_the_old_state_with_one_event(name):
    """Rising past the up fold: the same states as the rising-ramp rule, but one snap event, at the
    first sample past the fold."""
    c = CASES[name]
    ref, _ = reference(name)
    _, _, v_up, _ = folds(name)
    v = np.linspace(0.0, 1.01 * v_up, 80)
    assert np.min(np.abs(v - v_up)) > FOLD_MARGIN
    new = solve(c.model, c.geom, c.material, c.stretch, v, path=True)
    old = solve(c.model, c.geom, c.material, c.stretch, v)
    first = int(np.flatnonzero(v > v_up)[0])
    np.testing.assert_array_equal(np.flatnonzero(new.status == SNAPPED), [first])
    assert np.all(new.status[np.arange(v.size) != first] == OK)
    assert new.critical_voltage[first] == pytest.approx(v_up, rel=CV_RTOL)
    assert np.all(np.isnan(np.delete(new.critical_voltage, first)))
    _assert_package_states_agree(c, ref, v, new, old)


def _assert_package_states_agree(c, ref, v, new, old):
    """path=True and path=False states agree to Y_RTOL plus the minimum's resolution (both sides)."""
    y_new, y_old = coordinate(c.model, new), coordinate(c.model, old)
    err = resolution_at(c, ref, c.stretch, v, y_old)
    assert_close(y_new, y_old, Y_RTOL * np.abs(y_old) + 2 * ERR_FACTOR * err + y_atol(c), "coordinate")
    assert_close(new.sigma1, old.sigma1, np.full(v.size, 2 * SIG_RTOL * np.max(np.abs(old.sigma1))), "sigma1")
