"""Viscoelastic overstress (44): exact update, relaxation, quasi-static limit, stiffness."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rdea_lab.physics.viscoelastic import branch_strains, overstress, stretch_rate

K1, ETA1 = 8271e3, 86e3  # Table 3: tau = 10.4 ms


def test_relaxation_after_a_ramp_matches_the_analytic_exponential():
    """Ramp at rate s for T, then hold: q(T) = s tau (1 - e^-T/tau), then q decays as
    e^-(t-T)/tau. Exact for piecewise-linear stretch, so to rounding."""
    tau = ETA1 / K1
    s, T = 0.5, 0.05
    t = np.concatenate([np.linspace(0, T, 11), np.linspace(T, 0.2, 301)[1:]])
    lam = 1.0 + s * np.minimum(t, T)
    sigma = overstress(t, lam, [K1], [ETA1])
    q_T = s * tau * -np.expm1(-T / tau)
    hold = t >= T
    expected = K1 * q_T * np.exp(-(t[hold] - T) / tau)
    np.testing.assert_allclose(sigma[hold], expected, rtol=1e-12, atol=1e-9)
    ramp = t <= T
    np.testing.assert_allclose(sigma[ramp], K1 * s * tau * -np.expm1(-t[ramp] / tau), rtol=1e-12, atol=1e-9)


def test_sine_matches_a_tightly_converged_ode_reference():
    """The paper's 0.1 Hz loading, against solve_ivp (rtol 1e-11) on the same
    piecewise-linear stretch; the ODE solver's own error is ~1e-6 of the peak."""
    t = np.linspace(0, 20, 2001)
    lam = 1 + 0.25 * (1 - np.cos(2 * np.pi * 0.1 * t))
    sigma = overstress(t, lam, [K1], [ETA1])
    ref = solve_ivp(lambda tt, x: (K1 / ETA1) * (np.interp(tt, t, lam) - x), (0, 20), [1.0], t_eval=t,
                    rtol=1e-11, atol=1e-13, max_step=0.005)
    np.testing.assert_allclose(sigma, K1 * (lam - ref.y[0]), rtol=0, atol=1e-5 * np.abs(sigma).max())


@pytest.mark.parametrize("ratio", [1e-4, 1e-2, 1.0, 1e2, 1e4])
def test_any_tau_over_dt_is_stable_and_exact(ratio):
    """tau/dt from 1e-4 (stiff: the branch follows at once) to 1e4 (a spring): the update
    never exceeds its bounds and matches the closed form of a constant-rate ramp."""
    dt, s = 1e-3, 0.3
    tau = ratio * dt
    t = np.arange(0, 2001) * dt
    q = branch_strains(t, 1 + s * t, [tau])[0]
    exact = s * tau * -np.expm1(-t / tau)
    assert np.all(np.isfinite(q)) and np.all(q >= 0) and np.all(q <= s * tau * (1 + 1e-12))
    np.testing.assert_allclose(q, exact, rtol=1e-10, atol=1e-300)


def test_vanishes_at_quasi_static_rates():
    """At constant rate s the steady overstress is eta s: it goes to 0 with the rate."""
    for s in (1e-1, 1e-3, 1e-5):
        t = np.linspace(0, 1.0 / s * 0.5, 5001)
        sigma = overstress(t, 1 + s * t, [K1], [ETA1], eta_v0=1e3)
        assert sigma[-1] == pytest.approx((ETA1 + 1e3) * s, rel=1e-9, abs=0)


def test_branches_add_and_parallel_damper_uses_the_interval_slope():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(1e-3, 1e-2, 400))  # uneven sampling
    lam = 1 + 0.3 * np.sin(t) ** 2
    both = overstress(t, lam, [K1, 2e5], [ETA1, 1e6], eta_v0=500.0)
    one = overstress(t, lam, [K1], [ETA1]) + overstress(t, lam, [2e5], [1e6])
    rate = np.concatenate([[(lam[1] - lam[0]) / (t[1] - t[0])], np.diff(lam) / np.diff(t)])
    np.testing.assert_allclose(both, one + 500.0 * rate, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(stretch_rate(t, lam), rate, rtol=1e-15)


def test_prefix_scan_equals_the_sequential_recurrence():
    """A slow straightforward reference: the same exact update, one sample at a time."""
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(1e-4, 1e-1, 3000))
    lam = 1 + np.abs(np.cumsum(rng.normal(0, 1e-3, t.size)))
    taus = np.array([1e-3, 0.1, 10.0])
    fast = branch_strains(t, lam, taus, q0=[0.01, 0.0, -0.02])
    for j, tau in enumerate(taus):
        q = [[0.01, 0.0, -0.02][j]]
        for n in range(t.size - 1):
            dt = t[n + 1] - t[n]
            s = (lam[n + 1] - lam[n]) / dt
            q.append(q[-1] * np.exp(-dt / tau) + s * tau * -np.expm1(-dt / tau))
        np.testing.assert_allclose(fast[j], q, rtol=1e-12, atol=1e-15)


def test_no_branches_no_overstress():
    t = np.linspace(0, 1, 5)
    assert np.all(overstress(t, 1 + t, [], []) == 0.0)


def test_bad_time_axis_is_refused():
    with pytest.raises(ValueError, match=r"strictly increasing; t\[2\] = 0.5 follows t\[1\] = 0.5"):
        overstress([0.0, 0.5, 0.5], [1.0, 1.1, 1.2], [K1], [ETA1])
    with pytest.raises(ValueError, match="relaxation times must be > 0"):
        branch_strains([0.0, 1.0], [1.0, 1.1], [0.0])
