"""The two minimizers (Nelder-Mead, least squares), the evaluation count and the record's statistics (issue 13)."""

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from rdea_lab.calibration import Budget, calibrate, calibrate_runs, gather_runs
from rdea_lab.calibration.methods import Objective
from rdea_lab.calibration.objective import RunData, predict_force
from rdea_lab.calibration.parameters import fit_parameters, values_of, with_values
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.protocols import load_plan
from rdea_lab.specs import SpecError, ViscoBranch, load_params, load_specimen
from rdea_lab.twin import simulate

ROOT = Path(__file__).resolve().parents[2]
SPECIMEN2 = ROOT / "datasets" / "paper2021" / "specimen-2"
TABLE3 = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")


def twin_runs(params, noise, seed, names=("tensile_ramp_sine_0V", "tensile_ramp_sine_2.6kV")):
    """Tensile tests of the paper on specimen 2 by the twin (SU), plus white noise [N]."""
    card = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
    geom = geometry_from_card(card)
    rng = np.random.default_rng(seed)
    runs = []
    for name in names:
        plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / f"{name}.yaml")
        force = simulate(geom, params, plan.time, plan.stretch, plan.voltage, model="su")["force"].values
        force = force + noise * rng.standard_normal(force.size)
        runs.append(RunData(Path(f"<{name}>"), "", name, "tensile", card.id, geom, plan.time, plan.stretch.copy(),
                            plan.voltage.copy(), force, float(np.max(np.abs(force)))))
    return runs


def test_both_methods_find_the_analytic_optimum_of_a_model_linear_in_its_parameters():
    """Without branches the SU force is linear in C10, C20, C30 (eq. 39), so the rms objective is a
    quadratic whose minimum is the weighted linear least-squares solution: the design matrix by exact
    differences (linear), the weights those of `residuals` (1 / peak * sqrt(n_mean / n)). At 0 V only:
    there the model force stays >= 0, so the slack clip (nonlinear) never acts."""
    truth = TABLE3.replace(branches=(), eta_v0=0.0)
    runs = twin_runs(truth, noise=5e-3, seed=3, names=("tensile_ramp_sine_0V",))
    free = ["C10", "C20", "C30"]
    p0 = truth.replace(C10=1.5 * truth.C10, C20=0.5 * truth.C20, C30=1.5 * truth.C30)
    n_mean = np.mean([r.n for r in runs])
    w = np.concatenate([np.full(r.n, np.sqrt(n_mean / r.n) / r.peak) for r in runs])
    F = np.concatenate([r.force for r in runs])
    base = np.concatenate([predict_force(r, p0, "su") for r in runs])
    c0 = np.array([p0.C10, p0.C20, p0.C30])
    D = np.column_stack([(np.concatenate([predict_force(r, p0.replace(**{k: getattr(p0, k) + 1e3}), "su")
                                          for r in runs]) - base) / 1e3 for k in free])
    exact = np.linalg.lstsq(D * w[:, None], (F - base + D @ c0) * w, rcond=None)[0]
    assert np.all(D @ exact + base - D @ c0 >= 0)  # no slack sample at the optimum either
    for method in ("nelder-mead", "least-squares"):
        res = calibrate(runs, p0, model="su", free=free, method=method, xatol=1e-12, ftol=1e-14)
        got = np.array([res.values[k] for k in free])
        # 1e-6: the design matrix by differences is exact to ~1e-9 (a linear model), the fits converge to ~1e-8
        np.testing.assert_allclose(got, exact, rtol=1e-6, err_msg=method)
        assert res.method == method and res.converged
        assert res.nvarys == 3 and res.nfree == res.ndata - 3 == sum(r.n for r in runs) - 3


@pytest.fixture(scope="module")
def both():
    """Specimen 2 (the shipped emulator data), SU, one branch, from Table 3 (eta_v0 1 kPa s), by both methods.

    Tolerances tightened (the defaults stop Nelder-Mead at ~5e-7 in the weakly determined eta_v0)."""
    runs = gather_runs([SPECIMEN2])
    start = TABLE3.replace(eta_v0=1e3)
    return runs, {m: calibrate(runs, start, model="su", method=m, xatol=1e-12, ftol=1e-14)
                  for m in ("nelder-mead", "least-squares")}


@pytest.mark.slow
def test_nelder_mead_and_least_squares_agree_on_specimen_2(both):
    _, res = both
    nm, ls = res["nelder-mead"], res["least-squares"]
    assert nm.converged and ls.converged
    # six significant digits: a relative difference below 5e-7
    assert ls.objective == pytest.approx(nm.objective, rel=5e-7, abs=0)
    identifiable = [n for n in nm.free_names if n not in nm.unidentifiable and n not in ls.unidentifiable]
    assert len(identifiable) == 6  # every parameter is identified on these data; none is left out
    for name in identifiable:
        assert ls.values[name] == pytest.approx(nm.values[name], rel=5e-7, abs=0), name
    assert ls.nfev < nm.nfev  # a Gauss-Newton method needs far fewer evaluations, Jacobian evaluations included


