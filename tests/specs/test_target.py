"""Target files: every input refused cleanly when out of range, naming the file, the field and what is allowed."""

import copy

import numpy as np
import pytest
import yaml

from rdea_lab.specs import SpecError
from rdea_lab.specs.target import G, load_target, target_from_mapping

BASE = yaml.safe_load("""
name: spring_stroke
target: stretch
sample_rate: 500 Hz
bias: {kind: spring, stiffness: 200 N/m, preload: 1 N}
samples: {units: {time: s, stretch: "1"}, time: [0, 1, 2], stretch: [1.054, 1.062, 1.054]}
""")


def with_(**changes):
    m = copy.deepcopy(BASE)
    for k, v in changes.items():
        if v is None:
            m.pop(k, None)
        else:
            m[k] = v
    return m


def samples(time, values, units=None, col="stretch"):
    return {"units": units or {"time": "s", col: "1" if col == "stretch" else "N"}, "time": time, col: values}


def test_a_good_target():
    t = target_from_mapping(BASE, "x.yaml")
    assert t.settings.bias.stiffness == 200.0 and t.settings.bias.preload == 1.0
    np.testing.assert_array_equal(t.values, [1.054, 1.062, 1.054])
    # the spring relaxes as the roll lengthens: 1 N - 200 N/m * 0.1 * 34 mm at stretch 1.1
    assert t.settings.bias.force(1.1, 0.034) == pytest.approx(1.0 - 200.0 * 0.1 * 0.034, rel=1e-12)
    mass = target_from_mapping(with_(bias={"kind": "mass", "mass": "70 g"}), "x.yaml").settings.bias
    assert mass.force(np.array([1.05]), 0.034)[0] == pytest.approx(0.070 * G, rel=1e-15)


@pytest.mark.parametrize("changes, match", [
    (dict(bias={"kind": "spring", "stiffness": "-200 N/m", "preload": "1 N"}), r"bias\.stiffness: must be > 0 N/m"),
    (dict(bias={"kind": "spring", "stiffness": "0 N/m", "preload": "1 N"}), r"bias\.stiffness: must be > 0 N/m"),
    (dict(bias={"kind": "spring", "stiffness": "200 N", "preload": "1 N"}), r"bias\.stiffness: .* not a stiffness"),
    (dict(bias={"kind": "spring", "preload": "1 N"}), r"bias\.stiffness: missing"),
    (dict(bias={"kind": "spring", "stiffness": "200 N/m", "preload": "-1 N"}), r"bias\.preload: must be >= 0 N"),
    (dict(bias={"kind": "rubber"}), r"bias\.kind: 'rubber'; allowed: none, mass, spring"),
    (dict(bias={"kind": "mass", "mass": "0 g"}), r"bias\.mass: must be > 0 g"),
    (dict(bias={"kind": "mass", "mass": "70"}), r"bias\.mass: .* has no unit"),
    (dict(bias={"kind": "none"}), r"bias: none .* a stretch target moves against a bias"),
    (dict(bias="spring"), r"bias: expected a mapping"),
    (dict(target="torque"), r"target: 'torque'; allowed: force .*, stretch"),
    (dict(stretch=1.5), r"stretch: a stretch target gives its stretch as samples"),
    (dict(sample_rate="0 Hz"), r"sample_rate: must be > 0 Hz"),
    (dict(approach="1.001 s"), r"approach: 1.001 s is not a whole number of sample periods at 500 Hz"),
    (dict(samples=samples([0, 1, 1], [1.05, 1.06, 1.07])), r"samples\.time\[2\]: 1 s does not come after 1 s"),
    (dict(samples=samples([0, 1, 2], [1.05, 0.9, 1.07])), r"samples\.stretch\[1\]: 0.9; allowed: 1 to 2"),
    (dict(samples=samples([0, 1, 2], [1.05, 2.5, 1.07])), r"samples\.stretch\[1\]: 2.5; allowed: 1 to 2"),
    (dict(samples=samples([0, 1, float("nan")], [1.05, 1.06, 1.07])), r"samples\.time\[2\]: nan is not a finite"),
    (dict(samples=samples([0, 1, 2], [1.05, float("inf"), 1.07])), r"samples\.stretch\[1\]: inf is not a finite"),
    (dict(samples=samples([0, 1, 2], [1.05, 1.06])), r"samples\.stretch: 2 values for 3 times"),
    (dict(samples=samples([0], [1.05])), r"samples\.stretch: 1 samples; give at least 2"),
    (dict(samples=samples([0, 1], [1.05, 1.06], {"time": "s"})), r"samples\.units: give the unit of each column"),
    (dict(samples=samples([0, 1], [1.05, 1.06], {"time": "N", "stretch": "1"})),
     r"samples\.units\.time: .* not a time"),
    (dict(samples=samples([0, "1 s"], [1.05, 1.06])), r"samples\.time\[1\]: .* not a plain number"),
    (dict(samples=None), r"samples: missing"),
    (dict(samples=[1, 2]), r"samples: expected a CSV file name or a mapping"),
])
def test_bad_stretch_targets(changes, match):
    with pytest.raises(SpecError, match=match) as info:
        target_from_mapping(with_(**changes), "x.yaml")
    assert str(info.value).startswith("x.yaml: ") and "\n" not in str(info.value)


