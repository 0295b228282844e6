"""Tests of rdea_lab.emulator.rig: the emulated specimen, against independent references.

The reference for the true force is built here from the physics layer directly
(`solve` for the quasi-static stress, `viscoelastic.overstress` over the
whole series for the branches), not from `TwinStream`, which the emulator uses.
"""

import math

import numpy as np
import pytest

from rdea_lab.emulator import COLUMNS, EmulatedRig, RunConfig, limit_violation
from rdea_lab.emulator.rig import BLOCK
from rdea_lab.physics import viscoelastic
from rdea_lab.physics.geometry import RollGeometry, geometry_from_card
from rdea_lab.physics.models import solve

from .helpers import truth_with

COL = {name: j for j, name in enumerate(COLUMNS)}
RATE = 100.0


def config(x, v, rate=RATE, measure=("force", "capacitance"), max_force=50.0, L1=0.034, L3=48e-6):
    return RunConfig(rate, x, v, L1=L1, L3=L3, max_voltage=3000.0, max_stretch=1.6, max_force=max_force,
                     max_field=80e6, measure=measure)


def rig(card, truth, cfg, seed=0, **kwargs):
    return EmulatedRig(card, truth, np.random.default_rng(seed), cfg, **kwargs)


def factored(card, truth):
    """True geometry, computed here: nominal radii times the truth's factors."""
    g, f = geometry_from_card(card), truth.radii_factors
    return RollGeometry(g.Ri * f.Ri, g.Rie * f.Rie, g.Roe * f.Roe, g.Ro * f.Ro, g.L1, g.L1e, g.L3)


def slow_trajectory(n=1001):
    t = np.arange(n) / RATE
    x = 1.0 + 0.3 * np.sin(np.pi * t / t[-1]) ** 2          # 1 -> 1.3 -> 1, 10 s
    v = np.where((t > 2.0) & (t < 8.0), 1500.0, 0.0)
    return t, x, v


def test_force_is_the_true_model_without_instrument_effects(card, quiet):
    t, x, v = slow_trajectory()
    rows = rig(card, quiet, config(x, v)).produce(5000)
    assert rows.shape == (1001, 8)
    # ideal actuator and amplifier: what the rig measures is what it was told
    np.testing.assert_array_equal(rows[:, COL["stretch"]], x)
    np.testing.assert_array_equal(rows[:, COL["voltage"]], v)
    np.testing.assert_array_equal(rows[:, COL["time"]], t)
    np.testing.assert_allclose(rows[:, COL["position"]], (x - 1.0) * 0.034, rtol=1e-15, atol=0)
    geom, m = factored(card, quiet), quiet.material
    res = solve(quiet.model, geom, m, x, v)
    sigma = res.tension + viscoelastic.overstress(t, x, [b.modulus for b in m.branches], [b.eta for b in m.branches],
                                                  m.eta_v0, law=m.law)
    # a roll that would push is slack: the load cell reads 0 (Assumption 1)
    force = np.maximum(sigma * math.pi * (geom.Ro**2 - geom.Ri**2) / x, 0.0)
    # same formulas, evaluated block-wise vs. at once: rounding only
    np.testing.assert_allclose(rows[:, COL["force"]], force, rtol=1e-12, atol=1e-12)
    at_0V = np.abs(v) < 1.0
    np.testing.assert_allclose(rows[at_0V, COL["capacitance"]], res.capacitance[at_0V], rtol=1e-13)
    assert np.isnan(rows[~at_0V, COL["capacitance"]]).all()


