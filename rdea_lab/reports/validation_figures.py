"""Figures of the validation report, in the manner of Figures 11-16 of [1].

Measured in the specimen's colour (red, blue, green for specimens 1-3, as in
the paper), the twin's prediction dashed black, and under every time history
and loop the residual, twin − measured, in N (or pF) and in % of the run's
peak (:func:`~rdea_lab.reports.plots.residual_panel`); with bands, the prediction band shaded grey
over the force's time history (:func:`~rdea_lab.reports.plots.band_shade`). PNG at `DPI` and, if
asked for, a PDF beside each (vector, for a paper). A run at 0 V throughout gets no
voltage axis. A series longer than three times `BINS` is drawn through the
samples :func:`~rdea_lab.reports.plots.minmax_index` keeps (each bin's first,
last, smallest and largest value: the same picture with fewer vertices; the
errors in the tables use every sample).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .plots import band_shade, is_zero_voltage, minmax_index, residual_panel, save_figure

SPECIMEN_COLORS = {"specimen-1": "tab:red", "specimen-2": "tab:blue", "specimen-3": "tab:green"}
OTHER_COLORS = ("tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")
PRED = {"color": "black", "ls": "--", "lw": 1.0}
DPI = 200
#: Index bins of a drawn series (about a panel's width in pixels at `DPI`).
BINS = 1500


def _drawn(s: dict, keys=("position", "voltage", "force", "force_pred"), mask=None) -> dict:
    """The series ``s[k]`` for ``k`` in ``keys`` (and ``t``) at the samples to draw (within ``mask``)."""
    where = np.flatnonzero(mask) if mask is not None else np.arange(s["t"].size)
    ys = [s[k][where] for k in keys] + [s["force_pred"][where] - s["force"][where]]
    keys = (*keys, *(k for k in BAND_KEYS if k in s))  # a band's bounds drawn at the same samples
    pick = where[minmax_index(where.size, ys, BINS)]
    return {k: s[k][pick] for k in ("t", *keys)}


#: The series of a prediction band (`rdea_lab.reports.validation.add_bands`), when the report has bands.
BAND_KEYS = ("force_lower", "force_upper")


def _band(ax, full: dict, s: dict) -> None:
    """Shade the run's prediction band over time, if the report has one (`band_shade`)."""
    if "force_lower" in s:
        band_shade(ax, s["t"], s["force_lower"], s["force_upper"], full["band_level"], full["band_status"])


def _color(specimen: str, order: list[str]) -> str:
    if specimen in SPECIMEN_COLORS:
        return SPECIMEN_COLORS[specimen]
    return OTHER_COLORS[order.index(specimen) % len(OTHER_COLORS)]


def _save(fig, path: Path, pdf: bool = True) -> Path:
    save_figure(fig, path, dpi=DPI, vector=pdf)
    return Path(path)


def _title(row) -> str:
    """Which run, its role and error; a second line with its extrapolation flags, if any."""
    flags = f"\nbeyond the calibration: {'; '.join(row['flags'])}" if row.get("flags") else ""
    return (f"{row['specimen']}, {row['name']} ({row.get('role', '?')}): max. rel. error "
            f"{100 * row['max_rel_error']:.2f} %, model {row['model'].upper()}{flags}")


#: Margins [in] of the figures: fixed, as a layout engine costs more than the drawing (text measured
#: once for the layout and again for each file).
MARGINS = {"left": 0.85, "right": 0.8, "top": 0.5, "bottom": 0.55}
#: Gap [in] between groups of panels (an x label and tick labels, a title) and within a group.
GROUP_GAP, PANEL_GAP = 0.75, 0.12


def _grid(fig, groups: list[list[float]], ncols: int = 1, wspace: float = 0.0):
    """Axes in vertical groups (panels of a group touch but for `PANEL_GAP`; groups `GROUP_GAP` apart),
    inside `MARGINS`; ``groups`` gives each group's panel heights [in]. Returns one list of axes rows
    per group, each row a list of ``ncols`` axes."""
    w, h = fig.get_size_inches()
    m = MARGINS
    outer = fig.add_gridspec(len(groups), 1, height_ratios=[sum(g) + PANEL_GAP * (len(g) - 1) for g in groups],
                             left=m["left"] / w, right=1 - m["right"] / w, top=1 - m["top"] / h,
                             bottom=m["bottom"] / h,
                             hspace=GROUP_GAP / np.mean([sum(g) for g in groups]))
    out = []
    for spec, g in zip(outer, groups):
        inner = spec.subgridspec(len(g), ncols, height_ratios=g, hspace=PANEL_GAP / np.mean(g), wspace=wspace)
        out.append([[fig.add_subplot(inner[i, j]) for j in range(ncols)] for i in range(len(g))])
    return out