FORCE = dict(target="force", stretch=1.5, bias=None, samples=samples([0, 1], [4.1, 4.0], col="force"))


@pytest.mark.parametrize("changes, match", [
    (dict(stretch=None), r"stretch: missing; a force target is at a fixed stretch"),
    (dict(stretch=0.9), r"stretch: stretch 0.9 is below 1"),
    (dict(stretch=1.7, limits={"max_stretch": 1.6}), r"stretch: 1.7 is above limits.max_stretch 1.6"),
    (dict(bias={"kind": "mass", "mass": "70 g"}), r"bias: mass: a force target is a blocking test; allowed: none"),
    (dict(samples=samples([0, 1], [4.1, 0.0], col="force")), r"samples\.force\[1\]: 0 N; allowed: > 0 N"),
    (dict(samples=samples([0, 1], [4.1, -1.0], col="force")), r"samples\.force\[1\]: -1 N; allowed: > 0 N"),
    (dict(samples=samples([0, 1], [4.1, 4.0], {"time": "s", "force": "m"}, col="force")),
     r"samples\.units\.force: .* not a force"),
])
def test_bad_force_targets(changes, match):
    with pytest.raises(SpecError, match=match):
        target_from_mapping(with_(**{**FORCE, **changes}), "x.yaml")


def test_csv_samples(tmp_path):
    (tmp_path / "f.csv").write_text("# comment\ntime [ms],force [mN]\n0,4100\n500,4000\n")
    t = load_target(tmp_path / "f.csv", stretch="1.5")
    np.testing.assert_allclose(t.time, [0.0, 0.5]) and np.testing.assert_allclose(t.values, [4.1, 4.0])
    assert t.settings.target == "force" and t.settings.stretch == 1.5


@pytest.mark.parametrize("text, options, match", [
    ("time,force\n0,1\n1,2\n", {}, r"f\.csv: header: 'time' has no unit in brackets"),
    ("time [s],torque [N m]\n0,1\n1,2\n", {}, r"f\.csv: header: .* allowed: 'time \[s\],force \[N\]' or"),
    ("time [s],force [N]\n0,1\n1,x\n", {"stretch": "1.5"}, r"f\.csv: line 3: '1,x' is not two numbers"),
    ("time [s],force [N]\n0,1\n0,2\n", {"stretch": "1.5"}, r"f\.csv: time \(line 3\): 0 s does not come after"),
    ("time [s],force [N]\n0,1\n1,0\n", {"stretch": "1.5"}, r"f\.csv: force \(line 3\): 0 N; allowed: > 0 N"),
    ("time [s],force [N]\n0,1\n1,2\n", {}, r"options for a CSV target\): stretch: missing"),
    ("time [s],force [N]\n0,1\n1,2\n", {"stretch": "0.5"}, r"--stretch: stretch 0.5 is below 1"),
    ("time [s],stretch [-]\n0,1.05\n1,1.06\n", {"bias": "{kind: spring, stiffness: -1 N/m, preload: 1 N}"},
     r"--bias\.stiffness: must be > 0 N/m"),
    ("time [s],stretch [-]\n0,1.05\n1,1.06\n", {"bias": "{kind: [}"}, r"--bias: .* is not a YAML mapping"),
    ("time [s],stretch [-]\n0,1.05\n1,1.06\n", {"bias": "{kind: mass, mass: 70 g}", "sample_rate": "-1 Hz"},
     r"--sample-rate: must be > 0 Hz"),
])
def test_bad_csv_targets(tmp_path, text, options, match):
    (tmp_path / "f.csv").write_text(text)
    with pytest.raises(SpecError, match=match) as info:
        load_target(tmp_path / "f.csv", **options)
    assert "\n" not in str(info.value)


def test_yaml_target_with_csv_samples_and_no_options(tmp_path):
    (tmp_path / "s.csv").write_text("time [s],stretch [-]\n0,1.05\n1,1.06\n")
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(with_(samples="s.csv")))
    assert load_target(tmp_path / "t.yaml").values.tolist() == [1.05, 1.06]
    with pytest.raises(SpecError, match=r"t\.yaml: the target file gives its own settings; stretch"):
        load_target(tmp_path / "t.yaml", stretch="1.5")
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(with_(samples="missing.csv")))
    with pytest.raises(SpecError, match=r"missing\.csv: file not found"):
        load_target(tmp_path / "t.yaml")
