"""The refinement of a root (`branch.newton_step`, which `branch._refine_root` and the kernels iterate, with a
safeguarded second pass) on a synthetic wiggly ``h``, checked against the function itself in long double: the
ramp rule never leaves a bracketed root unconverged, and each root it returns is one to the float spacing
(``h - K`` changes sign within two floats of it, or ``h = K`` to the refinement's rounding floor) beyond ``y0``
and no later than the first scan node where ``h`` reaches ``K``; and the compiled step gives the numpy step's
bits.

The family: ``h(y) = x + a (sin(w x + p) - sin p)``, ``x = y - y0``, with ``a w`` from 0.3 to 5 (``h`` falls
between rises where it exceeds 1) and up to a thousand wiggles in the range, so that a scan bracket often
holds several roots; ``y0`` from 3 to 5 and a range of 0.01 to 0.1, so that the tolerance ``1e-14 * span`` is
at or below the float spacing at ``y`` (4.4e-16 or 8.9e-16). There the refinement cycled between two adjacent
floats on either side of the root until it ran out of iterations (NOT_CONVERGED, 9 of these 20000 samples
before it stopped at such a bracket), from the inverse-Hermite start and from the midpoint alike.
"""

from __future__ import annotations

import numpy as np
import pytest

from rdea_lab.physics import branch
from rdea_lab.physics.result import NOT_CONVERGED, OK, SNAPPED


def _wiggly(n, seed):
    rng = np.random.default_rng(seed)
    y0 = rng.uniform(3.0, 5.0, n)
    span = 10.0 ** rng.uniform(-2.0, -1.0, n)
    w = 10.0 ** rng.uniform(0.0, 3.0, n) / span
    a = rng.uniform(0.3, 5.0, n) / w
    p = rng.uniform(0.0, 2.0 * np.pi, n)
    K = rng.uniform(0.0, 1.0, n) * span

    def h(y, idx, sin=np.sin):
        x = y - y0[idx]
        return x + a[idx] * (sin(w[idx] * x + p[idx]) - sin(p[idx]))

    def terms(y, idx, second):
        x = y - y0[idx]
        one = np.ones_like(y)
        return h(y, idx), 1.0 + a[idx] * w[idx] * np.cos(w[idx] * x + p[idx]), one, 0.0 * one

    params = [np.asarray(v, np.longdouble) for v in (y0, a, w, p, K)]
    return branch.Problem(terms, y0, y0 + span, K, np.ones(n)), h, params


def _g_exact(y, idx, params):
    """``h(y) - K`` in long double (``y`` a float)."""
    y0, a, w, p, K = (v[idx] for v in params)
    x = np.asarray(y, np.longdouble) - y0
    return x + a * (np.sin(w * x + p) - np.sin(p)) - K


def test_wiggly_h_every_bracketed_root_converges_to_a_root():
    n = 20000
    problem, h, params = _wiggly(n, 1)
    res = branch.follow_branch(problem)
    assert not np.any(res.status == NOT_CONVERGED), np.flatnonzero(res.status == NOT_CONVERGED)
    found = np.flatnonzero((res.status == OK) | (res.status == SNAPPED))
    assert found.size > n // 4  # the family reaches its loads (the rest folds or leaves the range)
    y = res.y[found]
    # a root (long double, independent of the float iteration): h - K changes sign within two floats of y, or
    # h(y) is K to the refinement's rounding floor (|g_y| within 64 eps of the size of its two terms, h and K)
    step = 2.0 * np.spacing(y)
    lo_g, hi_g = _g_exact(y - step, found, params), _g_exact(y + step, found, params)
    K = problem.K[found]
    g = _g_exact(y, found, params)
    root = (lo_g * hi_g <= 0.0) | (np.abs(g) <= 64.0 * np.finfo(float).eps * (np.abs(g + K) + K))
    assert np.all(root), found[~root][:5]
    # no later than the first scan node where h reaches K (the ramp rule's bracket ends there), after y0
    Y = branch.scan_nodes(problem)[found]
    H = h(Y, found[:, None])
    k = np.argmax(H >= problem.K[found, None], axis=1)
    assert np.all(H[np.arange(found.size), k] >= problem.K[found])  # every sample's h reaches K at a node
    assert np.all((y > problem.y0[found]) & (y <= Y[np.arange(found.size), k]))
    # the family has brackets holding several roots: h - K changes sign 3+ times between the two nodes
    rows = np.arange(found.size)
    a, b = np.concatenate([problem.y0[found, None], Y], axis=1)[rows, k], Y[rows, k]
    dense = a[:, None] + np.linspace(0.0, 1.0, 65) * (b - a)[:, None]
    changes = np.sum(np.diff(np.sign(h(dense, found[:, None]) - problem.K[found, None]), axis=1) != 0, axis=1)
    assert np.sum(changes >= 3) > 100, np.sum(changes >= 3)


