"""Plots of plans and runs, in the manner of xarray and pandas.

Each helper draws on an ``ax=`` it is given (or into a ``fig=``), or makes
its own figure with :mod:`matplotlib.pyplot` so that a notebook shows it, and
returns the :class:`~matplotlib.figure.Figure`. No backend is chosen here:
that is the caller's business (the CLI runs headless, where matplotlib picks
Agg by itself).
"""

from __future__ import annotations

import os

import numpy as np

from ..store.schema import is_emulated

DPI = 120
#: How a twin prediction is drawn over a measurement.
PREDICTION = {"color": "black", "ls": "--", "lw": 0.9, "label": "twin"}


def _new_figure(figsize):
    import matplotlib.pyplot as plt

    return plt.figure(figsize=figsize)


def _finish(fig, path, created: bool, tight: bool = True):
    """Lay out, save to ``path`` if given, close the figure if it was made here and saved."""
    if tight and fig.get_layout_engine() is None:
        fig.tight_layout()
    if path is not None:
        os.makedirs(os.path.dirname(os.path.abspath(os.fspath(path))), exist_ok=True)  # a new folder is fine
        fig.savefig(os.fspath(path), dpi=DPI)
        if created:
            import matplotlib.pyplot as plt

            plt.close(fig)
    return fig


def _plan_on(ax, plan):
    """Stretch setpoint on ``ax``, voltage setpoint on a twin y-axis; returns the twin axis."""
    ax.plot(plan.time, plan.stretch, color="tab:blue")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("stretch λ1 [-]", color="tab:blue")
    ax.grid(alpha=0.3)
    twin = ax.twinx()
    twin.plot(plan.time, np.asarray(plan.voltage) / 1e3, color="tab:red")
    twin.set_ylabel("voltage [kV]", color="tab:red")
    return twin


def plot_plan(plan, path=None, *, ax=None):
    """Stretch and voltage setpoints of a plan against time.

    Parameters
    ----------
    plan : Plan
        An expanded protocol (:func:`rdea_lab.protocols.load_plan`): ``time`` [s],
        ``stretch`` [-], ``voltage`` [V].
    path : str or path-like, optional
        Save the figure there as PNG (dpi 120). A figure made here is then
        closed (it is still returned).
    ax : matplotlib.axes.Axes, optional
        Draw on this axis: the stretch setpoint [-] against time [s], the
        voltage setpoint [kV] on a twin y-axis. Without it, a new pyplot
        figure with two panels (stretch above, voltage below).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on (``ax.figure`` when ``ax`` is given).
    """
    title = f"{plan.name} ({plan.kind}), {plan.time.size} samples at {plan.sample_rate:g} Hz"
    if ax is not None:
        _plan_on(ax, plan)
        ax.set_title(title)
        return _finish(ax.figure, path, created=False, tight=False)
    fig = _new_figure((8, 5))
    axes = fig.subplots(2, 1, sharex=True)
    axes[0].plot(plan.time, plan.stretch, color="tab:blue")
    axes[0].set_ylabel("stretch λ1 [-]")
    axes[1].plot(plan.time, np.asarray(plan.voltage) / 1e3, color="tab:red")
    axes[1].set_ylabel("voltage [kV]")
    axes[1].set_xlabel("time [s]")
    axes[0].set_title(title)
    for a in axes:
        a.grid(alpha=0.3)
    return _finish(fig, path, created=True)


def _prediction(ds, prediction) -> dict:
    """The predicted series to draw, checked against the run's time coordinate."""
    if prediction is None:
        return {}
    if "force" not in prediction:
        raise ValueError(f"prediction has no 'force' variable (it has {sorted(prediction.data_vars)})")
    n = ds["time"].size
    out = {}
    for name in ("force", "capacitance"):
        if name not in prediction:
            continue
        values = np.asarray(prediction[name].values, float)
        if values.shape != (n,):
            raise ValueError(f"prediction {name} has shape {values.shape}; the run has {n} samples on 'time'")
        out[name] = values
    if "time" in prediction.variables:
        t, tp = ds["time"].values, np.asarray(prediction["time"].values)
        if tp.shape != t.shape or not np.allclose(tp, t, rtol=1e-9, atol=1e-9):
            raise ValueError(f"prediction time ({tp[0]:g} ... {tp[-1]:g} s, {tp.size} samples) is not the run's "
                             f"time ({t[0]:g} ... {t[-1]:g} s, {t.size} samples)")
    return out


