"""Suspender conditions (rdea_lab.specs.suspenders): read by a tokenizer, refused with the column and what is
allowed; their suspenders, and a campaign's merged with a protocol's."""

import math

import pytest

from rdea_lab.specs import SpecError
from rdea_lab.specs.campaign import CampaignSpec
from rdea_lab.specs.suspenders import (DEFAULT_WAIT, Condition, Suspender, merged_suspenders,
                                       parse_condition)
from rdea_lab.specs.protocol import load_protocol, protocol_from_yaml


@pytest.mark.parametrize("text, channel, op, value, magnitude", [
    ("interlock == open", "interlock", "==", "open", False),
    ("interlock != closed", "interlock", "!=", "closed", False),
    ("amplifier_temperature > 60 degC", "amplifier_temperature", ">", 333.15, False),
    ("amplifier_temperature>=333 K", "amplifier_temperature", ">=", 333.0, False),
    ("amplifier_temperature <= 60 °C", "amplifier_temperature", "<=", 333.15, False),
    ("force_offset_drift < -5 mN", "force_offset_drift", "<", -0.005, False),
    ("|force_offset_drift| > 5 mN", "force_offset_drift", ">", 0.005, True),
    ("| force_offset_drift |>=0.5e-2 N", "force_offset_drift", ">=", 0.005, True),
])
def test_conditions_read(text, channel, op, value, magnitude):
    c = parse_condition(text)
    assert (c.channel, c.op, c.magnitude) == (channel, op, magnitude)
    # 60 degC is 333.15 K up to the float rounding of 60 + 273.15
    assert c.value == (value if isinstance(value, str) else pytest.approx(value, rel=1e-15))
    assert c.text == " ".join(text.split()) and str(c) == c.text


@pytest.mark.parametrize("text, match", [
    ("temp > 60 degC", r"at column 1 of 'temp > 60 degC': unknown channel 'temp'; allowed: interlock, "
                       r"amplifier_temperature, force_offset_drift"),
    ("interlock > open", r"at column 11 .*got '>'; interlock is open or closed, compared with == or !="),
    ("interlock == ajar", r"at column 14 .*interlock is open or closed, not 'ajar'"),
    ("amplifier_temperature => 60 degC", r"at column 23 .*got '='; allowed: >=, <=, ==, !=, >, <"),
    ("amplifier_temperature = 60 degC", r"at column 23 .*allowed: >=, <=, ==, !=, >, <"),
    ("amplifier_temperature > 60", r"at column 27 .*60 has no unit; give e\.g\. '60 degC'"),
    ("amplifier_temperature > 60 C", r"at column 25 .*'60 C' is not a temperature"),
    ("amplifier_temperature > 60 parsecs", r"at column 25 .*is not a temperature"),
    ("amplifier_temperature > -300 degC", r"at column 25 .*below absolute zero"),
    ("force_offset_drift > 5 kPa", r"at column 22 .*'5 kPa' is not a force"),
    ("amplifier_temperature > x", r"at column 25 .*expected a number with a unit, e\.g\. '60 degC', got 'x'"),
    ("amplifier_temperature > 60 degC and interlock == open", r"at column 33 .*'and' is not supported"),
    ("|interlock| == open", r"at column 2 .*it has no magnitude"),
    ("|force_offset_drift > 5 mN", r"at column 21 .*expected '\|' closing"),
    ("interlock == open closed", r"at column 19 .*unexpected 'closed'"),
    ("interlock", r"at column 10 .*got the end of the condition"),
    ("", r"at column 1 .*expected a channel"),
    ("__import__('os') == open", r"at column 1 .*unknown channel '__import__'"),
    ("x" * 201, r"a condition of 201 characters; allowed: .* at most 200"),
])
def test_bad_conditions_name_field_column_and_what_is_allowed(text, match):
    with pytest.raises(SpecError, match=rf"^f\.yaml: suspend\[1\]\.when: {match}"):
        parse_condition(text, "f.yaml", "suspend[1].when")


