"""`rdea_lab.design.evaluate`: the metrics of a table of designs against one-roll-at-a-time references.

Each reference solves one design on its own: its membrane as the study format
says (`rdea_lab.specs.study`'s docstring: what is not varied keeps the card's
passive lengths), its radii from the scalar `radii_from_membrane`, its force
from the ordinary `rdea_lab.physics.models.solve`, its equilibria with the
bias by `scipy.optimize.brentq`, a protocol's force from `rdea_lab.simulate`.
evaluate finds the equilibria by 64 bisections of [1, 2.5] (to the last bit)
on the mapped force of `solve_designs` (equal to solve's to ~1e-15), so the
stretches agree to about 1e-14: the tolerances below are 1e-12 in stretch and
what that moves in the other metrics.
"""

from __future__ import annotations


import numpy as np
import pytest
from scipy.optimize import brentq

import rdea_lab
from rdea_lab.design.evaluate import MAX_STRETCH, NO_EQUILIBRIUM, NO_ROLL, OK, Fixed, evaluate
from rdea_lab.physics.geometry import RollGeometry, radii_from_membrane
from rdea_lab.physics.models import solve
from rdea_lab.protocols import as_plan
from rdea_lab.specs import load_params, load_specimen
from rdea_lab.specs.study import study_from_mapping
from rdea_lab.specs.target import G

#: stretch agreement of two root finders on the same force to ~1e-15 (module docstring)
STRETCH_TOL = 1e-12
V = 2.6e3


def make_study(root, variables, bias, **extra):
    mapping = {"name": "evaluate-test", "model": "su", "params": str(root / "params" / "paper2021_table3.yaml"),
               "specimen": str(root / "specimens" / "specimen2.yaml"), "variables": variables,
               "voltage": "2.6 kV", "bias": bias, "objectives": [{"maximize": "stroke"}], **extra}
    return study_from_mapping(mapping, "evaluate-test.yaml", root)


def roll_of(card, row):
    """One design's RollGeometry, by the study format's rules (docstring of rdea_lab.specs.study), with the
    scalar radii_from_membrane."""
    m = card.membrane
    L1 = row.get("L1", m.L1)
    L1e = row.get("L1e", L1 - (m.L1 - m.L1e))
    Lp1, L2e, L3 = row.get("Lp1", m.Lp1), row.get("L2e", m.L2e), row.get("L3", m.L3)
    L2 = row.get("L2", Lp1 + L2e + (m.L2 - m.Lp1 - m.L2e))
    r = radii_from_membrane(L2, L3, Lp1, L2e, m.Ri)
    return RollGeometry(r["Ri"], r["Rie"], r["Roe"], r["Ro"], L1, L1e, L3), L2


def rows(table):
    n = len(next(iter(table.values())))
    return [{k: float(v[i]) for k, v in table.items()} for i in range(n)]


def force(geom, params, stretch, voltage, **kw):
    return float(solve("su", geom, params, [stretch], [voltage], **kw).force[0])


def equilibrium(geom, params, voltage, bias_force):
    """The stretch where the roll's force meets the bias's, by brentq on [1, MAX_STRETCH]."""
    return brentq(lambda lam: force(geom, params, lam, voltage) - bias_force(lam), 1.0, MAX_STRETCH,
                  xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)


@pytest.fixture(scope="module")
def params(root):
    return load_params(root / "params" / "paper2021_table3.yaml")


@pytest.fixture(scope="module")
def card(root):
    return load_specimen(root / "specimens" / "specimen2.yaml")


