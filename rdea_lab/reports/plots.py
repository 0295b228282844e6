"""Plots of plans and runs, in the manner of xarray and pandas.

Each helper draws on an ``ax=`` it is given (or into a ``fig=``), or makes
its own figure with :mod:`matplotlib.pyplot` so that a notebook shows it, and
returns the :class:`~matplotlib.figure.Figure`. No backend is chosen here:
that is the caller's business (the CLI runs headless, where matplotlib picks
Agg by itself).
"""

from __future__ import annotations

import io
import math
import os

import numpy as np

from ..store.schema import is_emulated

DPI = 200
#: How a twin prediction is drawn over a measurement.
PREDICTION = {"color": "black", "ls": "--", "lw": 0.9, "label": "twin"}
#: Below this |voltage| [V] everywhere a run is a 0 V run: no voltage axis is drawn for it.
ZERO_VOLTAGE = 5.0
#: A run of more samples than this is drawn as a min/max envelope per pixel column, read chunk by chunk
#: (`rdea_lab.reports.long_plots`); a shorter one sample by sample, as it always was.
ENVELOPE_ABOVE = 200_000


def save_figure(fig, path, dpi: int = DPI, vector: bool = False):
    """Save ``fig`` to ``path`` (PNG at ``dpi``) and, with ``vector``, a PDF of it beside (same stem).

    The PNG is stored with a palette of 256 colours (no dithering): plots have few
    colours, and the antialiased edges keep their shades; noisy traces at 200 dpi
    shrink 3-4 times (the committed reference report stays a few MB), and the
    palette image encodes about 4 times faster than the RGB one. The figure is
    rendered once by Agg and quantized from its buffer (the pixels of matplotlib's
    own PNG, without encoding and decoding that first).

    Returns the PNG's path.
    """
    from PIL import Image  # matplotlib's own dependency

    path = os.fspath(path)
    stem, ext = os.path.splitext(path)
    if ext.lower() != ".png":  # another format asked for (show --plot run.pdf): matplotlib's, as named
        fig.savefig(path, dpi=dpi)
        return path
    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=dpi)  # Agg's pixels, as its PNG would hold them, not encoded
    width = int(fig.get_figwidth() * dpi)
    height, rest = divmod(buf.getbuffer().nbytes, 4 * width)
    if rest:
        raise RuntimeError(f"save_figure: {buf.getbuffer().nbytes} bytes of RGBA are not rows of {width} pixels")
    image = Image.frombuffer("RGBA", (width, height), buf.getvalue(), "raw", "RGBA", 0, 1)
    image.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE,
                                  dither=Image.Dither.NONE).save(path, format="PNG")
    if vector:
        fig.savefig(stem + ".pdf")
    return path


def minmax_index(n: int, ys, bins: int = 1500) -> np.ndarray:
    """Indices of the samples to draw of ``n``: all of them if ``n <= 3 bins``; otherwise, in each of
    ``bins`` equal index ranges, the first and last sample and those where each of ``ys`` is smallest
    and largest (what a line drawn ``bins`` pixels wide shows, with far fewer vertices).

    Parameters
    ----------
    n : int
        Samples.
    ys : sequence of array_like
        Series of ``n`` samples each (NaN ignored).
    bins : int
        Index ranges, about the panel's width in pixels.
    """
    if n <= 3 * bins:
        return np.arange(n)
    edges = np.linspace(0, n, bins + 1).astype(int)
    keep = [edges[:-1], edges[1:] - 1]
    width = int(np.max(np.diff(edges)))
    pos = np.minimum(edges[:-1, None] + np.arange(width)[None, :], edges[1:, None] - 1)  # (bins, width)
    for y in ys:
        block = np.asarray(y, float)[pos]
        keep += [pos[np.arange(bins), np.argmin(np.where(np.isnan(block), np.inf, block), axis=1)],
                 pos[np.arange(bins), np.argmax(np.where(np.isnan(block), -np.inf, block), axis=1)]]
    return np.unique(np.concatenate(keep))


