"""A precomputed `History` for eq. (44): the same numbers as plain arrays, by a filter or the prefix scan."""

import numpy as np
import pytest

from rdea_lab.physics import viscoelastic
from rdea_lab.physics.viscoelastic import History, branch_strains, overstress_step

# the filter and the scan round in a different order: over a few thousand
# samples the strains agree to ~1e-15 of the largest where tau ~ dt and to a few
# 1e-14 where tau ~ 1e4 dt (long memory: sums of thousands of terms); 1e-13 is the
# bound the calibration may differ by
AGREE = 1e-13


def random_history(rng, n, uniform=True):
    dt = 10.0 ** rng.uniform(-3, -1)
    if uniform:
        t = dt * (rng.integers(0, 100) + np.arange(n))  # as sampled: jitter ~ n eps, within UNIFORM_RTOL
    else:
        t = np.cumsum(dt * rng.uniform(0.5, 1.5, n))
    cycles = rng.uniform(0.5, 3)
    lam = 1.0 + 0.3 * np.abs(np.sin(2 * np.pi * cycles * (t - t[0]) / (t[-1] - t[0] + dt))) \
        + 1e-3 * rng.standard_normal(n)  # measured stretch: noisy from sample to sample
    return t, lam


def random_branches(rng, m, dt):
    tau = dt * 10.0 ** rng.uniform(-3, 4, m)  # from far below a sample interval to ten thousand of them
    k = 10.0 ** rng.uniform(4, 7, m)
    return k, k * tau


def scale(x):
    return np.max(np.abs(x))


def test_history_holds_the_data_only_parts():
    t = np.arange(6) * 0.1
    lam = np.array([1.0, 1.1, np.nan, 1.3, 1.2, 1.0])
    h = History.of(t, lam)
    np.testing.assert_array_equal(h.finite, np.isfinite(lam))
    np.testing.assert_array_equal(h.t_finite, t[[0, 1, 3, 4, 5]])
    np.testing.assert_allclose(h.dt, [0.1, 0.2, 0.1, 0.1], rtol=1e-14)
    np.testing.assert_allclose(h.slope, [1.0, 1.0, -1.0, -2.0], rtol=1e-12)
    np.testing.assert_array_equal(h.rate, np.concatenate([h.slope[:1], h.slope]))
    assert h.step is None and h.offset is None  # the lost sample leaves an interval twice as long
    assert not h.all_finite
    with pytest.raises(ValueError, match="read-only"):
        h.t[0] = 1.0
    clean = History.of(t, 1 + t)
    assert clean.step == pytest.approx(0.1, rel=1e-15)
    assert clean.all_finite
    # offsets from the exact grid: the rounding of t (a few 1e-17 s here)
    np.testing.assert_allclose(clean.offset, t - t[0] - clean.step * np.arange(6), rtol=0, atol=1e-16)


def test_history_checks_time_as_overstress_does():
    with pytest.raises(ValueError, match=r"strictly increasing; t\[2\]"):
        History.of([0.0, 1.0, 1.0], [1.0, 1.1, 1.2])
    with pytest.raises(ValueError, match="1-D arrays of one length"):
        History.of([0.0, 1.0], [1.0, 1.1, 1.2])


def test_history_and_stretch_together_is_refused():
    h = History.of([0.0, 1.0], [1.0, 1.1])
    with pytest.raises(ValueError, match="stretch must be None"):
        overstress_step(h, h.stretch, [1e5], [1e3])


def test_uniformity_tolerance():
    t = 0.01 * np.arange(1000)
    assert History.of(t, 1 + t).step is not None  # t = i * 0.01 rounds: dt within ~5e-13 of 0.01
    jitter = t.copy()
    jitter[500] += 1e-9 * 0.01
    assert History.of(jitter, 1 + t).step is None


