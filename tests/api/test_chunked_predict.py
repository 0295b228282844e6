"""``ds.rdea.predict`` block by block (predict_blocks, out=PATH) against the one-shot prediction, and the error
measures accumulated over blocks against the whole-array ones."""

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import rdea_lab.api.accessor  # noqa: F401 (registers ds.rdea)
from rdea_lab.reports.errors import ErrorAccumulator, long_run_errors
from rdea_lab.reports.validation import compare
from rdea_lab.specs import SpecError
from rdea_lab.store import open_run
from rdea_lab.twin import predict
from rdea_lab.twin.predict import predict_blocks

ROOT = Path(__file__).resolve().parents[2]
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
RUN = ROOT / "datasets" / "paper2021" / "specimen-2" / "blocking_force.nc"
FLOATS = ("force", "capacitance", "sigma1", "sigma1_irr", "lambda2b")


@pytest.fixture(scope="module")
def run():
    """The first 2000 samples of a measured blocking run (voltage steps: the branches relax between them)."""
    return open_run(RUN).isel(time=slice(0, 2000)).load()


def random_sizes(n, rng, largest):
    sizes = []
    while sum(sizes) < n:
        sizes.append(int(min(rng.integers(1, largest), n - sum(sizes))))
    return sizes


def joined(blocks):
    parts = {}
    for _, _, data in blocks:
        for k, v in data.items():
            parts.setdefault(k, []).append(v)
    return {k: np.concatenate(v) for k, v in parts.items()}


def assert_same(got, one):
    """Floats to 1e-12 of each variable's largest magnitude (rounding in the branch update, ~1e-16 relative);
    status codes exactly."""
    for k in FLOATS:
        ref = one[k].values
        np.testing.assert_allclose(got[k], ref, rtol=1e-12, atol=1e-12 * np.nanmax(np.abs(ref)), err_msg=k)
    for k in ("converged", "model_status"):
        np.testing.assert_array_equal(got[k], one[k].values, err_msg=k)
    np.testing.assert_array_equal(got["time"], one["time"].values)


def test_blocks_of_random_sizes_join_into_the_one_shot_prediction(run):
    one = predict(run, PARAMS, "su")
    sizes = random_sizes(run.sizes["time"], np.random.default_rng(7), 300)
    assert len(sizes) > 5 and min(sizes) >= 1
    blocks = predict_blocks(run, PARAMS, "su", block=sizes)
    assert_same(joined(blocks), one)
    assert blocks.summary() == one.attrs["model_summary"]  # all converged here: the same sentence


@pytest.mark.slow
@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_every_model_joins_across_blocks(run, model):
    one = predict(run, PARAMS, model)
    assert_same(joined(predict_blocks(run, PARAMS, model, block=random_sizes(2000, np.random.default_rng(1), 200))),
                one)


def test_predict_out_writes_the_prediction_block_by_block(run, tmp_path):
    one = predict(run, PARAMS, "su")
    with run.rdea.predict(PARAMS, "su", out=tmp_path / "pred.nc", block=333) as got:
        assert not got["force"].variable._in_memory  # opened lazily
        assert_same({k: got[k].values for k in (*FLOATS, "converged", "model_status", "time")}, one)
        assert got.attrs["model"] == "su" and got.attrs["parameters"] == one.attrs["parameters"]
        assert got["force"].attrs["units"] == "N" and got["time"].attrs["units"] == run["time"].attrs["units"]
        lo, hi = got["force"].attrs["actual_range"]
        assert (lo, hi) == (np.nanmin(one["force"].values), np.nanmax(one["force"].values))
    assert not (tmp_path / "pred.nc.tmp").exists()


def test_predict_out_refuses_what_needs_the_whole_run(run, tmp_path):
    with pytest.raises(SpecError, match="model: auto chooses over the whole history"):
        run.rdea.predict(PARAMS, "auto", out=tmp_path / "a.nc")
    with pytest.raises(SpecError, match="bands: not with out="):
        run.rdea.predict(PARAMS, "su", out=tmp_path / "b.nc", bands=0.9)
    with pytest.raises(SpecError, match="block: 1; allowed"):
        run.rdea.predict(PARAMS, "su", out=tmp_path / "c.nc", block=1)
    with pytest.raises(SpecError, match="block: needs out=PATH"):
        run.rdea.predict(PARAMS, "su", block=100)
    (tmp_path / "d.nc").write_text("")
    with pytest.raises(SpecError, match="exists"):
        run.rdea.predict(PARAMS, "su", out=tmp_path / "d.nc")


