"""The run figure of a long run, drawn from min/max envelopes read chunk by chunk (`rdea_lab.reports.decimate`).

:func:`rdea_lab.reports.plots.plot_run` comes here for a run of more than
:data:`~rdea_lab.reports.plots.ENVELOPE_ABOVE` samples: the same panels, each
series drawn as its envelope per pixel column (a one-sample spike stays
visible), the force-displacement loop as the raster cells its samples fall in
(`~rdea_lab.reports.decimate.occupancy`), and the title says so. Nothing of the
run is held but one chunk of each variable and the envelopes.
"""

from __future__ import annotations

import math

import numpy as np

from . import decimate

#: The share of the figure's width the time histories take (the left column of `plot_run`'s grid).
LEFT = 0.45


def pixel_columns(ax_or_width, dpi: int) -> int:
    """Pixel columns of an axis (or of a width [in]) at ``dpi``."""
    if hasattr(ax_or_width, "get_position"):
        width = ax_or_width.get_position().width * ax_or_width.figure.get_figwidth()
    else:
        width = float(ax_or_width)
    return max(1, int(round(width * dpi)))


def _finite_range(lo, hi) -> tuple[float, float]:
    """The range of an envelope's finite values, or (nan, nan)."""
    lo, hi = lo[np.isfinite(lo)], hi[np.isfinite(hi)]
    return (float(lo.min()), float(hi.max())) if lo.size else (math.nan, math.nan)


def note(per: int) -> str:
    """What the figure says of the decimation."""
    return f"min/max envelope of {per} samples per pixel column"


def _residual(pred, measured):
    """A sliceable ``pred[a:b] - measured[a:b]``."""
    class Residual:
        def __getitem__(self, s):
            return decimate._slice(pred, s.start, s.stop) - decimate._slice(measured, s.start, s.stop)
    return Residual()


def check_prediction(ds, prediction, n: int) -> dict:
    """The prediction's series (sliceable, not read), checked against the run's length and end times."""
    if prediction is None:
        return {}
    if "force" not in prediction:
        raise ValueError(f"prediction has no 'force' variable (it has {sorted(prediction.data_vars)})")
    out = {}
    for name in ("force", "capacitance", "force_lower", "force_upper"):
        if name in prediction:
            if prediction[name].shape != (n,):
                raise ValueError(f"prediction {name} has shape {prediction[name].shape}; the run has {n} samples "
                                 "on 'time'")
            out[name] = prediction[name]
    if "time" in prediction.variables:
        ends = [float(prediction["time"][i]) for i in (0, -1)]
        own = [float(ds["time"][i]) for i in (0, -1)]
        if not np.allclose(ends, own, rtol=1e-9, atol=1e-9):
            raise ValueError(f"prediction time ({ends[0]:g} ... {ends[1]:g} s) is not the run's time "
                             f"({own[0]:g} ... {own[1]:g} s)")
    return out


def series_envelopes(ds, names, sources: dict, n: int, columns: int):
    """``(per, t, envelopes, from_overview)``: the envelopes of the run's variables ``names`` and of the
    other ``sources`` at ``per`` samples per column (at most ``columns`` columns), ``t`` each column's first
    time [s]. The run's variables come from its file's overview (`rdea_lab.store.overview`) when it has one
    (``per`` then a multiple of its block; the same envelopes as of the samples), else are read chunk by chunk."""
    from ..store.overview import read_overview

    ov = read_overview(ds)
    if ov is None or ov.samples != n or not all(k in ov.envelopes for k in ("time", *names)):
        per = decimate.samples_per_column(n, columns)
        env = decimate.envelopes({**{k: ds[k] for k in names}, **sources}, n, per)
        return per, decimate.first_of_columns(ds["time"], n, per), env, None
    m = math.ceil(decimate.samples_per_column(n, columns) / ov.block)
    per = m * ov.block
    env = {k: (decimate.envelope(ov.envelopes[k][0], m)[0], decimate.envelope(ov.envelopes[k][1], m)[1])
           for k in names}
    env.update(decimate.envelopes(sources, n, per) if sources else {})
    return per, decimate.envelope(ov.envelopes["time"][0], m)[0], env, ov


