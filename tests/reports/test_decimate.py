"""The min/max envelope for display (reports/decimate.py) against a loop over columns, the spike it keeps, the
figure of a long run drawn from it (and saying so), and a run's ranges read chunk by chunk."""

import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from matplotlib.figure import Figure

from rdea_lab.reports import decimate
from rdea_lab.reports.plots import ENVELOPE_ABOVE, plot_run
from rdea_lab.store import open_run
from rdea_lab.store.catalog import describe_run, finite_range

RUNS = Path(__file__).resolve().parents[2] / "datasets" / "paper2021" / "specimen-2"


def reference_envelope(y, per):
    """Column by column, in plain Python: the min and max of the finite values of y[j*per:(j+1)*per]."""
    lo, hi = [], []
    for a in range(0, len(y), per):
        finite = [v for v in y[a:a + per] if math.isfinite(v)]
        lo.append(min(finite) if finite else math.nan)
        hi.append(max(finite) if finite else math.nan)
    return np.array(lo), np.array(hi)


@pytest.mark.parametrize("n, per", [(1, 1), (10, 1), (10, 3), (12, 4), (97, 10), (5, 8), (0, 3)])
def test_envelope_equals_a_loop_over_columns(n, per):
    y = np.random.default_rng(n * 31 + per).standard_normal(n)
    y[::7] = np.nan  # NaN ignored; a column of NaN only stays NaN (per 1: every seventh)
    lo, hi = decimate.envelope(y, per)
    ref_lo, ref_hi = reference_envelope(list(y), per)
    np.testing.assert_array_equal(lo, ref_lo)
    np.testing.assert_array_equal(hi, ref_hi)


def test_envelope_rejects_a_column_of_no_samples():
    with pytest.raises(ValueError, match="per: 0; allowed"):
        decimate.envelope(np.ones(3), 0)


