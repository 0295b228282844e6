"""Tests of rdea_lab.specs.protocol: protocol YAML to SI models and back."""

import math

import pytest

from rdea_lab.specs import (
    Limits,
    ProtocolSpec,
    SpecError,
    dump_protocol,
    load_protocol,
    protocol_from_mapping,
    protocol_from_yaml,
)
from rdea_lab.specs.protocol import (
    StretchHold,
    StretchRamp,
    TensileRampSineSettings,
    VoltageRamp,
    VoltageSine,
    format_angle,
)

EXAMPLE = """
name: tensile_ramp_sine_2.6kV
kind: tensile
description: an example
source: the brief
sample_rate: 100 Hz
measure: [force]
limits:
  max_voltage: 3 kV
  max_stretch: 2.0
  max_force: 50 N
  max_field: 80 V/um
stretch:
  - {kind: hold, duration: 2 s, value: 1.0}
  - {kind: ramp_sine, duration: 50 s, frequency: 0.1 Hz, base: 1.0, peak_start: 1.1, peak_end: 1.5}
voltage:
  - {kind: ramp, duration: 2 s, to: 2.6 kV}
  - {kind: hold, duration: 50 s}
"""

PRESET = """
name: tensile_ramp_sine_2.6kV
kind: tensile
sample_rate: 100 Hz
preset: tensile_ramp_sine
settings: {voltage: 2.6 kV, max_stretch: 1.5, frequency: 0.1 Hz, cycles: 5}
"""

EVERY_KIND = """
name: every-kind
kind: custom
sample_rate: 1 kHz
stretch:
  - {kind: hold, duration: 1 s}
  - {kind: step, duration: 1 s, value: 1.1}
  - {kind: ramp, duration: 1 s, from: 1.1, to: 1.2}
  - {kind: sine, duration: 1 s, mean: 1.2, amplitude: 0.01, frequency: 3 Hz, phase: 30 deg}
  - {kind: ramp_sine, duration: 1 s, frequency: 2 Hz, base: 1.2, peak_start: 1.25, peak_end: 1.3}
  - {kind: chirp, duration: 1 s, mean: 1.2, amplitude: 0.01, f_start: 1 Hz, f_end: 7 Hz}
voltage:
  - {kind: hold, duration: 1 s, value: 10 V}
  - {kind: step, duration: 1 s, value: 0.1 kV}
  - {kind: ramp, duration: 1 s, to: 1000 V}
  - {kind: sine, duration: 1 s, mean: 1 kV, amplitude: 100 V, frequency: 3 Hz, phase: 0.25 rad}
  - {kind: ramp_sine, duration: 1 s, frequency: 2 Hz, base: 1 kV, peak_start: 1.5 kV, peak_end: 2 kV}
  - {kind: chirp, duration: 1 s, mean: 1 kV, amplitude: 0.3 kV, f_start: 1 Hz, f_end: 7 Hz}
"""


def test_example_parses_to_si():
    spec = protocol_from_yaml(EXAMPLE)
    assert (spec.name, spec.kind, spec.sample_rate, spec.measure) == ("tensile_ramp_sine_2.6kV", "tensile", 100.0,
                                                                      ("force",))
    assert spec.limits == Limits(max_voltage=3e3, max_stretch=2.0, max_force=50.0, max_field=80e6)
    hold, rs = spec.stretch
    assert (hold.kind, hold.duration, hold.value) == ("hold", 2.0, 1.0)
    assert (rs.duration, rs.frequency, rs.base, rs.peak_start, rs.peak_end) == (50.0, 0.1, 1.0, 1.1, 1.5)
    ramp, vhold = spec.voltage
    assert (ramp.to, ramp.from_, vhold.value) == (2600.0, None, None)
    assert spec.duration == 52.0 and spec.preset is None and spec.settings is None
    assert spec.origin == "<string>"


def test_defaults():
    spec = protocol_from_yaml(
        "name: d\nkind: custom\nsample_rate: 10 Hz\nstretch: [{kind: hold, duration: 1 s}]\n"
        "voltage: [{kind: hold, duration: 1 s}]\n"
    )
    assert spec.measure == ("force",)
    assert spec.limits == Limits() == Limits(max_voltage=3e3, max_stretch=2.0, max_force=50.0, max_field=80e6)


def test_preset_keeps_preset_and_settings_as_given():
    spec = protocol_from_yaml(PRESET)
    assert spec.preset == "tensile_ramp_sine" and spec.stretch is None and spec.voltage is None
    assert isinstance(spec.settings, TensileRampSineSettings)
    assert spec.settings.model_fields_set == {"voltage", "max_stretch", "frequency", "cycles"}
    assert (spec.settings.voltage, spec.settings.cycles, spec.settings.settle) == (2600.0, 5, 2.0)
    assert spec.duration is None


