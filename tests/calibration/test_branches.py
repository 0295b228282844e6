"""The branch count chosen by the data (`calibrate_auto`), and Nelder-Mead's least-squares warm start."""

from pathlib import Path

import numpy as np
import pytest

from rdea_lab.calibration import calibrate, calibrate_runs, initial_guess
from rdea_lab.calibration.branches import calibrate_auto, criterion, effective_samples
from rdea_lab.calibration.objective import RunData
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.protocols import load_plan
from rdea_lab.specs import SpecError, ViscoBranch, load_params, load_specimen
from rdea_lab.twin import simulate

ROOT = Path(__file__).resolve().parents[2]
TABLE3 = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
#: two time scales a decade and a half apart, each well inside the runs (0.01 s samples... 54 s long)
TWO = TABLE3.replace(branches=(ViscoBranch(k=300e3, eta=300e3 * 0.3), ViscoBranch(k=100e3, eta=100e3 * 15.0)),
                     eta_v0=0.0)
ONE = TWO.replace(branches=TWO.branches[:1])


def twin_runs(params, noise=4e-3, seed=1, every=4):
    """The paper's two tensile tests on specimen 2 made by the twin (SU) on every ``every``-th sample of the
    plan, with white force noise [N] (the emulated rig's 4 mN)."""
    card = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
    geom = geometry_from_card(card)
    rng = np.random.default_rng(seed)
    runs = []
    for name in ("tensile_ramp_sine_0V", "tensile_ramp_sine_2.6kV"):
        plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / f"{name}.yaml")
        t, lam, v = plan.time[::every], plan.stretch[::every].copy(), plan.voltage[::every].copy()
        force = simulate(geom, params, t, lam, v, model="su")["force"].values + noise * rng.standard_normal(t.size)
        runs.append(RunData(Path(f"<{name}>"), "", name, "tensile", card.id, geom, t, lam, v, force,
                            float(np.max(np.abs(force)))))
    return runs


def test_effective_samples_of_white_noise_and_a_smooth_misfit():
    rng = np.random.default_rng(0)
    n = 200_000
    white = rng.standard_normal(n)
    # white noise: every sample counts; Geyer's sum stops within a few lags (spread ~ sqrt(4 m / n) ~ 1 %)
    assert effective_samples([white]) == pytest.approx(n, rel=0.04)
    smooth = np.sin(np.linspace(0, 3, 1000))  # a smooth misfit: next to nothing independent
    assert effective_samples([smooth]) < 5
    assert effective_samples([white[:1000], smooth]) == pytest.approx(1000 + effective_samples([smooth]), rel=0.1)


@pytest.mark.slow  # 2 s: two million samples, for a spread of the estimate well below the tolerance
def test_effective_samples_of_an_ar1_series_are_its_textbook_value():
    from scipy.signal import lfilter

    from rdea_lab.calibration.branches import autocorrelation_time

    n = 2_000_000
    white = np.random.default_rng(0).standard_normal(n)
    rho = 0.9  # AR(1): x_t = rho x_{t-1} + e_t, tau = (1 + rho) / (1 - rho) = 19 samples
    x = lfilter([1.0], [1.0, -rho], white)
    # the estimate's relative spread is about sqrt(4 m / n) with m ~ 100 lags summed: 1.4 %; 5 % is > 3 of it
    assert autocorrelation_time(x) == pytest.approx((1 + rho) / (1 - rho), rel=0.05)
    assert effective_samples([x]) == pytest.approx(n * (1 - rho) / (1 + rho), rel=0.05)


def test_criterion_is_the_bic_with_n_eff_in_place_of_n():
    # BIC = n ln(chisqr / n) + k ln(n) (lmfit's definition) when n_eff = n
    assert criterion(2.0, 100, 3, 100.0) == pytest.approx(100 * np.log(0.02) + 3 * np.log(100))
    assert criterion(2.0, 100, 3, 10.0) == pytest.approx(10 * np.log(0.02) + 3 * np.log(10))