def plot_long_run(ds, *, ax=None, fig=None, prediction=None, new_figure, finish, path, styles, dpi):
    """`plot_run` of a long run (see the module's docstring); ``styles`` are `plot_run`'s labels and styles,
    ``new_figure`` and ``finish`` its figure helpers."""
    from .plots import _title, residual_axes

    n = int(ds.sizes["time"])
    pred = check_prediction(ds, prediction, n)
    own, style = styles["own"], styles["prediction"]
    if ax is not None:
        per, t, env, _ = series_envelopes(ds, ["force"], {f"pred_{k}": v for k, v in pred.items()}, n,
                                          pixel_columns(ax, dpi))
        _band(ax, t, env)
        ax.plot(*decimate.stroke(t, *env["force"]), lw=0.8, label=own)
        if "force" in pred:
            ax.plot(*decimate.stroke(t, *env["pred_force"]), **style)
            ax.legend(fontsize=8)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("force [N]")
        ax.set_title(note(per), fontsize=8)
        ax.grid(alpha=0.3)
        return finish(ax.figure, path, created=False, tight=False)
    created = fig is None
    if created:
        fig = new_figure((11, 2.3))  # resized when the panels are known
    names = [k for k in ("stretch", "voltage", "force", "capacitance", "position") if k in ds]
    sources = {f"pred_{k}": v for k, v in pred.items()}
    sources.update({f"res_{k}": _residual(pred[k], ds[k]) for k in ("force", "capacitance") if k in pred})
    per, t, env, ov = series_envelopes(ds, names, sources, n, pixel_columns(fig.get_figwidth() * LEFT, dpi))
    ranges = {k: _finite_range(*v) for k, v in env.items()}
    from .plots import ZERO_VOLTAGE

    measured_c = "capacitance" in env and math.isfinite(ranges["capacitance"][0])
    vr = ranges.get("voltage", (0.0, 0.0))
    zero_v = not (max(abs(vr[0]), abs(vr[1])) >= ZERO_VOLTAGE)  # NaN (never measured) counts as 0 V
    series = [("stretch", 1.0, "stretch λ1 [-]")] + ([] if zero_v else [("voltage", 1e-3, "voltage [kV]")])
    series.append(("force", 1.0, "force [N]"))
    if measured_c:
        series.append(("capacitance", 1e12, "capacitance [pF]"))
    panels = []
    for name, scale, label in series:
        panels.append(("series", name, scale, label))
        if name in pred:
            panels.append(("residual", name, scale, "pF" if name == "capacitance" else "N"))
    heights = [1.0 if kind == "series" else 0.6 for kind, *_ in panels]
    if created:
        fig.set_figheight(2.3 * sum(heights))
    grid = fig.add_gridspec(len(panels), 2, height_ratios=heights)
    for i, (kind, name, scale, label) in enumerate(panels):
        a = fig.add_subplot(grid[i, 0])
        if kind == "residual":
            lo, hi = env[f"res_{name}"]
            a.plot(*decimate.stroke(t, lo * scale, hi * scale), color="black", lw=0.7)
            peak = max(abs(v) for v in ranges[name])
            residual_axes(a, peak, label, scale)
        else:
            if name == "force":
                _band(a, t, env)
            lo, hi = env[name]
            a.plot(*decimate.stroke(t, lo * scale, hi * scale), lw=0.8, label=own)
            if name in pred:
                plo, phi = env[f"pred_{name}"]
                a.plot(*decimate.stroke(t, plo * scale, phi * scale), **style)
                a.legend(fontsize=8)
            a.set_ylabel(label)
            a.grid(alpha=0.3)
        if i == len(panels) - 1:
            a.set_xlabel("time [s]")
    loop_rows = slice(0, len(panels) - 1) if "force" in pred else slice(0, len(panels))
    a = fig.add_subplot(grid[loop_rows, 1])
    shape = (max(1, pixel_columns(a.get_position().height * fig.get_figheight(), dpi // 2)),
             max(1, pixel_columns(a.get_position().width * fig.get_figwidth(), dpi // 2)))
    xlim = tuple(1e3 * v for v in ranges.get("position", (math.nan, math.nan)))
    curves = [(ds["force"], "tab:blue", own)] + ([(pred["force"], "black", style["label"])] if "force" in pred else [])
    ylim = _union([ranges["force"]] + ([ranges["pred_force"]] if "force" in pred else []))
    if ov is not None and ov.loop is not None and "force" not in pred:  # the raster stored with the run
        x0, x1, y0, y1 = ov.loop_extent
        _draw_raster(a, ov.loop, (1e3 * x0, 1e3 * x1), (y0, y1), "tab:blue", own)
    else:
        for y, color, label in curves:
            _raster(a, _scaled(ds["position"], 1e3), y, n, xlim, ylim, shape, color, label)
    if "force" in pred:
        a.legend(fontsize=8)
        r = fig.add_subplot(grid[len(panels) - 1, 1])
        rlim = ranges["res_force"]
        _raster(r, _scaled(ds["position"], 1e3), sources["res_force"], n, xlim, rlim, shape, "black", None)
        residual_axes(r, max(abs(v) for v in ranges["force"]), "N", 1.0)
        r.set_xlabel("displacement [mm]")
    else:
        a.set_xlabel("displacement [mm]")
    a.set_ylabel("force [N]")
    a.grid(alpha=0.3)
    fig.suptitle(_title(ds) + (" at 0 V throughout" if zero_v else "") + f"\n{n} samples: time histories as "
                 f"{note(per)}; loop as the pixels its samples fall in", fontsize=10)
    return finish(fig, path, created)


def _union(ranges) -> tuple[float, float]:
    ranges = [r for r in ranges if math.isfinite(r[0])]
    return (min(r[0] for r in ranges), max(r[1] for r in ranges)) if ranges else (math.nan, math.nan)


def _scaled(source, k: float):
    class Scaled:
        def __getitem__(self, s):
            return decimate._slice(source, s.start, s.stop) * k
    return Scaled()


def _band(ax, t, env) -> None:
    if "pred_force_lower" in env:
        lower, upper = env["pred_force_lower"][0], env["pred_force_upper"][1]
        ok = np.isfinite(lower) & np.isfinite(upper)
        ax.fill_between(t, lower, upper, where=ok, color="tab:gray", alpha=0.3, lw=0, label="band")


def _raster(ax, x, y, n, xlim, ylim, shape, color, label) -> None:
    """Draw the cells the samples of (x, y) fall in, in ``color``."""
    if not (math.isfinite(xlim[0]) and math.isfinite(ylim[0])):
        return
    xlim, ylim = _padded(*xlim), _padded(*ylim)
    _draw_raster(ax, decimate.occupancy(x, y, n, xlim, ylim, shape), xlim, ylim, color, label)


def _padded(lo: float, hi: float) -> tuple[float, float]:
    """An extent of some width (a flat curve: one row or column about its value)."""
    return (lo, hi) if hi > lo else (lo - 0.5, hi + 0.5)


def _draw_raster(ax, counts, xlim, ylim, color, label) -> None:
    """Draw the cells of ``counts`` that hold a sample, over ``xlim`` x ``ylim``."""
    from matplotlib.colors import ListedColormap

    xlim, ylim = _padded(*xlim), _padded(*ylim)
    image = np.ma.masked_equal((counts > 0).astype(float), 0.0)
    ax.imshow(image, origin="lower", extent=(*xlim, *ylim), aspect="auto", interpolation="nearest",
              cmap=ListedColormap([color]), vmin=0.0, vmax=1.0)
    if label:
        ax.plot([], [], color=color, label=label)
