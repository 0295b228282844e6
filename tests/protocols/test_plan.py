"""Plans: shipped protocols, limit checks, summaries, blocks."""

import json
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.protocols import Plan, check_plan, expand, first_violation, load_plan
from rdea_lab.specs import SpecError, dump_protocol, load_protocol, protocol_from_yaml

from .conftest import make_plan

PROTOCOLS = Path(__file__).resolve().parents[2] / "rdea_lab" / "data" / "protocols"
SHIPPED = sorted(PROTOCOLS.glob("*.yaml"))
#: the day-long fatigue protocol (86 400 001 samples): checked whole in seconds, so with the slow tests
LONG = {"fatigue_24h.yaml"}
L3 = 48e-6  # [m] membrane thickness of the paper's specimens (Table 1)


def test_the_shipped_protocols_are_there():
    names = {p.name for p in SHIPPED}
    assert {"tensile_ramp_sine_0V.yaml", "tensile_ramp_sine_2.6kV.yaml", "blocking_force.yaml",
            "capacitance_sweep.yaml", "custom_example.yaml"} <= names


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.name in LONG else p for p in SHIPPED],
                         ids=[p.name for p in SHIPPED])
def test_shipped_protocol_loads_expands_checks_and_round_trips(path):
    spec = load_protocol(path)
    assert spec.source and spec.description
    assert path.read_text(encoding="utf-8").startswith("#")  # a comment on where the settings come from
    plan = load_plan(path)
    assert isinstance(plan, Plan) and plan.source == str(path)
    assert check_plan(plan, L3=L3) == []
    first_violation(plan, L3=L3)  # does not raise
    assert protocol_from_yaml(dump_protocol(spec)) == spec
    # the plan's YAML is the expanded protocol; it gives the same setpoints
    again = expand(protocol_from_yaml(plan.yaml))
    assert again.spec == plan.spec
    for (_, mine), (_, theirs) in zip(plan.windows(), again.windows()):  # a long plan is never held whole
        np.testing.assert_array_equal(theirs.stretch, mine.stretch)
        np.testing.assert_array_equal(theirs.voltage, mine.voltage)


@pytest.mark.parametrize("name, rate, duration", [
    ("tensile_ramp_sine_0V", 100, 54), ("tensile_ramp_sine_2.6kV", 100, 54), ("capacitance_sweep", 100, 54),
    ("blocking_force", 1000, 25),
])
def test_paper_protocols(name, rate, duration):
    plan = load_plan(PROTOCOLS / f"{name}.yaml")
    assert (plan.sample_rate, plan.duration, plan.samples) == (rate, duration, duration * rate + 1)
    lim = plan.limits
    assert (lim.max_voltage, lim.max_stretch, lim.max_force, lim.max_field) == (3e3, 1.6, 50.0, 80e6)
    assert plan.stretch.max() == pytest.approx(1.5, abs=6e-4)  # see test_presets for the overshoot
    assert plan.voltage.max() == pytest.approx(0.0 if name.endswith(("0V", "sweep")) else 2600.0, rel=1e-15)
    assert ("capacitance" in plan.measure) == (name == "capacitance_sweep")


# ------------------------------------------------------------- check_plan
def _hold(seconds, value=None):
    seg = {"kind": "hold", "duration": f"{seconds} s"}
    return seg if value is None else {**seg, "value": value}


def test_voltage_above_limit_names_segment_time_and_limit():
    plan = make_plan(
        [_hold(20, 1.2)],
        [{"kind": "ramp", "duration": "10 s", "to": "2 kV"}, _hold(2.5),
         {"kind": "step", "duration": "7.5 s", "value": "3.2 kV"}],
        limits={"max_voltage": "3 kV"},
    )
    problems = check_plan(plan)
    assert len(problems) == 1
    with pytest.raises(SpecError, match=r"^<test>: voltage\[2\]: voltage 3\.2 kV at t = 12\.5 s is above the "
                                        r"limit max_voltage = 3 kV"):
        first_violation(plan)


def test_negative_voltage_beyond_limit():
    plan = make_plan([_hold(2)], [{"kind": "ramp", "duration": "2 s", "to": "-3.5 kV"}])
    with pytest.raises(SpecError, match=r"voltage\[0\]: voltage -3\.5 kV at t = 2 s is beyond \(in magnitude\) "
                                        r"the limit max_voltage = 3 kV"):
        first_violation(plan)


def test_stretch_above_max_stretch():
    plan = make_plan([{"kind": "ramp", "duration": "4 s", "to": 1.8}], [_hold(4)], limits={"max_stretch": 1.6})
    with pytest.raises(SpecError, match=r"stretch\[0\]: stretch 1\.8 at t = 4 s is above the limit "
                                        r"max_stretch = 1\.6 \(exceeded from t = 3\.01 s to 4 s\)"):
        first_violation(plan)