def _steps(rng, n):
    """Inputs of `branch.newton_step`: Newton inside, outside and beyond half the step before last, at the
    rounding floor, a NaN slope, brackets of adjacent floats; and (the second half) Newton's regime, a root
    ``delta`` below ``y`` inside the bracket, with a last step ``dn_last`` 10 to 1e8 times larger and the slope
    before it within 20 % of this one's, so that the quadratic rule ends some of them alone."""
    lo = rng.uniform(1.0, 2.0, n)
    hi = lo + 10.0 ** rng.uniform(-16.0, 0.0, n)
    y = lo + rng.uniform(0.0, 1.0, n) * (hi - lo)
    K = rng.uniform(0.0, 2.0, n)
    c_y = rng.uniform(0.5, 2.0, n)
    p_y = K * c_y + rng.choice([1.0, 1e-17, 0.0], n) * rng.normal(size=n)
    p_yy = rng.normal(size=n)
    c_yy = rng.normal(size=n)
    p_yy[rng.uniform(size=n) < 0.05] = np.nan
    tol = 10.0 ** rng.uniform(-18.0, -12.0, n)
    sgn = rng.choice([1.0, -1.0], n)
    dx_before = np.where(rng.uniform(size=n) < 0.3, np.inf, 10.0 ** rng.uniform(-16.0, 0.0, n))
    dn_last = np.where(rng.uniform(size=n) < 0.3, np.inf, 10.0 ** rng.uniform(-16.0, 0.0, n))
    g2_last = np.where(rng.uniform(size=n) < 0.1, np.nan, rng.normal(size=n))
    h = slice(n // 2, n)  # Newton's regime
    m = n - n // 2
    lo[h], hi[h] = 1.0, 2.0
    y[h] = rng.uniform(1.4, 1.6, m)
    delta = 10.0 ** rng.uniform(-14.0, -6.0, m)
    g2 = rng.uniform(0.5, 2.0, m)
    p_y[h], p_yy[h] = K[h] * c_y[h] + g2 * delta, g2 + K[h] * c_yy[h]  # g_y = g2 delta, its slope g2
    sgn[h], dx_before[h] = 1.0, np.inf
    dn_last[h] = delta * 10.0 ** rng.uniform(1.0, 8.0, m)
    g2_last[h] = g2 * rng.uniform(0.8, 1.2, m)
    tol[h] = 10.0 ** rng.uniform(-18.0, -8.0, m)
    return y, lo, hi, p_y, p_yy, c_y, c_yy, K, tol, sgn, dx_before, dn_last, g2_last


def test_compiled_step_same_bits():
    numba = pytest.importorskip("numba")
    from rdea_lab.physics import kernels

    @numba.njit(cache=False)
    def steps(y, lo, hi, p_y, p_yy, c_y, c_yy, K, tol, sgn, dx_before, dn_last, g2_last):
        out = np.empty((7, y.size))
        for i in range(y.size):
            out[0, i], out[1, i], out[2, i], out[3, i], done, out[5, i], out[6, i] = kernels._newton(
                y[i], lo[i], hi[i], p_y[i], p_yy[i], c_y[i], c_yy[i], K[i], tol[i], sgn[i], dx_before[i], dn_last[i],
                g2_last[i])
            out[4, i] = 1.0 if done else 0.0
        return out

    args = _steps(np.random.default_rng(3), 5000)
    with np.errstate(divide="ignore", invalid="ignore"):
        ref = branch.newton_step(*args)
        without = branch.newton_step(*args[:-2], np.full(args[0].size, np.inf), args[-1])  # no quadratic rule
    got = steps(*args)
    for j, name in enumerate(("y_new", "lo", "hi", "dx", "done", "dn", "g2")):
        assert np.array_equal(got[j], np.asarray(ref[j], float), equal_nan=True), name
    assert 0 < np.sum(ref[4]) < args[0].size  # both outcomes seen
    by_rule = ref[4] & ~without[4]  # ended by the quadratic rule alone
    assert 100 < np.sum(by_rule) < np.sum(~without[4]), (np.sum(by_rule), np.sum(~without[4]))


@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_second_pass_the_same_in_the_reference_and_the_kernels(model, monkeypatch):
    """With a budget of 2 steps and a tolerance far below the float spacing (``rtol`` 1e-20: only the rounding
    floor, a bracket of adjacent floats or the quadratic rule ends the iteration) many samples need the
    refinement's second pass (from the middle of the bracket the first left, safeguarded), which converges
    some of them: the reference (`follow_branch`), its rule compiled (`scan_kernel.follow_branch_at`,
    `kernels._refine`) and the certified kernel (`branch_roots`, whose lanes hand their unconverged samples to
    `kernels._guarded`) agree on it as with the full budget and tolerance."""
    pytest.importorskip("numba")
    from rdea_lab.physics import kernels, scan_kernel
    from rdea_lab.physics.models import continuum, one_ring, three_ring

    from physics_cases import RIZZELLO, core

    second = []  # the samples the reference's second pass converged
    iterate = branch._iterate

    def spy(*args):
        out = iterate(*args)
        if args[-1]:
            second.append(int(np.sum(out[3])))
        return out

    monkeypatch.setattr(branch, "_iterate", spy)
    rng = np.random.default_rng(5)
    l1, v = rng.uniform(1.0, 1.75, 2000), rng.uniform(0.0, 3500.0, 2000)
    problem = {"1r": one_ring, "3r": three_ring, "cr": continuum}[model].problem(core("hollow"), RIZZELLO, l1, v)
    for max_iter, rtol in ((2, 1e-20), (branch.MAX_ITER, branch.RTOL)):
        second.clear()
        ref = branch.follow_branch(problem, max_iter=max_iter, rtol=rtol)
        if max_iter == 2:  # the second pass converges some samples, not all
            assert sum(second) > 0 and np.any(ref.status == NOT_CONVERGED), (second, np.bincount(ref.status))
        comp = scan_kernel.follow_branch_at(problem, np.arange(l1.size), max_iter=max_iter, rtol=rtol)
        assert np.array_equal(comp.status, ref.status)
        assert np.allclose(comp.y, ref.y, rtol=1e-12, atol=0.0)
        y, certified = kernels.branch_roots(problem, whole=False, max_iter=max_iter, rtol=rtol)
        # on this scene h rises over every bracket: the kernel certifies exactly the samples the reference solved
        assert np.array_equal(certified, ref.status == OK)
        assert np.allclose(y[certified], ref.y[certified], rtol=1e-12, atol=0.0)


def _steep(n, seed, rtol, g="sinh"):
    """Roots ``r`` of ``g(y) = sinh(s (y - r))`` (no curvature at the root: Newton converges there cubically)
    or ``expm1(s (y - r))`` (curvature ``s / 2`` a unit of slope: quadratically), ``c_y = 1`` and ``K = 0`` (no
    rounding floor short of ``g = 0``; ``g``'s sign is exact near ``r``), ``s`` from 0.01 to 300 per unit of
    the bracket (Newton from far off crawls in steps of about ``1 / s`` before it converges), brackets
    ``[lo, hi]`` of 1 to 2 around them, starts anywhere in them."""
    rng = np.random.default_rng(seed)
    lo = rng.uniform(1.0, 2.0, n)
    hi = lo + rng.uniform(1.0, 2.0, n)
    r = lo + rng.uniform(0.0, 1.0, n) * (hi - lo)
    s = 10.0 ** rng.uniform(-2.0, 2.5, n)
    start = lo + rng.uniform(0.0, 1.0, n) * (hi - lo)
    count = np.zeros(n, np.int64)  # the terms evaluated per sample: its steps
    f, df = (np.sinh, np.cosh) if g == "sinh" else (np.expm1, np.exp)

    def terms(y, idx, second):
        np.add.at(count, idx, 1)
        x = s[idx] * (y - r[idx])
        one = np.ones_like(y)
        return f(x), s[idx] * df(x), one, 0.0 * one

    def solve():
        count[:] = 0
        y, ok = branch._refine_root(terms, np.arange(n), lo.copy(), hi.copy(), np.zeros(n), hi - lo, rtol, 100,
                                    start=start.copy())
        return y, ok, count.copy()

    return solve, r, rtol * (hi - lo)


def _without_rule(monkeypatch):
    """`branch.newton_step` without its quadratic rule (``dn_last`` always inf)."""
    step = branch.newton_step
    monkeypatch.setattr(branch, "newton_step", lambda *a: step(*a[:-2], np.inf, a[-1]))


@pytest.mark.parametrize("g", ["sinh", "expm1"])
@pytest.mark.parametrize("rtol", [1e-6, 1e-10, 1e-13])
def test_the_quadratic_rule_ends_within_the_tolerance(rtol, g, monkeypatch):
    """`newton_step` ends an iteration where two Newton steps in a row show quadratic convergence and the next
    step would be far below ``tol``: each root so found is within ``tol`` of the true one (``r``, exact in
    floats), also where Newton crawls before it converges; and the rule only ever ends an iteration early: with
    it disabled no sample takes fewer steps, and some take more."""
    solve, r, tol = _steep(4000, 11, rtol, g)
    with np.errstate(over="ignore"):
        y, ok, steps = solve()
        assert ok.all()
        err = np.abs(y - r)
        assert np.all(err <= tol), (err / tol).max()
        _without_rule(monkeypatch)
        y_off, ok_off, steps_off = solve()
    assert ok_off.all() and np.all(np.abs(y_off - r) <= tol)
    assert np.all(steps <= steps_off) and np.any(steps < steps_off)


@pytest.mark.parametrize("s, rtol", [(1e5, 1e-6), (1e8, 1e-10), (1e12, 1e-14)])
def test_the_quadratic_rule_is_not_fooled_by_an_overshoot(s, rtol):
    """A Newton step from the flat side of ``expm1(s (y - r))`` lands far up its steep side; from there Newton
    crawls down in steps of about ``1 / s``, each a hundredth of the overshoot and, for a steep enough rise,
    small enough that the step and contraction tests alone took the first crawl step for convergence (the
    root then a thousand tolerances off and more). The slope of ``g_y`` changes by a factor ``e`` and more over a
    crawl step, so the rule waits until Newton's model holds: the root is within ``tol``."""
    r = 0.5
    start = np.array([r - 5.0 / s, r - 3.0 / s, r - 8.0 / s])
    n = start.size

    def terms(y, idx, second):
        x = s * (y - r)
        return np.expm1(x), s * np.exp(x), np.ones_like(y), np.zeros_like(y)

    with np.errstate(over="ignore"):
        y, ok = branch._refine_root(terms, np.arange(n), np.zeros(n), np.ones(n), np.zeros(n), np.ones(n), rtol, 100,
                                    start=start)
    assert ok.all()
    assert np.all(np.abs(y - r) <= rtol), np.abs(y - r) / rtol
