"""Figures of the validation report, in the manner of Figures 11-16 of [1].

Measured in the specimen's colour (red, blue, green for specimens 1-3, as in
the paper), the twin's prediction dashed black. PNG, labels with units.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

SPECIMEN_COLORS = {"specimen-1": "tab:red", "specimen-2": "tab:blue", "specimen-3": "tab:green"}
OTHER_COLORS = ("tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")
PRED = {"color": "black", "ls": "--", "lw": 1.0}
DPI = 110


def _color(specimen: str, order: list[str]) -> str:
    if specimen in SPECIMEN_COLORS:
        return SPECIMEN_COLORS[specimen]
    return OTHER_COLORS[order.index(specimen) % len(OTHER_COLORS)]


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    return Path(path)


def _title(row) -> str:
    return (f"{row['specimen']}, {row['protocol']}: max. rel. error {100 * row['max_rel_error']:.2f} %, "
            f"model {row['model'].upper()}")


def tensile_figure(e: dict, color: str, path: Path) -> Path:
    """Figures 11-13: displacement and force over time (upper), force against displacement (lower)."""
    s, row = e["series"], e["row"]
    fig = Figure(figsize=(8, 8.5))
    axes = fig.subplots(3, 1, gridspec_kw={"height_ratios": [1, 1.2, 1.6]})
    ax = axes[0]
    ax.plot(s["t"], s["position"] * 1e3, color="black", lw=0.9)
    ax.set_ylabel("displacement [mm]")
    ax.set_title(_title(row), fontsize=9)
    ax2 = ax.twinx()
    ax2.plot(s["t"], s["voltage"] / 1e3, color="tab:gray", lw=0.8, ls=":")
    ax2.set_ylabel("voltage [kV] (dotted)")
    ax = axes[1]
    ax.plot(s["t"], s["force"], color=color, lw=0.9, label="measured")
    ax.plot(s["t"], s["force_pred"], **PRED, label="twin")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.legend(fontsize=8)
    ax = axes[2]
    ax.plot(s["position"] * 1e3, s["force"], color=color, lw=0.9, label="measured")
    ax.plot(s["position"] * 1e3, s["force_pred"], **PRED, label="twin")
    ax.set_xlabel("displacement [mm]")
    ax.set_ylabel("force [N]")
    ax.legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    return _save(fig, path)


def blocking_figure(items: list[dict], colors: dict, path: Path) -> Path:
    """Figure 15: blocking force over time (left) and over voltage (right), one row per run."""
    fig = Figure(figsize=(11, 2.8 * len(items)))
    axes = fig.subplots(len(items), 2, squeeze=False)
    for (left, right), e in zip(axes, items):
        s, row = e["series"], e["row"]
        c = colors[row["specimen"]]
        left.plot(s["t"], s["force"], color=c, lw=0.7, label=f"{row['specimen']} measured")
        left.plot(s["t"], s["force_pred"], **PRED, label="twin")
        left.set_xlabel("time [s]")
        left.set_ylabel("force [N]")
        left.set_title(_title(row), fontsize=9)
        w = s.get("window", np.ones(s["t"].size, bool))
        right.plot(s["voltage"][w] / 1e3, s["force"][w], color=c, lw=0.7, label="measured")
        right.plot(s["voltage"][w] / 1e3, s["force_pred"][w], **PRED, label="twin")
        right.set_xlabel("voltage [kV]")
        right.set_ylabel("force [N]")
        right.set_title("during the voltage cycles", fontsize=9)
        for ax in (left, right):
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    return _save(fig, path)


def capacitance_figure(items: list[dict], colors: dict, path: Path) -> Path:
    """Figure 16: capacitance against displacement, measured and predicted, every run on one axis."""
    fig = Figure(figsize=(7, 4.5))
    ax = fig.subplots()
    for e in items:
        s, row = e["series"], e["row"]
        x = s["position"][s["cap_mask"]] * 1e3
        ax.plot(x, s["capacitance"] * 1e12, color=colors[row["specimen"]], lw=0.8,
                label=f"{row['specimen']} measured ({100 * row['max_rel_error']:.2f} %)")
        ax.plot(x, s["capacitance_pred"] * 1e12, **PRED, label="twin" if e is items[0] else None)
    ax.set_xlabel("displacement [mm]")
    ax.set_ylabel("capacitance [pF]")
    ax.set_title("capacitance at 0 V (LCR bridge), measured and predicted", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def write_figures(evaluated: list[dict], out: Path) -> dict[Path, str]:
    """Every figure of the report into ``out``; returns the files written, each with a caption."""
    specimens = sorted({e["row"]["specimen"] for e in evaluated})
    colors = {sp: _color(sp, specimens) for sp in specimens}
    files = {}
    for e in evaluated:
        row = e["row"]
        if row["quantity"] == "force" and row["kind"] != "blocking":
            prefix = "tensile" if row["kind"] in ("tensile", "capacitance") else "run"
            stem = f"{prefix}_{row['specimen']}_{row['protocol']}"
            name, n = f"{stem}.png", 1
            while out / name in files:  # the same protocol run twice on one specimen
                n += 1
                name = f"{stem}_{n}.png"
            files[tensile_figure(e, colors[row["specimen"]], out / name)] = (
                f"As Figures 11-13: {row['specimen']}, {row['protocol']} ({row['voltage']}): displacement and "
                "voltage, force over time, force against displacement; measured and twin.")
    blocking = [e for e in evaluated if e["row"]["kind"] == "blocking"]
    if blocking:
        files[blocking_figure(blocking, colors, out / "blocking_force.png")] = (
            "As Figure 15: blocking force over time and, during the voltage cycles, over voltage; measured and twin.")
    cap = [e for e in evaluated if e["row"]["quantity"] == "capacitance"]
    if cap:
        files[capacitance_figure(cap, colors, out / "capacitance.png")] = (
            "As Figure 16: capacitance at 0 V against displacement; measured (LCR bridge) and twin.")
    return files
