"""Plot helpers in the manner of xarray and pandas: ax= or fig= or their own pyplot figure; they return the Figure."""

from pathlib import Path

import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

from rdea_lab.protocols import load_plan
from rdea_lab.reports.plots import minmax_index, plot_plan, plot_run
from rdea_lab.store import open_run

ROOT = Path(__file__).resolve().parents[2]
RUNS = ROOT / "datasets" / "paper2021" / "specimen-2"


@pytest.fixture(scope="module")
def run():
    ds = open_run(RUNS / "tensile_ramp_sine_0V.nc")
    yield ds.load()
    ds.close()


@pytest.fixture(scope="module")
def kv_run():
    """A run at 2.6 kV (a voltage panel)."""
    ds = open_run(RUNS / "tensile_ramp_sine_2.6kV.nc")
    yield ds.load()
    ds.close()


@pytest.fixture(scope="module")
def cap_run():
    """A run with measured capacitance (four panels)."""
    ds = open_run(RUNS / "capacitance_sweep.nc")
    yield ds.load()
    ds.close()


@pytest.fixture(scope="module")
def plan():
    return load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml")


def prediction_of(ds, factor=1.05):
    """A stand-in twin prediction on the run's time: the measured force and capacitance scaled."""
    pred = ds[["force", "capacitance"]].copy(deep=True)
    return pred * factor


def png_size(path):
    return matplotlib.image.imread(path).shape[:2]


def test_plot_run_on_ax_draws_force_against_time(run):
    fig, ax = plt.subplots()
    assert plot_run(run, ax=ax) is fig
    np.testing.assert_array_equal(ax.lines[0].get_xdata(), run["time"].values)
    np.testing.assert_array_equal(ax.lines[0].get_ydata(), run["force"].values)
    assert ax.get_xlabel() == "time [s]" and ax.get_ylabel() == "force [N]"
    assert len(ax.lines) == 1 and ax.get_legend() is None


def test_plot_run_prediction_on_ax_is_a_dashed_twin_line_with_legend(run):
    fig, ax = plt.subplots()
    pred = prediction_of(run)
    plot_run(run, ax=ax, prediction=pred)
    twin = [line for line in ax.lines if line.get_label() == "prediction"]
    assert len(twin) == 1 and twin[0].get_linestyle() == "--"
    np.testing.assert_allclose(twin[0].get_ydata(), 1.05 * run["force"].values)
    # the shipped runs come from the emulator, and say so in the legend
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["measured (emulator)", "prediction"]


def test_labels_say_what_made_each_line(run):
    twin_run = run.assign_attrs(backend="twin", model="3r", emulated="")
    pred = prediction_of(run).assign_attrs(model="su")
    fig, ax = plt.subplots()
    plot_run(twin_run, ax=ax, prediction=pred)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["run (twin, 3r)", "prediction (su)"]


def test_plot_run_default_layout(run, kv_run, cap_run):
    """A 0 V run has no voltage panel (its voltage axis would show only noise about 0); a 2.6 kV run has one."""
    fig = plot_run(run)
    assert isinstance(fig, Figure) and plt.fignum_exists(fig.number)  # pyplot's own: a notebook shows it
    assert float(np.max(np.abs(run["voltage"].values))) < 5.0  # the fixture is a 0 V run
    assert [ax.get_ylabel() for ax in fig.axes] == ["stretch λ1 [-]", "force [N]", "force [N]"]
    loop = fig.axes[-1]
    np.testing.assert_array_equal(loop.lines[0].get_xdata(), run["position"].values * 1e3)
    np.testing.assert_array_equal(loop.lines[0].get_ydata(), run["force"].values)
    assert fig.get_size_inches() == pytest.approx((11, 4.6))  # 2.3 in per panel
    assert "at 0 V throughout" in fig._suptitle.get_text()
    fig = plot_run(kv_run)
    assert [ax.get_ylabel() for ax in fig.axes] == ["stretch λ1 [-]", "voltage [kV]", "force [N]", "force [N]"]
    np.testing.assert_allclose(fig.axes[1].lines[0].get_ydata(), kv_run["voltage"].values / 1e3, rtol=1e-15)
    assert [ax.get_ylabel() for ax in plot_run(cap_run).axes][-2:] == ["capacitance [pF]", "force [N]"]


