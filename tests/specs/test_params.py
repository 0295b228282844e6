"""Tests of rdea_lab.specs.params: material parameter sets and their physics checks."""

import copy
import math
import re
from pathlib import Path

import pytest
from hypothesis import assume, given, strategies as st

from rdea_lab.specs import (
    ParameterSet,
    SpecError,
    ViscoBranch,
    dump_params,
    load_params,
    material_problems,
    params_from_mapping,
    params_from_yaml,
    yeoh_slope_nonpositive_at,
)

PARAMS = Path(__file__).resolve().parents[2] / "rdea_lab" / "data" / "params"
KPA = 1e3
TABLE3 = dict(C10=242 * KPA, C20=-69 * KPA, C30=47 * KPA, eps_r=2.8)  # Table 3 as corrected in ERRATA
RIZZELLO = dict(C10=241 * KPA, C20=-33.2 * KPA, C30=20.1 * KPA, eps_r=2.8)  # Section 3.4, ref. [36]


def test_table3():
    ps = load_params(PARAMS / "paper2021_table3.yaml")
    # integers in kPa: the parsed SI floats are exact
    assert (ps.name, ps.C10, ps.C20, ps.C30, ps.eps_r) == ("paper2021-table3", 242000.0, -69000.0, 47000.0, 2.8)
    assert ps.M == 1
    (branch,) = ps.branches
    assert (branch.k, branch.eta) == (8271000.0, 86000.0)
    assert branch.tau == pytest.approx(86 / 8271, rel=1e-15)  # ~10.4 ms
    assert ps.eta_v0 == 0.0
    assert "Table 3" in ps.source


def test_rizzello():
    ps = load_params(PARAMS / "rizzello2020.yaml")
    # -33.2 kPa and 20.1 kPa are parsed in decimal: the nearest floats to the SI values
    assert (ps.C10, ps.C20, ps.C30, ps.eps_r) == (241e3, -33.2e3, 20.1e3, 2.8)
    assert (ps.M, ps.branches, ps.eta_v0) == (0, (), 0.0)


@pytest.mark.parametrize("name", ["paper2021_table3.yaml", "rizzello2020.yaml"])
def test_dump_then_load_gives_an_equal_set(name):
    ps = load_params(PARAMS / name)
    text = dump_params(ps)
    assert params_from_yaml(text) == ps
    assert "C10: 242 kPa" in text or "C10: 241 kPa" in text


def test_dump_units():
    text = dump_params(load_params(PARAMS / "paper2021_table3.yaml"))
    for line in ("C20: -69 kPa", "k: 8271 kPa", "eta: 86 kPa s", "eta_v0: 0 kPa s", "eps_r: 2.8"):
        assert line in text


def test_dump_round_trips_calibrated_values():
    ps = load_params(PARAMS / "paper2021_table3.yaml").replace(
        C10=241234.56789, C20=-12345.678901, eps_r=2.8 + 1e-13,
        branches=[ViscoBranch(k=1 / 3 * 1e6, eta=86001.5), {"k": 1e5, "eta": 2e4}], eta_v0=1e-3,
    )
    assert params_from_yaml(dump_params(ps)) == ps


def test_material_problems_accepts_the_papers_sets():
    assert material_problems(**TABLE3, ks=[8271 * KPA], etas=[86 * KPA], eta_v0=0.0) == []
    assert material_problems(**RIZZELLO) == []


@pytest.mark.parametrize(
    "changes, field, match",
    [
        (dict(C10=0.0), "yeoh.C10", r"C10 = 0 kPa must be > 0 kPa"),
        (dict(C10=-1 * KPA), "yeoh.C10", r"C10 = -1 kPa must be > 0 kPa"),
        (dict(C10=math.nan), "yeoh.C10", r"must be a finite number"),
        (dict(C30=-10 * KPA), "yeoh.C30", r"C30 = -10 kPa must be >= 0 kPa"),
        (dict(eps_r=0.5), "eps_r", r"eps_r = 0.5 must be a finite number >= 1"),
        (dict(eps_r=-2.8), "eps_r", r">= 1"),
        (dict(eps_r=math.inf), "eps_r", r">= 1"),
        (dict(etas=[-86 * KPA]), "viscoelastic.branches[0].eta", r"eta = -86 kPa s must be a finite viscosity > 0"),
        (dict(etas=[0.0]), "viscoelastic.branches[0].eta", r"> 0 kPa s"),
        (dict(ks=[0.0]), "viscoelastic.branches[0].k", r"k = 0 kPa must be a finite stiffness > 0"),
        (dict(eta_v0=-1.0), "viscoelastic.eta_v0", r"eta_v0 = -0.001 kPa s must be a finite viscosity >= 0"),
        (dict(ks=[1.0, 2.0]), "viscoelastic.branches", r"got 2 stiffnesses k and 1 dampings eta"),
    ],
)
def test_material_problems_refuses(changes, field, match):
    args = dict(TABLE3, ks=[8271 * KPA], etas=[86 * KPA], eta_v0=0.0)
    args.update(changes)
    problems = material_problems(**args)
    assert [f for f, _ in problems] == [field]
    assert re.search(match, problems[0][1])


