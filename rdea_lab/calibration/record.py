"""The calibration record: a parameter file that also says how it was obtained."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import yaml

from ..specs import dump_params, format_quantity

_UNIT = {"Pa": "kPa", "Pa s": "kPa s"}
_SCALE = {"Pa": 1e3, "Pa s": 1e3}


def _q(value: float, unit: str) -> str | None:
    if not math.isfinite(value):
        return None
    return f"{value / _SCALE[unit]:.6g} {_UNIT[unit]}"


def record_mapping(result, runs) -> dict:
    """The ``calibration`` section of the record (YAML-ready)."""
    params = {}
    for p in result.parameters:
        entry = {"value": _q(result.values[p.name], p.unit), "start": _q(p.start, p.unit), "free": p.free}
        if p.free:
            entry["stderr"] = _q(result.stderr.get(p.name, float("nan")), p.unit) or "not identifiable"
            entry["bounds"] = [_q(p.lo, p.unit), _q(p.hi, p.unit)]
            flags = [f for f, names in (("at bound", result.at_bound), ("never moved from start", result.unmoved),
                                        ("not identifiable", result.unidentifiable)) if p.name in names]
            if flags:
                entry["flags"] = flags
        params[p.name] = entry
    corr = [[None if not math.isfinite(c) else round(float(c), 4) for c in row] for row in result.correlation]
    return {
        "model": result.model,
        "metric": result.metric,
        "objective": float(result.objective),
        "converged": result.converged,
        "message": result.message,
        "parameters": params,
        "correlation": {"names": list(result.free_names), "matrix": corr},
        "runs": [{**g, "sha256": r.sha256} for g, r in zip(result.runs, runs)],
        "skipped": [dict(s) for s in getattr(result, "skipped", ())],
        "statistics": {"ndata": result.ndata, "nfree": result.nfree, "chisqr": result.chisqr, "redchi": result.redchi,
                       "aic": result.aic, "bic": result.bic, "nfev": result.nfev, "nit": result.nit,
                       "restarts": result.restarts, "wall_time_s": round(result.wall_time, 3)},
        "notes": ("standard errors from the Jacobian at the optimum; residuals of a time series are correlated, "
                  "so they are lower bounds"),
        "software": f"rdea-lab {result.software}",
    }


def write_record(result, runs, out: Path, name: str | None = None) -> dict[str, Path]:
    """Write ``out`` (loadable by load_params), ``<out>.history.csv`` and ``<out>.history.png``."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    params = result.params.replace(name=name) if name else result.params
    files = ", ".join(sorted({r.path.name for r in runs}))
    params = params.replace(description=f"calibrated by rdea-lab on {len(runs)} run(s): {files}",
                            source=f"rdea-lab calibrate, model {result.model}, metric {result.metric}")
    text = dump_params(params)
    text += yaml.safe_dump({"calibration": record_mapping(result, runs)}, sort_keys=False, width=1000,
                           allow_unicode=True)
    out.write_text(text)
    hist = out.with_name(out.stem + ".history.csv")
    with open(hist, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["evaluation", "best_objective"])
        w.writerows([[int(n), repr(float(f))] for n, f in result.history])
    png = out.with_name(out.stem + ".history.png")
    _plot_history(result, png)
    return {"params": out, "history": hist, "plot": png}


def _plot_history(result, path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.5))
    ax = fig.subplots()
    h = result.history
    ax.semilogy(h[:, 0], h[:, 1], drawstyle="steps-post")
    ax.set_xlabel("objective evaluations")
    ax.set_ylabel(f"best {result.metric} normalized force error [-]")
    ax.set_title(f"calibration ({result.model}, {result.nfev} evaluations, {result.restarts} restarts)")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


__all__ = ["record_mapping", "write_record", "format_quantity"]
