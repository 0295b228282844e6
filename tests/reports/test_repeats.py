"""Repeat spread (issue 27): how much two measurements of one test differ, against known noise.

The reference is independent of the code: two records that differ only by white noise of standard deviation
s each differ by s * sqrt(2) rms; a prediction equal to the noiseless signal is off by s rms, so its ratio to
the repeat spread is 1 / sqrt(2).
"""

import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from rdea_lab.reports.repeats import add_repeats, columns_for, pair_difference, repeat_lines
from rdea_lab.reports.validation import COLUMNS, CSV_KEYS

ROOT = Path(__file__).resolve().parents[2]
TABLE3 = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
#: 2 x 5 s ramps up and 2 x 5 s down at 100 Hz: 2001 samples
PROTOCOL = """name: repeat_ramp
kind: tensile
description: a ramp up and down, twice, for the repeat checks
sample_rate: 100 Hz
measure: [force]
limits: {max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}
stretch:
  - {kind: ramp, duration: 5 s, to: 1.3}
  - {kind: ramp, duration: 5 s, to: 1.0}
  - {kind: ramp, duration: 5 s, to: 1.3}
  - {kind: ramp, duration: 5 s, to: 1.0}
voltage:
  - {kind: hold, duration: 20 s, value: 0 V}
"""


def rel_sigma(n: int) -> float:
    """Relative standard deviation of an rms estimated from n independent Gaussian samples: 1 / sqrt(2 n)."""
    return 1.0 / math.sqrt(2 * n)


def test_two_noisy_records_differ_by_s_sqrt2_whatever_their_start_and_sampling():
    """Run b starts at t = 5 s and samples twice as often (a's times are among b's once each is counted from
    its first sample, so interpolation adds nothing) and lasts 8 s less: the difference is measured over a's
    first 32 s, and is the noise's s * sqrt(2)."""
    rng = np.random.default_rng(7)
    s, signal = 0.01, lambda t: np.sin(0.3 * t) + 0.1 * t
    ta = np.arange(0.0, 40.0, 0.01)
    tb = 5.0 + np.arange(0.0, 32.0 + 1e-9, 0.005)
    ya = signal(ta) + s * rng.standard_normal(ta.size)
    yb = signal(tb - 5.0) + s * rng.standard_normal(tb.size)
    n = int(np.sum(ta <= 32.0 + 1e-9))
    assert pair_difference(ta, ya, tb, yb) == pytest.approx(s * math.sqrt(2), rel=4 * rel_sigma(n))
    # the same records without noise: nothing
    assert pair_difference(ta, signal(ta), tb, signal(tb - 5.0)) == pytest.approx(0.0, abs=1e-9)


def _evaluated(name, test, t, force, pred):
    peak = float(np.max(np.abs(force)))
    rms = float(np.sqrt(np.mean((pred - force) ** 2))) / peak
    return {"row": {"name": name, "test": test, "quantity": "force", "peak": peak, "rms_rel_error": rms},
            "series": {"t": t, "force": force, "cap_mask": np.zeros(t.size, bool)}}


def test_only_runs_of_one_test_are_repeats_and_a_perfect_model_is_within_them():
    """Three runs of test A (noise s each on one signal), one of test B, one simulation (no test): A's runs
    get a spread of s * sqrt(2) / peak and, predicted by the signal itself, a ratio of 1 / sqrt(2); B and
    the simulation get none."""
    rng = np.random.default_rng(11)
    s, t = 0.02, np.arange(0.0, 20.0, 0.01)
    signal = 1.0 + np.sin(t)
    a = [_evaluated(f"a{k}", "A", t, signal + s * rng.standard_normal(t.size), signal) for k in range(3)]
    others = [_evaluated("b", "B", t, signal + s * rng.standard_normal(t.size), signal),
              _evaluated("sim", "", t, signal, signal)]
    (group,) = add_repeats(a + others)
    assert group["test"] == "A" and group["runs"] == ["a0", "a1", "a2"] and group["within"]
    tol = 4 * rel_sigma(2 * t.size)  # each spread pools two pairs
    for e in a:
        r = e["row"]
        assert r["repeat_spread"] == pytest.approx(s * math.sqrt(2) / r["peak"], rel=tol)
        assert r["rms_over_spread"] == pytest.approx(1 / math.sqrt(2), rel=2 * tol)
    assert a[0]["row"]["repeats"] == "a1, a2"
    assert all(e["row"]["repeats"] == "" and e["row"]["repeat_spread"] is None for e in others)
    (line,) = repeat_lines((group,))
    assert line.startswith("A: 3 runs") and line.endswith("the twin is within the measurement's own repeatability.")
    # the table shows the columns only when some run has a repeat
    assert [k for k, _, _ in columns_for(COLUMNS, [e["row"] for e in a])][-3:] == [
        "repeat_spread", "rms_over_spread", "notes"]
    assert columns_for(COLUMNS, [e["row"] for e in others]) == COLUMNS
    # a model 3 s off everywhere is not within them
    worse = [_evaluated(f"w{k}", "W", t, signal + s * rng.standard_normal(t.size), signal + 3 * s) for k in range(2)]
    (bad,) = add_repeats(worse)
    assert not bad["within"] and all(x > 1 for x in bad["ratio"])
    assert "not within" in repeat_lines((bad,))[0]


