"""The hyperelastic choice of a fit: the paper's Yeoh, a Yeoh restricted to monotone stiffening, neo-Hookean.

Independent references: the Yeoh curvature ``d2W/dI1^2`` of the physics (`rdea_lab.physics.yeoh.slope`)
sampled on a grid of ``I1 - 3`` (the docstring's proof, checked numerically); the truth of seeded
synthetic data (a monotone material recovered by the monotone fit).
"""

from pathlib import Path

import numpy as np
import pytest
import yaml

from rdea_lab.calibration import calibrate_runs
from rdea_lab.calibration.methods import Objective
from rdea_lab.calibration.record import calibration_record
from rdea_lab.calibration.parameters import HYPERELASTIC, constrain_start, fit_parameters, names_for
from rdea_lab.physics.yeoh import slope
from rdea_lab.specs import ParameterSet, SpecError, ViscoBranch, load_specimen
from rdea_lab.specs.record import CalibrationRecord
from rdea_lab.twin import simulate

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"


def material(C20, C30, law="finite_strain"):
    return ParameterSet(name="m", C10=30e3, C20=C20, C30=C30, eps_r=2.8, law=law,
                        branches=(ViscoBranch(mu=60e3, eta=120e3),))


@pytest.mark.parametrize("C20", [-1e3, 0.0, 1e3])
@pytest.mark.parametrize("C30", [-10.0, 0.0, 10.0])
def test_monotone_stiffening_is_exactly_c20_and_c30_non_negative(C20, C30):
    x = np.concatenate([[0.0], np.geomspace(1e-6, 1e6, 400)])  # I1 - 3, far beyond any stretch of a test
    _, W2 = slope(x, (30e3, C20, C30))
    assert bool(np.all(W2 >= 0)) == (C20 >= 0 and C30 >= 0)


def test_the_start_is_projected_onto_the_choice():
    s = material(-1e3, 0.2e3)
    assert constrain_start(s, "yeoh") is s
    m = constrain_start(s, "yeoh-monotone")
    assert (m.C10, m.C20, m.C30) == (30e3, 0.0, 0.2e3)
    n = constrain_start(s, "neo-hookean")
    assert (n.C10, n.C20, n.C30) == (30e3, 0.0, 0.0)
    with pytest.raises(SpecError, match="hyperelastic: 'ogden'; allowed: yeoh, yeoh-monotone, neo-hookean"):
        constrain_start(s, "ogden")


def test_bounds_of_each_choice():
    s = material(0.0, 0.0)
    names = set(names_for(1, "finite_strain"))
    by = {h: {p.name: p for p in fit_parameters(s, names, h)} for h in HYPERELASTIC}
    assert by["yeoh"]["C20"].lo < 0 and by["yeoh-monotone"]["C20"].lo == 0.0
    assert all(by[h]["C30"].lo == 0.0 for h in HYPERELASTIC)
    assert not by["neo-hookean"]["C20"].free and not by["neo-hookean"]["C30"].free
    assert by["neo-hookean"]["C10"].free and by["yeoh-monotone"]["C20"].free


def test_least_squares_keeps_c20_in_its_box_under_the_monotone_choice():
    """The Yeoh margin variable (C20 + sqrt(3 C10 C30)) is only for the paper's Yeoh: under the monotone
    choice every point of least squares' unit box has C20 >= 0."""
    s = material(0.0, 0.1e3)
    names = set(names_for(1, "finite_strain"))
    obj = Objective([], s, fit_parameters(s, names, "yeoh-monotone"), "su", "rms", 10, 10.0)
    assert obj._margin_slot() is None
    rng = np.random.default_rng(0)
    for u in rng.uniform(0, 1, (50, len(obj.free))):
        v = obj.values_unit(u)
        assert v["C20"] >= 0.0 and v["C30"] >= 0.0
    assert Objective([], s, fit_parameters(s, names, "yeoh"), "su", "rms", 10, 10.0)._margin_slot() is not None