def tensile_figure(e: dict, color: str) -> Figure:
    """Figures 11-13: displacement (and voltage) over time; force over time and against displacement,
    each with its residual panel below."""
    s, row = _drawn(e["series"]), e["row"]
    peak = float(np.max(np.abs(e["series"]["force"])))
    fig = Figure(figsize=(8, 10))
    history, loop = _grid(fig, [[1.6, 2.0, 1.0], [2.4, 1.0]])
    axes = [row[0] for row in history + loop]
    for a in axes[:2]:
        a.sharex(axes[2])
        a.tick_params(labelbottom=False)
    axes[3].sharex(axes[4])
    axes[3].tick_params(labelbottom=False)
    ax = axes[0]
    ax.plot(s["t"], s["position"] * 1e3, color="black", lw=0.9)
    ax.set_ylabel("displacement [mm]")
    ax.set_title(_title(row), fontsize=8, loc="left")
    if is_zero_voltage(s["voltage"]):
        ax.text(0.01, 0.96, "0 V throughout", transform=ax.transAxes, ha="left", va="top", fontsize=8,
                color="tab:gray")
    else:
        ax2 = ax.twinx()
        ax2.plot(s["t"], s["voltage"] / 1e3, color="tab:gray", lw=0.8, ls=":")
        ax2.set_ylabel("voltage [kV] (dotted)")
    ax = axes[1]
    _band(ax, e["series"], s)
    ax.plot(s["t"], s["force"], color=color, lw=0.9, label="measured")
    ax.plot(s["t"], s["force_pred"], **PRED, label="twin")
    ax.set_ylabel("force [N]")
    ax.legend(fontsize=8)
    residual_panel(axes[2], s["t"], s["force"], s["force_pred"], peak, color=color)
    axes[2].set_xlabel("time [s]")
    ax = axes[3]
    ax.plot(s["position"] * 1e3, s["force"], color=color, lw=0.9, label="measured")
    ax.plot(s["position"] * 1e3, s["force_pred"], **PRED, label="twin")
    ax.set_ylabel("force [N]")
    ax.legend(fontsize=8)
    residual_panel(axes[4], s["position"] * 1e3, s["force"], s["force_pred"], peak, color=color)
    axes[4].set_xlabel("displacement [mm]")
    for ax in axes[:2]:
        ax.grid(alpha=0.3)
    axes[3].grid(alpha=0.3)
    return fig


def blocking_figure(items: list[dict], colors: dict) -> Figure:
    """Figure 15: blocking force over time (left) and over voltage (right), one pair of rows per run
    (the curves, then their residual)."""
    fig = Figure(figsize=(11, 3.8 * len(items)))
    groups = _grid(fig, [[1.9, 0.85]] * len(items), ncols=2, wspace=0.3)
    for e, ((left, right), (rleft, rright)) in zip(items, groups):
        for top, bottom in ((left, rleft), (right, rright)):
            top.sharex(bottom)
            top.tick_params(labelbottom=False)
        full, row = e["series"], e["row"]
        c = colors[row["specimen"]]
        w = full.get("window", np.ones(full["t"].size, bool))
        peak = float(np.max(np.abs(full["force"][w])))  # the row's error scale: the force during the window
        s, sw = _drawn(full), _drawn(full, mask=w)
        _band(left, full, s)
        left.plot(s["t"], s["force"], color=c, lw=0.7, label=f"{row['specimen']} measured")
        left.plot(s["t"], s["force_pred"], **PRED, label="twin")
        left.set_ylabel("force [N]")
        left.set_title(_title(row), fontsize=8, loc="left")
        residual_panel(rleft, s["t"], s["force"], s["force_pred"], peak, color=c, lw=0.5)
        rleft.set_xlabel("time [s]")
        right.plot(sw["voltage"] / 1e3, sw["force"], color=c, lw=0.7, label="measured")
        right.plot(sw["voltage"] / 1e3, sw["force_pred"], **PRED, label="twin")
        right.set_ylabel("force [N]")
        right.set_title("during the voltage cycles", fontsize=8)
        residual_panel(rright, sw["voltage"] / 1e3, sw["force"], sw["force_pred"], peak, color=c, lw=0.3)
        rright.set_xlabel("voltage [kV]")
        for ax in (left, right):
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    return fig


