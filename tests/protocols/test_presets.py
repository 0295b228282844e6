"""The paper's presets (Section 4.2, Figs. 11-16 of [1]) expanded into plans."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rdea_lab.protocols import BUILDERS, expand, expand_preset
from rdea_lab.specs import protocol_from_mapping
from rdea_lab.specs.protocol import PRESETS, channel_duration


def preset_plan(preset, rate="100 Hz", **settings):
    return expand(protocol_from_mapping(
        {"name": "p", "sample_rate": rate, "preset": preset, "settings": settings}, "<test>"
    ))


def local_maxima(x):
    """Indices i with x[i-1] < x[i] >= x[i+1]."""
    i = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    return i


def test_every_declared_preset_has_a_builder():
    assert set(BUILDERS) == set(PRESETS)


@pytest.mark.parametrize("cycles, lo, hi, f", [(5, 1.0, 1.5, 0.1), (3, 1.1, 1.4, 0.2), (1, 1.0, 1.2, 0.5)])
def test_tensile_ramp_sine_stretch(cycles, lo, hi, f):
    plan = preset_plan("tensile_ramp_sine", voltage="2.6 kV", cycles=cycles, min_stretch=lo, max_stretch=hi,
                       frequency=f"{f} Hz")
    x = plan.stretch
    assert plan.kind == "tensile" and plan.measure == ("force",)
    assert x.min() == lo and x[0] == lo and x[-1] == lo
    tops = local_maxima(x)
    assert tops.size == cycles
    # cycle k tops out at lo + (k + 1) (hi - lo) / cycles; the top samples sit at 2 s + (k + 1/2) / f
    expected = lo + (np.arange(cycles) + 1) * (hi - lo) / cycles
    at_tops = x[np.round((2.0 + (np.arange(cycles) + 0.5) / f) * 100).astype(int)]
    np.testing.assert_allclose(at_tops, expected, rtol=1e-15, atol=0)
    # the amplitude keeps growing past each top, so the continuous maximum lies
    # above max_stretch by about (hi - lo) / (4 pi^2 cycles^2) (a second-order
    # expansion of the envelope times (1 - cos) / 2 around the top)
    overshoot = (hi - lo) / (4 * math.pi**2 * cycles**2)
    assert 0.0 <= x.max() - hi <= 1.05 * overshoot
    assert x.max() == pytest.approx(hi, abs=1.05 * overshoot)


def test_tensile_ramp_sine_defaults_are_the_papers():
    plan = preset_plan("tensile_ramp_sine")
    s = plan.summary()
    assert s["stretch_min"] == 1.0 and s["stretch_max"] == pytest.approx(1.5, abs=6e-4)  # see the overshoot above
    assert s["voltage_min_V"] == s["voltage_max_V"] == 0.0
    assert local_maxima(plan.stretch).size == 5
    assert plan.duration == 2 + 5 / 0.1 + 2 == 54.0
    assert plan.samples == round(54.0 * 100) + 1 == 5401


def test_tensile_ramp_sine_voltage():
    plan = preset_plan("tensile_ramp_sine", voltage="2.6 kV", settle="3 s")
    v = plan.voltage
    assert v[0] == 0.0 and v[-1] == 0.0
    plateau = plan.voltage_segment == 1
    assert np.all(v[plateau] == 2600.0)
    assert np.all(plan.stretch_segment[plateau] == 1)  # the plateau spans the ramp sine
    # ramps over the 3 s settle: no step larger than 2.6 kV / 300 samples
    assert np.abs(np.diff(v)).max() == pytest.approx(2600.0 / 300, rel=1e-12)
    assert plan.duration == 3 + 50 + 3


def test_blocking_force():
    plan = preset_plan("blocking_force", rate="1 kHz")
    x, v = plan.stretch, plan.voltage
    assert plan.kind == "blocking"
    sine = plan.voltage_segment == 1
    assert np.all(x[sine] == 1.5)
    assert v.min() == 0.0 and v.max() == pytest.approx(2600.0, rel=1e-15)
    assert v[sine][0] == 0.0  # phase -90 deg: the sine starts at voltage_min
    assert local_maxima(v).size == 10
    assert x[0] == 1.0 and x[-1] == 1.0 and x.max() == 1.5
    assert plan.duration == 5 + (5 + 10 / 1.0) + 5 == 25.0
    assert plan.samples == 25001


def test_blocking_force_settings():
    plan = preset_plan("blocking_force", rate="1 kHz", stretch=1.3, voltage_min="0.5 kV", voltage_max="2 kV",
                       frequency="2 Hz", cycles=4, approach="1 s", settle="0.5 s")
    sine = plan.voltage_segment == 1
    v = plan.voltage[sine]
    assert v[0] == pytest.approx(500.0, rel=1e-15) and v.max() == pytest.approx(2000.0, rel=1e-15)
    assert local_maxima(plan.voltage).size == 4
    assert np.all(plan.stretch[sine] == 1.3)
    assert plan.duration == 1 + 0.5 + 4 / 2 + 1


def test_capacitance_sweep():
    plan = preset_plan("capacitance_sweep")
    tensile = preset_plan("tensile_ramp_sine")
    assert plan.kind == "capacitance" and plan.measure == ("force", "capacitance")
    np.testing.assert_array_equal(plan.stretch, tensile.stretch)
    assert np.all(plan.voltage == 0.0)
    assert plan.duration == tensile.duration and plan.samples == tensile.samples


def test_capacitance_sweep_has_no_voltage_setting():
    from rdea_lab.specs import SpecError
    with pytest.raises(SpecError, match=r"settings\.voltage: unknown key 'voltage'"):
        preset_plan("capacitance_sweep", voltage="1 kV")


def test_expand_preset_gives_explicit_segments_and_keeps_the_rest():
    spec = protocol_from_mapping(
        {"name": "p", "sample_rate": "100 Hz", "preset": "tensile_ramp_sine", "description": "d",
         "limits": {"max_stretch": 1.6}}, "file.yaml",
    )
    explicit = expand_preset(spec)
    assert explicit.preset is None and explicit.settings is None
    assert [s.kind for s in explicit.stretch] == ["hold", "ramp_sine", "hold"]
    assert [s.kind for s in explicit.voltage] == ["ramp", "hold", "ramp"]
    assert (explicit.name, explicit.kind, explicit.description, explicit.limits) == (
        spec.name, spec.kind, spec.description, spec.limits)
    assert explicit.origin == "file.yaml"
    assert expand_preset(explicit) is explicit


def test_a_preset_whose_expansion_has_too_many_samples_is_refused_when_read_naming_the_file():
    """The spec checks the file whole (the protocols layer only expands): 10000 cycles at 1 Hz plus 2 x 5 s
    of approach and 5 s of settle are 10015 s, at 100 kHz 1001500001 samples, above the 1e9 allowed."""
    from rdea_lab.specs import SpecError
    with pytest.raises(SpecError, match=r"^x\.yaml: sample_rate: .* gives 1001500001 samples; at most 1000000000 "
                                        r"\(1 billion\) are allowed"):
        protocol_from_mapping(
            {"name": "p", "sample_rate": "100 kHz", "preset": "blocking_force", "settings": {"cycles": 10000}},
            "x.yaml")


def test_a_preset_too_long_to_count_its_samples_is_refused_when_read():
    from rdea_lab.specs import SpecError
    with pytest.raises(SpecError, match=r"^x\.yaml: sample_rate: inf s at 100 Hz gives more than 1000000000 samples"):
        protocol_from_mapping(
            {"name": "p", "sample_rate": "100 Hz", "preset": "tensile_ramp_sine", "settings": {"settle": "1e308 s"}},
            "x.yaml")


_durations = st.floats(1e-3, 1e4, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(preset=st.sampled_from(sorted(PRESETS)), settle=_durations, approach=_durations,
       frequency=st.floats(1e-3, 40.0), cycles=st.integers(1, 50))
def test_a_preset_lasts_the_duration_its_settings_declare(preset, settle, approach, frequency, cycles):
    """The spec counts a preset's samples from ``settings.duration`` [s]; the expansion must last exactly
    that (the stretch channel: the duration a plan has), the voltage channel within the rounding of sums."""
    settings_ = {"settle": f"{settle!r} s", "frequency": f"{frequency!r} Hz", "cycles": cycles}
    if preset == "blocking_force":
        settings_["approach"] = f"{approach!r} s"
    spec = protocol_from_mapping({"name": "p", "sample_rate": "100 Hz", "preset": preset, "settings": settings_},
                                 "<test>")
    explicit = expand_preset(spec)
    assert channel_duration(explicit.stretch) == spec.settings.duration == explicit.duration
    assert math.isclose(channel_duration(explicit.voltage), spec.settings.duration, rel_tol=1e-12)
