"""Phase weights and the relaxation spectrum (issue 27).

Independent references: the twin's own force under finite differences (linearity of the SU strip's force
in the Yeoh coefficients and, at fixed time scales, in the branch moduli); a known emulated truth of three
branches on the grid (noise-free: the bounded least squares must find it); an unconstrained least squares
that goes negative (so the non-negativity test can fail); sums and per-decade integrals of weights computed
here from the stated rule; the baseline of a hold that stops relaxing at the end of what was fitted.
"""

from pathlib import Path

import numpy as np
import pytest
import yaml
from vhb_data import needs_vhb

from rdea_lab.calibration import load_run, predict_force
from rdea_lab.calibration.objective import residuals
from rdea_lab.calibration.phases import HOLD, LOADING, UNLOADING, phases, sample_weights
from rdea_lab.calibration.spectrum import design, fit_spectrum, tau_grid
from rdea_lab.specs import ParameterSet, ViscoBranch, load_specimen
from rdea_lab.twin import simulate

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"
YEOH = dict(C10=10e3, C20=-0.3e3, C30=0.03e3, eps_r=2.8)
TAUS = (1.0, 10.0, 100.0)


def truth(law, moduli=(30e3, 10e3, 5e3), taus=TAUS):
    return ParameterSet(name=f"truth-{law}", **YEOH, law=law,
                        branches=tuple(ViscoBranch.of(law, m, m * t) for m, t in zip(moduli, taus)))


def step_hold(rate=0.25, top=2.0, hold=300.0, n_hold=400):
    """Ramp at ``rate`` to ``top`` (50 samples), then a hold sampled log-evenly (times [s], stretches)."""
    t_up = (top - 1.0) / rate
    t = np.r_[np.linspace(0.0, t_up, 50), t_up + np.geomspace(0.05, hold, n_hold)]
    return t, np.minimum(1.0 + rate * t, top)


def loading_unloading(rate=0.05, top=1.5, n=201):
    t_up = (top - 1.0) / rate
    t = np.linspace(0.0, 2 * t_up, n)
    return t, np.maximum(1.0 + rate * np.minimum(t, 2 * t_up - t), 1.0)


def run_of(params, t, lam, name, noise=0.0, seed=0):
    ds = simulate(load_specimen(CARD), params, t, lam, 0.0, model="su")
    if noise:
        f = ds["force"].values
        ds["force"].values = f + noise * np.abs(f).max() * np.random.default_rng(seed).standard_normal(f.size)
    ds.attrs.update({"specimen": CARD.read_text(), "run_id": name, "protocol_name": name})
    return load_run(ds)


# ---- phase weights


def test_phases_and_weights_follow_the_stated_rule():
    """Ramp up 10 s, hold 1000 s, ramp down 10 s, hold 100 s, at 10 Hz: the ramps and each hold weigh
    1/3 (three parts); within the first hold, the decades 1-10 s and 10-100 s after its start weigh the
    same (to one sample cell at each end: 0.1 s of ln-width at most 0.1/1 of a decade's 2.3)."""
    t = np.arange(0.0, 1120.0, 0.1)
    lam = np.interp(t, [0, 10, 1010, 1020, 1120], [1.0, 2.0, 2.0, 1.2, 1.2])
    ph = phases(t, lam)
    assert set(np.unique(ph)) == {LOADING, UNLOADING, HOLD}
    w = sample_weights(t, lam)
    assert w.sum() == pytest.approx(1.0, rel=1e-12)
    assert w[ph != HOLD].sum() == pytest.approx(1 / 3, rel=1e-12)
    first = (ph == HOLD) & (t < 1015)
    assert w[first].sum() == pytest.approx(1 / 3, rel=1e-12)
    assert w[(ph == HOLD) & (t > 1015)].sum() == pytest.approx(1 / 3, rel=1e-12)
    start = t[first][0]
    d1 = w[first & (t - start >= 1) & (t - start < 10)].sum()
    d2 = w[first & (t - start >= 10) & (t - start < 100)].sum()
    assert d1 == pytest.approx(d2, rel=0.05)
    # ramp samples all alike
    assert np.ptp(w[ph != HOLD]) < 1e-15


def test_holds_shorter_than_the_ramps_weigh_as_ramp_samples():
    """Settle 3 s, ramp 20 s, hold 2 s, ramp back 20 s at 10 Hz (the shape of the paper's tensile tests):
    two holds, each shorter than the ramps, so every sample weighs 1/n; stretch that hold to 100 s and it
    weighs as much as the ramps (half the run), the rest of the run alike."""
    def run(hold):
        t = np.arange(0.0, 45.0 + hold, 0.1)
        return t, np.interp(t, [0, 3, 23, 23 + hold, 43 + hold, 45 + hold], [1.0, 1.0, 1.5, 1.5, 1.0, 1.0])
    t, lam = run(2.0)
    assert int(np.sum(phases(t, lam) == HOLD)) > 0
    np.testing.assert_allclose(sample_weights(t, lam), 1.0 / t.size, rtol=1e-12)
    t, lam = run(100.0)
    ph, w = phases(t, lam), sample_weights(t, lam)
    long = (ph == HOLD) & (lam > 1.4)
    rest = ~long
    assert w[long].sum() == pytest.approx(w[ph != HOLD].sum(), rel=1e-12)
    assert np.ptp(w[rest]) < 1e-15