@pytest.mark.parametrize("seed", range(8))
def test_filter_and_scan_agree_on_uniform_histories(seed):
    rng = np.random.default_rng(seed)
    t, lam = random_history(rng, int(rng.integers(2, 4000)))
    h = History.of(t, lam)
    assert h.step is not None
    k, eta = random_branches(rng, 3, h.step)
    tau = eta / k
    q0 = 1e-3 * rng.standard_normal(3)
    a, c, u = viscoelastic._uniform_coefficients(h.dt, h.slope, tau, h.step, h.offset)
    assert a.shape == (3, 1)
    fast, scan = np.empty((3, t.size)), np.empty((3, t.size))
    viscoelastic._linear_recurrence(a, c, q0, fast)
    viscoelastic._linear_recurrence(a, c, q0, scan, scan=True)  # same a and c, the other algorithm
    for j in range(3):
        assert np.max(np.abs(fast[j] - scan[j])) <= AGREE * scale(scan[j]), j
    # and against the plain-array path (the scan, each interval's own a_n = a u_{n+1} / u_n): measured
    # <= 6e-14 for tau up to 1e4 dt, and the filter is the closer of the two to a long-double recurrence
    plain = branch_strains(t, lam, tau, q0)
    for j in range(3):
        assert np.max(np.abs(branch_strains(h, None, tau, q0)[j] - plain[j])) <= AGREE * scale(plain[j]), j
    for eta_v0 in (0.0, 1e3):
        s_h, st_h = overstress_step(h, None, k, eta, eta_v0, q0=q0)
        s_p, st_p = overstress_step(t, lam, k, eta, eta_v0, q0=q0)
        assert np.max(np.abs(s_h - s_p)) <= AGREE * scale(s_p)
        assert st_h.t == st_p.t and st_h.stretch == st_p.stretch
        np.testing.assert_allclose(st_h.q, st_p.q, rtol=0, atol=AGREE * scale(plain))


@pytest.mark.parametrize("seed", range(4))
def test_non_uniform_histories_use_the_scan(seed, monkeypatch):
    rng = np.random.default_rng(100 + seed)
    t, lam = random_history(rng, 2000, uniform=False)
    lam[rng.integers(0, 2000, 5)] = np.nan
    h = History.of(t, lam)
    assert h.step is None
    scans = []
    real = viscoelastic._affine_prefix
    monkeypatch.setattr(viscoelastic, "_affine_prefix", lambda a, b: scans.append(a.shape) or real(a, b))
    k, eta = random_branches(rng, 2, float(np.mean(h.dt)))
    s_h = overstress_step(h, None, k, eta, 50.0)[0]
    assert scans == [(2, h.dt.size)]  # one scan, each interval its own a
    assert h.offset is None
    s_p = overstress_step(t, lam, k, eta, 50.0)[0]
    # the same coefficients and the same scan: bit-identical to the plain arrays, NaN where the stretch is
    np.testing.assert_array_equal(s_h, s_p)


def test_uniform_history_does_not_scan(monkeypatch):
    t = 0.01 * np.arange(3000)
    lam = 1 + 0.2 * np.sin(t)
    monkeypatch.setattr(viscoelastic, "_affine_prefix", lambda a, b: pytest.fail("scan on a uniform history"))
    assert np.all(np.isfinite(overstress_step(History.of(t, lam), None, [1e5, 1e6], [1e3, 1e5], 10.0)[0]))


def test_degenerate_histories():
    for t, lam in (([], []), ([0.0], [1.1]), ([0.0, 1.0], [np.nan, np.nan]), ([0.0, 1.0], [1.0, np.nan])):
        h = History.of(t, lam)
        s_h, st_h = overstress_step(h, None, [1e5], [1e3], 10.0)
        s_p, st_p = overstress_step(t, lam, [1e5], [1e3], 10.0)
        np.testing.assert_array_equal(s_h, s_p)
        assert (st_h is None) == (st_p is None)
    h = History.of([0.0, 1.0, 2.0], [1.0, 1.1, 1.3])
    np.testing.assert_array_equal(overstress_step(h, None, [], [], 10.0)[0],
                                  overstress_step(h.t, h.stretch, [], [], 10.0)[0])


def test_state_continues_from_a_history_as_from_arrays():
    # block continuation (TwinStream's path) is evaluated from the History's arrays: exactly as before
    t = 0.01 * np.arange(200)
    lam = 1 + 0.1 * np.sin(3 * t)
    first = overstress_step(t[:100], lam[:100], [1e5], [2e3], 5.0)[1]
    s_h, st_h = overstress_step(History.of(t[100:], lam[100:]), None, [1e5], [2e3], 5.0, state=first)
    s_p, st_p = overstress_step(t[100:], lam[100:], [1e5], [2e3], 5.0, state=first)
    np.testing.assert_array_equal(s_h, s_p)
    np.testing.assert_array_equal(st_h.q, st_p.q)


def test_finite_strain_from_a_history_matches_arrays():
    pytest.importorskip("numba")
    t = 0.01 * np.arange(300)
    lam = 1 + 0.5 * np.sin(t) ** 2
    s_h = overstress_step(History.of(t, lam), None, [1e5], [1e3], law="finite_strain")[0]
    s_p = overstress_step(t, lam, [1e5], [1e3], law="finite_strain")[0]
    np.testing.assert_array_equal(s_h, s_p)  # the same kernel on the same samples
