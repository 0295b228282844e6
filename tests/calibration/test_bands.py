"""Prediction bands (issue 27): coverage on a known truth, the ensemble against the delta method, the rule
beyond the calibration envelope, and predict's output without bands."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from scipy.stats import norm

from rdea_lab.calibration import Budget, calibrate_runs, cross_validate, load_run, predict_force
from rdea_lab.calibration.bands import (LEVELS, PARAMETER_ONLY, UNBOUNDED, WIDENED, Uncertainty, coverage,
                                        history_run, misfit_mapping, weighted_quantile)
from rdea_lab.calibration.envelope import Envelope, beyond, flag_axis
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.specs import SpecError, load_params, load_specimen
import rdea_lab.api.accessor  # noqa: F401  (ds.rdea)
from rdea_lab.twin import predict, simulate

ROOT = Path(__file__).resolve().parents[2]
CARD = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml")
GEOM = geometry_from_card(CARD)
# C10 242, C20 -69, C30 47 kPa; one branch 8271 kPa / 86 kPa s (linear law)
TRUE = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")


def triangle(rate=0.03, top=1.5, n=511):
    """A loading-unloading history at ``rate`` [1/s] to ``top``: n samples (odd: one of them at the top)."""
    T = 2 * (top - 1) / rate
    t = np.linspace(0.0, T, n)
    return t, 1.0 + rate * np.minimum(t, T - t)


def twin_run(t, lam, sigma=0.0, seed=0, name="run"):
    """A run dataset the twin made from TRUE at 0 V, with white Gaussian noise of ``sigma`` [N]."""
    f = simulate(GEOM, TRUE, t, lam, np.zeros_like(t), model="su")["force"].values
    f = f + sigma * np.random.default_rng(seed).standard_normal(t.size)
    ds = xr.Dataset({"stretch": ("time", lam), "voltage": ("time", np.zeros_like(t)), "force": ("time", f)},
                    coords={"time": t})
    ds.attrs.update(specimen=CARD.dump(), protocol_name=name, protocol_kind="tensile", run_id=name)
    return ds


def known(names, sd, envelope=None, misfit=None, params=TRUE):
    """An Uncertainty with independent parameters of standard deviations ``sd`` [SI]."""
    return Uncertainty(params, tuple(names), np.diag(np.asarray(sd, float) ** 2), (), misfit, envelope, "test")


@pytest.mark.slow
def test_the_90_percent_band_covers_90_percent_of_a_new_noisy_realization():
    """The truth is the twin itself (TRUE), the noise white and Gaussian, sigma 1 % of the peak force: then
    a 90 % prediction band should hold 90 % of a new measurement's samples, whatever the code. Four repeats
    of one test (all inside each other's envelope), leave-one-out for the misfit, the fit on all four, a
    fifth realization judged. Tolerance: binomial, 3 sigma of the coverage of N_test samples, plus that of
    the misfit quantile learnt from N_cv held-out samples: 3 sqrt(0.09 / N_test + 0.09 / N_cv)."""
    t, lam = triangle()
    sigma = 0.01 * np.max(twin_run(t, lam)["force"].values)
    runs = [twin_run(t, lam, sigma, seed, f"repeat-{seed}") for seed in range(4)]
    kw = {"model": "su", "init": TRUE, "method": "least-squares", "budget": Budget(2000, 60)}
    cv = cross_validate(runs, cv="leave-one-out", **kw)
    misfit = misfit_mapping(cv)
    assert misfit["beyond"] is None and misfit["inside"]["samples"] == 4 * t.size
    unc = Uncertainty.of_fit(calibrate_runs(runs, **kw), misfit)
    new = load_run(twin_run(t, lam, sigma, 99, "new"))
    b = unc.band(new, 0.9)
    got = coverage(new.force, b["lower"], b["upper"])
    tol = 3 * math.sqrt(0.09 / new.n + 0.09 / (4 * t.size))
    assert b["status"] == "bounded" and not b["flags"]
    assert abs(got - 0.9) <= tol, (got, tol)


def test_the_ensemble_mean_is_the_point_prediction_to_first_order():
    """Antithetic draws u* +- d: the odd terms of the force's expansion cancel in the mean, so its distance
    from the point prediction is second order: halving the standard deviations quarters it, while the
    band's half-width (first order) halves."""
    t, lam = triangle(n=201)
    run = history_run(t, lam, 0.0, GEOM)
    names = ["C10", "C20", "C30", "k_v1", "eta_v1"]
    sd = np.array([0.05 * TRUE.C10, 0.05 * abs(TRUE.C20), 0.05 * TRUE.C30, 0.05 * TRUE.branches[0].k,
                   0.05 * TRUE.branches[0].eta])
    dev, half = [], []
    for s in (1.0, 0.5):
        p = known(names, s * sd).parameter_band(run, 0.9, method="ensemble")
        dev.append(np.max(np.abs(p["mean"] - p["force"])))
        half.append(np.median(p["upper"] - p["lower"]) / 2)
    assert dev[0] < 0.05 * half[0]  # the mean sits on the point prediction, far inside the band
    assert dev[0] / dev[1] == pytest.approx(4.0, rel=0.25)  # second order (sampling noise: same seed)
    assert half[0] / half[1] == pytest.approx(2.0, rel=0.1)  # first order


@pytest.mark.slow
def test_delta_and_ensemble_agree_where_the_force_is_linear_in_the_parameters():
    """At 0 V the quasi-static stress is linear in C20, and the fit's asinh variable is linear near zero:
    with C20 = 0 and a standard deviation far below the asinh scale (0.1 C10) the force is linear in the
    drawn variable, so both methods give z sd_F, sd_F = |a| sd with a the force's derivative in C20, here by
    central differences in the test (independent of the code's)."""
    params = TRUE.replace(C20=0.0)
    t, lam = triangle(n=201)
    run = history_run(t, lam, 0.0, GEOM)
    sd = 200.0  # Pa: 0.8 % of the asinh scale
    unc = known(["C20"], [sd], params=params)
    h = 10.0
    a = (predict_force(run, params.replace(C20=h), "su") - predict_force(run, params.replace(C20=-h), "su")) / (2 * h)
    sd_f = np.abs(a) * sd
    half_ref = norm.ppf(0.95) * sd_f
    d = unc.parameter_band(run, 0.9, method="delta")
    e = unc.parameter_band(run, 0.9, method="ensemble", draws=2000)
    moving = sd_f > 0.05 * sd_f.max()
    np.testing.assert_allclose((d["upper"] - d["lower"])[moving] / 2, half_ref[moving], rtol=1e-3)
    # the 95th percentile of 2000 normal draws: standard error sqrt(0.05 * 0.95 / 2000) / phi(1.645) = 0.047 sd,
    # 2.9 % of the half-width 1.645 sd (antithetic: both sides the same); 4 standard errors
    np.testing.assert_allclose((e["upper"] - e["lower"])[moving] / 2, half_ref[moving], rtol=0.12)


ENV = Envelope(stretch=(1.0, 1.5), rate=(0.02, 0.04), voltage=(0.0, 0.0), hold=0.0, runs=("a",))


def misfit(inside, beyond=None):
    """A misfit section whose quantiles are ``inside`` (and ``beyond``) times the level (a hand-made one)."""
    stats = lambda f: None if f is None else {"runs": ["x"], "samples": 1000,  # noqa: E731
                                             "quantiles": [f * q for q in LEVELS]}
    return {"levels": list(LEVELS), "inside": stats(inside), "beyond": stats(beyond)}


def test_inside_the_envelope_the_misfit_term_adds_in_quadrature():
    t, lam = triangle(n=201)
    run = history_run(t, lam, 0.0, GEOM)
    unc = known(["C10"], [0.01 * TRUE.C10], ENV, misfit(0.05))
    b, p = unc.band(run, 0.9), unc.parameter_band(run, 0.9)
    m = 0.05 * 0.9 * np.max(np.abs(p["force"]))  # the quantile at 0.9 times the predicted peak [N]
    assert b["status"] == "bounded" and b["misfit_rel"] == pytest.approx(0.045)
    np.testing.assert_allclose(b["upper"] - p["force"], np.hypot(p["upper"] - p["force"], m), rtol=1e-12)
    np.testing.assert_allclose(p["force"] - b["lower"], np.hypot(p["force"] - p["lower"], m), rtol=1e-12)


def test_beyond_the_envelope_the_band_widens_or_is_unbounded():
    t, lam = triangle(top=2.0, n=201)  # stretch 2.0 beyond the calibrated 1.5
    run = history_run(t, lam, 0.0, GEOM)
    wide = known(["C10"], [0.01 * TRUE.C10], ENV, misfit(0.05, beyond=0.3)).band(run, 0.9)
    assert wide["status"] == WIDENED and wide["misfit_rel"] == pytest.approx(0.27)
    assert wide["flags"] == ("stretch 2.0 beyond the calibrated 1.5",)
    for m in (misfit(0.05), None):  # no fold extrapolated; no cross-validation at all
        b = known(["C10"], [0.01 * TRUE.C10], ENV, m).band(run, 0.9)
        assert b["status"] == UNBOUNDED and math.isinf(b["misfit_rel"]) and "unbounded" in b["detail"]
        lo, hi = np.full(run.n, -np.inf), np.full(run.n, np.inf)  # what add_to writes for it
        assert math.isnan(coverage(run.stretch, lo, hi))  # no coverage claimed for an unbounded band
    ds = predict((t, lam, 0.0), TRUE, specimen=GEOM, bands=0.9, uncertainty=known(["C10"], [1e3], ENV, None))
    assert np.isneginf(ds["force_lower"].values).all() and np.isposinf(ds["force_upper"].values).all()
    assert ds.attrs["band_status"] == UNBOUNDED and "stretch 2.0" in ds.attrs["band_beyond_calibration"]


def test_a_run_beyond_learns_only_from_folds_that_extrapolated_the_same_way():
    """Stretch 2.0 beyond the calibrated 1.5: a held-out run that extrapolated only in hold time says
    nothing of it (unbounded); one that extrapolated in stretch (and rate) does (widened, its quantile)."""
    t, lam = triangle(top=2.0, n=201)
    run = history_run(t, lam, 0.0, GEOM)
    m = misfit(0.05, beyond=0.3)
    group = lambda axes, f: {"axes": axes, **misfit(0.05, beyond=f)["beyond"]}  # noqa: E731
    m["beyond_by_axes"] = [group(["hold"], 0.3)]
    b = known(["C10"], [0.01 * TRUE.C10], ENV, m).band(run, 0.9)
    assert b["status"] == UNBOUNDED and "along stretch" in b["detail"]
    m["beyond_by_axes"] = [group(["hold"], 0.3), group(["rate", "stretch"], 0.1)]
    b = known(["C10"], [0.01 * TRUE.C10], ENV, m).band(run, 0.9)
    assert b["status"] == WIDENED and b["misfit_rel"] == pytest.approx(0.09)


def test_each_kind_of_flag_names_its_axis():
    """Envelopes made by hand, each left along one axis or in one combination only."""
    pts = ((("loading", 1.4, 0.05, 0.0),))
    c = Envelope(stretch=(1.0, 3.0), rate=(0.01, 0.05), voltage=(0.0, 0.0), hold=10.0, runs=("a",), points=pts)
    cases = {"stretch": dataclasses.replace(c, stretch=(1.0, 4.0), points=()),
             "rate": dataclasses.replace(c, rate=(0.01, 0.5), points=()),
             "voltage": dataclasses.replace(c, voltage=(0.0, 2600.0), points=()),
             "hold": dataclasses.replace(c, hold=600.0, points=()),
             "stretch-rate": dataclasses.replace(c, points=(("loading", 2.9, 0.01, 0.0),))}
    for axis, run in cases.items():
        flags = beyond(c, run)
        assert flags and {flag_axis(f) for f in flags} == {axis}, (axis, flags)


def test_without_cross_validation_inside_the_band_is_parameter_only():
    t, lam = triangle(n=101)
    b = known(["C10"], [0.01 * TRUE.C10], ENV, None).band(history_run(t, lam, 0.0, GEOM), 0.9)
    assert b["status"] == PARAMETER_ONLY and "no cross-validation" in b["detail"]


def test_bands_none_leaves_predict_unchanged_and_bands_add_two_cf_variables():
    t, lam = triangle(n=101)
    plain = predict((t, lam, 0.0), TRUE, specimen=GEOM)
    again = predict((t, lam, 0.0), TRUE, specimen=GEOM, bands=None)
    assert list(again.variables) == list(plain.variables)
    for name in plain.data_vars:  # the same values and attributes (the time of creation aside)
        xr.testing.assert_identical(again[name].variable, plain[name].variable)
    np.testing.assert_array_equal(again["time"].values, plain["time"].values)
    assert set(again.attrs) == set(plain.attrs)
    banded = predict((t, lam, 0.0), TRUE, specimen=GEOM, bands=0.9,
                     uncertainty=known(["C10"], [0.01 * TRUE.C10], ENV, misfit(0.05)))
    assert set(banded.data_vars) - set(plain.data_vars) == {"force_lower", "force_upper"}
    xr.testing.assert_identical(banded["force"].variable, plain["force"].variable)  # time: its creation stamp
    for name in ("force_lower", "force_upper"):
        assert banded[name].attrs["units"] == "N" and "90 % prediction band" in banded[name].attrs["long_name"]
    assert (banded["force_lower"] <= banded["force"]).all() and (banded["force"] <= banded["force_upper"]).all()
    assert all(v is not None for v in banded.attrs.values()) and banded.attrs["band_level"] == 0.9


def test_bad_levels_and_a_band_without_uncertainty_are_refused():
    t, lam = triangle(n=51)
    unc = known(["C10"], [1e3], ENV, None)
    for level in (1.5, 0.0, True, "0.9"):
        with pytest.raises(SpecError, match=r"^arguments: bands: .*allowed: a nominal level from 0.05 to 0.99"):
            predict((t, lam, 0.0), TRUE, specimen=GEOM, bands=level, uncertainty=unc)
    with pytest.raises(SpecError, match=r"^arguments: uncertainty: required with bands"):
        predict((t, lam, 0.0), TRUE, specimen=GEOM, bands=0.9)


def test_weighted_quantiles_with_equal_weights_are_numpys_hazen_percentiles():
    x = np.random.default_rng(3).standard_normal(101)
    q = np.array([0.05, 0.5, 0.9])
    np.testing.assert_allclose(weighted_quantile(x, np.ones_like(x), q), np.quantile(x, q, method="hazen"))
    # two runs weighted equally: a run of 1 sample at 10 weighs as much as 99 samples at 0
    assert weighted_quantile(np.r_[np.zeros(99), 10.0], np.r_[np.full(99, 1 / 99), 1.0], 0.9) == 10.0


@pytest.mark.slow
def test_a_holdout_record_carries_the_misfit_and_reads_back_as_the_fits_uncertainty(tmp_path):
    """``calibrate --holdout`` writes the held-out errors' quantiles into the record; the band read from the
    record has the fit's covariance (to the record's 6 digits) and that misfit."""
    t, lam = triangle(n=201)
    sigma = 0.01 * np.max(twin_run(t, lam)["force"].values)
    runs = [twin_run(t, lam, sigma, seed, f"repeat-{seed}") for seed in range(3)]
    cv = cross_validate(runs, holdout=[runs[2]], out=tmp_path / "cal.yaml", model="su", init=TRUE,
                        method="least-squares", budget=Budget(2000, 60))
    res = cv.folds[0].result
    unc = Uncertainty.of_record(tmp_path / "cal.yaml")
    assert unc.names == res.free_names and not unc.missing
    np.testing.assert_allclose(unc.covar, res.covar, rtol=1e-5)
    held = np.abs(cv.folds[0].residuals["<dataset repeat-2>"])
    q90 = unc.misfit["inside"]["quantiles"][LEVELS.index(0.9)]
    assert q90 == pytest.approx(np.quantile(held, 0.9, method="hazen"), rel=1e-5)  # one run: plain quantiles
    assert unc.envelope is not None and unc.envelope.stretch[1] == pytest.approx(1.5)
    ds = runs[2].rdea.predict(str(tmp_path / "cal.yaml"), bands=0.9)
    assert ds.attrs["band_status"] == "bounded" and ds.attrs["band_misfit_rel"] == pytest.approx(q90, rel=1e-6)


def test_the_report_refuses_bad_band_levels_and_parameters_without_a_record(tmp_path, capsys):
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    args = ["report", "validation", "--params", str(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"),
            "--datasets", str(ROOT / "datasets" / "paper2021"), "--out", str(tmp_path / "r")]
    for extra, said in ((["--bands", "1.5"], "bands: 1.5; allowed: a nominal level from 0.05 to 0.99"),
                        (["--bands", "0.9"], "calibration: no calibration record; allowed: a parameter file")):
        assert run_cli(cli, args + extra) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], err
        assert not (tmp_path / "r").exists()


def _cf_checkers():
    """tests/store/test_cf.py's two external CF checkers (IOOS compliance-checker, cfchecker)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("_cf", ROOT / "tests" / "store" / "test_cf.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.ioos, module.cfchecks


@pytest.mark.slow
@pytest.mark.parametrize("checker", ["ioos", "cfchecker"])
@pytest.mark.parametrize("top", [1.5, 2.0])  # a bounded band; an unbounded one (+-inf, beyond the envelope)
def test_a_banded_prediction_passes_the_cf_checkers(tmp_path, top, checker):
    ioos, cfchecks = _cf_checkers()
    t, lam = triangle(top=top, n=101)
    ds = predict((t, lam, 0.0), TRUE, specimen=GEOM, bands=0.9,
                 uncertainty=known(["C10"], [0.01 * TRUE.C10], ENV, misfit(0.05)))
    assert ds.attrs["band_status"] == ("bounded" if top == 1.5 else UNBOUNDED)
    ds.to_netcdf(tmp_path / "banded.nc")
    if checker == "ioos":
        assert ioos(tmp_path / "banded.nc") == {"high": [], "medium": [], "low": [], "exceptions": []}
    else:
        found = cfchecks(tmp_path / "banded.nc")  # skips where UDUNITS-2 is missing
        assert not found["FATAL"] and not found["ERROR"] and not found["WARN"], found


@pytest.mark.slow
def test_the_validation_report_gives_each_runs_coverage_and_marks_the_unbounded(tmp_path):
    """A holdout record fitted on three noisy repeats (one held out: the misfit), then the report on the
    folder with a fourth, new realization (inside: coverage 0.9 within the binomial tolerance of the
    coverage test above) and a run to stretch 2.0 (beyond the calibrated 1.5, no fold extrapolated:
    unbounded, no coverage claimed)."""
    from rdea_lab.reports.validation import validation_report

    t, lam = triangle()
    sigma = 0.01 * np.max(twin_run(t, lam)["force"].values)
    folder = tmp_path / "runs"
    folder.mkdir()
    paths = []
    for seed, (tt, ll) in enumerate([(t, lam)] * 4 + [triangle(top=2.0)]):
        ds = twin_run(tt, ll, sigma, seed, f"run-{seed}")
        ds.attrs["status"] = "complete"
        paths.append(folder / f"run-{seed}.nc")
        ds.to_netcdf(paths[-1])
    cv = cross_validate([str(p) for p in paths[:3]], holdout=[str(paths[2])], out=tmp_path / "cal.yaml",
                        model="su", init=TRUE, method="least-squares", budget=Budget(2000, 60))
    assert cv.folds[0].residuals
    report = validation_report(tmp_path / "cal.yaml", folder, bands=0.9)
    rows = {r["name"]: r for r in report.rows}
    new = rows["run-3"]
    assert new["band_status"] == "bounded" and new["band_level"] == 0.9
    assert abs(new["band_coverage"] - 0.9) <= 3 * math.sqrt(0.09 / t.size + 0.09 / t.size), new["band_coverage"]
    far = rows["run-4"]
    assert far["band_status"] == UNBOUNDED and math.isnan(far["band_coverage"])
    assert "band coverage" in report.markdown and "90 % prediction band" in report.legend
    files = report.write(tmp_path / "out", pdf=False)
    assert "band_coverage" in files["csv"].read_text().splitlines()[0]


def test_the_run_figure_shades_a_band_and_says_when_it_is_unbounded():
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    from rdea_lab.reports.plots import plot_run

    t, lam = triangle(n=101)
    run = twin_run(t, lam, 0.0)
    run["position"] = ("time", (lam - 1.0) * GEOM.L1)
    run["capacitance"] = ("time", np.full(t.size, np.nan))
    for env, shaded in ((ENV, True), (Envelope((1.0, 1.2), (0.02, 0.04), (0.0, 0.0), 0.0, ("a",)), False)):
        pred = predict(run, TRUE, bands=0.9, uncertainty=known(["C10"], [0.01 * TRUE.C10], env, misfit(0.05)))
        ax = Figure().add_subplot()
        plot_run(run, ax=ax, prediction=pred)
        bands = [c for c in ax.collections if isinstance(c, PolyCollection)]
        assert bool(bands) == shaded
        if shaded:
            assert bands[0].get_label() == "90 % band"
        else:
            assert any("band unbounded" in tx.get_text() for tx in ax.texts)


@pytest.mark.slow
def test_a_cross_validations_misfit_goes_into_a_record_of_the_full_fit(tmp_path):
    from rdea_lab.calibration.bands import add_misfit

    t, lam = triangle(n=201)
    sigma = 0.01 * np.max(twin_run(t, lam)["force"].values)
    folder = tmp_path / "runs"
    folder.mkdir()
    for seed in range(3):
        ds = twin_run(t, lam, sigma, seed, f"run-{seed}")
        ds.attrs["status"] = "complete"
        ds.to_netcdf(folder / f"run-{seed}.nc")
    kw = {"model": "su", "init": TRUE, "method": "least-squares", "budget": Budget(2000, 60)}
    full = calibrate_runs(str(folder), **kw)
    full.write(tmp_path / "cal.yaml")
    assert Uncertainty.of_record(tmp_path / "cal.yaml").misfit is None
    cv = cross_validate(str(folder), cv="leave-one-out", **kw)
    add_misfit(tmp_path / "cal.yaml", cv)
    unc = Uncertainty.of_record(tmp_path / "cal.yaml")
    assert unc.misfit["inside"]["runs"] == ["run-0.nc", "run-1.nc", "run-2.nc"]
    assert unc.envelope is not None  # from the fitted files, still there with their sha256
    b = unc.band(load_run(folder / "run-0.nc"), 0.9)
    assert b["status"] == "bounded" and not b["flags"]
