"""Long plans: windows equal the whole arrays' slices, the check over windows equals the whole check,
and a plan far too long to hold is expanded, summarized and checked window by window."""

import tracemalloc
from types import SimpleNamespace

import numpy as np
import pytest

from rdea_lab.physics.selection import envelope
from rdea_lab.protocols import check_plan, expand, plan as plan_module
from rdea_lab.specs import protocol_from_mapping
from rdea_lab.specs.limits import limit_violations

L3 = 48e-6  # [m]


def _segment(rng, channel, duration):
    """A random segment of any kind, in the YAML form (quantities with units)."""
    kind = rng.choice(["hold", "step", "ramp", "sine", "ramp_sine", "chirp", "table"])
    d = f"{duration!r} s"
    if channel == "stretch":
        val = lambda: float(rng.uniform(1.0, 1.8))  # noqa: E731  (up to 1.8: some beyond max_stretch 1.6)
        amp = lambda: float(rng.uniform(0.0, 0.2))  # noqa: E731  (a sine may dip below 1)
    else:
        val = lambda: f"{rng.uniform(-3.5, 3.5)!r} kV"  # noqa: E731  (some beyond max_voltage 3 kV)
        amp = lambda: f"{rng.uniform(0.0, 1.0)!r} kV"  # noqa: E731
    hz = lambda: f"{rng.uniform(0.05, 5.0)!r} Hz"  # noqa: E731
    if kind == "hold":
        return {"kind": "hold", "duration": d, **({"value": val()} if rng.random() < 0.5 else {})}
    if kind == "step":
        return {"kind": "step", "duration": d, "value": val()}
    if kind == "ramp":
        return {"kind": "ramp", "duration": d, "to": val(), **({"from": val()} if rng.random() < 0.5 else {})}
    if kind == "sine":
        return {"kind": "sine", "duration": d, "mean": val(), "amplitude": amp(), "frequency": hz(),
                "phase": f"{rng.uniform(-180, 180)!r} deg"}
    if kind == "ramp_sine":
        return {"kind": "ramp_sine", "duration": d, "frequency": hz(), "base": val(), "peak_start": val(),
                "peak_end": val()}
    if kind == "chirp":
        return {"kind": "chirp", "duration": d, "mean": val(), "amplitude": amp(), "f_start": hz(), "f_end": hz()}
    m = int(rng.integers(2, 9))
    if channel == "stretch":
        return {"kind": "table", "duration": d, "values": [float(v) for v in rng.uniform(1.0, 1.8, m)]}
    return {"kind": "table", "duration": d, "unit": "V", "values": [float(v) for v in rng.uniform(-3500, 3500, m)]}


def random_plan(seed):
    """A random protocol: 1-5 segments per channel over the same total, a random rate, maybe a probe."""
    rng = np.random.default_rng(seed)
    rate = float(rng.choice([10.0, 100.0, 250.0, 1000.0]))
    total = round(float(rng.uniform(0.5, 20.0)), 3)
    channels = {}
    for channel in ("stretch", "voltage"):
        cuts = np.sort(np.round(rng.uniform(0, total, int(rng.integers(0, 5))), 3))
        edges = np.unique(np.concatenate([[0.0], cuts, [total]]))
        channels[channel] = [_segment(rng, channel, float(b - a)) for a, b in zip(edges[:-1], edges[1:])]
    mapping = {"name": "r", "kind": "custom", "sample_rate": f"{rate} Hz", **channels,
               "limits": {"max_stretch": 1.6, "max_voltage": "3 kV", "max_field": "60 V/um"}}
    if rng.random() < 0.4:
        mapping.update(measure=["force", "current"],
                       probe={"amplitude": f"{rng.uniform(1, 200)!r} V",
                              "frequency": f"{rng.uniform(0.1, 0.45) * rate!r} Hz"})
    return expand(protocol_from_mapping(mapping, "<random>"))


#: a few random protocols in the default suite (between them every check fails somewhere: seed 8 and 16
#: dip below stretch 1), many more with the slow tests
DEFAULT = (0, 3, 8, 14, 16)
SEEDS = [*DEFAULT, *(pytest.param(seed, marks=pytest.mark.slow) for seed in range(60) if seed not in DEFAULT)]


@pytest.mark.parametrize("seed", SEEDS)
def test_a_window_is_the_same_slice_of_the_whole_arrays_bit_for_bit(seed):
    lazy, whole = random_plan(seed), random_plan(seed)
    n = whole.samples
    arrays = {name: getattr(whole, name) for name in ("time", "stretch", "voltage", "stretch_segment",
                                                      "voltage_segment")}
    assert arrays["time"].size == n == lazy.samples
    rng = np.random.default_rng(1000 + seed)
    cuts = [(0, n), (0, 0), (n, n), (n - 1, n), (0, 1)] + [tuple(sorted(rng.integers(0, n + 1, 2))) for _ in range(8)]
    for a, b in cuts:
        w = lazy.window(a, b)
        for name, values in arrays.items():
            got = getattr(w, name)
            assert got.dtype == values.dtype and not got.flags.writeable
            np.testing.assert_array_equal(got, values[a:b], strict=True)
    at = np.unique(rng.integers(0, n, 17))
    picked = lazy.at(at)
    for name, values in arrays.items():
        np.testing.assert_array_equal(getattr(picked, name), values[at], strict=True)
    assert lazy.held() == {}  # none of it was computed whole