def test_a_run_without_a_hold_keeps_the_old_normalization():
    """e sqrt(n_mean / n) of the objective before holds were weighted, computed here from its definition."""
    p = truth("linear")
    runs = [run_of(p, *loading_unloading(0.05, n=201), "a", noise=0.01),
            run_of(p, *loading_unloading(0.01, n=301), "b", noise=0.01, seed=1)]
    n_mean = np.mean([r.n for r in runs])
    old = np.concatenate([(predict_force(r, p, "su") - r.force) / r.peak * np.sqrt(n_mean / r.n) for r in runs])
    np.testing.assert_allclose(residuals(runs, p, "su"), old, rtol=1e-13, atol=0)


# ---- the spectrum


def test_tau_grid_spans_the_data_at_the_stated_density():
    """10 sample intervals (0.1 s) to one decade past the longest run, 2 per decade: log-even, both ends;
    beyond=0 ends at the run."""
    p = truth("linear")
    t, lam = step_hold(hold=50.0, n_hold=100)
    r = run_of(p, np.arange(0.0, t[-1], 0.01), np.interp(np.arange(0.0, t[-1], 0.01), t, lam), "hold")
    g = tau_grid([r])
    assert g[0] == pytest.approx(0.1, rel=1e-9) and g[-1] == pytest.approx(10 * (r.t[-1] - r.t[0]), rel=1e-12)
    assert tau_grid([r], beyond=0)[-1] == pytest.approx(r.t[-1] - r.t[0], rel=1e-12)
    ratios = g[1:] / g[:-1]
    np.testing.assert_allclose(ratios, ratios[0], rtol=1e-9)
    assert ratios[0] <= 10 ** 0.5 * (1 + 1e-9) and len(g) == int(np.ceil(2 * np.log10(g[-1] / g[0]))) + 1


def test_bad_grid_arguments_are_refused_naming_them():
    from rdea_lab.specs import SpecError

    r = run_of(truth("linear"), *loading_unloading(0.05), "lu")
    with pytest.raises(SpecError, match="per_decade.*time scales > 0"):
        tau_grid([r], per_decade=0)
    with pytest.raises(SpecError, match="beyond.*decades >= 0"):
        tau_grid([r], beyond=-1)


@pytest.mark.parametrize("law", ["linear", "finite_strain"])
def test_force_is_linear_in_yeoh_and_moduli_by_finite_differences(law):
    """The design matrix (the spectrum's premise) against central differences of the twin's force, and
    A x + f0 against the twin's force itself; a finite difference of a linear function is exact up to
    rounding, so two step sizes agree to 1e-6 of the column (the finite-strain kernel's own accuracy,
    2e-9 of the peak, is far below)."""
    p = truth(law)
    run = run_of(p, *step_hold(hold=100.0, n_hold=200), "hold")
    taus = np.array([b.tau for b in p.branches])
    A, f0 = design(run, taus, law, p.eps_r)
    x = np.r_[p.C10, p.C20, p.C30, [b.modulus for b in p.branches], p.eta_v0]
    f = predict_force(run, p, "su")
    assert np.all(f[1:] > 0)  # no slack sample (the first, at stretch 1, carries 0): the clip is not involved
    np.testing.assert_allclose(A @ x + f0, f, rtol=1e-10, atol=1e-12 * f.max())
    names = ["C10", "C20", "C30"]
    for j in range(len(names) + taus.size):
        cols = []
        for rel in (1e-3, 1e-1):
            h = rel * abs(x[j])  # (a tenth of C20 keeps the Yeoh set admissible)

            def moved(sign):
                if j < 3:
                    return p.replace(**{names[j]: getattr(p, names[j]) + sign * h})
                b = p.branches[j - 3]
                m = b.modulus + sign * h
                branches = list(p.branches)
                branches[j - 3] = ViscoBranch.of(law, m, m * b.tau)  # tau fixed
                return p.replace(branches=tuple(branches))

            cols.append((predict_force(run, moved(1), "su") - predict_force(run, moved(-1), "su")) / (2 * h))
        scale = np.abs(A[:, j]).max()
        np.testing.assert_allclose(cols[0], A[:, j], rtol=0, atol=1e-6 * scale)
        np.testing.assert_allclose(cols[1], cols[0], rtol=0, atol=1e-6 * scale)


