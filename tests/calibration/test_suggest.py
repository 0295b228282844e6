"""`rdea_lab.calibration.suggest` and ``rdea-lab suggest``: the next experiment.

Independent references: the force's closed-form derivatives where the SU force at 0 V is linear in the
Yeoh coefficients (no branch: ``dF/dlog C10`` is the force of C10 alone); the information of a fit to
one run as `calibrate` computes it (its own Jacobian, in SI, from ``covar``), against the information
`candidate_information` builds for that run (internal variables, another step); an explicit loop for the
scene's variance; the project's protocol loader for the written suggestion; and, slow, the brute-force
refit over every candidate on an emulated truth beyond the model (benchmarks/suggest_check.py).
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.calibration.fit import calibrate
from rdea_lab.calibration.objective import predict_force
from rdea_lab.calibration.parameters import fit_parameters
from rdea_lab.calibration.suggest import (PRIOR_SD, Calibrated, candidate_information, candidate_spec, candidates,
                                          information_from_covariance, plan_run, scene_variance, sensitivity,
                                          suggest, write_suggestion)
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import ParameterSet, ViscoBranch, load_protocol
from rdea_lab.specs.limits import Limits
from rdea_lab.specs.protocol import dump_protocol

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"
RIG = Limits(max_stretch=3.0)
TRUTH = ParameterSet(name="t", C10=18e3, C20=-0.2e3, C30=0.02e3, eps_r=4.7, law="finite_strain",
                     branches=(ViscoBranch.of("finite_strain", 25e3, 50e3),), eta_v0=0.0)


def emulated(spec, params, seed):
    run = plan_run(spec, CARD)
    f = predict_force(run, params, "su")
    run.force = f + np.random.default_rng(seed).normal(0.0, 4e-3, f.shape)
    run.peak = float(np.max(np.abs(run.force)))
    return run


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """A calibration record of two emulated ramps to stretch 2 (least squares, one finite-strain branch)."""
    runs = [emulated(candidate_spec("ramp", 2.0, r, 0.0, RIG, sample_rate=5.0), TRUTH, i)
            for i, r in enumerate((0.05, 0.25))]
    res = calibrate(runs, TRUTH.replace(C10=15e3), model="su", method="least-squares")
    path = tmp_path_factory.mktemp("suggest") / "cal.yaml"
    res.write(path)
    return path


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene.yaml"
    path.write_text(dump_protocol(candidate_spec("hold", 2.5, 0.25, 300.0, RIG, sample_rate=2.0)))
    return path


def test_sensitivity_in_log_and_asinh_variables_matches_the_linear_yeoh_force():
    ps = TRUTH.replace(branches=(), C20=0.1e3)
    run = plan_run(candidate_spec("ramp", 2.0, 0.25, 0.0, RIG), CARD)
    params = [p for p in fit_parameters(ps, {"C10", "C30"}) if p.free]
    J = sensitivity(run, ps, "su", params)
    F = lambda **c: predict_force(run, ps.replace(**c), "su")  # noqa: E731
    # no branch, no damper: F is linear in (C10, C20, C30), so dF/dC is an exact finite difference
    dF_dC10 = (F() - F(C10=ps.C10 / 2)) / (ps.C10 / 2)
    dF_dC30 = (F() - F(C30=0.0)) / ps.C30
    # u = log C10: dF/du = C10 dF/dC10; u = asinh(C30 / s): dF/du = sqrt(s^2 + C30^2) dF/dC30
    assert np.allclose(J[:, 0], ps.C10 * dF_dC10, rtol=1e-6, atol=1e-9)
    assert np.allclose(J[:, 1], np.hypot(params[1].scale, ps.C30) * dF_dC30, rtol=1e-6, atol=1e-9)


def test_a_spectrums_moduli_vary_at_fixed_relaxation_times():
    """At fixed time scales the force is linear in a branch's modulus (the spectrum's premise), so with
    ``fixed_taus`` the sensitivity in u = log mu is mu times the exact difference quotient of the force at
    fixed tau; at fixed viscosity (the default) tau moves with mu and the column differs."""
    ps = TRUTH
    run = plan_run(candidate_spec("hold", 2.0, 0.25, 60.0, RIG, sample_rate=5.0), CARD)
    params = [p for p in fit_parameters(ps, {"mu_v1"}) if p.free]
    b = ps.branches[0]
    at_tau = lambda mu: predict_force(run, ps.replace(branches=(ViscoBranch.of(ps.law, mu, b.tau * mu),  # noqa: E731
                                                               *ps.branches[1:])), "su")
    full, half = at_tau(b.modulus), at_tau(b.modulus / 2)
    taut = (full > 1e-3 * full.max()) & (half > 1e-3 * full.max())  # linear where the roll is not slack
    assert taut.sum() > run.n / 2
    exact = (b.modulus * (full - half) / (b.modulus / 2))[taut]
    fixed = sensitivity(run, ps, "su", params, fixed_taus=True)[taut, 0]
    assert np.allclose(fixed, exact, rtol=1e-5, atol=1e-9 * np.abs(exact).max())
    moving = sensitivity(run, ps, "su", params)[taut, 0]
    assert not np.allclose(moving, exact, rtol=1e-2, atol=1e-3 * np.abs(exact).max())


def test_a_candidates_information_is_what_a_fit_to_it_alone_would_know():
    spec = candidate_spec("hold", 2.0, 0.25, 60.0, RIG, sample_rate=5.0)
    run = emulated(spec, TRUTH, 3)
    res = calibrate([run], TRUTH, model="su", method="least-squares", free=["C10", "C30", "mu_v1", "eta_v1"])
    params = [p for p in fit_parameters(res.params, set(res.free_names)) if p.free]
    F_fit = information_from_covariance(params, res.values, res.covar) - np.eye(len(params)) / PRIOR_SD**2
    cal = Calibrated(res.params, "su", tuple(params), np.zeros_like(F_fit), res.redchi, float(run.n))
    F_c, _ = candidate_information(cal, run)
    # the fit's covariance uses the measured peak (noise 4 mN on about 1.4 N) and its own difference steps
    assert np.allclose(F_c, F_fit, rtol=2e-2, atol=1e-6 * np.abs(F_fit).max())


def test_scene_variance_is_the_mean_over_samples_of_g_F_inverse_g():
    rng = np.random.default_rng(1)
    G = rng.normal(size=(7, 3))
    A = rng.normal(size=(3, 3))
    F = A @ A.T + np.eye(3)
    Finv = np.linalg.inv(F)
    assert scene_variance(G, F) == pytest.approx(np.mean([g @ Finv @ g for g in G]), rel=1e-12)


def test_candidates_stay_inside_the_limits_and_the_others_are_named():
    kept, refused = candidates(CARD, Limits(max_stretch=2.0), stretches=(1.5, 2.5), rates=(0.1,), holds=(10.0,))
    assert [c.name for c in kept] == ["ramp_1.5_at_0.1_per_s", "hold_1.5_for_10s"]
    assert len(refused) == 2 and all("above the limit max_stretch = 2" in r for r in refused)


def test_the_suggestion_is_written_as_a_protocol_that_loads_back(record, scene, tmp_path):
    sug = suggest(record, CARD, scene=scene, stretches=(1.5, 2.5), rates=(0.25,), holds=(30.0,), sample_rate=2.0)
    assert sug.criterion == "scene" and len(sug.rows) == 4
    assert [r["shrink"] for r in sug.rows] == sorted((r["shrink"] for r in sug.rows), reverse=True)
    assert all(0.0 <= r["shrink"] < 1.0 for r in sug.rows)
    out = write_suggestion(sug, tmp_path / "next.yaml")
    assert load_protocol(out) == sug.best.spec


def test_cli_ranks_and_writes(record, scene, tmp_path, capsys):
    out = tmp_path / "next.yaml"
    assert run_cli(cli, ["suggest", "--params", str(record), "--specimen", str(CARD), "--target", str(scene),
                         "--stretches", "1.5,2.5", "--rates", "0.25", "--holds", "30", "--sample-rate", "2",
                         "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "suggested: " in text and f"wrote {out}" in text
    assert load_protocol(out).name in text


@pytest.mark.parametrize("args, message", [
    (["--max-stretch", "1.2", "--stretches", "1.5"], "--stretches/--rates/--holds/--max-stretch: no candidate inside"),
    (["--target", "SCENE", "--max-stretch", "2"], "the scene is outside the rig's limits"),
    (["--target", "BEYOND_ITS_OWN"], "stretch[0]: the scene is outside its own limits: stretch"),
    (["--params", str(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")], "no calibration record"),
    (["--params", "missing.yaml"], "missing.yaml: no such file; allowed: a calibration record"),
    (["--target", "missing.yaml"], "missing.yaml: no such file; allowed: a protocol YAML"),
    (["--rates", "0"], "--rates: 0; allowed: numbers > 0"),
])
def test_bad_input_exits_2_with_one_line(record, scene, tmp_path, capsys, args, message):
    beyond = tmp_path / "beyond.yaml"  # stretch 2.5 in a protocol whose own limit is 2
    beyond.write_text(dump_protocol(candidate_spec("hold", 2.5, 0.25, 10.0, Limits(max_stretch=2.0))))
    args = [{"SCENE": str(scene), "BEYOND_ITS_OWN": str(beyond)}.get(a, a) for a in args]
    base = {"--params": str(record), "--specimen": str(CARD)}
    for k in list(base):
        if k in args:
            del base[k]
    argv = ["suggest", *[x for kv in base.items() for x in kv], *args]
    code = run_cli(cli, argv)
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and message in err, err


@pytest.mark.slow
def test_the_suggested_experiment_reduces_the_scenes_error_more_than_the_median_candidate():
    """Brute force: every candidate emulated on a two-branch truth, added to the fit set of a one-branch
    model and refitted; the scene's error measured against the truth (benchmarks/suggest_check.py)."""
    spec = importlib.util.spec_from_file_location("suggest_check", ROOT / "benchmarks" / "suggest_check.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.check(verbose=False)
    assert out["scene_error_initial"] > 0.05  # the one-branch model is wrong on the hold: something to fix
    assert out["suggested_reduction"] >= out["median_reduction"]