def capacitance_figure(items: list[dict], colors: dict) -> Figure:
    """Figure 16: capacitance against displacement, measured and predicted, every run on one axis;
    below, each run's residual in % of its own peak capacitance (the runs' peaks differ)."""
    fig = Figure(figsize=(7, 6))
    ((ax,), (res,)), = _grid(fig, [[3.4, 1.5]])
    ax.sharex(res)
    ax.tick_params(labelbottom=False)
    for e in items:
        s, row = e["series"], e["row"]
        c = colors[row["specimen"]]
        x = s["position"][s["cap_mask"]] * 1e3
        ax.plot(x, s["capacitance"] * 1e12, color=c, lw=0.8,
                label=f"{row['specimen']} measured ({100 * row['max_rel_error']:.2f} %)")
        ax.plot(x, s["capacitance_pred"] * 1e12, **PRED, label="twin" if e is items[0] else None)
        peak = float(np.max(np.abs(s["capacitance"])))
        res.plot(x, 100.0 * (s["capacitance_pred"] - s["capacitance"]) / peak, color=c, lw=0.7,
                 label=f"{row['specimen']}: rms {row['rms_text']}")
    ax.set_ylabel("capacitance [pF]")
    ax.set_title("capacitance at 0 V (LCR bridge), measured and predicted", fontsize=9)
    ax.legend(fontsize=8)
    res.axhline(0.0, color="tab:gray", lw=0.6)
    res.set_ylabel("twin − measured\n[% of the run's peak]", fontsize=8)
    res.set_xlabel("displacement [mm]")
    res.legend(fontsize=7)
    for a in (ax, res):
        a.grid(alpha=0.3)
    return fig


def write_figures(evaluated: list[dict], out: Path, pdf: bool = True, executor=None) -> dict[Path, str]:
    """Every figure of the report into ``out`` (PNG, and with ``pdf`` a PDF beside each); returns the PNGs
    written, each with a caption. With ``executor`` (a process pool) each figure is drawn by a task."""
    specimens = sorted({e["row"]["specimen"] for e in evaluated})
    colors = {sp: _color(sp, specimens) for sp in specimens}
    jobs = {}  # path -> (figure function, its data, caption)
    for e in evaluated:
        row = e["row"]
        if row["quantity"] == "force" and row["kind"] != "blocking":
            prefix = "tensile" if row["kind"] in ("tensile", "capacitance") else "run"
            stem = f"{prefix}_{row['specimen']}_{row['name']}"
            name, n = f"{stem}.png", 1
            while out / name in jobs:  # the same run name twice on one specimen
                n += 1
                name = f"{stem}_{n}.png"
            jobs[out / name] = (tensile_figure, (_drawn_part(e), colors[row["specimen"]]), (
                f"As Figures 11-13: {row['specimen']}, {row['name']} ({row['protocol']}, {row['voltage']}, "
                f"{row['role']}): displacement, force over time, force against displacement; measured and twin, "
                "with the residual (twin − measured, in N and in % of the run's peak force) under each."))
    blocking = [_drawn_part(e) for e in evaluated if e["row"]["kind"] == "blocking"]
    if blocking:
        jobs[out / "blocking_force.png"] = (blocking_figure, (blocking, colors), (
            "As Figure 15: blocking force over time and, during the voltage cycles, over voltage; measured and twin, "
            "with the residual (N and % of the peak force during the voltage cycles) under each."))
    cap = [_drawn_part(e) for e in evaluated if e["row"]["quantity"] == "capacitance"]
    if cap:
        jobs[out / "capacitance.png"] = (capacitance_figure, (cap, colors), (
            "As Figure 16: capacitance at 0 V against displacement; measured (LCR bridge) and twin, with each run's "
            "residual in % of its peak capacitance below."))
    paths = list(jobs)
    if executor is None:
        written = [_draw(jobs[p][0], jobs[p][1], p, pdf) for p in paths]
    else:  # the blocking figure (the largest) first, so that no task is left alone at the end
        order = sorted(paths, key=lambda p: jobs[p][0] is not blocking_figure)
        futures = {p: executor.submit(_draw, jobs[p][0], jobs[p][1], p, pdf) for p in order}
        written = [futures[p].result() for p in paths]
    return {path: jobs[key][2] for path, key in zip(written, paths)}


def _drawn_part(e: dict) -> dict:
    """What the figures use of an evaluated run (its row and series: what a drawing task is sent)."""
    return {"row": e["row"], "series": e["series"]}


def _draw(figure, args, path, pdf) -> Path:
    """``figure(*args)`` saved to ``path`` (one figure: a task of `write_figures`)."""
    return _save(figure(*args), path, pdf)