def test_stretch_below_one_from_a_sine():
    plan = make_plan(
        [_hold(1, 1.05), {"kind": "sine", "duration": "4 s", "mean": 1.05, "amplitude": 0.1, "frequency": "0.5 Hz"}],
        [_hold(5)],
    )
    with pytest.raises(SpecError, match=r"stretch\[1\]: stretch 0\.95 at t = 2\.5 s is below 1; the roll must "
                                        r"stay in tension"):
        first_violation(plan)


def test_field_above_limit_only_with_L3():
    plan = make_plan([_hold(2, 1.44)], [_hold(2, "2.5 kV")], limits={"max_field": "60 V/um"})
    assert check_plan(plan) == []
    # E = 2.5 kV * sqrt(1.44) / 48 um = 62.5 V/um
    with pytest.raises(SpecError, match=r"voltage\[0\]: field estimate .* = 62\.5 V/um \(voltage 2\.5 kV, "
                                        r"stretch 1\.44, L3 = 48 um\) at t = 0 s is above the limit "
                                        r"max_field = 60 V/um"):
        first_violation(plan, L3=L3)


def test_every_violation_is_listed_in_time_order():
    plan = make_plan(
        [{"kind": "ramp", "duration": "2 s", "to": 1.7}, _hold(2, 1.0),
         {"kind": "sine", "duration": "2 s", "mean": 1.0, "amplitude": 0.1, "frequency": "1 Hz"}],
        [_hold(3), {"kind": "step", "duration": "3 s", "value": "4 kV"}],
        limits={"max_stretch": 1.5},
    )
    problems = check_plan(plan, L3=L3)
    assert [p.field for p in problems] == ["stretch[0]", "voltage[1]", "voltage[1]", "stretch[2]"]
    assert ["above the limit max_stretch" in problems[0].message, "max_voltage" in problems[1].message,
            "max_field" in problems[2].message, "below 1" in problems[3].message] == [True] * 4
    assert all(p.source == "<test>" and "\n" not in str(p) for p in problems)


def test_a_limit_met_exactly_is_not_a_violation():
    plan = make_plan(
        [{"kind": "ramp", "duration": "3 s", "to": 1.6},
         {"kind": "sine", "duration": "3 s", "mean": 1.3, "amplitude": 0.3, "frequency": "1 Hz", "phase": "90 deg"}],
        [{"kind": "ramp", "duration": "6 s", "to": "3 kV"}],
        limits={"max_stretch": 1.6},
    )
    assert check_plan(plan) == []


def test_bad_L3_is_a_programming_error():
    plan = make_plan([_hold(1)], [_hold(1)])
    with pytest.raises(ValueError, match="L3 must be a finite thickness > 0 m"):
        check_plan(plan, L3=0.0)


# --------------------------------------------------------- summary, blocks
def test_summary_and_describe():
    plan = load_plan(PROTOCOLS / "blocking_force.yaml")
    s = plan.summary()
    json.dumps(s)
    assert s == {
        "name": "blocking_force", "kind": "blocking", "duration_s": 25.0, "samples": 25001,
        "sample_rate_hz": 1000.0, "stretch_min": 1.0, "stretch_max": 1.5, "voltage_min_V": 0.0,
        "voltage_max_V": pytest.approx(2600.0, rel=1e-15), "measure": ["force"],
        "segments": {"stretch": 3, "voltage": 3},
    }
    text = plan.describe()
    assert text.splitlines()[0] == f"blocking_force (blocking) from {PROTOCOLS / 'blocking_force.yaml'}"
    for piece in ("25 s, 25001 samples at 1 kHz", "voltage[1] 10 s .. 20 s: sine 1.3 kV +- 1.3 kV at 1 Hz, "
                  "phase -90 deg", "stretch[2] 20 s .. 25 s: ramp 1.5 (previous) -> 1"):
        assert piece in text, piece


@pytest.mark.parametrize("seconds", [1.0, 0.5, 0.333, 7.0, 100.0, 0.01])
def test_block_slices_cover_every_sample_once(seconds):
    plan = load_plan(PROTOCOLS / "tensile_ramp_sine_0V.yaml")
    blocks = plan.block_slices(seconds)
    covered = np.concatenate([np.arange(plan.samples)[b] for b in blocks])
    np.testing.assert_array_equal(covered, np.arange(plan.samples))
    assert all(0 < b.stop - b.start <= seconds * plan.sample_rate + 1e-9 for b in blocks)


def test_block_slices_need_one_sample():
    plan = make_plan([_hold(1)], [_hold(1)])
    assert len(plan.block_slices()) == 2  # 101 samples: 100 + 1
    with pytest.raises(ValueError, match="hold no sample"):
        plan.block_slices(0.001)
