"""A protocol's pause: mapping and suspend: list (rdea_lab.specs.protocol_pause, .suspenders): read in SI,
checked where the protocol is read, written back by the protocol's dump (an old protocol's dump unchanged)."""

from pathlib import Path

import pytest

from rdea_lab.protocols import expand
from rdea_lab.protocols.pause import PauseSpec, pause_spec_of
from rdea_lab.specs import SpecError, dump_protocol, load_protocol, protocol_from_yaml
from rdea_lab.specs.protocol_pause import DEFAULT_RAMP_RATE, DEFAULT_STRETCH_RATE, Pause
from rdea_lab.specs.suspenders import Suspender

PROTOCOLS = Path(__file__).resolve().parents[2] / "rdea_lab" / "data" / "protocols"

BASE = """\
name: p
kind: custom
sample_rate: 10 Hz
limits: {max_stretch: 1.6}
stretch: [{kind: hold, duration: 1 s, value: 1.2}]
voltage: [{kind: hold, duration: 1 s, value: 1 kV}]
"""

SUSPEND = """\
suspend:
  - {name: door, when: interlock == open}
  - {name: hot, when: amplifier_temperature > 60 degC, resume: amplifier_temperature < 50 degC, wait: 30 min}
  - {when: "|force_offset_drift| > 5 mN", wait: 45 s}
"""


def test_pause_in_si_and_its_plan_pause_spec():
    spec = protocol_from_yaml(BASE + "pause: {ramp_rate: 1 kV/s, hold_stretch: 1.05, stretch_rate: 0.05 /s}\n")
    assert spec.pause == Pause(ramp_rate=1000.0, hold_stretch=1.05, stretch_rate=0.05)
    assert pause_spec_of(expand(spec)) == PauseSpec(1000.0, 1.05, 0.05)


@pytest.mark.parametrize("text, expected", [
    ("{}", (DEFAULT_RAMP_RATE, None, DEFAULT_STRETCH_RATE)),
    ("{ramp_rate: 500 V/s}", (500.0, None, DEFAULT_STRETCH_RATE)),
    ("{hold_stretch: 1.6, stretch_rate: 5 %/s}", (DEFAULT_RAMP_RATE, 1.6, 0.05)),  # at the limit: allowed
    ("{stretch_rate: 0.1/s}", (DEFAULT_RAMP_RATE, None, 0.1)),
    ("{stretch_rate: 0.1 1/s}", (DEFAULT_RAMP_RATE, None, 0.1)),
])
def test_every_pause_key_is_optional(text, expected):
    pause = protocol_from_yaml(BASE + f"pause: {text}\n").pause
    assert (pause.ramp_rate, pause.hold_stretch, pause.stretch_rate) == expected


def test_no_pause_no_suspenders():
    spec = protocol_from_yaml(BASE)
    assert spec.pause is None and spec.suspend == ()
    assert pause_spec_of(expand(spec)) == PauseSpec()


@pytest.mark.parametrize("text, match", [
    ("pause: {hold_stretch: 1.7}", r"pause\.hold_stretch: stretch 1\.7 is above the limit max_stretch = 1\.6; "
                                   r"allowed: 1 <= hold_stretch <= 1\.6 \(limits\.max_stretch\)"),
    ("pause: {hold_stretch: 0.95}", r"pause\.hold_stretch: stretch 0\.95 is below 1; .*allowed: 1 <= hold_stretch"),
    ("pause: {ramp_rate: 0 kV/s}", r"pause\.ramp_rate: must be > 0 kV/s, got 0 kV/s"),
    ("pause: {ramp_rate: inf kV/s}", r"pause\.ramp_rate: 'inf kV/s' is not a finite number"),
    ("pause: {ramp_rate: 1 kV}", r"pause\.ramp_rate: '1 kV' is not a voltage rate"),
    ("pause: {ramp_rate: 1000}", r"pause\.ramp_rate: '1000' has no unit; give a voltage rate, e\.g\. '1000 V/s'"),
    ("pause: {stretch_rate: -0.05 /s}", r"pause\.stretch_rate: must be > 0 /s, got -0\.05 /s"),
    ("pause: {stretch_rate: 0.05}", r"pause\.stretch_rate: '0\.05' has no unit; give a stretch rate, "
                                    r"e\.g\. '0\.05 /s'"),
    ("pause: {stretch_rate: 0.05 V}", r"pause\.stretch_rate: '0\.05 V' is not a stretch rate"),
    ("pause: {ramp: 1 kV/s}", r"pause\.ramp: unknown key 'ramp'; allowed keys: ramp_rate, hold_stretch, "
                              r"stretch_rate"),
    ("pause:", r"pause: no value given"),
    ("pause: 1 kV/s", r"pause: expected a mapping with keys ramp_rate, hold_stretch, stretch_rate"),
    ("suspend: interlock == open", r"suspend: expected a list"),
    ("suspend: [interlock == open]", r"suspend\[0\]: expected a mapping with keys name, when, resume, wait"),
    ("suspend: [{when: interlock == open}, {when: temp > 3 K}]",
     r"suspend\[1\]\.when: at column 1 of 'temp > 3 K': unknown channel 'temp'; allowed: interlock, "
     r"amplifier_temperature, force_offset_drift"),
    ("suspend: [{name: a, when: interlock == open}, {name: a, when: interlock == closed}]",
     r"suspend\[1\]\.name: 'a' also names suspend\[0\]"),
])
def test_bad_pause_and_suspend_name_the_file_and_field(text, match):
    with pytest.raises(SpecError, match=rf"^x\.yaml: {match}"):
        protocol_from_yaml(BASE + text + "\n", "x.yaml")