@pytest.mark.parametrize("preset, kind, measure", [
    ("tensile_ramp_sine", "tensile", ("force",)),
    ("blocking_force", "blocking", ("force",)),
    ("capacitance_sweep", "capacitance", ("force", "capacitance")),
])
def test_preset_supplies_kind_and_measure(preset, kind, measure):
    spec = protocol_from_yaml(f"name: p\nsample_rate: 100 Hz\npreset: {preset}\n")
    assert (spec.kind, spec.measure) == (kind, measure)
    assert spec.settings.model_fields_set == set()


def test_measure_can_be_given_for_a_preset():
    spec = protocol_from_yaml("name: p\nsample_rate: 100 Hz\npreset: capacitance_sweep\nmeasure: [capacitance]\n")
    assert spec.measure == ("capacitance",)


@pytest.mark.parametrize("text", [EXAMPLE, PRESET, EVERY_KIND])
def test_dump_then_load_gives_an_equal_spec(text):
    spec = protocol_from_yaml(text)
    dumped = dump_protocol(spec)
    again = protocol_from_yaml(dumped)
    assert again == spec
    assert dump_protocol(again) == dumped


def test_dump_writes_units():
    text = dump_protocol(protocol_from_yaml(EVERY_KIND))
    for piece in ("sample_rate: 1 kHz", "max_field: 80 V/um", "duration: 1 s", "value: 0.01 kV", "to: 1 kV",
                  "phase: 30 deg", "f_end: 7 Hz", "from: 1.1", "measure: [force]"):
        assert piece in text, piece


def test_dump_of_a_preset_writes_the_given_settings_only():
    text = dump_protocol(protocol_from_yaml(PRESET))
    assert "preset: tensile_ramp_sine" in text and "voltage: 2.6 kV" in text and "cycles: 5" in text
    assert "settle" not in text and "\nstretch:" not in text and "\nvoltage:" not in text


def test_dump_round_trips_awkward_values():
    spec = ProtocolSpec(
        name="odd", kind="custom", sample_rate=1 / 3 * 1e3,
        stretch=[StretchRamp(duration=math.pi, to=1 + 1 / 7)],
        voltage=[VoltageSine(duration=math.pi, mean=1 / 3, amplitude=2 / 3 * 1e3, frequency=math.e, phase=1.0)],
        limits=Limits(max_voltage=2345.678, max_field=7.1e7),
    )
    assert protocol_from_yaml(dump_protocol(spec)) == spec


def test_python_numbers_are_si_and_from_is_an_alias():
    spec = ProtocolSpec(
        name="py", kind="custom", sample_rate=100,
        stretch=[StretchHold(duration=1.0, value=1.2), {"kind": "ramp", "duration": 1.0, "to": 1.0}],
        voltage=[VoltageRamp(duration=2.0, to=1e3, **{"from": 500.0})],
    )
    assert spec.voltage[0].from_ == 500.0 and spec.stretch[1].to == 1.0
    assert spec.origin == "<python>"