def test_the_statistics_have_lmfit_meanings_counted_from_the_datasets(both):
    runs, res = both
    ndata = 0
    for f in sorted(SPECIMEN2.glob("tensile*.nc")):  # the samples the fit can use, counted from the files
        with xr.open_dataset(f, decode_times=False) as ds:  # time in seconds, as open_run gives it
            v = {k: ds[k].values for k in ("time", "stretch", "voltage", "force")}
        ndata += int(np.sum(np.all([np.isfinite(a) for a in v.values()], axis=0) & (v["stretch"] >= 1.0)))
    for r in res.values():
        assert r.ndata == ndata and r.nvarys == len(r.free_names) == 6 and r.nfree == ndata - 6
        assert r.redchi == pytest.approx(r.chisqr / r.nfree, rel=1e-12)
        assert r.aic == pytest.approx(ndata * np.log(r.chisqr / ndata) + 2 * 6, rel=1e-12)
        assert r.bic == pytest.approx(ndata * np.log(r.chisqr / ndata) + np.log(ndata) * 6, rel=1e-12)
        sd = np.sqrt(np.diag(r.covar))  # covar and the standard errors tell the same story
        np.testing.assert_allclose(sd, [r.stderr[n] for n in r.free_names], rtol=1e-12)
        assert r.budgets["max_evals"] == 20000 and "tolerances" in r.budgets
        assert {"rdea-lab", "numpy", "scipy"} <= set(r.versions)


def test_the_objective_builds_the_sets_with_values_would_and_refuses_the_same():
    """The per-evaluation set skips pydantic's revalidation; it must equal the validated one, and be
    refused exactly where validation refuses (random points over the bounds, many of them not physical)."""
    start = TABLE3.replace(branches=TABLE3.branches + (ViscoBranch(k=1e5, eta=1e6),), eta_v0=1e3)
    params = fit_parameters(start, set(values_of(start)))
    obj = Objective([], start, params, "su", "rms", 10, 10.0)
    rng = np.random.default_rng(5)
    refused = 0
    for _ in range(400):
        v = obj.values(rng.uniform(-np.pi / 2, np.pi / 2, len(params)))
        fast = obj.paramset(v)
        try:
            slow = with_values(start, v, start.M)
        except SpecError:
            slow = None
        assert (fast is None) == (slow is None), v
        if slow is None:
            refused += 1
        else:
            assert fast == slow and fast.model_dump() == slow.model_dump()
    assert 0 < refused < 400  # both kinds of point were tried


def test_least_squares_counts_jacobian_evaluations_against_the_budget():
    runs = gather_runs([SPECIMEN2])
    res = calibrate(runs, TABLE3.replace(eta_v0=1e3), model="su", method="least-squares",
                    budget=Budget(evaluations=20))
    assert res.nfev == 20 and res.message == "stopped at the evaluation budget of 20 evaluations"
    assert not res.converged


def test_metric_max_refuses_least_squares_and_marks_what_does_not_apply(tmp_path, capsys):
    with pytest.raises(SpecError, match="least-squares minimizes the rms error only.*allowed with metric max: "
                                        "nelder-mead"):
        calibrate_runs([SPECIMEN2], metric="max", method="least-squares")
    with pytest.raises(SpecError, match="method: 'simplex'; allowed: nelder-mead, least-squares"):
        calibrate_runs([SPECIMEN2], method="simplex")
    rc = run_cli(cli, ["calibrate", str(SPECIMEN2), "--metric", "max", "--method", "least-squares",
                       "--out", str(tmp_path / "x.yaml")])
    err = capsys.readouterr().err
    assert rc == 2 and "--method" in err and "nelder-mead" in err and len(err.strip().splitlines()) == 1, err
    res = calibrate_runs([SPECIMEN2], metric="max", free="C10,C20,C30", init=TABLE3, budget=Budget(evaluations=60))
    res.write(tmp_path / "max.yaml")
    rec = yaml.safe_load((tmp_path / "max.yaml").read_text())["calibration"]
    assert rec["statistics"]["aic"] is None and rec["statistics"]["bic"] is None
    assert rec["covar"] == "not applicable (metric max)" == rec["parameters"]["C10"]["stderr"]
    assert "not applicable" in rec["notes"] and rec["method"] == "nelder-mead"
    assert rec["statistics"]["nfree"] == rec["statistics"]["ndata"] - rec["statistics"]["nvarys"]
    text = res.fit_report()
    assert text.startswith("nelder-mead: ") and "not applicable (metric max)" in text


def test_cli_least_squares_writes_its_method(tmp_path, capsys):
    out = tmp_path / "ls.yaml"
    rc = run_cli(cli, ["calibrate", str(SPECIMEN2),
                       "--init", str(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"),
                       "--method", "least-squares", "--quiet", "--out", str(out)])
    stdout = capsys.readouterr().out
    assert rc == 0, stdout
    assert "least-squares: " in stdout
    rec = yaml.safe_load(out.read_text())["calibration"]
    assert rec["method"] == "least-squares" and rec["budgets"]["max_restarts"] == "not used by least-squares"
    assert rec["parameters"]["C10"]["init_value"] == "242 kPa"