def test_actuator_lag_follows_one_minus_exp(card, truth):
    lagged = truth_with(truth, actuator_lag="40 ms", force_noise="0 N")
    k0, n = 50, 200
    x = np.where(np.arange(n) >= k0, 1.2, 1.0)
    rows = rig(card, lagged, config(x, np.zeros(n))).produce(n)
    t = rows[:, COL["time"]]
    # setpoint k0 is commanded from t_{k0-1} on; before it the actuator rests at the first setpoint
    expected = np.where(t >= k0 / RATE, 1.0 + 0.2 * -np.expm1(-(t - (k0 - 1) / RATE) / 0.04), 1.0)
    np.testing.assert_allclose(rows[:, COL["stretch"]], expected, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(rows[:, COL["stretch_setpoint"]], x)


def test_amplifier_bandwidth_follows_one_minus_exp(card, truth):
    slow = truth_with(truth, amplifier_bandwidth="5 Hz")
    k0, n = 20, 100
    v = np.where(np.arange(n) >= k0, 1000.0, 0.0)
    rows = rig(card, slow, config(np.ones(n), v)).produce(n)
    t = rows[:, COL["time"]]
    tau = 1.0 / (2.0 * math.pi * 5.0)
    expected = np.where(t >= k0 / RATE, 1000.0 * -np.expm1(-(t - (k0 - 1) / RATE) / tau), 0.0)
    np.testing.assert_allclose(rows[:, COL["voltage"]], expected, rtol=0, atol=1e-10)


def test_capacitance_only_at_zero_volts_and_when_configured(card, quiet):
    with_parasitics = truth_with(quiet, parasitic_capacitance="25 pF", amplifier_bandwidth="30 Hz")
    t, x, v = slow_trajectory()
    rows = rig(card, with_parasitics, config(x, v)).produce(2000)
    volts = rows[:, COL["voltage"]]
    measured = np.abs(volts) < 1.0
    # the amplifier decays after the voltage is switched off: some samples after 8 s are still above 1 V
    assert measured.sum() < np.sum(v == 0.0)
    C = solve(quiet.model, factored(card, quiet), quiet.material, rows[:, COL["stretch"]], volts).capacitance
    np.testing.assert_allclose(rows[measured, COL["capacitance"]], C[measured] + 25e-12, rtol=1e-13)
    assert np.isnan(rows[~measured, COL["capacitance"]]).all()
    no_cap = rig(card, with_parasitics, config(x, v, measure=("force",))).produce(2000)
    assert np.isnan(no_cap[:, COL["capacitance"]]).all()
    no_force = rig(card, with_parasitics, config(x, v, measure=("capacitance",))).produce(2000)
    assert np.isnan(no_force[:, COL["force"]]).all()


def test_noise_has_the_configured_standard_deviation(card, truth):
    n = 20_000
    # at stretch 1 and 0 V the true force is 0: the reading is offset + noise
    rows = rig(card, truth, config(np.ones(n), np.zeros(n)), seed=7).produce(n)
    inst = truth.instrument
    force = rows[:, COL["force"]] - inst.force_drift * rows[:, COL["time"]]  # the offset drifts linearly
    cap = rows[:, COL["capacitance"]]
    geom = factored(card, truth)
    C0 = solve(truth.model, geom, truth.material, 1.0, 0.0).capacitance
    if truth.effects.fringe_capacitance:  # Palmer (1937): 1 + d / (pi a) (1 + ln(2 pi a / d)), a = L1e, d = L3
        C0 = C0 * (1.0 + geom.L3 / (math.pi * geom.L1e) * (1.0 + math.log(2.0 * math.pi * geom.L1e / geom.L3)))
    # sample mean: standard error sigma / sqrt(n); sample std: sigma / sqrt(2 (n - 1)); 5 standard errors
    for reading, mean, sigma in ((force, inst.force_offset, inst.force_noise),
                                 (cap, C0 + inst.parasitic_capacitance, inst.capacitance_noise)):
        assert abs(reading.mean() - mean) < 5 * sigma / math.sqrt(n)
        assert abs(reading.std(ddof=1) - sigma) < 5 * sigma / math.sqrt(2 * (n - 1))
    # the two noises are independent streams
    assert abs(np.corrcoef(force, cap)[0, 1]) < 5 / math.sqrt(n)


def test_same_seed_same_data_other_seed_other_noise(card, truth):
    t, x, v = slow_trajectory()
    a = rig(card, truth, config(x, v), seed=3).produce(2000)
    b = rig(card, truth, config(x, v), seed=3).produce(2000)
    c = rig(card, truth, config(x, v), seed=4).produce(2000)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[:, COL["force"]], c[:, COL["force"]])
    # only the noise differs: the noise-free columns agree
    for name in ("time", "stretch", "position", "voltage", "stretch_setpoint", "voltage_setpoint"):
        np.testing.assert_array_equal(a[:, COL[name]], c[:, COL[name]])


@pytest.mark.parametrize("sizes", [[1, 7, 333], [BLOCK - 1, 2], *(pytest.param(s, marks=pytest.mark.slow)
                                                                 for s in ([500, 1], [BLOCK, BLOCK], [3] * 3000))])
def test_chunking_does_not_change_the_data(card, truth, sizes):
    t, x, v = slow_trajectory(10_001)  # more than two blocks of BLOCK samples
    whole = rig(card, truth, config(x, v)).produce(10_001)
    r = rig(card, truth, config(x, v))
    parts = [r.produce(s) for s in sizes]
    parts.append(r.produce(20_000))
    # bit-identical: the rig computes in blocks aligned on the run's start, whatever is asked
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert r.state == "done" and r.acquired == 10_001 and r.produce(10).shape == (0, 8)