@pytest.mark.slow  # two growths to M = 3 and M = 2 (least squares): 60 s here unloaded, 300 s on a busy machine
def test_auto_picks_the_number_of_branches_of_the_truth():
    """Noisy twin data from a truth with two time scales (0.3 s, 15 s) and from one with only the first:
    auto picks 2 and 1 (white residuals at the true M, so n_eff = n and the criterion is the BIC); it
    tries one more and says why it stopped."""
    for truth, want in ((TWO, 2), (ONE, 1)):
        runs = twin_runs(truth)
        res = calibrate_auto(runs, initial_guess(runs, 1, 2.8), model="su", method="least-squares")
        choice = res.branch_choice
        assert choice["chosen"] == want == res.params.M, choice["reason"]
        assert [t["M"] for t in choice["tried"]] == list(range(want + 2))  # up to the first that did not improve
        crit = [t["criterion"] for t in choice["tried"]]
        assert crit[want] == min(crit) and f"M = {want + 1} did not lower it" in choice["reason"]
        assert choice["n_eff"] > 0.5 * choice["ndata"]  # white noise left: nearly every sample counts
        # each time scale found is nearer (in log) its own true one than any other: both were found (their
        # precision on noise-free data is test_fit's growth test)
        taus = np.log(sorted(b.tau for b in res.params.branches))
        true_taus = np.log(sorted(b.tau for b in truth.branches))
        for i, tau in enumerate(taus):
            assert np.argmin(np.abs(true_taus - tau)) == i


def test_auto_refuses_metric_max_and_a_bad_count(tmp_path, capsys):
    runs = twin_runs(ONE, every=20)
    with pytest.raises(ValueError, match="metric 'max'"):
        calibrate_auto(runs, initial_guess(runs, 1, 2.8), metric="max")
    with pytest.raises(ValueError, match="max_branches 7"):
        calibrate_auto(runs, initial_guess(runs, 1, 2.8), 7)
    ds = simulate(runs[0].geom, ONE, runs[0].t, runs[0].stretch, runs[0].voltage, model="su")
    ds.attrs["specimen"] = (ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml").read_text()
    for branches, metric in (("many", "rms"), ("auto", "max")):
        with pytest.raises(SpecError, match="branches.*auto"):
            calibrate_runs(ds, branches=branches, metric=metric)
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    rc = run_cli(cli, ["calibrate", str(tmp_path), "--viscous-branches", "many", "--out", str(tmp_path / "x.yaml")])
    err = capsys.readouterr().err
    assert rc == 2 and "--viscous-branches" in err and "auto" in err, err


@pytest.mark.slow  # ~5 s: Nelder-Mead from the start as in the paper, and polished from least squares
def test_nelder_mead_polish_reaches_the_noise_free_optimum_the_truth():
    """Noise-free twin data (one branch, the truth known): Nelder-Mead warm-started by least squares ends on
    the truth (1e-6: the polish's tolerances are 1e-9 in the variables), as least squares alone does, and
    in fewer evaluations than Nelder-Mead from the start."""
    runs = twin_runs(ONE, noise=0.0)
    start = ONE.replace(C10=3 * ONE.C10, C20=ONE.C20 / 3, C30=3 * ONE.C30,
                        branches=(ViscoBranch(k=ONE.branches[0].k / 3, eta=3 * ONE.branches[0].eta),))
    free = ["C10", "C20", "C30", "k_v1", "eta_v1"]
    warm = calibrate(runs, start, model="su", free=free)
    lsq = calibrate(runs, start, model="su", free=free, method="least-squares")
    plain = calibrate(runs, start, model="su", free=free, warm_start="none")
    assert warm.method == "nelder-mead" and warm.converged and warm.warm_start.startswith("least-squares start, ")
    truth = {"C10": ONE.C10, "C20": ONE.C20, "C30": ONE.C30, "k_v1": ONE.branches[0].k, "eta_v1": ONE.branches[0].eta}
    for name, value in truth.items():
        assert warm.values[name] == pytest.approx(value, rel=1e-6), name
        assert lsq.values[name] == pytest.approx(value, rel=1e-6), name
    assert warm.objective <= lsq.objective * (1 + 1e-9) + 1e-14
    assert warm.nfev < plain.nfev
    n_lsq = int(warm.warm_start.split(", ")[1].split()[0])
    assert n_lsq == lsq.nfev  # the same least squares from the same start, then the polish
    with pytest.raises(ValueError, match="warm_start"):
        calibrate(runs, start, model="su", metric="max", warm_start="least-squares")
