"""The emulator's amplifier current channel (rdea_lab.emulator.rig, instruments.CurrentMonitor).

References: the charge ``C v`` of the true roll (`TrueRoll` replayed on the
rig's own stretch and voltage), the leakage ``v / R`` integrated by hand, and
the rig's data without the channel.
"""

import numpy as np
import pytest

from rdea_lab.emulator import COLUMNS, EmulatedRig, RunConfig, true_geometry
from rdea_lab.emulator.roll import TrueRoll
from rdea_lab.emulator.rig import BLOCK

from .helpers import truth_with

RATE = 2000.0


def trajectory(seconds=3.0):
    t = np.arange(int(seconds * RATE) + 1) / RATE
    x = 1.0 + 0.2 * np.sin(np.pi * t / t[-1]) ** 2
    v = 1300.0 * (1.0 - np.cos(2.0 * np.pi * t)) + 20.0 * np.sin(2.0 * np.pi * 200.0 * t)
    return t, x, v


def produce(card, truth, measure, seed=4, chunk=10**9):
    t, x, v = trajectory()
    cfg = RunConfig(RATE, x, v, L1=0.034, L3=48e-6, max_voltage=3000.0, max_stretch=1.6, max_field=80e6,
                    measure=measure)
    rig = EmulatedRig(card, truth, np.random.default_rng(seed), cfg)
    out = []
    while rig.running:
        out.append(rig.produce(chunk))
    return np.concatenate(out)


def true_capacitance(card, truth, rows):
    roll = TrueRoll(true_geometry(card, truth), truth)
    t, x, v = rows[:, 0], rows[:, 1], rows[:, 3]
    return np.concatenate([roll.step(t[k:k + BLOCK], np.maximum(x[k:k + BLOCK], 1.0), v[k:k + BLOCK])["capacitance"]
                           for k in range(0, t.size, BLOCK)])


def test_the_charge_of_the_current_is_the_true_rolls_c_v(card, truth):
    quiet = truth_with(truth, current_noise="0 A", leakage_resistance="1 Gohm")
    rows = produce(card, quiet, ("force", "current"))
    assert rows.shape[1] == len(COLUMNS) + 1
    v, i = rows[:, 3], rows[:, -1]
    C = true_capacitance(card, quiet, rows)
    leak = 0.5 * (v + np.concatenate(([0.0], v[:-1]))) / 1e9  # trapezoid of v / R per interval
    charge = np.cumsum(i - leak) / RATE
    # the integral of the charging current is the charge C v at every sample (the roll starts discharged):
    # exact but for the cumulative sum's rounding, about 1e-16 of the largest charge per sample summed
    np.testing.assert_allclose(charge, C * v, rtol=0, atol=1e-12 * np.max(np.abs(C * v)))
    # and the leakage is there: 1 Gohm at up to 2.6 kV is 2.6 uA, not negligible against the charging
    assert np.max(np.abs(np.cumsum(i) / RATE - C * v)) > 1e-3 * np.max(np.abs(C * v))


def test_noise_is_the_configured_std_and_leaves_the_other_channels_alone(card, truth):
    noisy = truth_with(truth, current_noise="500 nA")
    with_current = produce(card, noisy, ("force", "current"))
    without = produce(card, noisy, ("force",))
    # the current's stream is its own: force and everything else bit-identical without the channel
    np.testing.assert_array_equal(with_current[:, :len(COLUMNS)], without)
    quiet = produce(card, truth_with(truth, current_noise="0 A"), ("force", "current"))
    d = with_current[:, -1] - quiet[:, -1]
    # 6001 draws: the sample std is within 5 % of 500 nA (its standard error is 0.9 %)
    assert np.std(d) == pytest.approx(500e-9, rel=0.05)


@pytest.mark.parametrize("chunk", [1, 777, 5000])
def test_chunking_does_not_change_the_current(card, truth, chunk):
    whole = produce(card, truth, ("force", "current"))
    np.testing.assert_array_equal(produce(card, truth, ("force", "current"), chunk=chunk), whole)


def test_bad_current_monitor_settings_are_refused(truth):
    from rdea_lab.specs import SpecError

    with pytest.raises(SpecError, match=r"instrument\.current_noise: must be >= 0"):
        truth_with(truth, current_noise="-1 nA")
    with pytest.raises(SpecError, match=r"instrument\.leakage_resistance: must be >= 0.001 Gohm"):
        truth_with(truth, leakage_resistance="10 ohm")
    with pytest.raises(SpecError, match=r"instrument\.current_noise: .* not a current"):
        truth_with(truth, current_noise="5 V")