def test_produce_until_a_time(card, truth):
    t, x, v = slow_trajectory()
    r = rig(card, truth, config(x, v))
    assert r.produce_until(0.0).shape[0] == 1          # sample 0 at t = 0
    assert r.produce_until(0.5).shape[0] == 50         # samples 1..50: t = 0.01 .. 0.5
    assert r.produce_until(0.5).shape[0] == 0
    assert r.samples_before(2.0) == 200 and r.samples_until(2.0) == 201


def test_breakdown_at_the_sample_where_the_field_crosses(card, quiet):
    weak = truth_with(quiet, breakdown_field="60 V/um")
    n = 1000
    v = np.linspace(0.0, 3500.0, n)
    x = np.full(n, 1.2)
    r = rig(card, weak, config(x, v))
    rows = r.produce(n)
    E = v * math.sqrt(1.2) / card.L3                  # true L3 = card L3; ideal amplifier: v as commanded
    k = int(np.flatnonzero(E > 60e6)[0])
    assert rows.shape[0] == k + 1 and r.acquired == k + 1
    assert r.state == "aborted"
    assert r.reason == f"dielectric breakdown at t = {k / RATE:.10g} s (field {E[k] / 1e6:.4g} V/um)"
    assert r.produce(10).shape == (0, 8)              # nothing after the abort


@pytest.mark.parametrize("at, chunk", [(1.5, 10_000), (50.0, 777)])  # 50 s: sample 5000, in the second block
def test_injected_breakdown(card, quiet, at, chunk):
    n = 10_000
    r = rig(card, quiet, config(np.ones(n), np.zeros(n)), breakdown_at=at)
    rows = np.concatenate([r.produce(chunk) for _ in range(n // chunk + 1)])
    k = int(at * RATE)
    assert rows.shape[0] == k + 1 and rows[-1, COL["time"]] == at
    assert r.reason.startswith(f"dielectric breakdown at t = {at:g} s") and r.reason.endswith("injected fault)")


def test_force_limit_aborts_at_the_first_reading_above_it(card, quiet):
    t, x, v = slow_trajectory()
    full = rig(card, quiet, config(x, v)).produce(2000)
    k = int(np.flatnonzero(np.abs(full[:, COL["force"]]) > 1.0)[0])
    r = rig(card, quiet, config(x, v, max_force=1.0))
    rows = r.produce(2000)
    assert rows.shape[0] == k + 1
    np.testing.assert_array_equal(rows, full[:k + 1])
    assert r.reason == f"force {full[k, COL['force']]:.4g} N at t = {k / RATE:.10g} s above LIM:FORC 1 N"


def test_abort_stops_production(card, truth):
    t, x, v = slow_trajectory()
    r = rig(card, truth, config(x, v))
    r.produce(10)
    r.abort("aborted by ABOR")
    assert (r.state, r.reason, r.acquired, r.running) == ("aborted", "aborted by ABOR", 10, False)
    assert r.produce(10).shape == (0, 8)


# ------------------------------------------------------------- ARM checks
def test_limit_violation_message_of_the_doc():
    x = np.ones(2000)
    v = np.zeros(2000)
    v[1250] = 3200.0
    assert limit_violation(config(x, v)) == "voltage 3200 V at t = 12.5 s is above LIM:VOLT 3000 V"


def test_limit_violation_reports_the_earliest_sample():
    n = 100
    x, v = np.ones(n), np.zeros(n)
    x[60] = 1.7
    v[40] = -3100.0
    assert limit_violation(config(x, v)) == "voltage -3100 V at t = 0.4 s is beyond (in magnitude) LIM:VOLT 3000 V"
    v[40] = 0.0
    assert limit_violation(config(x, v)) == "stretch 1.7 at t = 0.6 s is above LIM:STR 1.6"
    x[10] = 0.99
    assert limit_violation(config(x, v)) == "stretch 0.99 at t = 0.1 s is below 1 (the roll must stay in tension)"
    x[10] = np.nan
    assert limit_violation(config(x, v)) == "stretch setpoint nan at t = 0.1 s is not a finite number"


def test_limit_violation_field_and_slack():
    n = 10
    x, v = np.full(n, 1.44), np.zeros(n)
    v[3] = 3000.0   # 3000 V x 1.2 / 48 um = 75 V/um: below 80
    assert limit_violation(config(x, v)) is None
    v[3] = 2999.0
    x[3] = 1.6 * (1 + 1e-13)   # rounding above a limit is no violation
    assert limit_violation(config(x, v)) is None
    E = 2999.0 * math.sqrt(x[3]) / 40e-6
    assert limit_violation(config(x, v, L3=40e-6)) == (
        f"field estimate {E:.6g} V/m (voltage 2999 V, stretch 1.6, CONF:THIC 4e-05 m) at t = 0.03 s is "
        "above LIM:FIEL 8e+07 V/m")