def test_slope_turns_negative_hand_calculation():
    # C10 = 242, C20 = -200, C30 = 10 [kPa]: dW/dI1 = 242 - 400 x + 30 x^2 [kPa]
    # roots x = (400 -+ sqrt(400^2 - 4*30*242)) / 60 = (400 -+ sqrt(130960)) / 60
    # smaller root (400 - 361.88396) / 60 = 0.635267: the slope is <= 0 from there on
    x = yeoh_slope_nonpositive_at(242 * KPA, -200 * KPA, 10 * KPA)
    assert x == pytest.approx(0.635267345, rel=1e-8)  # 9 digits of the hand value above
    problems = material_problems(242 * KPA, -200 * KPA, 10 * KPA, 2.8)
    assert problems[0][0] == "yeoh.C20"
    assert "turns non-positive at x = I1 - 3 = 0.6353" in problems[0][1]
    assert "need C20 > -sqrt(3 C10 C30) = -85.21 kPa" in problems[0][1]  # sqrt(3*242*10) = 85.206


def test_slope_linear_case():
    # C30 = 0: 242 - 242 x turns zero at x = C10 / (-2 C20) = 1 exactly
    assert yeoh_slope_nonpositive_at(242 * KPA, -121 * KPA, 0.0) == 1.0
    assert yeoh_slope_nonpositive_at(242 * KPA, 0.0, 0.0) is None


def test_slope_positive_for_the_papers_sets():
    # -69 > -sqrt(3*242*47) = -184.7 and -33.2 > -sqrt(3*241*20.1) = -120.5 [kPa]
    assert yeoh_slope_nonpositive_at(242 * KPA, -69 * KPA, 47 * KPA) is None
    assert yeoh_slope_nonpositive_at(241 * KPA, -33.2 * KPA, 20.1 * KPA) is None


def test_slope_tangent_is_refused():
    # C20 = -sqrt(3 C10 C30) = -90 kPa for C10 = 270, C30 = 10: the slope touches 0 at x = 3
    assert yeoh_slope_nonpositive_at(270 * KPA, -90 * KPA, 10 * KPA) == pytest.approx(3.0, rel=1e-12)


def test_slope_negative_C30_always_turns():
    # 242 - 138 x - 141 x^2 [kPa]: positive root (-138 + sqrt(138^2 + 4*141*242)) / 282
    # = (-138 + sqrt(155532)) / 282 = (-138 + 394.3754) / 282 = 0.909133 (6 digits by hand)
    assert yeoh_slope_nonpositive_at(242 * KPA, -69 * KPA, -47 * KPA) == pytest.approx(0.909133, rel=1e-6)


# coefficients of a plausible material: 0 or 1 mPa ... 10 MPa in magnitude
_COEF = st.floats(-1e7, 1e7).filter(lambda v: v == 0.0 or abs(v) >= 1e-3)


@given(C10=st.floats(1e-3, 1e7), C20=_COEF, C30=_COEF)
def test_slope_root_matches_the_slope(C10, C20, C30):
    slope = lambda x: C10 + 2 * C20 * x + 3 * C30 * x * x  # noqa: E731
    x = yeoh_slope_nonpositive_at(C10, C20, C30)
    scale = C10 + 2 * abs(C20) + 3 * abs(C30)
    if x is None:
        # test-only sampling: the analytic answer "always positive" holds on a grid
        xs = [i / 100 for i in range(0, 10001)] + [10.0 ** e for e in range(3, 9)]
        assert all(slope(v) > -1e-9 * scale * (1 + v * v) for v in xs)
    else:
        assert x >= 0
        # a root: |slope| small against the size of its terms at x
        assert abs(slope(x)) <= 1e-9 * (C10 + 2 * abs(C20) * x + 3 * abs(C30) * x * x)
        assume(x > 1e-6)
        assert slope(0.99 * x) > 0  # the first one


# ------------------------------------------------------------ the model
def test_python_construction_replace_and_M():
    ps = ParameterSet(name="t3", **TABLE3, branches=[{"k": 8271e3, "eta": 86e3}])
    assert ps == load_params(PARAMS / "paper2021_table3.yaml").replace(name="t3", description=None, source=None)
    other = ps.replace(C10=250e3)
    assert (other.C10, ps.C10) == (250e3, 242e3)  # a new set; the old one is unchanged
    assert ps.replace(branches=()).M == 0


def test_python_construction_accepts_quantities():
    ps = ParameterSet(name="q", C10="242 kPa", C20="-69 kPa", C30="47 kPa", eps_r=2.8, eta_v0="1 Pa s")
    assert (ps.C10, ps.eta_v0) == (242e3, 1.0)