def test_origin_is_not_part_of_equality(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(PRESET)
    spec = load_protocol(path)
    assert spec.origin == str(path) and spec == protocol_from_yaml(PRESET)
    assert hash(spec) == hash(protocol_from_yaml(PRESET))


def test_spec_is_frozen():
    spec = protocol_from_yaml(EXAMPLE)
    with pytest.raises(Exception):
        spec.name = "other"


def _voltage_sine(phase):
    spec = protocol_from_yaml(
        "name: s\nkind: custom\nsample_rate: 100 Hz\nstretch: [{kind: hold, duration: 1 s}]\n"
        f"voltage: [{{kind: sine, duration: 1 s, mean: 1 kV, amplitude: 1 kV, frequency: 1 Hz, phase: {phase}}}]\n"
    )
    return spec.voltage[0]


@pytest.mark.parametrize("angle, radians", [("-90 deg", -math.pi / 2), ("0.5 rad", 0.5), ("180 degree", math.pi)])
def test_phase_units(angle, radians):
    seg = _voltage_sine(angle)
    assert seg.phase == pytest.approx(radians, rel=1e-15)
    assert format_angle(seg.phase).endswith(" deg")


def test_minus_90_deg_is_exactly_minus_half_pi():
    assert _voltage_sine("-90 deg").phase == -math.pi / 2


# ----------------------------------------------------------------- errors
def _error(text, source="p.yaml"):
    with pytest.raises(SpecError) as info:
        protocol_from_yaml(text, source)
    assert "\n" not in str(info.value)
    return info.value


CHANNELS = "stretch: [{kind: hold, duration: 2 s}]\nvoltage: [{kind: hold, duration: 2 s}]\n"
TOP = "name: x\nkind: custom\nsample_rate: 100 Hz\n"


def test_durations_must_agree():
    err = _error(EXAMPLE.replace("duration: 2 s, to: 2.6 kV", "duration: 1 s, to: 2.6 kV"))
    assert err.field == "voltage"
    assert "stretch lasts 52 s but voltage lasts 51 s" in err.message


def test_durations_equal_up_to_rounding():
    spec = protocol_from_yaml(
        TOP + "stretch: [{kind: hold, duration: 0.1 s}, {kind: hold, duration: 0.2 s}]\n"
        "voltage: [{kind: hold, duration: 0.3 s}]\n"
    )
    assert spec.duration == pytest.approx(0.3)


@pytest.mark.parametrize("text, field, match", [
    (TOP + CHANNELS + "preset: blocking_force\n", "preset", "not both"),
    (TOP, "stretch", "missing waveform"),
    (TOP + "stretch: [{kind: hold, duration: 2 s}]\n", "voltage", "missing required key 'voltage'"),
    (TOP + CHANNELS + "settings: {cycles: 2}\n", "settings", "belong to a preset"),
    ("name: x\nsample_rate: 100 Hz\npreset: blocking_force\nsettings: [1, 2]\n", "settings", "expected a mapping"),
    ("name: x\nsample_rate: 100 Hz\npreset: blocking_force\nsettings: {voltage_max: 1 kV, voltage_min: 2 kV}\n",
     "settings.voltage_max", "below voltage_min"),
    ("name: x\nsample_rate: 100 Hz\npreset: tensile_ramp_sine\nsettings: {min_stretch: 1.5, max_stretch: 1.5}\n",
     "settings.max_stretch", "not above min_stretch"),
    ("name: x\nsample_rate: 100 Hz\npreset: tensile_ramp_sine\nsettings: {cycles: true}\n",
     "settings.cycles", "whole number"),
    ("name: x\nsample_rate: 100 Hz\npreset: tensile_ramp_sine\nsettings: {cycles: 0}\n",
     "settings.cycles", "whole number of cycles"),
    (TOP.replace("kind: custom", "kind: [tensile]") + CHANNELS, "kind", "not allowed"),
    (TOP + "measure: [force, force]\n" + CHANNELS, "measure", "listed twice"),
    (TOP + "measure: force\n" + CHANNELS, "measure", "expected a list"),
    (TOP + "stretch: {kind: hold, duration: 2 s}\nvoltage: [{kind: hold, duration: 2 s}]\n", "stretch",
     "expected a list of segments"),
    (TOP + "stretch: [{kind: 3, duration: 2 s}]\nvoltage: [{kind: hold, duration: 2 s}]\n", "stretch[0].kind",
     "unknown segment kind 3"),
    (TOP + "stretch: [{kind: step, duration: 2 s}]\nvoltage: [{kind: hold, duration: 2 s}]\n", "stretch[0].value",
     "missing required key 'value'"),
    (TOP + "stretch: [{kind: sine, duration: 2 s, mean: 1.2 kV, amplitude: 0.1, frequency: 1 Hz}]\n"
     "voltage: [{kind: hold, duration: 2 s}]\n", "stretch[0].mean", "not a dimensionless number"),
])
def test_structural_errors(text, field, match):
    err = _error(text)
    assert err.source == "p.yaml" and err.field == field
    assert match in err.message


def test_a_stretch_sine_may_dip_below_one_until_the_plan_check():
    spec = protocol_from_yaml(TOP + "stretch: [{kind: sine, duration: 2 s, mean: 1.05, amplitude: 0.1, "
                              "frequency: 1 Hz}]\nvoltage: [{kind: hold, duration: 2 s}]\n")
    assert spec.stretch[0].mean == 1.05


def test_literal_stretch_below_one_names_the_field():
    err = _error(TOP + "stretch: [{kind: sine, duration: 2 s, mean: 0.95, amplitude: 0.01, frequency: 1 Hz}]\n"
                 "voltage: [{kind: hold, duration: 2 s}]\n")
    assert err.field == "stretch[0].mean" and "stretch 0.95 is below 1" in err.message


def test_errors_from_python_are_spec_errors():
    with pytest.raises(SpecError, match=r"^<python>: stretch\[0\]\.duration: must be > 0 s"):
        ProtocolSpec(name="x", kind="custom", sample_rate=1.0, stretch=[{"kind": "hold", "duration": 0.0}],
                     voltage=[{"kind": "hold", "duration": 1.0}])
    with pytest.raises(SpecError, match=r"^<python>: voltage\[0\]: StretchHold is not a voltage segment"):
        ProtocolSpec(name="x", kind="custom", sample_rate=1.0, stretch=[StretchHold(duration=1.0)],
                     voltage=[StretchHold(duration=1.0)])
    with pytest.raises(SpecError, match="stretch 0.5 is below 1"):
        StretchHold(duration=1.0, value=0.5)


def test_mapping_and_file_errors(tmp_path):
    with pytest.raises(SpecError, match=r"^<mapping>: expected a mapping"):
        protocol_from_mapping([1, 2])
    with pytest.raises(SpecError, match="file not found"):
        load_protocol(tmp_path / "missing.yaml")
    with pytest.raises(SpecError, match=r": the document is empty"):
        protocol_from_yaml("")
