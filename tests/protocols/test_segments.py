"""Each segment kind sampled by a plan, against its formula written out here."""

import numpy as np
import pytest

from rdea_lab.protocols import evaluate
from rdea_lab.specs.protocol import StretchRamp, VoltageSine

from .conftest import make_plan

RATE = 100.0  # [Hz]


def _hold(seconds):
    return [{"kind": "hold", "duration": f"{seconds} s"}]


def _local(plan, channel, index, start):
    """Local time and values of segment `index` of `channel`."""
    mask = getattr(plan, f"{channel}_segment") == index
    return plan.time[mask] - start, getattr(plan, channel)[mask]


def test_time_axis_and_sample_count():
    plan = make_plan(_hold(2.345), _hold(2.345))
    n = round(2.345 * RATE) + 1
    assert plan.samples == plan.time.size == n == 236
    np.testing.assert_array_equal(plan.time, np.arange(n) / RATE)
    assert plan.duration == 2.345


def test_arrays_are_read_only():
    plan = make_plan(_hold(1), _hold(1))
    for name in ("time", "stretch", "voltage", "stretch_segment", "voltage_segment"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(plan, name)[0] = 1


def test_hold_without_value_continues_the_previous_value():
    plan = make_plan(
        [{"kind": "ramp", "duration": "2 s", "to": 1.3}, {"kind": "hold", "duration": "3 s"}],
        [{"kind": "hold", "duration": "1 s"}, {"kind": "ramp", "duration": "2 s", "to": "1 kV"},
         {"kind": "hold", "duration": "2 s"}],
    )
    _, held = _local(plan, "stretch", 1, 2.0)
    assert held.size == 301 and np.all(held == 1.3)  # the last segment also holds the final sample
    _, rest = _local(plan, "voltage", 0, 0.0)
    assert np.all(rest == 0.0)  # the voltage channel rests at 0 V
    _, held = _local(plan, "voltage", 2, 3.0)
    assert np.all(held == 1000.0)


def test_first_hold_without_value_is_the_rest_stretch():
    plan = make_plan(_hold(1), _hold(1))
    assert np.all(plan.stretch == 1.0) and np.all(plan.voltage == 0.0)


def test_step_jumps_at_the_boundary_sample():
    plan = make_plan(
        [{"kind": "hold", "duration": "1 s", "value": 1.1}, {"kind": "step", "duration": "1 s", "value": 1.4}],
        _hold(2),
    )
    assert plan.stretch[99] == 1.1
    assert plan.stretch[100] == 1.4 and plan.stretch_segment[100] == 1  # the boundary sample is the new segment's
    assert np.all(plan.stretch[100:] == 1.4)


def test_ramp_from_previous_and_explicit_from():
    plan = make_plan(
        [{"kind": "hold", "duration": "1 s", "value": 1.2}, {"kind": "ramp", "duration": "4 s", "to": 1.5}],
        [{"kind": "ramp", "duration": "5 s", "from": "-1 kV", "to": "2 kV"}],
    )
    t, x = _local(plan, "stretch", 1, 1.0)
    # the convex form a (1 - w) + b w and a + (b - a) w differ by rounding only
    np.testing.assert_allclose(x, 1.2 + (1.5 - 1.2) * t / 4.0, rtol=1e-15, atol=0)
    assert x[0] == 1.2 and plan.stretch[-1] == 1.5
    t, v = _local(plan, "voltage", 0, 0.0)
    np.testing.assert_allclose(v, -1000.0 + 3000.0 * t / 5.0, rtol=0, atol=1e-12)
    assert v[0] == -1000.0 and v[-1] == 2000.0


def test_sine_with_phase_minus_90_deg_starts_at_mean_minus_amplitude():
    plan = make_plan(
        _hold(10),
        [{"kind": "sine", "duration": "10 s", "mean": "1.3 kV", "amplitude": "1.3 kV", "frequency": "1 Hz",
          "phase": "-90 deg"}],
    )
    t = plan.time
    assert plan.voltage[0] == 0.0
    np.testing.assert_allclose(plan.voltage, 1300.0 - 1300.0 * np.cos(2 * np.pi * t), rtol=0, atol=1e-9)
    assert plan.voltage.max() == pytest.approx(2600.0, rel=1e-15)


def test_sine_phase_in_rad_and_default_zero():
    plan = make_plan(
        [{"kind": "sine", "duration": "4 s", "mean": 1.2, "amplitude": 0.1, "frequency": "0.5 Hz"}],
        [{"kind": "sine", "duration": "4 s", "mean": "0 V", "amplitude": "1 kV", "frequency": "0.25 Hz",
          "phase": "0.5 rad"}],
    )
    t = plan.time
    np.testing.assert_allclose(plan.stretch, 1.2 + 0.1 * np.sin(2 * np.pi * 0.5 * t), rtol=0, atol=1e-15)
    np.testing.assert_allclose(plan.voltage, 1000.0 * np.sin(2 * np.pi * 0.25 * t + 0.5), rtol=0, atol=1e-12)


def test_ramp_sine_tops_equal_the_peak_ramp_and_cycles_start_at_base():
    f, T, base, p0, p1 = 0.1, 50.0, 1.0, 1.1, 1.5
    plan = make_plan(
        [{"kind": "hold", "duration": "2 s"},
         {"kind": "ramp_sine", "duration": "50 s", "frequency": "0.1 Hz", "base": base,
          "peak_start": p0, "peak_end": p1}],
        _hold(52),
    )
    t, x = _local(plan, "stretch", 1, 2.0)
    peak = p0 + (p1 - p0) * (t / T)
    np.testing.assert_allclose(x, base + (peak - base) * (1 - np.cos(2 * np.pi * f * t)) / 2, rtol=1e-15, atol=0)
    for k in range(5):
        top = np.flatnonzero(np.isclose(t, (k + 0.5) / f, rtol=0, atol=1e-9))
        assert top.size == 1 and x[top[0]] == peak[top[0]]  # exactly: (1 - cos(pi (2k + 1))) / 2 == 1
        start = np.flatnonzero(np.isclose(t, k / f, rtol=0, atol=1e-9))
        assert x[start[0]] == base
    assert plan.stretch[-1] == base  # the segment ends a whole cycle later, at base


def test_chirp_matches_its_formula():
    T, f0, f1 = 10.0, 0.5, 5.0
    plan = make_plan(
        _hold(12),
        [{"kind": "hold", "duration": "2 s", "value": "1 kV"},
         {"kind": "chirp", "duration": "10 s", "mean": "1 kV", "amplitude": "0.5 kV", "f_start": "0.5 Hz",
          "f_end": "5 Hz"}],
        rate="1 kHz",
    )
    t, v = _local(plan, "voltage", 1, 2.0)
    expected = 1000.0 + 500.0 * np.sin(2 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2 * T)))
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-9)
    assert v[0] == 1000.0