@pytest.mark.parametrize("n", [1, 2, 99, 101, 5000])
def test_accumulated_errors_equal_the_whole_array_ones(n):
    rng = np.random.default_rng(n)
    measured = rng.standard_normal(n)
    predicted = measured + rng.standard_t(3, n) * 0.1  # heavy tails: the 99th percentile is not the max
    predicted[rng.random(n) < 0.05] = np.nan  # samples without an equilibrium
    acc = ErrorAccumulator(n)
    a = 0
    for k in random_sizes(n, rng, 400):
        acc.add(measured[a:a + k], predicted[a:a + k])
        a += k
    got, ref = acc.result(), compare(measured, predicted)
    assert got.keys() == ref.keys()
    for key in ref:
        np.testing.assert_allclose(got[key], ref[key], rtol=1e-12, err_msg=key)  # summation order only


def test_accumulated_errors_of_no_finite_prediction_are_nan():
    got = ErrorAccumulator(3).add([1.0, 2.0, 3.0], [np.nan] * 3).result()
    assert np.isnan(got["max_rel_error"]) and got["excluded"] == 3 and got["peak"] == 3.0
    with pytest.raises(ValueError, match="4 samples added, made for 3"):
        ErrorAccumulator(3).add(np.ones(4), np.ones(4))


def test_long_run_errors_equal_compare_on_the_one_shot_prediction(run):
    ref = compare(run["force"].values, predict(run, PARAMS, "su")["force"].values)
    got = long_run_errors(run, PARAMS, "su", block=251)
    for key in ref:
        np.testing.assert_allclose(got[key], ref[key], rtol=1e-12, err_msg=key)


def _long_file(run, reps, path):
    """The run's samples repeated ``reps`` times, time running on, written to ``path``."""
    n = reps * run.sizes["time"]
    dt = float(run["time"][1] - run["time"][0])
    xr.Dataset({k: ("time", np.tile(run[k].values, reps), run[k].attrs) for k in ("stretch", "voltage", "force")},
               coords={"time": ("time", np.arange(n) * dt, run["time"].attrs)}, attrs=run.attrs).to_netcdf(path)
    return n


def _traced_peak(path):
    with xr.open_dataset(path, decode_times=False) as ds:
        tracemalloc.start()
        errors = long_run_errors(ds, PARAMS, "su")
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak, errors


@pytest.mark.slow
def test_a_long_lazy_run_is_predicted_in_bounded_memory(run, tmp_path):
    """6e5 and 2.4e6 samples (the run's 2000 repeated) predicted and compared block by block from the file:
    what numpy holds does not grow with the run (a one-shot prediction of the longer one is 9 x 19 MB)."""
    short = _long_file(run, 300, tmp_path / "short.nc")
    n = _long_file(run, 1200, tmp_path / "long.nc")
    peak_short, _ = _traced_peak(tmp_path / "short.nc")
    peak, errors = _traced_peak(tmp_path / "long.nc")
    assert errors["excluded"] == 0 and np.isfinite(errors["p99_rel_error"])
    # 4 times the samples: only the kept largest 1 % of the errors grows (0.01 x 8 B x 1.8e6 = 0.15 MB)
    assert peak < peak_short + 2e6, f"{peak / 1e6:.1f} MB for {n} samples, {peak_short / 1e6:.1f} MB for {short}"
    assert peak < 9 * 8 * n / 2
    with xr.open_dataset(tmp_path / "long.nc", decode_times=False) as ds:
        with ds.rdea.predict(PARAMS, "su", out=tmp_path / "pred.nc") as pred:
            assert pred.sizes["time"] == n
            head = predict(ds.isel(time=slice(0, 2000)).load(), PARAMS, "su")["force"].values
            np.testing.assert_allclose(pred["force"][:2000].values, head, rtol=1e-12)