def _title(ds) -> str:
    a = ds.attrs
    return (f"{a.get('protocol_name', '?')} on {a.get('specimen_id', '?')} ({a.get('backend', '?')}, "
            f"{a.get('status', '?')})")


def _run_label(ds) -> str:
    """What the run's line is: measured on a rig (or imported), or made by the twin."""
    backend = str(ds.attrs.get("backend", ""))
    if backend == "twin":
        return f"run (twin, {ds.attrs.get('model', '?')})"
    return "measured" + (" (emulator)" if is_emulated(ds.attrs) else "")


def _prediction_label(prediction) -> str:
    model = getattr(prediction, "attrs", {}).get("model") if prediction is not None else None
    return f"prediction ({model})" if model else "prediction"


def plot_run(ds, path=None, *, ax=None, fig=None, prediction=None):
    """Time histories of a run and its force-displacement loop.

    Parameters
    ----------
    ds : xarray.Dataset
        A run (:func:`rdea_lab.store.open_run`) over ``time`` [s]: ``stretch`` [-],
        ``voltage`` [V], ``force`` [N], ``position`` [m] and ``capacitance`` [F]
        (drawn in a fourth panel when any of it was measured).
    path : str or path-like, optional
        Save the figure there as PNG (dpi 120). A figure made here is then
        closed (it is still returned).
    ax : matplotlib.axes.Axes, optional
        Draw only force [N] against time [s] on this axis.
    fig : matplotlib.figure.Figure, optional
        Draw the full layout into this (empty) figure: time histories on the
        left, force [N] against displacement [mm] on the right. Not with ``ax``.
    prediction : xarray.Dataset, optional
        The twin on the same ``time``: ``force`` [N] and optionally
        ``capacitance`` [F], drawn dashed and labelled ``twin`` over the
        measurement (force panel, loop and capacitance panel, or ``ax``).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on (``ax.figure`` when ``ax`` is given).

    Raises
    ------
    ValueError
        Both ``ax`` and ``fig`` given, or a ``prediction`` without ``force`` or
        not on the run's time coordinate.
    """
    if ax is not None and fig is not None:
        raise ValueError("plot_run: give ax= or fig=, not both")
    pred = _prediction(ds, prediction)
    t = ds["time"].values
    own = _run_label(ds)
    style = dict(PREDICTION, label=_prediction_label(prediction))
    if ax is not None:
        ax.plot(t, ds["force"].values, lw=0.8, label=own)
        if "force" in pred:
            ax.plot(t, pred["force"], **style)
            ax.legend(fontsize=8)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("force [N]")
        ax.grid(alpha=0.3)
        return _finish(ax.figure, path, created=False, tight=False)
    measured_c = bool(np.any(np.isfinite(ds["capacitance"].values)))
    rows = 4 if measured_c else 3
    created = fig is None
    if created:
        fig = _new_figure((11, 2.3 * rows))
    grid = fig.add_gridspec(rows, 2)
    series = [("stretch", 1.0, "stretch λ1 [-]"), ("voltage", 1e-3, "voltage [kV]"), ("force", 1.0, "force [N]")]
    if measured_c:
        series.append(("capacitance", 1e12, "capacitance [pF]"))
    for i, (name, scale, label) in enumerate(series):
        a = fig.add_subplot(grid[i, 0])
        a.plot(t, ds[name].values * scale, lw=0.8, label=own)
        if name in pred:
            a.plot(t, pred[name] * scale, **style)
            a.legend(fontsize=8)
        a.set_ylabel(label)
        a.grid(alpha=0.3)
        if i == rows - 1:
            a.set_xlabel("time [s]")
    a = fig.add_subplot(grid[:, 1])
    x = ds["position"].values * 1e3
    a.plot(x, ds["force"].values, lw=0.8, label=own)
    if "force" in pred:
        a.plot(x, pred["force"], **style)
        a.legend(fontsize=8)
    a.set_xlabel("displacement [mm]")
    a.set_ylabel("force [N]")
    a.grid(alpha=0.3)
    fig.suptitle(_title(ds))
    return _finish(fig, path, created)
