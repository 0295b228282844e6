"""Voltage plans from a target: the plan drives the twin to its target, through the protocol file a rig runs."""

from pathlib import Path

import numpy as np
import pytest

import rdea_lab
from rdea_lab.protocols import load_plan
from rdea_lab.protocols.target import plan_target, write_protocol
from rdea_lab.reports.tracking import tracking_error
from rdea_lab.specs import SpecError
from rdea_lab.specs.target import load_target, target_from_mapping

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"


def short(**changes):
    m = {"name": "short", "target": "stretch", "sample_rate": "200 Hz", "approach": "2 s", "settle": "1 s",
         "bias": {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"},
         "samples": {"units": {"time": "s", "stretch": "1"}, "time": [0, 1, 2, 3],
                     "stretch": [1.054, 1.062, 1.062, 1.054]}}
    m.update(changes)
    return target_from_mapping(m, "short.yaml")


@pytest.mark.parametrize("path, options", [("targets/spring_stroke.yaml", {}),
                                           ("targets/blocking_ramp.csv", {"stretch": "1.5"})])
def test_examples_plan_within_1e6_on_the_twin(path, options):
    tp = plan_target(load_target(ROOT / "rdea_lab" / "data" / path, **options), CARD, PARAMS)
    assert tp.twin_error < 1e-6  # SU: closed form, so rounding only (about 1e-15)
    s = tp.summary()
    assert 0.0 < s["voltage_min_V"] <= s["voltage_max_V"] <= 3000.0


def test_the_written_protocol_drives_the_twin_backend_to_the_target(tmp_path):
    """End to end: the protocol file (YAML, values written exactly) run by the twin backend, as `rdea-lab run`
    would, gives the bias force at the target stretch within 1e-6."""
    tp = plan_target(short(), CARD, PARAMS)
    path = write_protocol(tp, tmp_path / "p.yaml")
    np.testing.assert_array_equal(load_plan(path).voltage, tp.plan.voltage)
    ds = rdea_lab.run_protocol(path, CARD, rdea_lab.Twin(PARAMS, "su"), out=tmp_path / "r.nc")
    tr = tracking_error(ds, tp)
    assert tr["relative_max"] < 1e-6 and tr["stretch_error_max"] < 1e-9
    with pytest.raises(SpecError, match=r"p\.yaml: exists; give another --out or --force"):
        write_protocol(tp, path)


@pytest.mark.parametrize("model", ["1r", "3r"])
def test_other_models_plan_within_1e6(model):
    tp = plan_target(short(sample_rate="50 Hz"), CARD, PARAMS, model)
    assert tp.twin_error < 1e-6


def test_a_stretch_out_of_reach_names_the_sample_and_the_range():
    # 1.04 is below where the roll, at 0 V, already balances the spring (about 1.050): out of reach
    with pytest.raises(SpecError, match=r"short\.yaml: samples\.stretch: at t = 0 s: stretch 1\.04 is out of "
                                        r"reach against the spring bias, which pulls 0\.728 N there: the twin "
                                        r"\(su\) gives [0-9.]+ N at 3 kV \(the voltage/field limit\) to "
                                        r"0\.5296[0-9]* N at 0 V"):
        plan_target(short(samples={"units": {"time": "s", "stretch": "1"}, "time": [0, 1],
                                   "stretch": [1.04, 1.054]}), CARD, PARAMS)


def test_a_force_out_of_reach_names_the_sample_and_the_range(tmp_path):
    (tmp_path / "f.csv").write_text("time [s],force [N]\n0,4.1\n1,3.5\n")
    # 4.1 -> 3.5 N over 1 s crosses 3.909 N (SU at 3 kV, stretch 1.5) between 0.3 and 0.4 s: the first sample
    # on the 10 Hz grid out of reach is 0.4 s
    with pytest.raises(SpecError, match=r"f\.csv: force: at t = 0\.4 s: 3\.86 N is out of reach at stretch 1\.5: "
                                        r"the twin \(su\) gives 3\.909[0-9]* N at 3 kV .* to 4\.20[0-9]* N at 0 V"):
        plan_target(load_target(tmp_path / "f.csv", stretch="1.5", sample_rate="10 Hz", approach="1 s",
                                settle="1 s"), CARD, PARAMS)


def test_a_lower_voltage_limit_shrinks_the_reach():
    with pytest.raises(SpecError, match=r"at 1 kV \(the voltage/field limit\)"):
        plan_target(short(limits={"max_voltage": "1 kV"}), CARD, PARAMS)


def test_a_bias_that_would_push_is_refused():
    # the spring is slack beyond stretch 1 + 1 N / (200 N/m * 34 mm) = 1.14706: on the ramp 1.054 -> 1.2 over
    # 1 s at 200 Hz the first sample past it is at 0.64 s
    with pytest.raises(SpecError, match=r"short\.yaml: bias: at t = 0\.64 s \(stretch 1\.147[0-9]*\) the spring "
                                        r"would pull -0\.00[0-9]+ N; a roll only takes tension"):
        plan_target(short(samples={"units": {"time": "s", "stretch": "1"}, "time": [0, 1],
                                   "stretch": [1.054, 1.2]}), CARD, PARAMS)


def test_a_run_of_another_plan_is_refused(tmp_path):
    tp = plan_target(short(), CARD, PARAMS)
    other = plan_target(short(bias={"kind": "spring", "stiffness": "210 N/m", "preload": "1 N"}), CARD, PARAMS)
    ds = rdea_lab.run_protocol(other.plan, CARD, rdea_lab.Twin(PARAMS, "su"), out=tmp_path / "r.nc")
    with pytest.raises(SpecError, match=r"r\.nc: voltage_setpoint: differs from the plan short-plan by up to"):
        tracking_error(ds, tp)


def test_against_a_mass():
    """A dead load: the twin's force equals m g along the whole target stretch history."""
    tp = plan_target(short(bias={"kind": "mass", "mass": "70 g"}), CARD, PARAMS)
    w = tp.window
    assert tp.twin_error < 1e-6 and tp.bias_slope == 0.0
    np.testing.assert_allclose(tp.twin_force[w], 0.070 * 9.80665, rtol=1e-12)
