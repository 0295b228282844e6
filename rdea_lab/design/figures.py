"""A study's figures: the Pareto front, parallel coordinates, the stroke map (matplotlib)."""

from __future__ import annotations

import numpy as np

from ..specs.study import METRICS

_DPI = 150


def _plt():
    import matplotlib.pyplot as plt  # the backend is the caller's (the CLI runs headless)
    return plt


def _scaled(metric, values):
    """Values in the metric's display unit, and its axis label."""
    from ..specs.units import ureg
    si, unit, text = METRICS[metric]
    if unit and unit != si:
        factor = ureg.Quantity(1.0, si.replace("^", "**")).to(unit.replace("^", "**")).magnitude
    else:
        factor = 1.0
    return np.asarray(values, float) * factor, f"{metric.replace('_', ' ')} [{unit or '-'}]"


def _var_scaled(study, name, values):
    from ..specs.units import ureg
    from .study import _si
    v = next(x for x in study.variables if x.name == name)
    si = _si(name)
    factor = ureg.Quantity(1.0, si).to(v.unit).magnitude if v.unit and si != "1" else 1.0
    return np.asarray(values, float) * factor, f"{name} [{v.unit or '-'}]"


def pareto_figure(ds, study, path) -> None:
    """The first two objectives of every feasible design, the front highlighted (one objective: against
    the first variable)."""
    plt = _plt()
    ok = ds["feasible"].values.astype(bool)
    front = ds["pareto"].values.astype(bool)
    fig, ax = plt.subplots(figsize=(6.4, 4.8), constrained_layout=True)
    g = study.objectives
    if len(g) >= 2:
        x, xl = _scaled(g[0].metric, ds[g[0].metric].values)
        y, yl = _scaled(g[1].metric, ds[g[1].metric].values)
    else:
        x, xl = _var_scaled(study, study.names[0], ds[study.names[0]].values)
        y, yl = _scaled(g[0].metric, ds[g[0].metric].values)
    ax.scatter(x[~ok], y[~ok], s=6, c="0.8", label=f"infeasible ({int((~ok).sum())})", rasterized=True)
    ax.scatter(x[ok & ~front], y[ok & ~front], s=8, c="tab:blue", alpha=0.5,
               label=f"feasible ({int(ok.sum())})", rasterized=True)
    order = np.argsort(x[front])
    ax.plot(x[front][order], y[front][order], "o-", c="tab:red", ms=4, lw=1, label=f"Pareto front ({int(front.sum())})")
    if "optimum" in ds.attrs and len(g) >= 2:
        import json
        o = json.loads(ds.attrs["optimum"])["metrics"]
        ox, _ = _scaled(g[0].metric, o[g[0].metric])
        oy, _ = _scaled(g[1].metric, o[g[1].metric])
        ax.plot(ox, oy, "*", c="k", ms=14, label="optimum")
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.set_title(f"study {study.name}: {', '.join(x.label for x in g)}")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)


def parallel_figure(ds, study, path, max_lines: int = 2000) -> None:
    """Parallel coordinates of the feasible designs over the variables and objectives (each axis its own
    range, 0 to 1), coloured by the first objective; the front drawn over them."""
    plt = _plt()
    ok = np.flatnonzero(ds["feasible"].values.astype(bool))
    if ok.size > max_lines:
        ok = ok[np.linspace(0, ok.size - 1, max_lines).astype(int)]
    front = np.flatnonzero(ds["pareto"].values.astype(bool))
    cols = list(study.names) + [g.metric for g in study.objectives]
    data = np.stack([ds[c].values for c in cols], axis=1)
    lo = np.nanmin(data[ok], axis=0) if ok.size else np.zeros(len(cols))
    hi = np.nanmax(data[ok], axis=0) if ok.size else np.ones(len(cols))
    for j, v in enumerate(study.variables):
        lo[j], hi[j] = v.low, v.high
    span = np.where(hi > lo, hi - lo, 1.0)
    norm = (data - lo) / span
    first = study.objectives[0].metric
    c = ds[first].values
    fig, ax = plt.subplots(figsize=(max(6.4, 1.4 * len(cols)), 4.8), constrained_layout=True)
    xs = np.arange(len(cols))
    cmap = plt.get_cmap("viridis")
    cmin, cmax = (np.nanmin(c[ok]), np.nanmax(c[ok])) if ok.size else (0, 1)
    for i in ok:
        ax.plot(xs, norm[i], c=cmap((c[i] - cmin) / ((cmax - cmin) or 1.0)), lw=0.5, alpha=0.35)
    for i in front:
        ax.plot(xs, norm[i], c="tab:red", lw=1.2, alpha=0.9)
    ax.set_xticks(xs)
    ax.set_xticklabels([f"{k}\n{_fmt(k, study, lo[j])}..{_fmt(k, study, hi[j])}" for j, k in enumerate(cols)],
                       fontsize=8)
    ax.set_ylim(-0.05, 1.05)
    ax.set_ylabel("position in range [-]")
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(*_scaled(first, [cmin, cmax])[0]))
    fig.colorbar(sm, ax=ax, label=_scaled(first, [0])[1])
    ax.set_title(f"study {study.name}: feasible designs (red: Pareto front)")
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)


def _fmt(name, study, value):
    if name in study.names:
        v, _ = _var_scaled(study, name, [value])
    else:
        v, _ = _scaled(name, [value])
    return f"{v[0]:.3g}"


def stroke_map(ds, study, path) -> None:
    """The stroke (or the first objective, without a stroke) over the first two variables; feasible
    designs filled, the others hollow."""
    plt = _plt()
    metric = "stroke" if "stroke" in ds else study.objectives[0].metric
    z, zl = _scaled(metric, ds[metric].values)
    ok = ds["feasible"].values.astype(bool)
    fig, ax = plt.subplots(figsize=(6.4, 4.8), constrained_layout=True)
    names = study.names
    x, xl = _var_scaled(study, names[0], ds[names[0]].values)
    if len(names) == 1:
        ax.plot(x[ok], z[ok], ".", ms=4)
        ax.set_xlabel(xl)
        ax.set_ylabel(zl)
    else:
        y, yl = _var_scaled(study, names[1], ds[names[1]].values)
        finite = np.isfinite(z)
        vmin, vmax = (np.nanmin(z[finite]), np.nanmax(z[finite])) if finite.any() else (0, 1)
        if len(names) == 2 and study.method == "grid":
            nx, ny = study.variables[0].levels, study.variables[1].levels
            pc = ax.pcolormesh(x.reshape(nx, ny), y.reshape(nx, ny), z.reshape(nx, ny), shading="nearest",
                               vmin=vmin, vmax=vmax)
        else:
            pc = ax.scatter(x[ok], y[ok], c=z[ok], s=14, vmin=vmin, vmax=vmax, rasterized=True)
            ax.scatter(x[~ok], y[~ok], facecolors="none", edgecolors="0.6", s=14, lw=0.5,
                       label="infeasible", rasterized=True)
            if (~ok).any():
                ax.legend(fontsize=8, loc="best")
        fig.colorbar(pc, ax=ax, label=zl)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        if len(names) > 2:
            ax.set_title(f"study {study.name}: {metric} over {names[0]}, {names[1]} (the other variables vary)",
                         fontsize=9)
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
