"""What a study writes: the dataset, the Pareto front and Sobol tables, the figures, the best design's card.

``OUT/`` holds ``study.nc`` (the one Dataset), ``pareto.csv`` (the front, best
first by the first objective), ``sobol.csv`` (with a sensitivity), ``card.yaml``
(with ``optimize``: the best design's specimen card, which ``rdea-lab run``
takes), ``summary.json`` and the figures ``pareto.png``, ``parallel.png``,
``stroke_map.png``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..specs.errors import DOCUMENT, SpecError
from ..specs.specimen import dump_specimen
from ..specs.study import METRICS
from ..specs.units import format_quantity
from ..store.outputs import check_writable
from .study import _si

FILES = ("study.nc", "pareto.csv", "sobol.csv", "card.yaml", "summary.json", "pareto.png", "parallel.png",
         "stroke_map.png")


def check_study_out(out, overwrite: bool = False) -> Path:
    """The output folder, refused (a `SpecError`, exit 2) if it holds a study's files and not ``overwrite``,
    or cannot be written."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise SpecError(str(out), "--out", "is a file; give a folder for the study's outputs")
    taken = [f for f in FILES if (out / f).exists()]
    if taken and not overwrite:
        raise SpecError(str(out), "--out", f"already holds {taken[0]}; give another folder or --force to replace")
    check_writable(out / "study.nc", "--out")
    return out


def _shown(metric: str, value: float) -> str:
    si, unit, _ = METRICS[metric]
    if not np.isfinite(value):
        return "nan"
    return format_quantity(float(value), unit, 4) if unit else f"{value:.4g}"


def study_summary(result) -> dict:
    """The figures a user reads first: counts, the best designs, the optimum, where the time went."""
    ds, study = result.dataset, result.study
    status = ds["design_status"].values
    from .evaluate import STATUS
    out = {"study": study.name, "designs": int(ds.sizes["design"]),
           "status": {STATUS[c]: int((status == c).sum()) for c in STATUS if (status == c).any()},
           "feasible": int(ds["feasible"].values.sum()), "pareto": int(ds["pareto"].values.sum()),
           "objectives": [g.label for g in study.objectives], "timings_s": result.timings}
    first = study.objectives[0]
    ok = ds["feasible"].values.astype(bool)
    vals = ds[first.metric].values
    best = int(np.flatnonzero(ok)[np.argmax(first.sense * vals[ok])])
    out["best_sweep"] = {"design": best, **{v: float(ds[v].values[best]) for v in study.names},
                         **{g.metric: float(ds[g.metric].values[best]) for g in study.objectives}}
    if result.optimum is not None:
        o = result.optimum
        out["optimum"] = {"how": o["how"], "variables": o["variables"], "evaluations": o["evaluations"],
                          **{k: o["metrics"][k] for k in [g.metric for g in study.objectives]
                             + [b.metric for b in study.constraints] if k in o["metrics"]}}
        for key in ("preload", "bias_mass", "rest_stretch", "on_stretch", "field"):
            if key in o["metrics"]:
                out["optimum"][key] = o["metrics"][key]
        out["card"] = {"variables": o["card_variables"], "feasible": o["card_feasible"],
                       **{k: o["card_metrics"][k] for k in out["optimum"] if k in o["card_metrics"]}}
    if "sobol_missing" in ds:
        out["sobol_missing"] = {str(o): int(ds["sobol_missing"].sel(objective=o)) for o in ds["objective"].values}
    if "sobol_ST" in ds:
        out["sobol_ST"] = {str(o): {str(v): float(ds["sobol_ST"].sel(objective=o, variable=v))
                                    for v in ds["variable"].values} for o in ds["objective"].values}
    return out


def study_lines(result) -> list[str]:
    """The summary as text lines."""
    s, study = study_summary(result), result.study
    counts = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in s["status"].items())
    out = [f"study {s['study']}: {s['designs']} designs ({counts}), {s['feasible']} feasible, "
           f"{s['pareto']} on the Pareto front ({', '.join(s['objectives'])}); sweep "
           f"{s['timings_s'].get('sweep_s', float('nan')):.1f} s"]
    b = s["best_sweep"]
    out.append("best of the sweep: " + ", ".join(f"{g.metric} {_shown(g.metric, b[g.metric])}"
                                                 for g in study.objectives)
               + " at " + ", ".join(_var(study, v, b[v]) for v in study.names))
    if "optimum" in s:
        o = s["optimum"]
        out.append("optimum: " + ", ".join(f"{k} {_shown(k, v)}" for k, v in o.items() if k in METRICS)
                   + " at " + ", ".join(_var(study, k, v) for k, v in o["variables"].items())
                   + f" ({o['how']}; {o['evaluations']} evaluations)")
        c = s["card"]
        out.append("card (cut to 0.01 mm, film to 0.1 um): " + ", ".join(
            f"{k} {_shown(k, v)}" for k, v in c.items() if k in METRICS) + " at "
            + ", ".join(_var(study, k, v) for k, v in c["variables"].items())
            + ("" if c["feasible"] else " (NOT meeting the constraints once rounded)"))
    if "sobol_ST" in s:
        for obj, row in s["sobol_ST"].items():
            missing = s.get("sobol_missing", {}).get(obj, 0)
            if missing:
                out.append(f"Sobol indices of {obj}: undefined, {missing} of the Saltelli designs have no value "
                           "(no roll, no equilibrium or past the protocol's limits); narrow the ranges")
                continue
            out.append(f"Sobol total index of {obj}: " + ", ".join(f"{k} {v:.2f}" for k, v in row.items()))
    return out