def test_hold_stretch_is_checked_against_the_protocols_own_limit():
    spec = protocol_from_yaml(BASE.replace("max_stretch: 1.6", "max_stretch: 1.8") + "pause: {hold_stretch: 1.7}\n")
    assert spec.pause.hold_stretch == 1.7


def test_suspenders_read_in_order():
    door, hot, drift = protocol_from_yaml(BASE + SUSPEND).suspend
    assert (door.name, door.when.text, door.resume, door.wait) == ("door", "interlock == open", None, 600.0)
    assert (hot.name, hot.resume.text, hot.wait) == ("hot", "amplifier_temperature < 50 degC", 1800.0)
    assert (drift.name, drift.when.magnitude, drift.wait) == (None, True, 45.0)


def test_pause_and_suspenders_round_trip_through_the_dump_and_the_plans_yaml():
    spec = protocol_from_yaml(BASE + "pause: {ramp_rate: 0.5 kV/s, hold_stretch: 1.05}\n" + SUSPEND)
    text = dump_protocol(spec)
    assert "pause: {ramp_rate: 0.5 kV/s, hold_stretch: 1.05, stretch_rate: 0.05 /s}\n" in text
    assert "- {name: hot, when: amplifier_temperature > 60 degC, resume: amplifier_temperature < 50 degC, " \
           "wait: 30 min}\n" in text
    assert protocol_from_yaml(text) == spec
    plan = expand(spec)
    assert plan.yaml == text  # the dataset's protocol attribute holds them
    assert protocol_from_yaml(plan.yaml).suspend == spec.suspend


def test_a_preset_keeps_its_pause_and_suspenders_when_expanded():
    text = (PROTOCOLS / "blocking_force.yaml").read_text() + "pause: {hold_stretch: 1.2}\n" \
        "suspend: [{when: interlock == open}]\n"
    plan = expand(protocol_from_yaml(text))
    assert plan.spec.pause.hold_stretch == 1.2
    assert plan.spec.suspend == (Suspender(when="interlock == open"),)
    assert expand(protocol_from_yaml(plan.yaml)).spec == plan.spec


# the dump of a shipped protocol as it was before pause: and suspend: existed
BLOCKING_FORCE_DUMP = """\
name: blocking_force
kind: blocking
description: blocking force at stretch 1.5, voltage sine 0-2.6 kV at 1 Hz
source: Section 4.2, Fig. 15 of Prechtl et al. 2021, doi:10.1088/1361-665X/ac34be
sample_rate: 1 kHz
measure: [force]
limits:
  max_voltage: 3 kV
  max_stretch: 1.6
  max_force: 50 N
  max_field: 80 V/um
preset: blocking_force
settings:
  stretch: 1.5
  voltage_min: 0 kV
  voltage_max: 2.6 kV
  frequency: 1 Hz
  cycles: 10
  approach: 5 s
  settle: 5 s
"""


def test_a_protocol_without_them_dumps_as_before():
    spec = load_protocol(PROTOCOLS / "blocking_force.yaml")
    assert spec.pause is None and spec.suspend == ()
    assert dump_protocol(spec) == BLOCKING_FORCE_DUMP


@pytest.mark.parametrize("name", ["blocking_force", "tensile_ramp_sine_2.6kV", "custom_example", "selfsense_0V"])
def test_no_pause_or_suspend_key_in_an_old_protocols_dumps(name):
    spec = load_protocol(PROTOCOLS / f"{name}.yaml")
    for text in (dump_protocol(spec), expand(spec).yaml):
        assert "pause" not in text and "suspend" not in text


def test_the_packaged_example_and_its_description():
    plan = expand(load_protocol("pause_example"))
    assert plan.spec.pause == Pause(ramp_rate=1000.0, hold_stretch=1.05, stretch_rate=0.05)
    assert [s.name for s in plan.spec.suspend] == ["door", "hot", "drift"]
    text = plan.describe()
    assert "  pause: voltage to 0 at 1 kV/s, holding stretch 1.05 (reached at 0.05 /s)\n" in text
    assert ("  suspend (hot): pause while amplifier_temperature > 60 degC; resume once amplifier_temperature "
            "< 50 degC; abort if not resumed within 10 min\n") in text
    assert "pause:" not in expand(load_protocol("custom_example")).describe()


@pytest.mark.parametrize("pause, match", [
    ("{ramp_rate: 1 V/s}", r"pause\.ramp_rate: 1 V/s takes max_voltage 3000 V to 0 in 3000 s; allowed: a ramp of "
                           r"at most 600 s \(at least 5 V/s\)"),
    ("{hold_stretch: 1.05, stretch_rate: 1e-4 /s}", r"pause\.stretch_rate: .* in 5500 s; allowed: a ramp of at most "
                                                    r"600 s"),
])
def test_a_pause_ramp_longer_than_ten_minutes_is_refused_where_the_protocol_is_read(pause, match):
    # BASE's limits: max_voltage 3 kV (the default), max_stretch 1.6. 3 kV at 1 V/s: 3000 s; the stretch from
    # 1.6 to 1.05 at 1e-4 /s: 5500 s
    with pytest.raises(SpecError, match=rf"^x\.yaml: {match}"):
        protocol_from_yaml(BASE + f"pause: {pause}\n", "x.yaml")
