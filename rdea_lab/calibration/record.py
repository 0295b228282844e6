"""The calibration record: a parameter file that also says how it was obtained."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ..specs import dump_params, format_quantity
from .phases import PHASE_RULE, hold_spans
from ..specs.record import CalibrationRecord, FitParameter, FitRun, Matrix, Statistics

_UNIT = {"Pa": "kPa", "Pa s": "kPa s"}
_SCALE = {"Pa": 1e3, "Pa s": 1e3}


def _q(value: float, unit: str) -> str | None:
    if not math.isfinite(value):
        return None
    return f"{value / _SCALE[unit]:.6g} {_UNIT[unit]}"


def _na(result) -> str | None:
    """Why standard errors, covariance and information criteria are missing, or None if they apply."""
    return f"not applicable (metric {result.metric})" if result.metric != "rms" else None


def calibration_record(result, runs) -> CalibrationRecord:
    """The calibration record of a fit (`rdea_lab.specs.CalibrationRecord`), with lmfit's names for the statistics."""
    na = _na(result)
    params = {}
    for p in result.parameters:
        entry = {"value": _q(result.values[p.name], p.unit), "init_value": _q(p.start, p.unit), "free": p.free}
        if p.free:
            entry["stderr"] = na or _q(result.stderr.get(p.name, float("nan")), p.unit) or "not identifiable"
            entry["bounds"] = [_q(p.lo, p.unit), _q(p.hi, p.unit)]
            flags = [f for f, names in (("at bound", result.at_bound), ("never moved from start", result.unmoved),
                                        ("not identifiable", result.unidentifiable)) if p.name in names]
            if flags:
                entry["flags"] = flags
        params[p.name] = FitParameter(**entry)
    units = {p.name: p.unit for p in result.parameters}

    def matrix(m, digits):
        return [[None if not math.isfinite(c) else float(f"{c:.{digits}g}") for c in row] for row in m]

    if na:
        corr = covar = na
    else:
        corr = Matrix(names=list(result.free_names), matrix=matrix(result.correlation, 4))
        covar = Matrix(names=list(result.free_names), matrix=matrix(result.covar, 6),
                       units="SI: entry (i, j) in the unit of names[i] times that of names[j] ("
                             + ", ".join(f"{n} {units[n]}" for n in result.free_names) + ")")
    stats = Statistics(ndata=result.ndata, nvarys=result.nvarys, nfree=result.nfree, chisqr=result.chisqr,
                       redchi=result.redchi, aic=None if na else result.aic, bic=None if na else result.bic,
                       nfev=result.nfev, nit=result.nit, restarts=result.restarts,
                       wall_time_s=round(result.wall_time, 3))
    notes = ["standard errors and covar from the Jacobian at the optimum, covar = redchi (J^T J)^-1; residuals "
             "of a time series are correlated, so they are lower bounds"]
    if na:
        notes = [f"stderr, covar, correlation, aic and bic: {na}: they describe a least-squares (rms) estimate"]
    holds = {f"{r.specimen}/{r.protocol}": len(hold_spans(r.t, r.stretch)) for r in runs}
    stages = [{k: (round(v, 3) if k == "wall_time_s" else v) for k, v in st.items()} for st in result.stages]
    optional = {k: v for k, v in (("warm_start", getattr(result, "warm_start", "")),
                                  ("branch_choice", dict(getattr(result, "branch_choice", {})))) if v}
    return CalibrationRecord(
        model=result.model, viscoelastic_law=result.params.law,
        hyperelastic=getattr(result, "hyperelastic", "yeoh"), metric=result.metric, method=result.method,
        objective=float(result.objective), converged=result.converged, message=result.message,
        parameters=params, correlation=corr, covar=covar,
        runs=[FitRun(**{**g, "sha256": r.sha256}) for g, r in zip(result.runs, runs)],
        skipped=[dict(s) for s in getattr(result, "skipped", ())], statistics=stats, stages=stages,
        budgets=dict(result.budgets), notes="; ".join(notes), software=f"rdea-lab {result.software}",
        versions=dict(result.versions), weighting={"rule": PHASE_RULE, "holds": holds}, **optional,
        **({"spectrum": dict(result.spectrum)} if getattr(result, "spectrum", None) else {}),
    )


def record_mapping(result, runs) -> dict:
    """The ``calibration`` section of the record (YAML-ready): `calibration_record` as a mapping."""
    return calibration_record(result, runs).mapping()


def record_files(out) -> dict[str, Path]:
    """The files a record at ``out`` is: ``params`` (``out``), ``history`` (``<out stem>.history.csv``),
    ``plot`` (``<out stem>.history.png``)."""
    out = Path(out)
    return {"params": out, "history": out.with_name(out.stem + ".history.csv"),
            "plot": out.with_name(out.stem + ".history.png")}


def write_record(result, runs, out: Path, name: str | None = None) -> dict[str, Path]:
    """Write ``out`` (loadable by load_params), ``<out>.history.csv`` and ``<out>.history.png``."""
    paths = record_files(out)
    out, hist, png = paths["params"], paths["history"], paths["plot"]
    out.parent.mkdir(parents=True, exist_ok=True)
    params = result.params.replace(name=name) if name else result.params
    files = ", ".join(sorted({r.path.name for r in runs}))
    params = params.replace(description=f"calibrated by rdea-lab on {len(runs)} run(s): {files}",
                            source=f"rdea-lab calibrate, model {result.model}, metric {result.metric}")
    out.write_text(dump_params(params) + calibration_record(result, runs).block())
    with open(hist, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["evaluation", "best_objective", "stage"])
        w.writerows([[int(n), repr(float(f)), int(st)] for n, f, st in result.history])
    _plot_history(result, png)
    return paths


def _plot_history(result, path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.5))
    ax = fig.subplots()
    h = result.history
    for st in result.stages:
        mine = h[h[:, 2] == st["stage"]]
        ax.plot(mine[:, 0], mine[:, 1], drawstyle="steps-post",
                label=st["label"] + ("" if st["kept"] else " (dropped)"))
    if h.size and np.all(h[:, 1] > 0):  # a fit that reaches 0 exactly (a run made by the same model) stays linear
        ax.set_yscale("log")
    if len(result.stages) > 1:
        ax.legend(fontsize="small")
    ax.set_xlabel("objective evaluations (all stages)")
    ax.set_ylabel(f"best {result.metric} normalized force error [-]")
    ax.set_title(f"calibration ({result.model}, {result.method}, {result.nfev} evaluations, "
                 f"{result.restarts} restarts)")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


__all__ = ["calibration_record", "record_files", "record_mapping", "write_record", "format_quantity"]
