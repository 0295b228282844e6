"""A precomputed `History` for eq. (44): the same numbers as plain arrays."""

import numpy as np
import pytest

from rdea_lab.physics import _backend
from rdea_lab.physics.viscoelastic import History, branch_strains, overstress_step


def random_history(rng, n, uniform=True):
    dt = 10.0 ** rng.uniform(-3, -1)
    if uniform:
        t = dt * (rng.integers(0, 100) + np.arange(n))  # as sampled
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


def test_history_holds_the_data_only_parts():
    t = np.arange(6) * 0.1
    lam = np.array([1.0, 1.1, np.nan, 1.3, 1.2, 1.0])
    h = History.of(t, lam)
    np.testing.assert_array_equal(h.finite, np.isfinite(lam))
    np.testing.assert_array_equal(h.t_finite, t[[0, 1, 3, 4, 5]])
    np.testing.assert_allclose(h.dt, [0.1, 0.2, 0.1, 0.1], rtol=1e-14)
    np.testing.assert_allclose(h.slope, [1.0, 1.0, -1.0, -2.0], rtol=1e-12)
    np.testing.assert_array_equal(h.rate, np.concatenate([h.slope[:1], h.slope]))
    assert not h.all_finite
    with pytest.raises(ValueError, match="read-only"):
        h.t[0] = 1.0
    assert History.of(t, 1 + t).all_finite


def test_history_checks_time_as_overstress_does():
    with pytest.raises(ValueError, match=r"strictly increasing; t\[2\]"):
        History.of([0.0, 1.0, 1.0], [1.0, 1.1, 1.2])
    with pytest.raises(ValueError, match="1-D arrays of one length"):
        History.of([0.0, 1.0], [1.0, 1.1, 1.2])


def test_history_and_stretch_together_is_refused():
    h = History.of([0.0, 1.0], [1.0, 1.1])
    with pytest.raises(ValueError, match="stretch must be None"):
        overstress_step(h, h.stretch, [1e5], [1e3])


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("uniform", [True, False])
@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_a_history_gives_the_plain_arrays_numbers_bit_for_bit(seed, uniform, kernel, monkeypatch):
    """The same coefficients and the same update from precomputed parts: identical, NaN where the stretch
    is; with the numpy scan for both, and with the compiled update for both (a History takes it under auto,
    plain arrays of this length only when told: here the threshold is lowered; the two kernels agree to
    1e-12, test_kernels.py)."""
    if kernel == "numpy":
        monkeypatch.setenv("RDEA_LAB_KERNELS", "numpy")
    else:
        pytest.importorskip("numba")
        monkeypatch.setattr(_backend, "AUTO_MIN_SAMPLES", 1)
    rng = np.random.default_rng(100 + seed)
    t, lam = random_history(rng, 2000, uniform=uniform)
    lam[rng.integers(0, 2000, 5)] = np.nan
    h = History.of(t, lam)
    k, eta = random_branches(rng, 2, float(np.mean(h.dt)))
    np.testing.assert_array_equal(overstress_step(h, None, k, eta, 50.0)[0], overstress_step(t, lam, k, eta, 50.0)[0])
    tau = eta / k
    np.testing.assert_array_equal(branch_strains(h, None, tau), branch_strains(t[np.isfinite(lam)],
                                                                             lam[np.isfinite(lam)], tau))


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
