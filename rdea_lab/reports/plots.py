"""Plots of plans and runs (PNG, labelled axes with units)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_plan(plan, path: Path) -> Path:
    """Stretch and voltage setpoints against time."""
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    axes[0].plot(plan.time, plan.stretch, color="tab:blue")
    axes[0].set_ylabel("stretch λ1 [-]")
    axes[1].plot(plan.time, plan.voltage / 1e3, color="tab:red")
    axes[1].set_ylabel("voltage [kV]")
    axes[1].set_xlabel("time [s]")
    axes[0].set_title(f"{plan.name} ({plan.kind}), {plan.time.size} samples at {plan.sample_rate:g} Hz")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_run(ds, path: Path) -> Path:
    """Time histories of a run and its force-stretch loop."""
    t = ds["time"].values
    measured_c = np.any(np.isfinite(ds["capacitance"].values))
    rows = 4 if measured_c else 3
    fig = plt.figure(figsize=(11, 2.3 * rows))
    grid = fig.add_gridspec(rows, 2)
    series = [("stretch", 1.0, "stretch λ1 [-]"), ("voltage", 1e-3, "voltage [kV]"), ("force", 1.0, "force [N]")]
    if measured_c:
        series.append(("capacitance", 1e12, "capacitance [pF]"))
    for i, (name, scale, label) in enumerate(series):
        ax = fig.add_subplot(grid[i, 0])
        ax.plot(t, ds[name].values * scale, lw=0.8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if i == rows - 1:
            ax.set_xlabel("time [s]")
    ax = fig.add_subplot(grid[:, 1])
    ax.plot(ds["position"].values * 1e3, ds["force"].values, lw=0.8)
    ax.set_xlabel("displacement [mm]")
    ax.set_ylabel("force [N]")
    ax.grid(alpha=0.3)
    a = ds.attrs
    fig.suptitle(f"{a.get('protocol_name', '?')} on {a.get('specimen_id', '?')} ({a.get('backend', '?')}, "
                 f"{a.get('status', '?')})")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