@pytest.mark.parametrize("seed", SEEDS)
def test_the_check_over_windows_is_the_whole_check(seed, monkeypatch):
    """The same errors (field, segment, message) as limit_violations over the whole arrays, in windows of
    61 samples (a violation spans many)."""
    plan = random_plan(seed)
    whole = limit_violations(plan.limits, plan.source, plan.time, plan.stretch, plan.voltage, L3,
                             plan.stretch_segment, plan.voltage_segment)
    if plan.spec.probe is not None:  # check_plan adds what the probe does to a voltage violation
        whole = check_plan(SimpleNamespace(**{k: getattr(plan, k) for k in (
            "limits", "source", "time", "stretch", "voltage", "stretch_segment", "voltage_segment", "spec")}), L3)
    monkeypatch.setattr(plan_module, "CHUNK", 61)
    lazy = random_plan(seed)
    found = check_plan(lazy, L3)
    assert [(e.source, e.field, e.message) for e in found] == [(e.source, e.field, e.message) for e in whole]
    assert lazy.held() == {}


def test_the_random_protocols_break_every_limit_somewhere():
    """The comparison above is not vacuous: each check fails in some of the default random plans."""
    messages = " ".join(e.message for seed in DEFAULT for e in check_plan(random_plan(seed), L3))
    for what in ("is below 1", "max_stretch", "max_voltage", "max_field", "exceeded from"):
        assert what in messages


@pytest.mark.parametrize("seed", SEEDS)
def test_summary_envelope_and_decimation_are_the_whole_arrays(seed, monkeypatch):
    monkeypatch.setattr(plan_module, "CHUNK", 13)
    plan, whole = random_plan(seed), random_plan(seed)
    s = plan.summary()
    assert (s["stretch_min"], s["stretch_max"], s["voltage_min_V"], s["voltage_max_V"]) == (
        whole.stretch.min(), whole.stretch.max(), whole.voltage.min(), whole.voltage.max())
    for points in (5, 50, 2000):
        got, want = plan.envelope(points), envelope(whole.stretch, whole.voltage, points)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w, strict=True)
    columns = 7
    shown = plan.decimated(columns)
    k = shown["per_column"]
    for name in ("stretch", "voltage"):
        t, values = shown[name]
        assert np.all(np.diff(t) > 0)
        full = getattr(whole, name)
        if k == 1:
            np.testing.assert_array_equal(values, full)
            continue
        for c in range(0, full.size, k):  # each run's min and max are drawn, at their times
            run = full[c:c + k]
            inside = (t >= whole.time[c]) & (t <= whole.time[min(c + k, full.size) - 1])
            assert values[inside].min() == run.min() and values[inside].max() == run.max()
    assert plan.held() == {}


def test_small_plans_still_hold_their_arrays_as_before():
    plan = random_plan(3)
    stretch = plan.stretch
    assert stretch is plan.stretch and not stretch.flags.writeable  # computed once, kept, read-only
    assert set(plan.held()) == {"stretch"}
    w = plan.window(2, 5)
    assert np.shares_memory(w.stretch, stretch)  # a held array is sliced, not computed again


def _day(samples, rate=1000.0):
    spec = protocol_from_mapping({
        "name": "long", "kind": "tensile", "sample_rate": f"{rate} Hz",
        "stretch": [{"kind": "hold", "duration": "5 s", "value": 1.0},
                    {"kind": "ramp_sine", "duration": f"{(samples - 1) / rate - 10.0!r} s", "frequency": "1 Hz",
                     "base": 1.0, "peak_start": 1.05, "peak_end": 1.5},
                    {"kind": "hold", "duration": "5 s", "value": 1.0}],
        "voltage": [{"kind": "ramp", "duration": "5 s", "from": "0 V", "to": "2.6 kV"},
                    {"kind": "hold", "duration": f"{(samples - 1) / rate - 10.0!r} s", "value": "2.6 kV"},
                    {"kind": "ramp", "duration": "5 s", "to": "0 V"}],
    }, "<long>")
    return expand(spec)


def _expanded_summarized_checked(samples):
    check_plan(_day(100_001), L3)  # the first read of a protocol fills caches (units, models): not the plan's
    tracemalloc.start()
    try:
        plan = _day(samples)
        s = plan.summary()
        problems = check_plan(plan, L3)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert plan.samples == samples and plan.held() == {}
    # the ramp sine's sampled tops reach 1.5 only within a step of its continuous peak (test_presets)
    assert s["stretch_min"] == 1.0 and s["stretch_max"] == pytest.approx(1.5, abs=1e-3)
    assert s["voltage_max_V"] == pytest.approx(2600.0, rel=1e-15)
    assert problems == []  # 2.6 kV sqrt(1.5) / 48 um = 66 V/um < 80 V/um
    return peak


def test_a_long_plan_is_expanded_summarized_and_checked_in_bounded_memory(monkeypatch):
    """2e6 samples (64 MB as whole arrays) in windows of 32768 samples: the peak is a few windows'."""
    monkeypatch.setattr(plan_module, "CHUNK", 1 << 15)
    whole_bytes = 2_000_000 * (3 * 8 + 2 * 4)
    assert _expanded_summarized_checked(2_000_000) < whole_bytes / 10


@pytest.mark.slow  # 1e8 samples: about 15 s window by window
def test_a_plan_of_1e8_samples_is_expanded_summarized_and_checked_far_below_its_size():
    whole_bytes = 100_000_000 * (3 * 8 + 2 * 4)  # 3.2 GB
    assert _expanded_summarized_checked(100_000_000) < whole_bytes / 20