def test_a_condition_from_python_writes_its_text():
    assert Condition(channel="amplifier_temperature", op=">", value=333.15).text == "amplifier_temperature > 60 degC"
    assert Condition(channel="force_offset_drift", op=">", value=0.005, magnitude=True).text == \
        "|force_offset_drift| > 5 mN"
    c = Condition(channel="interlock", op="==", value="open")
    assert c == parse_condition("interlock == open")
    with pytest.raises(SpecError, match=r"^<python>: text: 'interlock == closed' does not say interlock == open"):
        Condition(channel="interlock", op="==", value="open", text="interlock == closed")
    with pytest.raises(SpecError, match=r"^<python>: op: '<' does not compare interlock; allowed: ==, !="):
        Condition(channel="interlock", op="<", value="open")
    with pytest.raises(SpecError, match=r"^<python>: channel: unknown channel 'door'"):
        Condition(channel="door", op="==", value="open")
    with pytest.raises(SpecError, match=r"^<python>: value: nan is not a finite number"):
        Condition(channel="force_offset_drift", op=">", value=math.nan)


def test_holds_compares_si_readings_and_is_none_when_it_cannot_tell():
    hot = parse_condition("amplifier_temperature > 60 degC")
    assert hot.holds({"amplifier_temperature": 333.2}) is True
    assert hot.holds({"amplifier_temperature": 333.15}) is False  # not above: strictly greater
    assert hot.holds({"amplifier_temperature": 60.0}) is False  # a reading is kelvin, never degC
    assert hot.holds({}) is None
    assert hot.holds({"amplifier_temperature": None}) is None
    assert hot.holds({"amplifier_temperature": math.nan}) is None
    door = parse_condition("interlock == open")
    assert door.holds({"interlock": "open"}) is True and door.holds({"interlock": "closed"}) is False
    assert door.holds({"force_offset_drift": 0.0}) is None
    with pytest.raises(ValueError, match="interlock reading 'ajar' is not one of open, closed"):
        door.holds({"interlock": "ajar"})
    with pytest.raises(ValueError, match="amplifier_temperature reading 'hot' is not a number"):
        hot.holds({"amplifier_temperature": "hot"})


def test_magnitude_or_signed_drift():
    signed, either = parse_condition("force_offset_drift > 5 mN"), parse_condition("|force_offset_drift| > 5 mN")
    assert (signed.holds({"force_offset_drift": -0.006}), either.holds({"force_offset_drift": -0.006})) == \
        (False, True)
    assert (signed.holds({"force_offset_drift": 0.006}), either.holds({"force_offset_drift": 0.006})) == (True, True)
    assert either.holds({"force_offset_drift": 0.004}) is False


def test_a_suspender_and_its_defaults():
    s = Suspender.from_yaml_mapping({"name": "door", "when": "interlock == open"}, "f.yaml")
    assert (s.name, s.resume, s.wait) == ("door", None, DEFAULT_WAIT) and DEFAULT_WAIT == 600.0
    assert s.resume_text == "interlock == open no longer holds" and s.label == "suspender 'door'"
    hot = Suspender.from_yaml_mapping({"when": "amplifier_temperature > 60 degC",
                                       "resume": "amplifier_temperature < 50 degC", "wait": "24 h"}, "f.yaml")
    assert hot.wait == 86400.0 and hot.resume.value == pytest.approx(323.15, rel=1e-15)
    assert hot.label == "suspender 'amplifier_temperature > 60 degC'"
    assert Suspender(when="interlock == open", wait=30).wait == 30.0  # from Python a number is seconds


@pytest.mark.parametrize("item, match", [
    ({"when": "interlock == open", "wait": "25 h"}, r"wait: 25 h is not a wait; allowed: 0 s < wait <= 24 h"),
    ({"when": "interlock == open", "wait": "0 s"}, r"wait: 0 s is not a wait; allowed: 0 s < wait <= 24 h"),
    ({"when": "interlock == open", "wait": 600}, r"wait: '600' has no unit"),
    ({"when": "interlock == open", "wait": "10 V"}, r"wait: '10 V' is not a time"),
    ({"resume": "interlock == closed"}, r"when: missing required key 'when'"),
    ({"when": 5}, r"when: expected a condition such as 'interlock == open'"),
    ({"when": {"channel": "interlock", "op": "==", "value": "open"}}, r"when: expected a condition such as"),
    ({"when": "interlock == open", "resume": "temp < 3 K"}, r"resume: at column 1 .*unknown channel 'temp'"),
    ({"when": "interlock == open", "name": "a b"}, r"name: 'a b' is not a valid name"),
    ({"when": "interlock == open", "after": "1 s"}, r"after: unknown key 'after'; allowed keys: name, when, "
                                                    r"resume, wait"),
])
def test_bad_suspenders(item, match):
    with pytest.raises(SpecError, match=rf"^f\.yaml: {match}"):
        Suspender.from_yaml_mapping(item, "f.yaml")