def test_a_one_sample_spike_is_its_columns_maximum():
    n, columns = 1_000_003, 997
    y = np.sin(np.arange(n) * 1e-3)
    y[654_321] = 50.0  # one sample
    y[123_456] = -40.0
    per = decimate.samples_per_column(n, columns)
    lo, hi = decimate.envelope(y, per)
    assert lo.size <= columns and per == math.ceil(n / columns)
    assert hi[654_321 // per] == 50.0 and lo[123_456 // per] == -40.0
    assert np.sum(hi > 1.0) == 1 and np.sum(lo < -1.0) == 1


def test_chunked_envelopes_equal_the_whole_arrays():
    rng = np.random.default_rng(3)
    ys = {"a": rng.standard_normal(1001), "b": rng.standard_normal(1001)}
    whole = {k: decimate.envelope(v, 7) for k, v in ys.items()}
    chunked = decimate.envelopes(ys, 1001, 7, chunk=50)  # 49 samples (7 columns) per read
    for k in ys:
        np.testing.assert_array_equal(chunked[k][0], whole[k][0])
        np.testing.assert_array_equal(chunked[k][1], whole[k][1])
    np.testing.assert_array_equal(decimate.first_of_columns(np.arange(1001.0), 1001, 7, chunk=50),
                                  np.arange(0, 1001, 7))


def test_stroke_draws_each_column_from_min_to_max():
    x, y = decimate.stroke([0.0, 1.0], [1.0, 2.0], [3.0, 4.0])
    np.testing.assert_array_equal(x, [0, 0, 1, 1])
    np.testing.assert_array_equal(y, [1, 3, 2, 4])


def test_occupancy_counts_as_numpy_histogram2d():
    rng = np.random.default_rng(5)
    x, y = rng.uniform(0, 1, 5000), rng.uniform(-2, 2, 5000)
    x[:3] = [1.0, 0.0, np.nan]  # the upper edge is in the last cell (as histogram2d); NaN skipped
    got = decimate.occupancy(x, y, x.size, (0, 1), (-2, 2), (6, 9), chunk=777)
    ok = np.isfinite(x)
    ref, _, _ = np.histogram2d(y[ok], x[ok], bins=(6, 9), range=((-2, 2), (0, 1)))
    np.testing.assert_array_equal(got, ref)


def long_run(n, spike_at=None):
    """A run of n samples at 1 kHz with the attributes of a real one (a 2.6 kV tensile run's)."""
    base = open_run(RUNS / "tensile_ramp_sine_2.6kV.nc")
    t = np.arange(n) / 1000.0
    lam = 1.2 + 0.2 * np.sin(2 * np.pi * t / 10.0)
    force = 2.0 * (lam - 1.0)
    if spike_at is not None:
        force[spike_at] = 9.0
    data = {"stretch": lam, "voltage": np.where(np.sin(t) > 0, 2600.0, 0.0), "force": force,
            "position": (lam - 1.0) * 0.02, "capacitance": np.full(n, np.nan)}
    return xr.Dataset({k: ("time", v, base[k].attrs) for k, v in data.items()},
                      coords={"time": ("time", t, base["time"].attrs)}, attrs=base.attrs)


def _force_axis(fig):
    return next(a for a in fig.axes if a.get_ylabel() == "force [N]" and a.get_xlabel() != "displacement [mm]"
                and a.lines)


def test_a_long_run_is_drawn_from_the_file_as_an_envelope_that_keeps_a_spike_and_says_so(tmp_path):
    n = 30_011
    long_run(n, spike_at=17_777).to_netcdf(tmp_path / "run.nc")
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as ds:  # lazy: variables read by slices
        fig = plot_run(ds, fig=Figure(figsize=(11, 7)), envelope=True)
        assert not ds["force"].variable._in_memory
    y = _force_axis(fig).lines[0].get_ydata()
    per = decimate.samples_per_column(n, round(11 * 0.45 * 200))
    assert y.size == 2 * math.ceil(n / per)  # two vertices per pixel column, not one per sample
    assert np.max(y) == 9.0  # the one-sample spike
    assert f"min/max envelope of {per} samples per pixel column" in fig._suptitle.get_text()


def test_a_small_run_is_drawn_sample_by_sample_as_before(tmp_path):
    ds = open_run(RUNS / "tensile_ramp_sine_0V.nc")
    assert ds.sizes["time"] < ENVELOPE_ABOVE
    fig = plot_run(ds, fig=Figure(figsize=(11, 7)))
    np.testing.assert_array_equal(_force_axis(fig).lines[0].get_ydata(), ds["force"].values)
    assert "envelope" not in fig._suptitle.get_text()


def test_finite_range_reads_chunk_by_chunk_or_takes_actual_range():
    v = np.random.default_rng(2).standard_normal(1001)
    v[[0, 500, 1000]] = np.nan
    var = xr.DataArray(v, dims="time", attrs={"units": "N"})
    assert finite_range(var, chunk=7) == (np.nanmin(v), np.nanmax(v))
    assert finite_range(xr.DataArray(np.full(5, np.nan), dims="time"), chunk=2) is None
    var.attrs["actual_range"] = np.array([-1.0, 2.0])  # written with the file: taken as it is, nothing read
    assert finite_range(var) == (-1.0, 2.0)
    ds = long_run(2_000)
    ds["force"].attrs["actual_range"] = np.array([-7.0, 8.0])
    assert "[N] -7 .. 8" in describe_run(ds)


@pytest.mark.slow
def test_the_figure_of_a_long_lazy_run_holds_one_chunk(tmp_path):
    """4e6 samples (5 variables, 160 MB as float64) drawn from the file with a bound on what numpy holds."""
    n = 4_000_000
    path = tmp_path / "long.nc"
    long_run(n, spike_at=3_333_333).to_netcdf(path, encoding={k: {"zlib": True, "complevel": 1}
                                                              for k in ("stretch", "voltage", "force",
                                                                        "position", "capacitance")})
    with xr.open_dataset(path, decode_times=False) as ds:
        tracemalloc.start()
        fig = plot_run(ds, fig=Figure(figsize=(11, 7)))
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert np.max(_force_axis(fig).lines[0].get_ydata()) == 9.0
    assert peak < 40e6, f"peak {peak / 1e6:.0f} MB traced while drawing a 160 MB run"  # a few 8 MB chunks