def runs_of(params, seed=0):
    """Loading-unloading to stretch 2.5 at 1 and 0.1 /s (201 samples each), 0.5 % noise."""
    rng = np.random.default_rng(seed)
    card = load_specimen(CARD)
    out = []
    for rate in (1.0, 0.1):
        t_up = 1.5 / rate
        t = np.linspace(0.0, 2 * t_up, 201)
        lam = np.maximum(1.0 + rate * np.minimum(t, 2 * t_up - t), 1.0)
        ds = simulate(card, params, t, lam, 0.0, model="su")
        f = ds["force"].values
        ds["force"].values = f + 0.005 * np.abs(f).max() * rng.standard_normal(f.size)
        ds.attrs.update({"specimen": CARD.read_text(), "run_id": f"r{rate:g}", "protocol_name": f"r{rate:g}"})
        out.append(ds)
    return out


def test_each_choice_ends_inside_its_set_and_the_record_says_which():
    runs = runs_of(material(-1e3, 0.2e3))  # an S-shaped truth, outside the monotone set
    start = material(-0.5e3, 0.1e3).replace(name="start")
    for choice in HYPERELASTIC:
        res = calibrate_runs(runs, init=start, method="least-squares", hyperelastic=choice)
        assert res.hyperelastic == choice
        if choice == "neo-hookean":
            assert res.values["C20"] == 0.0 and res.values["C30"] == 0.0
            assert "C20" not in res.free_names and "C30" not in res.free_names
        elif choice == "yeoh-monotone":
            assert res.values["C20"] >= 0.0 and res.values["C30"] >= 0.0
        else:
            assert res.values["C20"] < 0.0  # the truth's sign: the paper's Yeoh may reach it
        block = yaml.safe_load(calibration_record(res, res.run_data).block())["calibration"]
        assert block["hyperelastic"] == choice and CalibrationRecord.from_mapping(block).hyperelastic == choice


def test_a_record_written_before_the_choice_still_loads():
    record = CalibrationRecord.from_mapping({"model": "su", "metric": "rms", "method": "least-squares"})
    assert record.hyperelastic is None


def test_the_monotone_fit_recovers_a_monotone_truth():
    truth = material(0.5e3, 0.1e3)
    start = material(0.2e3, 0.3e3).replace(C10=20e3, name="start")
    res = calibrate_runs(runs_of(truth, seed=1), init=start, method="least-squares", hyperelastic="yeoh-monotone")
    # 0.5 % noise on 402 samples: C10 to well under 1 %; C20, C30 are correlated with it and with each other
    assert res.values["C10"] == pytest.approx(truth.C10, rel=0.01)
    assert res.values["C20"] == pytest.approx(truth.C20, rel=0.3)
    assert res.values["C30"] == pytest.approx(truth.C30, rel=0.3)


def test_neo_hookean_refuses_a_free_c20():
    with pytest.raises(SpecError, match=r"free: C20 unknown \(hyperelastic neo-hookean holds C20 = C30 = 0\)"):
        calibrate_runs(runs_of(material(0.0, 0.0)), free="C10,C20", hyperelastic="neo-hookean")


@pytest.fixture
def data(tmp_path):
    path = tmp_path / "r.nc"
    runs_of(material(0.0, 0.0))[0].to_netcdf(path)
    return path


def test_cli_neo_hookean_with_a_free_c20_exits_2(data, tmp_path, capsys):
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    assert run_cli(cli, ["calibrate", str(data), "--hyperelastic", "neo-hookean", "--free", "C10,C20",
                         "--out", str(tmp_path / "o.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [err] and "--free: C20 unknown (hyperelastic neo-hookean holds C20 = C30 = 0)" in err


@pytest.mark.slow
def test_cli_records_the_choice(data, tmp_path, capsys):
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    out = tmp_path / "o.yaml"
    assert run_cli(cli, ["calibrate", str(data), "--hyperelastic", "yeoh-monotone", "--method", "least-squares",
                         "--quiet", "--out", str(out)]) == 0
    assert "(su, rms, yeoh-monotone)" in capsys.readouterr().out
    assert CalibrationRecord.of_file(out).hyperelastic == "yeoh-monotone"