def is_zero_voltage(voltage) -> bool:
    """Whether a run never leaves 0 V (|v| below `ZERO_VOLTAGE` at every sample)."""
    v = np.asarray(voltage, float)
    return bool(v.size == 0 or np.nanmax(np.abs(v)) < ZERO_VOLTAGE)


def residual_panel(ax, x, measured, predicted, peak: float, unit: str = "N", scale: float = 1.0, **style):
    """The twin's residual (predicted - measured) under a curve: in ``unit`` on the left axis, in % of
    ``peak`` on the right.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    x : array_like
        Abscissa (as the panel above).
    measured, predicted : array_like
        In SI [N] or [F]; drawn times ``scale`` (e.g. 1e12 for pF).
    peak : float
        The run's largest |measured| value [SI] (Table 4's error scale).
    unit : str
        Shown unit of the left axis.
    """
    r = (np.asarray(predicted, float) - np.asarray(measured, float)) * scale
    ax.plot(x, r, **{"color": "black", "lw": 0.7, **style})
    return residual_axes(ax, peak, unit, scale)


def residual_axes(ax, peak: float, unit: str = "N", scale: float = 1.0):
    """The axes of `residual_panel` (its zero line, left label in ``unit``, right axis in % of ``peak``
    [SI]), for a residual already drawn."""
    ax.axhline(0.0, color="tab:gray", lw=0.6)
    ax.set_ylabel(f"twin − measured [{unit}]", fontsize=8)
    ax.grid(alpha=0.3)
    if peak > 0 and np.isfinite(peak):
        k = 100.0 / (peak * scale)
        right = ax.secondary_yaxis("right", functions=(lambda y: y * k, lambda p: p / k))
        right.set_ylabel("[% of peak]", fontsize=8)
    return ax


#: How a prediction band is shaded.
BAND = {"color": "tab:gray", "alpha": 0.3, "lw": 0}


def band_shade(ax, x, lower, upper, level: float, status: str = "", scale: float = 1.0):
    """Shade a prediction band (`rdea_lab.calibration.bands`) between ``lower`` and ``upper`` over ``x``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    x : array_like
        Abscissa, increasing (time [s]).
    lower, upper : array_like
        Band [N] (times ``scale`` on the axis); NaN gaps left unshaded; an unbounded band (infinite) is not
        shaded but said in a corner of the axis.
    level : float
        Nominal level [-], for the label.
    status : str
        The band's status (``widened``, ``parameter-only``, ...), in the label when not ``bounded``.
    scale : float
        Factor onto the axis' unit.

    Returns
    -------
    matplotlib.axes.Axes
    """
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    note = f" ({status})" if status and status != "bounded" else ""
    if np.isinf(lo).any() or np.isinf(hi).any():
        ax.text(0.99, 0.03, f"{100 * level:g} % band unbounded: beyond the calibration", transform=ax.transAxes,
                ha="right", va="bottom", fontsize=7, color="tab:gray")
        return ax
    ok = np.isfinite(lo) & np.isfinite(hi)
    ax.fill_between(np.asarray(x, float), lo * scale, hi * scale, where=ok, label=f"{100 * level:g} % band{note}",
                    **BAND)
    return ax


def _new_figure(figsize):
    import matplotlib.pyplot as plt

    return plt.figure(figsize=figsize)


def _finish(fig, path, created: bool, tight: bool = True):
    """Lay out, save to ``path`` if given, close the figure if it was made here and saved."""
    if tight and fig.get_layout_engine() is None:
        fig.tight_layout()
    if path is not None:
        os.makedirs(os.path.dirname(os.path.abspath(os.fspath(path))), exist_ok=True)  # a new folder is fine
        save_figure(fig, path)
        if created:
            import matplotlib.pyplot as plt

            plt.close(fig)
    return fig


#: A plan of more samples than this is drawn decimated (min/max per column); a shorter one whole, as it is.
PLAN_DRAWN_WHOLE = 200_000