PROTOCOL = """\
name: p
kind: custom
sample_rate: 10 Hz
stretch: [{kind: hold, duration: 1 s}]
voltage: [{kind: hold, duration: 1 s}]
"""


def _campaign(suspend, origin="c.yaml"):
    spec = CampaignSpec(name="c", out="o", specimens=("s.yaml",), protocols=("p.yaml",), suspend=suspend)
    spec._origin = origin
    return spec


def test_merged_suspenders_the_protocols_then_the_campaigns():
    protocol = protocol_from_yaml(PROTOCOL + "suspend: [{name: door, when: interlock == open}]\n")
    hot = Suspender(name="hot", when="amplifier_temperature > 60 degC")
    door = Suspender(name="door", when="interlock == open")
    assert merged_suspenders(protocol, _campaign((hot,))) == (door, hot)
    assert merged_suspenders(protocol, _campaign((door, hot))) == (door, hot)  # an equal one given once
    assert merged_suspenders(protocol, None) == (door,)
    assert merged_suspenders(protocol_from_yaml(PROTOCOL), _campaign((hot,))) == (hot,)
    other = Suspender(name="door", when="interlock == closed")
    with pytest.raises(SpecError, match=r"^c\.yaml: suspend\[0\]\.name: 'door' also names a different suspender "
                                        r"of protocol 'p' \(when interlock == open\); give the campaign's another"):
        merged_suspenders(protocol, _campaign((other,)))


def test_a_campaign_file_declares_suspenders(tmp_path):
    (tmp_path / "specimens").mkdir()
    from rdea_lab.paths import resolve
    card = resolve("specimens/specimen2.yaml", "specimens")
    (tmp_path / "specimens" / "s.yaml").write_text(card.read_text())
    (tmp_path / "p.yaml").write_text(PROTOCOL)
    campaign = tmp_path / "c.yaml"
    campaign.write_text("name: c\nroot: .\nout: o\nspecimens: [specimens/s.yaml]\nprotocols: [p.yaml]\n"
                        "suspend:\n  - {name: hot, when: amplifier_temperature > 60 degC, wait: 1 h}\n")
    spec = CampaignSpec.load(campaign)
    assert spec.suspend == (Suspender(name="hot", when="amplifier_temperature > 60 degC", wait=3600.0),)
    campaign.write_text(campaign.read_text() + "  - {name: hot, when: interlock == open}\n")
    with pytest.raises(SpecError, match=rf"^{campaign}: suspend\[1\]\.name: 'hot' also names suspend\[0\]"):
        CampaignSpec.load(campaign)
    campaign.write_text(campaign.read_text().replace("interlock == open", "interlock is open"))
    with pytest.raises(SpecError, match=rf"^{campaign}: suspend\[1\]\.when: at column 11 .*got 'is'"):
        CampaignSpec.load(campaign)


def test_a_protocol_with_a_campaigns_suspenders_dumps_them_all():
    protocol = protocol_from_yaml(PROTOCOL + "suspend: [{name: door, when: interlock == open}]\n", "p.yaml")
    hot = Suspender(name="hot", when="amplifier_temperature > 60 degC")
    merged = protocol.with_suspenders(merged_suspenders(protocol, _campaign((hot,))))
    assert merged.origin == "p.yaml" and [s.name for s in merged.suspend] == ["door", "hot"]
    assert protocol_from_yaml(merged.dump()) == merged
    assert merged.with_suspenders(()) == protocol_from_yaml(PROTOCOL)
    with pytest.raises(SpecError, match=r"^p\.yaml: suspend\[1\]\.name: 'door' also names suspend\[0\]"):
        protocol.with_suspenders(protocol.suspend * 2)
    preset = load_protocol("blocking_force")
    assert preset.with_suspenders((hot,)).settings == preset.settings