@pytest.mark.parametrize("law", ["linear", "finite_strain"])
def test_spectrum_recovers_three_known_branches_on_its_grid(law):
    """Noise-free data of a three-branch truth whose time scales lie on the grid: the non-negative least
    squares (strength ~0) finds the truth; moduli to 1e-4 of the largest (the active-set and bvls
    tolerances), the other grid points at 0 to the same, Yeoh to 1e-4."""
    p = truth(law)
    runs = [run_of(p, *step_hold(hold=300.0), "hold"), run_of(p, *loading_unloading(0.05), "lu")]
    grid = np.geomspace(0.1, 1000.0, 9)  # 2 per decade: 1, 10 and 100 s are on it
    res = fit_spectrum(runs, p.replace(C10=8e3), strength=1e-14, taus=grid)
    moduli = np.array(res.spectrum["modulus_Pa"])
    want = np.zeros(grid.size)
    for m, tau in zip((30e3, 10e3, 5e3), TAUS):
        want[np.argmin(np.abs(np.log(grid / tau)))] = m
    np.testing.assert_allclose(moduli, want, rtol=0, atol=1e-4 * 30e3)
    for k in ("C10", "C20", "C30"):
        assert getattr(res.params, k) == pytest.approx(getattr(p, k), abs=1e-4 * p.C10)
    assert res.params.M == 3 and res.objective < 1e-6


def test_spectrum_moduli_are_never_negative_where_unconstrained_ones_would_be():
    """Noisy data of one branch on a grid of 9: the unconstrained least squares (numpy, on the same design)
    has negative moduli, the spectrum none."""
    p = truth("linear", moduli=(20e3,), taus=(10.0,))
    runs = [run_of(p, *step_hold(hold=300.0), "hold", noise=0.02, seed=3),
            run_of(p, *loading_unloading(0.05), "lu", noise=0.02, seed=4)]
    grid = np.geomspace(0.1, 1000.0, 9)
    A = np.vstack([design(r, grid, "linear", p.eps_r)[0] / r.peak for r in runs])
    b = np.concatenate([r.force / r.peak for r in runs])
    free = np.linalg.lstsq(A, b, rcond=None)[0]
    assert np.any(free[3:-1] < 0)
    res = fit_spectrum(runs, p, strength=1e-9, taus=grid)
    assert min(res.spectrum["modulus_Pa"]) >= 0.0 and res.params.eta_v0 >= 0.0
    assert all(b.modulus > 0 for b in res.params.branches)


@pytest.mark.slow
def test_spectrum_from_the_cli_writes_how_it_was_chosen(tmp_path):
    """--viscous-branches spectrum: the record's spectrum section (grid, rule, strength among those tried) and
    the weighting rule; a bad value exits 2 naming the option and what is allowed."""
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli
    from rdea_lab.store import write_dataset

    p = truth("finite_strain")
    for name, (t, lam) in {"hold": step_hold(hold=100.0, n_hold=200), "lu": loading_unloading(0.05)}.items():
        ds = simulate(load_specimen(CARD), p, t, lam, 0.0, model="su")
        ds.attrs.update({"protocol_name": name, "protocol_kind": "tensile", "specimen": CARD.read_text()})
        write_dataset(ds, tmp_path / f"{name}.nc")
    out = tmp_path / "spec.yaml"
    assert run_cli(cli, ["calibrate", str(tmp_path / "hold.nc"), str(tmp_path / "lu.nc"), "--viscous-branches",
                         "spectrum", "--law", "finite_strain", "--quiet", "--out", str(out)]) == 0
    record = yaml.safe_load(out.read_text())["calibration"]
    spec = record["spectrum"]
    assert len(spec["tau_s"]) == len(spec["modulus_Pa"]) >= 3
    assert float(spec["strength"]) in [float(s) for s in spec["cv_scores"]]
    assert "per decade" in record["weighting"]["rule"] and record["weighting"]["holds"]["vhb4910/hold"] == 1


def test_a_bad_branches_value_exits_2_with_one_line(tmp_path, capsys):
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    assert run_cli(cli, ["calibrate", str(tmp_path), "--viscous-branches", "spectra", "--out",
                         str(tmp_path / "x.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--viscous-branches" in err[0] and "0 to 6, auto or spectrum" in err[0]


# ---- the real hold


@pytest.mark.slow
@needs_vhb
def test_vhb_spectrum_predicts_the_unseen_rest_of_the_hold(tmp_path):
    """Fitted on the five loading-unloading files and the first 600 s of relax_2d0, the finite-strain
    spectrum predicts the remaining 1200 s of the hold better than a force that stops relaxing at 600 s
    (the measured force at the end of the fitted part held constant: what a model whose slowest branch
    has relaxed by then predicts at best), and better than two Maxwell branches fitted on the same runs."""
    import benchmarks.vhb_holds as bench  # noqa: PLC0415

    files = bench.imported(tmp_path / "vhb")
    lu = [files[n] for n in files if n != bench.RELAX]
    inputs = lu + [bench.first_part(files[bench.RELAX], bench.SPLIT_AT)]
    run = load_run(files[bench.RELAX])
    late = run.t - run.t[0] > bench.SPLIT_AT
    at_split = run.force[~late][-25:].mean()  # the last half second fitted
    constant = np.sqrt(np.mean((at_split - run.force[late]) ** 2)) / run.peak * 100
    key = f"hold>{bench.SPLIT_AT:g}s"
    spectrum = bench.phase_errors(files[bench.RELAX], bench.fit(inputs, "spectrum:finite_strain").params)[key]
    two = bench.phase_errors(files[bench.RELAX], bench.fit(inputs, "2:finite_strain").params)[key]
    assert spectrum < constant
    assert spectrum < two