def _plan_series(plan) -> dict:
    """The setpoints to draw: a long plan's min/max per pixel column (`rdea_lab.protocols.Plan.decimated`,
    window by window), a short one's (or a plan-like object's) whole arrays."""
    if hasattr(plan, "decimated") and plan.samples > PLAN_DRAWN_WHOLE:
        return plan.decimated()
    return {"stretch": (plan.time, plan.stretch), "voltage": (plan.time, plan.voltage), "per_column": 1}


def _plan_on(ax, plan, series=None):
    """Stretch setpoint on ``ax``, voltage setpoint on a twin y-axis; returns the twin axis."""
    series = _plan_series(plan) if series is None else series
    ax.plot(*series["stretch"], color="tab:blue")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("stretch λ1 [-]", color="tab:blue")
    ax.grid(alpha=0.3)
    twin = ax.twinx()
    t, v = series["voltage"]
    twin.plot(t, np.asarray(v) / 1e3, color="tab:red")
    twin.set_ylabel("voltage [kV]", color="tab:red")
    return twin


def plot_plan(plan, path=None, *, ax=None):
    """Stretch and voltage setpoints of a plan against time.

    Parameters
    ----------
    plan : Plan
        An expanded protocol (:func:`rdea_lab.protocols.load_plan`): ``time`` [s],
        ``stretch`` [-], ``voltage`` [V]. One of more than `PLAN_DRAWN_WHOLE` samples is drawn as the min
        and max of its samples in each of 2000 runs (`rdea_lab.protocols.Plan.decimated`, said in the
        title), never held whole.
    path : str or path-like, optional
        Save the figure there as PNG (dpi 200). A figure made here is then
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
    series = _plan_series(plan)
    samples = plan.samples if hasattr(plan, "samples") else plan.time.size
    title = f"{plan.name} ({plan.kind}), {samples} samples at {plan.sample_rate:g} Hz"
    if series["per_column"] > 1:
        title += f"\n(drawn: min and max of each {series['per_column']} samples)"
    if ax is not None:
        _plan_on(ax, plan, series)
        ax.set_title(title)
        return _finish(ax.figure, path, created=False, tight=False)
    fig = _new_figure((8, 5))
    axes = fig.subplots(2, 1, sharex=True)
    axes[0].plot(*series["stretch"], color="tab:blue")
    axes[0].set_ylabel("stretch λ1 [-]")
    t, v = series["voltage"]
    axes[1].plot(t, np.asarray(v) / 1e3, color="tab:red")
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
    for name in ("force", "capacitance", "force_lower", "force_upper"):
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


def plot_run(ds, path=None, *, ax=None, fig=None, prediction=None, envelope=None):
    """Time histories of a run and its force-displacement loop.

    Parameters
    ----------
    ds : xarray.Dataset
        A run (:func:`rdea_lab.store.open_run`) over ``time`` [s]: ``stretch`` [-],
        ``voltage`` [V] (no panel for a run at 0 V throughout, `is_zero_voltage`),
        ``force`` [N], ``position`` [m] and ``capacitance`` [F] (a panel when any
        of it was measured).
    path : str or path-like, optional
        Save the figure there as PNG (dpi 200). A figure made here is then
        closed (it is still returned).
    ax : matplotlib.axes.Axes, optional
        Draw only force [N] against time [s] on this axis.
    fig : matplotlib.figure.Figure, optional
        Draw the full layout into this (empty) figure: time histories on the
        left, force [N] against displacement [mm] on the right. Not with ``ax``.
    prediction : xarray.Dataset, optional
        The twin on the same ``time``: ``force`` [N] and optionally
        ``capacitance`` [F], drawn dashed and labelled ``twin`` over the
        measurement (force panel, loop and capacitance panel, or ``ax``); in
        the full layout a residual panel (`residual_panel`: predicted -
        measured in N or pF, and in % of the run's peak) under each of them.
    envelope : bool, optional
        Draw each time history as its min/max envelope per pixel column
        (:func:`rdea_lab.reports.decimate.envelope`, read chunk by chunk, so a
        lazily opened run is never loaded whole; a one-sample spike stays
        visible) and the loop as the pixels its samples fall in; the title
        says so. Default (None): for a run of more than `ENVELOPE_ABOVE`
        samples. False: every sample drawn (the run is read whole).

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
    if envelope or (envelope is None and ds.sizes["time"] > ENVELOPE_ABOVE):
        from .long_plots import plot_long_run

        styles = {"own": _run_label(ds), "prediction": dict(PREDICTION, label=_prediction_label(prediction))}
        return plot_long_run(ds, ax=ax, fig=fig, prediction=prediction, new_figure=_new_figure, finish=_finish,
                             path=path, styles=styles, dpi=DPI)
    pred = _prediction(ds, prediction)
    t = ds["time"].values
    own = _run_label(ds)
    style = dict(PREDICTION, label=_prediction_label(prediction))
    band = ({"lower": pred["force_lower"], "upper": pred["force_upper"],
             "level": float(prediction.attrs.get("band_level", math.nan)),
             "status": str(prediction.attrs.get("band_status", ""))} if "force_lower" in pred else None)
    if ax is not None:
        if band is not None:
            band_shade(ax, t, **band)
        ax.plot(t, ds["force"].values, lw=0.8, label=own)
        if "force" in pred:
            ax.plot(t, pred["force"], **style)
            ax.legend(fontsize=8)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("force [N]")
        ax.grid(alpha=0.3)
        return _finish(ax.figure, path, created=False, tight=False)
    measured_c = bool(np.any(np.isfinite(ds["capacitance"].values)))
    zero_v = is_zero_voltage(ds["voltage"].values)
    series = [("stretch", 1.0, "stretch λ1 [-]")] + ([] if zero_v else [("voltage", 1e-3, "voltage [kV]")])
    series.append(("force", 1.0, "force [N]"))
    if measured_c:
        series.append(("capacitance", 1e12, "capacitance [pF]"))
    panels = []  # (kind, name, scale, label): a series, or the residual under the one before
    for name, scale, label in series:
        panels.append(("series", name, scale, label))
        if name in pred:
            panels.append(("residual", name, scale, "pF" if name == "capacitance" else "N"))
    heights = [1.0 if kind == "series" else 0.6 for kind, *_ in panels]
    created = fig is None
    if created:
        fig = _new_figure((11, 2.3 * sum(heights)))
    grid = fig.add_gridspec(len(panels), 2, height_ratios=heights)
    for i, (kind, name, scale, label) in enumerate(panels):
        a = fig.add_subplot(grid[i, 0])
        measured = ds[name].values
        if kind == "residual":
            ok = np.isfinite(measured)
            residual_panel(a, t[ok], measured[ok], pred[name][ok], float(np.nanmax(np.abs(measured))), label, scale)
        else:
            if name == "force" and band is not None:
                band_shade(a, t, **band)
            a.plot(t, measured * scale, lw=0.8, label=own)
            if name in pred:
                a.plot(t, pred[name] * scale, **style)
                a.legend(fontsize=8)
            a.set_ylabel(label)
            a.grid(alpha=0.3)
        if i == len(panels) - 1:
            a.set_xlabel("time [s]")
    x = ds["position"].values * 1e3
    force = ds["force"].values
    loop_rows = slice(0, len(panels) - 1) if "force" in pred else slice(0, len(panels))
    a = fig.add_subplot(grid[loop_rows, 1])
    a.plot(x, force, lw=0.8, label=own)
    if "force" in pred:
        a.plot(x, pred["force"], **style)
        a.legend(fontsize=8)
        r = fig.add_subplot(grid[len(panels) - 1, 1])
        residual_panel(r, x, force, pred["force"], float(np.nanmax(np.abs(force))))
        r.set_xlabel("displacement [mm]")
    else:
        a.set_xlabel("displacement [mm]")
    a.set_ylabel("force [N]")
    a.grid(alpha=0.3)
    fig.suptitle(_title(ds) + (" at 0 V throughout" if zero_v else ""))
    return _finish(fig, path, created)