def _var(study, name, value) -> str:
    v = next(x for x in study.variables if x.name == name)
    return f"{name} {format_quantity(float(value), v.unit, 4) if v.unit else f'{value:.4g}'}"


def write_study(result, out, overwrite: bool = False, figures: bool = True) -> dict:
    """Write every output of a study into the folder ``out``; returns ``{name: path}``."""
    out = check_study_out(out, overwrite)
    out.mkdir(parents=True, exist_ok=True)
    ds, study = result.dataset, result.study
    paths = {}

    def target(name):
        paths[name] = str(out / name)
        return out / name

    tmp = out / ".study.nc.part"
    try:
        ds.to_netcdf(tmp)
        os.replace(tmp, target("study.nc"))
        _front(ds, study).to_csv(target("pareto.csv"), index=False)
        if "sobol_S1" in ds:
            _sobol(ds).to_csv(target("sobol.csv"), index=False)
        if result.card is not None:
            header = (f"# The best design of study {study.name} ({result.optimum['how']}).\n"
                      f"# Test it: rdea-lab run PROTOCOL --specimen THIS_FILE --backend emulator\n")
            target("card.yaml").write_text(header + dump_specimen(result.card), encoding="utf-8")
        target("summary.json").write_text(json.dumps(study_summary(result), indent=2, default=float) + "\n",
                                          encoding="utf-8")
        if figures:
            from .figures import parallel_figure, pareto_figure, stroke_map
            pareto_figure(ds, study, target("pareto.png"))
            parallel_figure(ds, study, target("parallel.png"))
            stroke_map(ds, study, target("stroke_map.png"))
    except OSError as exc:
        raise SpecError(str(out), DOCUMENT, f"cannot write: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)
    return paths


def _front(ds, study):
    import pandas as pd

    idx = np.flatnonzero(ds["pareto"].values.astype(bool))
    first = study.objectives[0]
    idx = idx[np.argsort(-first.sense * ds[first.metric].values[idx], kind="stable")]
    cols = {"design": idx}
    for v in study.variables:
        cols[f"{v.name} [{_si(v.name)}]"] = ds[v.name].values[idx]
    for k in dict.fromkeys([g.metric for g in study.objectives] + [b.metric for b in study.constraints]):
        cols[f"{k} [{METRICS[k][0]}]"] = ds[k].values[idx]
    return pd.DataFrame(cols)


def _sobol(ds):
    import pandas as pd

    rows = []
    for o in ds["objective"].values:
        for v in ds["variable"].values:
            rows.append({"objective": str(o), "variable": str(v),
                         **{k: float(ds[f"sobol_{k}"].sel(objective=o, variable=v))
                            for k in ("S1", "S1_conf", "ST", "ST_conf")}})
    return pd.DataFrame(rows)


def check_card_run(study) -> None:
    """Refuse (`StudyError`, exit 2) a run of the best design's card that the study cannot give: it needs
    ``optimize`` and ``protocol``, and the card holds the membrane only, so no material or voltage variable."""
    from .study import StudyError

    if study.optimize is None or study.protocol is None:
        raise StudyError(f"{study.source}: a run of the card needs a study with optimize and protocol; it has "
                         f"{'no optimize' if study.optimize is None else 'no protocol'}")
    varied = sorted(set(study.names) & {"C10", "C20", "C30", "eps_r", "voltage"})
    if varied:
        raise StudyError(f"{study.source}: variables: a run of the card would not see {', '.join(varied)} (the card "
                         "holds the membrane only); run it yourself with the optimum's values from summary.json")


def run_card(result, card_path, backend: str, out, overwrite: bool = False) -> dict:
    """Run the study's protocol on the best design's card (``emulator`` or ``twin``); the run's peak force and
    the study's prediction of it for the card."""
    from ..runs.app import run_protocol
    from ..runs.backend import Emulator, Twin

    study = result.study
    check_card_run(study)
    executor = Twin(study.params, study.model) if backend == "twin" else Emulator()
    ds = run_protocol(study.protocol_path, card_path, executor, out=out, overwrite=overwrite,
                      metadata={"study": study.name}, command="rdea-lab design")
    return {"backend": backend, "dataset": str(out), "peak_force": float(ds["force"].max()),
            "predicted_peak_force": result.optimum["card_metrics"].get("peak_force", float("nan"))}

