"""The self-sensing probe of a protocol (rdea_lab.specs.protocol.Probe, rdea_lab.protocols.plan)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.protocols import check_plan, expand, load_plan
from rdea_lab.specs import SpecError, dump_protocol, protocol_from_mapping, protocol_from_yaml

ROOT = Path(__file__).resolve().parents[2]


def spec(probe=None, rate="1 kHz", measure=("force", "current"), max_voltage="3 kV", volts="2 kV"):
    mapping = {"name": "p", "kind": "custom", "sample_rate": rate, "measure": list(measure),
               "limits": {"max_voltage": max_voltage},
               "stretch": [{"kind": "hold", "duration": "1 s", "value": 1.0}],
               "voltage": [{"kind": "hold", "duration": "1 s", "value": volts}]}
    if probe is not None:
        mapping["probe"] = probe
    return protocol_from_mapping(mapping, "<test>")


def test_the_probe_adds_a_sine_to_the_whole_voltage_channel():
    plan = expand(spec({"amplitude": "20 V", "frequency": "50 Hz"}))
    t = plan.time
    # a hold at 2 kV plus 20 sin(2 pi 50 t), to rounding of the sum
    np.testing.assert_allclose(plan.voltage, 2000.0 + 20.0 * np.sin(2.0 * np.pi * 50.0 * t), rtol=0, atol=1e-12)
    assert "probe: 20 V sine at 50 Hz" in plan.describe()
    assert not check_plan(plan)


def test_the_probe_round_trips_through_yaml():
    s = spec({"amplitude": "20 V", "frequency": "200 Hz"})
    assert "probe: {amplitude: 20 V, frequency: 200 Hz}" in dump_protocol(s)
    assert protocol_from_yaml(dump_protocol(s)) == s
    assert "probe" not in dump_protocol(spec())  # a protocol without a probe reads as before


@pytest.mark.parametrize("probe, field, allowed", [
    ({"amplitude": "20 V", "frequency": "500 Hz"}, "probe.frequency",
     r"500 Hz is not below the Nyquist frequency 500 Hz of the sample rate 1 kHz; allowed: 0 < frequency < "),
    ({"amplitude": "20 V", "frequency": "0.8 kHz"}, "probe.frequency", "not below the Nyquist frequency"),
    ({"amplitude": "20 V", "frequency": "0 Hz"}, "probe.frequency", "must be > 0 Hz"),
    ({"amplitude": "0 V", "frequency": "100 Hz"}, "probe.amplitude", "must be > 0 V"),
    ({"amplitude": "250 V", "frequency": "100 Hz"}, "probe.amplitude",
     "250 V is above 200 V: a probe is a small signal on the high voltage"),
    ({"amplitude": "20", "frequency": "100 Hz"}, "probe.amplitude", "has no unit"),
    ({"amplitude": "20 V", "frequency": "100 Hz", "phase": "0 deg"}, "probe.phase", "unknown key 'phase'"),
    ({"amplitude": "20 V"}, "probe.frequency", ""),
])
def test_bad_probes_are_refused_naming_the_field(probe, field, allowed):
    with pytest.raises(SpecError, match=rf"^<test>: {field}: .*{allowed}") as info:
        spec(probe)
    assert "\n" not in str(info.value)


def test_a_probe_needs_the_current_measured():
    with pytest.raises(SpecError, match=r"^<test>: measure: a probe is for self-sensing .* add current"):
        spec({"amplitude": "20 V", "frequency": "100 Hz"}, measure=("force",))


def test_the_voltage_limit_holds_with_the_probe_on():
    # 2 kV + 20 V peaks at 2.02 kV: within 2.01 kV without the probe, beyond it with
    assert not check_plan(expand(spec(max_voltage="2.01 kV")))
    problems = check_plan(expand(spec({"amplitude": "20 V", "frequency": "50 Hz"}, max_voltage="2.01 kV")))
    assert problems and problems[0].field == "voltage[0]"
    assert "with the probe's 20 V at 50 Hz on top" in problems[0].message


def test_the_shipped_selfsense_protocol():
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "selfsense_2.6kV.yaml")
    assert plan.spec.probe.frequency < plan.sample_rate / 2 and "current" in plan.measure
    assert plan.voltage.max() <= plan.limits.max_voltage and not check_plan(plan, 48e-6)


def test_cli_refuses_a_bad_probe_with_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text((ROOT / "rdea_lab" / "data" / "protocols" / "selfsense_2.6kV.yaml").read_text()
                   .replace("200 Hz}", "1.5 kHz}"))
    out = subprocess.run([sys.executable, "-m", "rdea_lab.cli.main", "protocol", "show", str(bad)],
                         capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    assert out.stderr.startswith(f"rdea-lab: {bad}: probe.frequency: 1.5 kHz is not below the Nyquist frequency "
                                 "1 kHz of the sample rate 2 kHz")