def test_spring_bias_equilibria_stroke_blocking_force_work(root, params, card):
    study = make_study(root, {"L1": ["20 mm", "60 mm"], "L3": ["30 um", "80 um"], "L2e": ["40 mm", "90 mm"],
                              "stiffness": ["50 N/m", "500 N/m"], "preload": ["0.5 N", "3 N"]},
                       {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"})
    rng = np.random.default_rng(5)
    n = 8
    table = {v.name: v.from_unit(rng.random(n)) for v in study.variables}
    got = evaluate(Fixed.of(study), table)
    assert np.all(got["design_status"] == OK)
    for i, row in enumerate(rows(table)):
        geom, L2 = roll_of(card, row)
        k, p, L1 = row["stiffness"], row["preload"], row["L1"]

        def spring(lam):
            return p - k * (lam - 1.0) * L1

        lam0 = equilibrium(geom, params, 0.0, spring)
        lam1 = equilibrium(geom, params, V, spring)
        assert lam1 > lam0 + 1e-4  # the voltage lengthens the roll: a real stroke
        assert got["rest_stretch"][i] == pytest.approx(lam0, abs=STRETCH_TOL, rel=0)
        assert got["on_stretch"][i] == pytest.approx(lam1, abs=STRETCH_TOL, rel=0)
        assert got["stroke"][i] == pytest.approx((lam1 - lam0) * L1, abs=2 * STRETCH_TOL * L1, rel=0)
        assert got["strain"][i] == pytest.approx(lam1 / lam0 - 1.0, abs=4 * STRETCH_TOL, rel=0)
        # blocking force at the rest length; the rest stretch's 1e-12 moves it by ~dF/dlambda 1e-12 (~1e-11 N)
        blocking = force(geom, params, lam0, 0.0) - force(geom, params, lam0, V)
        assert got["blocking_force"][i] == pytest.approx(blocking, rel=1e-9)
        # a linear spring: the trapezoid is exact, on evaluate's own stretches to rounding ...
        g0, g1 = got["rest_stretch"][i], got["on_stretch"][i]
        assert got["work"][i] == pytest.approx(0.5 * (spring(g0) + spring(g1)) * (g1 - g0) * L1, rel=1e-12)
        # ... and on the reference's to what the stretches allow
        work = 0.5 * (spring(lam0) + spring(lam1)) * (lam1 - lam0) * L1
        assert got["work"][i] == pytest.approx(work, rel=1e-8)
        volume = np.pi * (geom.Ro**2 - geom.Ri**2) * L1
        assert volume == pytest.approx(2 * L1 * L2 * geom.L3, rel=1e-12)  # the flat membranes' volume
        assert got["volume"][i] == pytest.approx(volume, rel=1e-12)
        assert got["energy_density"][i] == pytest.approx(got["work"][i] / volume, rel=1e-12)
        assert got["outer_radius"][i] == pytest.approx(geom.Ro, rel=1e-13)
        assert got["rest_force"][i] == pytest.approx(spring(lam0), rel=1e-10)
        assert got["rest_force"][i] == pytest.approx(force(geom, params, lam0, 0.0), rel=1e-10)
        # SU: C = C0 lambda1 (eq. 41), lambda2 = lambda1**-0.5, the field V lambda1 lambda2 / L3
        assert got["capacitance"][i] == pytest.approx(geom.C0(params.eps_r) * lam0, rel=1e-11)
        assert got["field"][i] == pytest.approx(V * np.sqrt(lam1) / geom.L3, rel=1e-11)
        sig = max(solve("su", geom, params, [lam0], [0.0]).sigma1[0], solve("su", geom, params, [lam1], [V]).sigma1[0])
        assert got["stress"][i] == pytest.approx(sig, rel=1e-10)
        assert got["preload"][i] == p


@pytest.mark.parametrize("kind", ["spring", "mass"])
def test_prestretch_sets_the_rest_stretch(root, params, card, kind):
    bias = {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"} if kind == "spring" else \
        {"kind": "mass", "mass": "50 g"}
    study = make_study(root, {"L1": ["20 mm", "60 mm"], "prestretch": [1.05, 1.6]}, bias)
    table = {"L1": np.array([20e-3, 34e-3, 47e-3, 60e-3]), "prestretch": np.array([1.05, 1.6, 1.3, 1.12])}
    got = evaluate(Fixed.of(study), table)
    assert np.all(got["design_status"] == OK)
    np.testing.assert_allclose(got["rest_stretch"], table["prestretch"], rtol=0, atol=STRETCH_TOL)
    for i, row in enumerate(rows(table)):
        geom, _ = roll_of(card, row)
        f0 = force(geom, params, row["prestretch"], 0.0)  # what the bias must pull at the prestretch
        if kind == "spring":
            assert got["preload"][i] == pytest.approx(f0 + 200.0 * (row["prestretch"] - 1.0) * row["L1"], rel=1e-12)
        else:
            assert got["bias_mass"][i] == pytest.approx(f0 / G, rel=1e-12)
        assert got["rest_force"][i] == pytest.approx(f0, rel=1e-10)


def test_no_bias_on_stretch_is_the_free_stretch(root, params, card):
    study = make_study(root, {"L1": ["20 mm", "60 mm"], "L3": ["30 um", "80 um"]}, {"kind": "none"})
    table = {"L1": np.array([20e-3, 34e-3, 60e-3, 45e-3]), "L3": np.array([30e-6, 48e-6, 80e-6, 35e-6])}
    got = evaluate(Fixed.of(study), table)
    assert np.all(got["design_status"] == OK)
    np.testing.assert_allclose(got["rest_stretch"], 1.0, rtol=0, atol=STRETCH_TOL)
    for i, row in enumerate(rows(table)):
        geom, _ = roll_of(card, row)
        # the free stretch: the SU stress at the voltage vanishes (the taut equilibrium, slack=False)
        free = brentq(lambda lam: solve("su", geom, params, [lam], [V], slack=False).sigma1[0], 1.0, MAX_STRETCH,
                      xtol=1e-15, rtol=4 * np.finfo(float).eps)
        assert free > 1.0 + 1e-4
        assert got["on_stretch"][i] == pytest.approx(free, abs=STRETCH_TOL, rel=0)
        assert got["stroke"][i] == pytest.approx((free - 1.0) * row["L1"], abs=2 * STRETCH_TOL * row["L1"], rel=0)


def test_mass_bias_equilibria(root, params, card):
    study = make_study(root, {"L2e": ["40 mm", "90 mm"], "mass": ["20 g", "100 g"]}, {"kind": "mass", "mass": "50 g"})
    table = {"L2e": np.array([40e-3, 60e-3, 76e-3, 90e-3]), "mass": np.array([20e-3, 100e-3, 55e-3, 70e-3])}
    got = evaluate(Fixed.of(study), table)
    assert np.all(got["design_status"] == OK)
    for i, row in enumerate(rows(table)):
        geom, _ = roll_of(card, row)
        weight = row["mass"] * G
        lam0 = equilibrium(geom, params, 0.0, lambda lam: weight)
        lam1 = equilibrium(geom, params, V, lambda lam: weight)
        assert got["rest_stretch"][i] == pytest.approx(lam0, abs=STRETCH_TOL, rel=0)
        assert got["on_stretch"][i] == pytest.approx(lam1, abs=STRETCH_TOL, rel=0)
        # a dead load: work m g x stroke, exactly so on evaluate's own stretches
        g0, g1 = got["rest_stretch"][i], got["on_stretch"][i]
        assert got["work"][i] == pytest.approx(weight * (g1 - g0) * card.membrane.L1, rel=1e-12)
        assert got["bias_mass"][i] == row["mass"]


def test_protocol_metrics_equal_simulate(root, params, card):
    """peak_force and the other protocol metrics against rdea_lab.simulate of each design as a card."""
    protocol = root / "protocols" / "tensile_ramp_sine_2.6kV.yaml"
    study = make_study(root, {"L1": ["20 mm", "60 mm"], "L3": ["30 um", "80 um"]},
                       {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"}, protocol=str(protocol))
    table = {"L1": np.array([25e-3, 52e-3]), "L3": np.array([70e-6, 44e-6])}
    got = evaluate(Fixed.of(study), table)
    assert np.all(got["design_status"] == OK)
    plan = as_plan(protocol)
    t, stretch, voltage = np.array(plan.time), np.array(plan.stretch), np.array(plan.voltage)
    for i, row in enumerate(rows(table)):
        m = card.membrane.model_copy(update={"L1": row["L1"], "L1e": row["L1"] - (card.membrane.L1 - card.membrane.L1e),
                                             "L3": row["L3"]})
        design = card.model_copy(update={"membrane": m, "id": f"design-{i}"})
        ds = rdea_lab.simulate(design, params, t, stretch, voltage, model="su")
        f = ds["force"].values
        assert np.all(np.isfinite(f)) and f.max() > 0.1
        assert got["peak_force"][i] == pytest.approx(f.max(), rel=1e-9)
        assert got["force_range"][i] == pytest.approx(f.max() - f.min(), rel=1e-9)
        assert got["peak_capacitance"][i] == pytest.approx(ds["capacitance"].values.max(), rel=1e-9)
        field = voltage * stretch * ds["lambda2b"].values / row["L3"]
        assert got["peak_field"][i] == pytest.approx(field.max(), rel=1e-9)
        # energy dissipated over the protocol: the loop's integral of F dx (trapezoid, x = stretch L1)
        loop = np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(stretch * row["L1"]))
        assert got["hysteresis"][i] == pytest.approx(loop, rel=1e-9)


def test_protocol_energy_dissipated_is_positive(root):
    """Over a closed stretch loop at constant voltage a viscoelastic roll only dissipates: the metric
    "energy dissipated over the protocol" must be > 0 (whatever sign its description gives the integral)."""
    protocol = root / "protocols" / "tensile_ramp_sine_2.6kV.yaml"
    plan = as_plan(protocol)
    assert plan.stretch[0] == pytest.approx(plan.stretch[-1], abs=1e-12)  # a closed loop
    study = make_study(root, {"L1": ["20 mm", "60 mm"]}, {"kind": "none"}, protocol=str(protocol))
    got = evaluate(Fixed.of(study), {"L1": np.array([20e-3, 40e-3, 60e-3])})
    assert np.all(got["hysteresis"] > 0), got["hysteresis"]


def test_designs_that_are_no_roll_get_status_and_nan(root):
    study = make_study(root, {"L2e": ["1 mm", "90 mm"], "L3": ["30 um", "80 um"]},
                       {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"})
    # entries 1 and 3: an electrode of 1 or 2 mm, shorter than the first turn (about 3.8 mm at 48 um)
    table = {"L2e": np.array([76e-3, 1e-3, 60e-3, 2e-3]), "L3": np.array([48e-6, 48e-6, 40e-6, 80e-6])}
    r = radii_from_membrane(10e-3 + table["L2e"] + 13e-3, table["L3"], 10e-3, table["L2e"], check=False)
    assert list(np.isnan(r["Ro"])) == [False, True, False, True]  # the premise, by the geometry itself
    got = evaluate(Fixed.of(study), table)
    assert list(got["design_status"]) == [OK, NO_ROLL, OK, NO_ROLL]
    for key in study.metrics:
        assert np.all(np.isnan(got[key][[1, 3]])), key
        assert np.all(np.isfinite(got[key][[0, 2]])), key
    # a table of nothing but such designs
    none = evaluate(Fixed.of(study), {"L2e": np.array([1e-3, 2e-3]), "L3": np.array([48e-6, 60e-6])})
    assert list(none["design_status"]) == [NO_ROLL, NO_ROLL]
    assert all(np.all(np.isnan(none[k])) for k in study.metrics)


def test_a_bias_the_roll_cannot_meet_is_no_equilibrium(root, params, card):
    """A preload larger than the roll's force at the largest stretch searched: no equilibrium, NaN."""
    study = make_study(root, {"preload": ["1 N", "500 N"]},
                       {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"})
    geom, _ = roll_of(card, {})
    top = force(geom, params, MAX_STRETCH, 0.0)
    big = top + 200.0 * (MAX_STRETCH - 1.0) * card.membrane.L1 + 1.0  # the spring still pulls more at 2.5
    got = evaluate(Fixed.of(study), {"preload": np.array([1.0, big])})
    assert list(got["design_status"]) == [OK, NO_EQUILIBRIUM]
    assert np.isnan(got["stroke"][1]) and np.isfinite(got["stroke"][0])


def test_a_design_past_the_protocols_field_limit_is_flagged(root, params, card):
    """The protocol could not test a roll whose field estimate |v| sqrt(stretch) / L3 passes its max_field."""
    protocol = root / "protocols" / "tensile_ramp_sine_2.6kV.yaml"
    study = make_study(root, {"L3": ["30 um", "80 um"]},
                       {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"}, protocol=str(protocol))
    plan = as_plan(protocol)
    worst = np.max(np.abs(plan.voltage) * np.sqrt(plan.stretch))  # by hand, per metre of film
    L3 = np.array([0.95, 1.05]) * worst / plan.limits.max_field  # just past, just within the limit
    got = evaluate(Fixed.of(study), {"L3": L3})
    assert list(got["design_status"]) == [5, OK]
    assert np.isnan(got["stroke"][0]) and np.isfinite(got["stroke"][1])
    assert got["limit_field"][1] == pytest.approx(worst / L3[1], rel=1e-12)


@pytest.mark.parametrize("model", [pytest.param("3r", marks=pytest.mark.slow), "cr"])  # 3R: ~10 s (simulate)
def test_3r_and_cr_studies_of_a_hollow_core_equal_one_roll_at_a_time(root, params, card, tmp_path, model):
    """A roll wound on a 0.5 mm mandrel (hollow core), its 3R / CR equilibria with a spring (brentq on the
    model's own solve) and, for 3R, the protocol's metrics against `rdea_lab.simulate` of each design."""
    hollow = card.model_copy(update={"membrane": card.membrane.model_copy(update={"Ri": 0.5e-3}),
                                     "id": "hollow"})
    path = tmp_path / "hollow.yaml"
    path.write_text("id: hollow\nkind: roll\nmembrane: {L1: 34 mm, L2: 99 mm, L3: 48 um, L1e: 29 mm, Lp1: 10 mm, "
                    "L2e: 76 mm, Ri: 0.5 mm}\n")
    protocol = root / "protocols" / "tensile_ramp_sine_2.6kV.yaml"
    extra = {"protocol": str(protocol)} if model == "3r" else {}
    study = make_study(root, {"L1": ["20 mm", "60 mm"], "L3": ["30 um", "80 um"]},
                       {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"}, model=model,
                       specimen=str(path), **extra)
    table = {"L1": np.array([25e-3, 52e-3]), "L3": np.array([70e-6, 44e-6])}
    got = evaluate(Fixed.of(study), table)
    assert np.all(got["design_status"] == OK)
    plan = as_plan(protocol)
    t, stretch, voltage = np.array(plan.time), np.array(plan.stretch), np.array(plan.voltage)
    for i, row in enumerate(rows(table)):
        geom, _ = roll_of(hollow, row)
        assert geom.Ri == 0.5e-3

        def spring(lam):
            return 1.0 - 200.0 * (lam - 1.0) * row["L1"]

        def excess(lam, v):
            return float(solve(model, geom, params, [lam], [v]).force[0]) - spring(lam)

        for key, v in (("rest_stretch", 0.0), ("on_stretch", V)):
            lam = brentq(excess, 1.0, MAX_STRETCH, args=(v,), xtol=1e-15, rtol=4 * np.finfo(float).eps)
            assert got[key][i] == pytest.approx(lam, abs=STRETCH_TOL, rel=0), key
        lam0 = got["rest_stretch"][i]
        assert got["capacitance"][i] == pytest.approx(solve(model, geom, params, [lam0], [0.0]).capacitance[0],
                                                      rel=1e-11)
        if model != "3r":
            continue
        m = hollow.membrane.model_copy(update={"L1": row["L1"], "L1e": row["L1"] - 5e-3, "L3": row["L3"]})
        ds = rdea_lab.simulate(hollow.model_copy(update={"membrane": m}), params, t, stretch, voltage, model="3r")
        f = ds["force"].values
        assert np.all(np.isfinite(f)) and f.max() > 0.1
        assert got["peak_force"][i] == pytest.approx(f.max(), rel=1e-9)
        assert got["peak_capacitance"][i] == pytest.approx(ds["capacitance"].values.max(), rel=1e-9)
        loop = np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(stretch * row["L1"]))
        assert got["hysteresis"][i] == pytest.approx(loop, rel=1e-9)