@pytest.mark.parametrize(
    "changes, match",
    [
        (dict(C10=-1.0), r"^<python>: yeoh\.C10: C10 = -0\.001 kPa must be > 0 kPa"),
        (dict(C20=-300e3), r"^<python>: yeoh\.C20: C20 = -300 kPa is too negative"),
        (dict(C30=math.inf), r"^<python>: yeoh\.C30: inf is not a finite number"),
        (dict(eps_r=0.9), r"^<python>: eps_r: eps_r = 0\.9 must be a finite number >= 1"),
        (dict(branches=[{"k": -1.0, "eta": 1.0}]), r"^<python>: viscoelastic\.branches\[0\]\.k: "),
        (dict(eta_v0=-1.0), r"^<python>: viscoelastic\.eta_v0: "),
        (dict(Mooney=1.0), r"^<python>: Mooney: unknown key 'Mooney'; allowed keys: name, C10"),
        (dict(name="a b"), r"^<python>: name: 'a b' is not a valid name"),
    ],
)
def test_replace_validates(changes, match):
    ps = load_params(PARAMS / "paper2021_table3.yaml")
    with pytest.raises(SpecError, match=match):
        ps.replace(**changes)


def test_visco_branch_checks_itself():
    assert ViscoBranch(k="8271 kPa", eta="86 kPa s").tau == pytest.approx(0.0103978, rel=1e-5)
    with pytest.raises(SpecError, match=r"^<python>: eta: eta = -86 kPa s must be"):
        ViscoBranch(k=8271e3, eta=-86e3)


# ------------------------------------------------------------ YAML form
BASE = {"name": "p", "yeoh": {"C10": "242 kPa", "C20": "-69 kPa", "C30": "47 kPa"}, "eps_r": 2.8,
        "viscoelastic": {"branches": [{"k": "8271 kPa", "eta": "86 kPa s"}], "eta_v0": "0 kPa s"}}


def _without(path):
    data = copy.deepcopy(BASE)
    *parents, last = path.split(".")
    target = data
    for key in parents:
        target = target[key]
    del target[last]
    return data


def test_viscoelastic_is_optional():
    ps = params_from_mapping(_without("viscoelastic"))
    assert (ps.M, ps.eta_v0) == (0, 0.0)
    assert params_from_mapping(_without("viscoelastic.eta_v0")).eta_v0 == 0.0
    assert params_from_mapping(_without("viscoelastic.branches")).M == 0
    empty = copy.deepcopy(BASE)
    empty["viscoelastic"]["branches"] = []
    assert params_from_mapping(empty).M == 0


def _with(path, value):
    data = copy.deepcopy(BASE)
    *parents, last = path.split(".")
    target = data
    for key in parents:
        target = target[int(key)] if key.isdigit() else target[key]
    target[last] = value
    return data


@pytest.mark.parametrize(
    "data, field, match",
    [
        (_with("yeoh.C10", 242000), "yeoh.C10", r"'242000' has no unit; give a pressure"),
        (_with("yeoh.C10", "0 kPa"), "yeoh.C10", r"C10 = 0 kPa must be > 0 kPa"),
        (_with("yeoh.C20", "-200 kPa"), "yeoh.C20", r"too negative"),
        (_with("yeoh.C30", "-1 kPa"), "yeoh.C30", r"must be >= 0 kPa"),
        (_with("yeoh.C40", "1 kPa"), "yeoh.C40", r"unknown key 'C40'; allowed keys: C10, C20, C30"),
        (_without("yeoh.C20"), "yeoh.C20", r"missing required key 'C20'"),
        (_without("yeoh"), "yeoh", r"missing required key 'yeoh'"),
        (_with("eps_r", "2.8 kPa"), "eps_r", r"is not a dimensionless number; give a plain number"),
        (_with("eps_r", 0.5), "eps_r", r">= 1"),
        (_with("eps_r", True), "eps_r", r"True is not a quantity"),
        (_with("viscoelastic.branches", "8271 kPa"), "viscoelastic.branches", r"expected a list"),
        (_with("viscoelastic.branches.0.eta", "86 kPa"), "viscoelastic.branches[0].eta", r"is not a viscosity"),
        (_with("viscoelastic.branches.0.eta", "-86 kPa s"), "viscoelastic.branches[0].eta", r"> 0 kPa s"),
        (_with("viscoelastic.branches.0.tau", "10 ms"), "viscoelastic.branches[0].tau",
         r"unknown key 'tau'; allowed keys: k, mu, eta"),
        (_with("viscoelastic.eta_v0", "-1 kPa s"), "viscoelastic.eta_v0", r">= 0 kPa s"),
        (_with("mooney", {}), "mooney",
         r"unknown key 'mooney'; allowed keys: name, description, source, yeoh, eps_r, viscoelastic"),
        (_with("name", None), "name", r"no value given"),
    ],
)
def test_invalid_parameter_mappings(data, field, match):
    with pytest.raises(SpecError, match=match) as info:
        params_from_mapping(data, source="params/p.yaml")
    assert (info.value.source, info.value.field) == ("params/p.yaml", field)


def test_params_not_a_mapping():
    with pytest.raises(SpecError, match=r"^<string>: top level is a list"):
        params_from_yaml("- 1\n- 2\n")
    with pytest.raises(SpecError, match=r"^<mapping>: expected a mapping of keys"):
        params_from_mapping("name: p")
