"""The overview a long run's file carries (store/overview.py) against the envelope and raster of its samples."""

import sys
from pathlib import Path

import numpy as np
import xarray as xr

from rdea_lab.reports import decimate
from rdea_lab.reports.long_plots import series_envelopes
from rdea_lab.store.catalog import describe_run
from rdea_lab.store.overview import occupancy, read_overview, write_overview

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "reports"))
from test_decimate import long_run  # noqa: E402 (a run of n samples with a real run's attributes)


def test_the_overview_holds_the_envelope_of_each_block_and_the_loop(tmp_path):
    n = 20_011
    ds = long_run(n, spike_at=12_345)
    ds["capacitance"][:100] = 1e-9  # a few measured samples; the rest NaN
    ds.to_netcdf(tmp_path / "run.nc")
    write_overview(tmp_path / "run.nc", block=10, chunk=999)  # reads of 990 samples
    ov = read_overview(tmp_path / "run.nc")
    assert ov.samples == n and ov.block == 10
    for name in ("time", "stretch", "force", "capacitance", "position"):
        lo, hi = decimate.envelope(ds[name].values, 10)
        np.testing.assert_array_equal(ov.envelopes[name][0], lo)
        np.testing.assert_array_equal(ov.envelopes[name][1], hi)
    x0, x1, y0, y1 = ov.loop_extent
    assert (x0, x1, y0, y1) == (ds.position.min(), ds.position.max(), ds.force.min(), ds.force.max())
    np.testing.assert_array_equal(ov.loop, occupancy(ds["position"].values, ds["force"].values, n, (x0, x1),
                                                     (y0, y1), ov.loop.shape))
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as back:  # the run's own variables as they were
        assert sorted(back.data_vars) == sorted(ds.data_vars)
        assert read_overview(back) is not None and "[N] 0 .. 9" in describe_run(back)


def test_columns_from_the_overview_equal_the_columns_of_the_samples(tmp_path):
    n = 50_003
    long_run(n, spike_at=31_337).to_netcdf(tmp_path / "run.nc")
    write_overview(tmp_path / "run.nc", block=7)
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as ds:
        per, t, env, ov = series_envelopes(ds, ["force", "stretch"], {}, n, 997)
        assert ov is not None and per % 7 == 0 and n / per <= 997
        direct = decimate.envelopes({"force": ds["force"], "stretch": ds["stretch"]}, n, per)
        for name in ("force", "stretch"):
            np.testing.assert_array_equal(env[name][0], direct[name][0])
            np.testing.assert_array_equal(env[name][1], direct[name][1])
        np.testing.assert_array_equal(t, ds["time"].values[::per])
        assert env["force"][1].max() == 9.0  # the one-sample spike


def test_the_builder_of_chunks_of_any_size_equals_the_envelope_of_the_whole():
    from rdea_lab.store.overview import OverviewBuilder

    rng = np.random.default_rng(0)
    for block in (1, 3, 10, 1000):
        for _ in range(10):
            n = int(rng.integers(1, 5000))
            v = rng.standard_normal(n)
            v[rng.random(n) < 0.3] = np.nan  # a block of NaN only stays NaN
            builder, i = OverviewBuilder(block), 0
            while i < n:
                k = int(rng.integers(1, 700))  # chunks shorter and longer than a block, never aligned
                builder.add({"x": v[i:i + k], "n": np.arange(i, min(i + k, n))})  # integers are not gathered
                i += k
            lo, hi = builder.envelopes()["x"]
            ref_lo, ref_hi = decimate.envelope(v, block)
            np.testing.assert_array_equal(lo, ref_lo)
            np.testing.assert_array_equal(hi, ref_hi)
            assert builder.samples == n and set(builder.envelopes()) == {"x"}


def test_the_overview_is_not_used_for_values_that_may_differ_from_the_file(tmp_path):
    """Drawn from the overview only while the dataset's variables are the file's: not once loaded (maybe
    edited: force scaled by 100 must show as 100 times larger), nor when the file now holds another run."""
    n = 20_011
    run = long_run(n, spike_at=12_345)
    run.attrs["run_id"] = "first"
    run.to_netcdf(tmp_path / "run.nc")
    write_overview(tmp_path / "run.nc", block=10)
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as ds:
        assert read_overview(ds) is not None
        edited = ds.load()
        edited["force"] = edited["force"] * 100.0
        assert read_overview(edited) is None
        per, t, env, ov = series_envelopes(edited, ["force"], {}, n, 997)
        assert ov is None and env["force"][1].max() == 900.0  # the spike, scaled
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as ds:
        ds.attrs["run_id"] = "second"  # as a dataset of another run would read
        assert read_overview(ds) is None