@pytest.fixture(scope="module")
def emulated(tmp_path_factory):
    """Two emulator runs of one protocol on one specimen, noise seeds 1 and 2."""
    import rdea_lab

    folder = tmp_path_factory.mktemp("repeats")
    protocol = folder / "repeat_ramp.yaml"
    protocol.write_text(PROTOCOL)
    for k in (1, 2):
        rdea_lab.run_protocol(protocol, CARD, "emulator", out=folder / "runs" / f"seed{k}.nc", seed=k)
    return folder / "runs"


@pytest.mark.slow
def test_the_report_gives_the_emulated_repeat_spread_the_truth_implies(emulated, tmp_path):
    """The truth's load cell (truth/paper2021.yaml): force noise 4 mN, white and independent between seeds;
    its offset, drift, lag and physics are the same in both runs. So the spread is 4 mN * sqrt(2) / peak."""
    from rdea_lab.reports.validation import validation_report
    from rdea_lab.specs.truth import load_truth

    s = load_truth(ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml").instrument.force_noise
    assert s == pytest.approx(4e-3)
    report = validation_report(TABLE3, emulated)
    (group,) = report.repeats
    assert group["runs"] == ["seed1", "seed2"]
    for r in report.rows:
        assert r["repeats"] == {"seed1": "seed2", "seed2": "seed1"}[r["name"]]
        assert r["repeat_spread"] == pytest.approx(s * math.sqrt(2) / r["peak"], rel=4 * rel_sigma(r["samples"]))
        assert r["rms_over_spread"] == pytest.approx(r["rms_rel_error"] / r["repeat_spread"], rel=1e-12)
    assert "repeat spread [%]" in report.markdown and "Repeat spread:" in report.legend
    files = report.write(tmp_path / "out", figures=False)
    assert "Repeats:" in files["markdown"].read_text()
    html = files["html"].read_text()
    assert "Repeats: the measurement" in html and "rms / repeat spread" in html
    assert set(CSV_KEYS) >= {"test", "repeats", "repeat_spread", "rms_over_spread"}


@pytest.mark.slow
def test_a_twin_equal_to_the_noiseless_signal_is_within_the_repeatability(emulated, tmp_path):
    """The two runs' forces replaced by the twin's own prediction (SU, Table 3, on their measured stretch)
    plus white noise of 20 mN (seeds 5 and 6): the report's twin is then the noiseless signal, off by the
    noise alone, and the ratio is 1 / sqrt(2)."""
    from rdea_lab.calibration import load_run
    from rdea_lab.reports.validation import validation_report
    from rdea_lab.twin import predict

    s, folder = 0.02, tmp_path / "runs"
    folder.mkdir()
    for k, path in enumerate(sorted(emulated.glob("*.nc")), start=5):
        run = load_run(path)
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        twin = predict({"time": run.t, "stretch": run.stretch, "voltage": run.voltage}, TABLE3, "su",
                       specimen=run.geom)["force"].values
        force = ds["force"].values.copy()
        force[run.index] = twin + s * np.random.default_rng(k).standard_normal(run.n)
        ds["force"].values = force
        ds.to_netcdf(folder / path.name)
    report = validation_report(TABLE3, folder)
    (group,) = report.repeats
    assert group["within"]
    for r in report.rows:
        assert r["rms_over_spread"] == pytest.approx(1 / math.sqrt(2), rel=8 * rel_sigma(r["samples"]))