def test_boundaries_that_are_inexact_sums_fall_on_their_sample():
    # 0.1 + 0.2 s = 0.30000000000000004 s: the step still starts at sample 30
    plan = make_plan(
        [{"kind": "hold", "duration": "0.1 s"}, {"kind": "hold", "duration": "0.2 s"},
         {"kind": "step", "duration": "0.7 s", "value": 1.5}],
        _hold(1),
    )
    assert plan.stretch_segment[29] == 1 and plan.stretch_segment[30] == 2
    assert plan.stretch[29] == 1.0 and plan.stretch[30] == 1.5


def test_segment_index_arrays():
    plan = make_plan(
        [{"kind": "hold", "duration": "1 s"}, {"kind": "hold", "duration": "2 s"}],
        [{"kind": "hold", "duration": "3 s"}],
    )
    assert plan.stretch_segment.dtype.kind == "i"
    np.testing.assert_array_equal(np.bincount(plan.stretch_segment), [100, 201])
    assert np.all(plan.voltage_segment == 0)


def test_last_sample_past_the_end_holds_the_end_value():
    # 1.006 s at 100 Hz: N = round(100.6) + 1 = 102, the last sample at 1.01 s
    plan = make_plan([{"kind": "ramp", "duration": "1.006 s", "to": 1.5}], _hold(1.006))
    assert plan.samples == 102 and plan.time[-1] == 1.01
    assert plan.stretch[-1] == 1.5


def test_evaluate_from_python_models():
    ramp = StretchRamp(duration=2.0, to=1.4)  # numbers from Python are SI
    np.testing.assert_allclose(evaluate(ramp, [0.0, 1.0, 2.0], previous=1.2), [1.2, 1.3, 1.4], rtol=1e-15)
    sine = VoltageSine(duration=1.0, mean=0.0, amplitude=100.0, frequency=1.0, phase=np.pi / 2)
    assert evaluate(sine, [0.0], previous=0.0)[0] == 100.0
