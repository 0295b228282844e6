"""Tests of rdea_lab.emulator.instruments: first-order lag, load cell, LCR bridge."""

import math

import numpy as np
import pytest

from rdea_lab.emulator import FirstOrderLag, lcr_bridge, load_cell, tau_of_bandwidth


def test_step_follows_one_minus_exp():
    # setpoint k is held over (t_{k-1}, t_k]: a step at sample k0 starts at t_{k0-1}
    dt, tau, k0 = 1e-3, 4e-3, 10
    u = np.where(np.arange(200) >= k0, 1.0, 0.0)
    y = FirstOrderLag(tau, dt, 0.0)(u)
    t = np.arange(200) * dt
    expected = np.where(t >= k0 * dt, -np.expm1(-(t - (k0 - 1) * dt) / tau), 0.0)
    # the recurrence y_k = a y_{k-1} + (1 - a) accumulates a few ulps over 200 steps
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-14)


def test_state_is_carried_across_chunks():
    rng = np.random.default_rng(0)
    u = rng.uniform(1.0, 1.5, 1000)
    whole = FirstOrderLag(2e-3, 1e-3, 1.2)(u)
    lag = FirstOrderLag(2e-3, 1e-3, 1.2)
    parts = np.concatenate([lag(u[a:b]) for a, b in [(0, 1), (1, 8), (8, 8), (8, 500), (500, 1000)]])
    # the prefix scan groups the products by chunk: equal to the last few ulps, not bit for bit
    np.testing.assert_allclose(parts, whole, rtol=4 * np.finfo(float).eps, atol=0)
    # and both are the recurrence y_k = a y_{k-1} + (1 - a) u_k run sample by sample
    a, y, seq = math.exp(-1e-3 / 2e-3), 1.2, []
    for uk in u:
        y = a * y + (1 - a) * uk
        seq.append(y)
    np.testing.assert_allclose(whole, seq, rtol=4 * np.finfo(float).eps, atol=0)


def test_zero_lag_is_an_ideal_follower_and_any_lag_is_stable():
    u = np.linspace(1.0, 2.0, 50)
    np.testing.assert_array_equal(FirstOrderLag(0.0, 1e-3, 5.0)(u), u)
    # tau / dt from 1e-6 to 1e6: the output stays between its start and the setpoints
    for tau in (1e-9, 1e-3, 1e3):
        y = FirstOrderLag(tau, 1e-3, 0.0)(np.ones(100))
        assert np.all((y >= 0.0) & (y <= 1.0))


def test_bandwidth_to_time_constant():
    assert tau_of_bandwidth(300.0) == pytest.approx(1.0 / (2.0 * math.pi * 300.0), rel=1e-15)


def test_load_cell_and_bridge_draw_one_variate_per_sample():
    force = np.zeros(10)
    a = load_cell(force, 0.0, 0.0, np.random.default_rng(1))
    np.testing.assert_array_equal(a, force)
    rng = np.random.default_rng(1)
    lcr_bridge(np.zeros(5), np.full(5, 100.0), 1e-12, 1e-13, rng, enabled=True)
    # five draws were made even though no sample was measured (|v| >= 1 V)
    assert rng.standard_normal() == np.random.default_rng(1).standard_normal(6)[5]


def test_bridge_measures_at_zero_volts_only():
    c = np.full(4, 2e-9)
    v = np.array([0.0, 0.999, 1.0, -5.0])
    out = lcr_bridge(c, v, 25e-12, 0.0, np.random.default_rng(0))
    np.testing.assert_array_equal(out, [2.025e-9, 2.025e-9, np.nan, np.nan])
    assert np.isnan(lcr_bridge(c, v, 0.0, 0.0, np.random.default_rng(0), enabled=False)).all()


def test_a_held_setpoint_is_followed_exactly():
    # at rest on its setpoint the lag has nothing to follow: the output is the setpoint to the bit (a
    # stretch of exactly 1 at the start stays 1, not 1 - 1 ulp, which the calibration would drop as < 1)
    for tau in (1e-4, 2e-3, 1.0):
        lag = FirstOrderLag(tau, 1e-3, 1.0)
        np.testing.assert_array_equal(lag(np.ones(5000)), np.ones(5000))
        y = lag(np.r_[np.ones(10), np.full(3000, 1.25)])
        assert y[-1] == 1.25 or tau == 1.0  # settled to the bit after 3000 steps of 1 ms unless tau = 1 s