def test_plot_run_into_a_given_figure(run):
    fig = Figure(figsize=(11, 7))
    assert plot_run(run, fig=fig) is fig
    assert len(fig.axes) == 3
    np.testing.assert_array_equal(fig.axes[0].lines[0].get_ydata(), run["stretch"].values)
    assert plt.get_fignums() == []


def test_plot_run_prediction_in_force_panel_loop_and_capacitance(cap_run):
    fig = plot_run(cap_run, fig=Figure(), prediction=prediction_of(cap_run, 0.9))
    labels = [(ax.get_ylabel(), [line.get_label() for line in ax.lines if not line.get_label().startswith("_")])
              for ax in fig.axes]
    assert labels == [("stretch λ1 [-]", ["measured (emulator)"]),
                      ("force [N]", ["measured (emulator)", "prediction"]), ("twin − measured [N]", []),
                      ("capacitance [pF]", ["measured (emulator)", "prediction"]), ("twin − measured [pF]", []),
                      ("force [N]", ["measured (emulator)", "prediction"]), ("twin − measured [N]", [])]
    loop = fig.axes[5]
    np.testing.assert_allclose(loop.lines[1].get_ydata(), 0.9 * cap_run["force"].values)
    assert loop.get_legend() is not None


def test_residual_panels_are_prediction_minus_measurement_in_n_and_percent_of_peak(kv_run):
    """Under the force history: 0.9 F - F = -0.1 F [N]; the right axis is the same in % of max |F|."""
    f = kv_run["force"].values
    fig = plot_run(kv_run, fig=Figure(), prediction=prediction_of(kv_run, 0.9))
    history, loop = [ax for ax in fig.axes if ax.get_ylabel() == "twin − measured [N]"]
    for ax in (history, loop):
        np.testing.assert_allclose(ax.lines[0].get_ydata(), -0.1 * f, atol=1e-12)
        (right,) = ax.child_axes
        assert right.get_ylabel() == "[% of peak]"
        np.testing.assert_allclose(right.get_ylim(), np.array(ax.get_ylim()) * 100 / np.max(np.abs(f)), rtol=1e-9)
    np.testing.assert_array_equal(loop.lines[0].get_xdata(), kv_run["position"].values * 1e3)


def test_plot_run_path_writes_png_at_200_dpi_and_closes_its_figure(run, tmp_path):
    out = tmp_path / "run.png"
    fig = plot_run(run, out)  # positionally, as the CLI calls it
    assert isinstance(fig, Figure)
    assert png_size(out) == (920, 2200)  # (4.6 x 11) in at 200 dpi
    assert not plt.fignum_exists(fig.number)  # made here and saved: closed, so a loop does not pile up figures


def test_plot_run_path_with_ax_saves_the_callers_figure_and_keeps_it(run, tmp_path):
    fig, ax = plt.subplots(figsize=(4, 3))
    plot_run(run, tmp_path / "ax.png", ax=ax)
    assert png_size(tmp_path / "ax.png") == (600, 800)
    assert plt.fignum_exists(fig.number)


def test_minmax_index_keeps_each_bins_extremes_and_ends():
    """A noisy series of 30000 samples in 1000 bins: the kept samples hold every bin's min and max (checked
    against a reshape of the series: bins of 30 samples), the first and the last sample."""
    y = np.random.default_rng(3).normal(size=30000)
    keep = minmax_index(y.size, [y], bins=1000)
    assert keep[0] == 0 and keep[-1] == y.size - 1 and np.all(np.diff(keep) > 0)
    assert keep.size <= 4 * 1000
    kept = np.zeros(y.size, bool)
    kept[keep] = True
    blocks = y.reshape(1000, 30)
    assert np.all(kept[np.arange(1000) * 30 + blocks.argmax(axis=1)])
    assert np.all(kept[np.arange(1000) * 30 + blocks.argmin(axis=1)])
    np.testing.assert_array_equal(minmax_index(2999, [y[:2999]], bins=1000), np.arange(2999))  # short: all of it


def test_plot_run_bad_arguments(run):
    fig, ax = plt.subplots()
    with pytest.raises(ValueError, match="give ax= or fig=, not both"):
        plot_run(run, ax=ax, fig=fig)
    with pytest.raises(ValueError, match=r"prediction has no 'force' variable \(it has \['stretch'\]\)"):
        plot_run(run, ax=ax, prediction=run[["stretch"]])
    short = prediction_of(run).isel(time=slice(0, 10))
    with pytest.raises(ValueError, match=r"prediction force has shape \(10,\); the run has \d+ samples"):
        plot_run(run, ax=ax, prediction=short)
    shifted = prediction_of(run).assign_coords(time=run["time"].values + 1.0)
    with pytest.raises(ValueError, match=r"prediction time \(1 \.\.\. .* s, \d+ samples\) is not the run's time"):
        plot_run(run, ax=ax, prediction=shifted)


def test_plot_plan_on_ax_draws_stretch_and_voltage_on_a_twin_axis(plan):
    fig, ax = plt.subplots()
    assert plot_plan(plan, ax=ax) is fig
    np.testing.assert_array_equal(ax.lines[0].get_xdata(), plan.time)
    np.testing.assert_array_equal(ax.lines[0].get_ydata(), plan.stretch)
    twin = [a for a in fig.axes if a is not ax]
    assert len(twin) == 1 and twin[0].get_ylabel() == "voltage [kV]"
    np.testing.assert_array_equal(twin[0].lines[0].get_ydata(), plan.voltage / 1e3)


def test_plot_plan_default_and_path(plan, tmp_path):
    fig = plot_plan(plan)
    assert plt.fignum_exists(fig.number) and len(fig.axes) == 2
    np.testing.assert_array_equal(fig.axes[1].lines[0].get_ydata(), plan.voltage / 1e3)
    out = tmp_path / "plan.png"
    saved = plot_plan(plan, out)
    assert png_size(out) == (1000, 1600)  # (5 x 8) in at 200 dpi
    assert not plt.fignum_exists(saved.number)


def test_a_long_plan_is_drawn_as_its_min_and_max_per_column_without_being_held():
    from rdea_lab.protocols import expand
    from rdea_lab.specs import protocol_from_mapping

    plan = expand(protocol_from_mapping({
        "name": "long", "kind": "custom", "sample_rate": "1 kHz",
        "stretch": [{"kind": "sine", "duration": "300 s", "mean": 1.3, "amplitude": 0.2, "frequency": "3 Hz"}],
        "voltage": [{"kind": "hold", "duration": "150 s", "value": "1 kV"},
                    {"kind": "step", "duration": "0.002 s", "value": "2.5 kV"},  # a 3-sample spike
                    {"kind": "hold", "duration": "149.998 s", "value": "1 kV"}],
    }, "<test>"))
    fig = plot_plan(plan)
    stretch, voltage = fig.axes[0].lines[0].get_ydata(), fig.axes[1].lines[0].get_ydata()
    assert plan.held() == {} and stretch.size <= 4000 and voltage.size <= 4000
    # the sine's extremes (1.1 and 1.5 within a sampling step of 3 Hz at 1 kHz) and the spike stay visible
    assert stretch.min() == pytest.approx(1.1, abs=1e-4) and stretch.max() == pytest.approx(1.5, abs=1e-4)
    assert voltage.max() == 2.5 and voltage.min() == 1.0
    assert "min and max of each" in fig.axes[0].get_title()
