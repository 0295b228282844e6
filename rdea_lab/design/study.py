"""A design study end to end: sample the designs, evaluate them on a cluster, rank, refine, write.

`run_study` returns a `StudyResult`: one xarray Dataset over the ``design``
dimension (the variables, every metric, the design's status, feasibility, the
Pareto front; with tolerances each metric's Monte Carlo samples over ``mc`` and
their mean, spread and 5th/95th percentiles; with ``sensitivity`` the Sobol
indices over ``objective`` x ``variable``), the optimizer's result and the
specimen card of the best design.

Results never depend on where the tasks ran: the designs are sampled on the
client from the study's seed, the chunks are the study's (``chunk`` designs
each, not a share of the workers), each Monte Carlo draw is seeded by the
design's index, and a chunk's arithmetic is the same in any process.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from .._version import __version__
from ..specs.errors import UserError
from ..specs.specimen import Membrane, SpecimenCard, dump_specimen
from ..specs.units import format_quantity, parse_quantity
from ..specs.study import METRICS, MEMBRANE, Bound, Study
from .cluster import Progress, connect
from .evaluate import STATUS, Fixed, evaluate, evaluate_chunk, membrane, protocol_needed


class StudyError(UserError):
    """A study that cannot give an answer as posed (no design meets its constraints): exit status 2."""


@dataclass(frozen=True, eq=False)
class StudyResult:
    """What `run_study` found: the sweep, the optimum, the best design's card, where the time went.

    Attributes
    ----------
    study : Study
        The study run.
    dataset : xarray.Dataset
        The sweep over ``design`` (variables, metrics, status, feasibility, Pareto front; Monte Carlo and
        Sobol indices when the study asks for them).
    optimum : dict or None
        The optimizer's result (None without ``optimize``).
    card : SpecimenCard or None
        The best design's specimen card, cut to manufacturable dimensions (None without ``optimize``).
    timings : dict
        Seconds [s] of the sweep, the sensitivity and the optimization.
    """

    study: Study
    dataset: xr.Dataset
    optimum: dict | None = None
    card: SpecimenCard | None = None
    timings: dict = field(default_factory=dict)

    @property
    def front(self):
        """The Pareto front as a table (pandas DataFrame): the design's index, its variables and the metrics
        of the objectives and constraints (SI units in the headings), best first by the first objective."""
        import pandas as pd

        ds, study = self.dataset, self.study
        idx = np.flatnonzero(ds["pareto"].values.astype(bool))
        first = study.objectives[0]
        idx = idx[np.argsort(-first.sense * ds[first.metric].values[idx], kind="stable")]
        cols = {"design": idx}
        for v in study.variables:
            cols[f"{v.name} [{_si(v.name)}]"] = ds[v.name].values[idx]
        for k in dict.fromkeys([g.metric for g in study.objectives] + [b.metric for b in study.constraints]):
            cols[f"{k} [{METRICS[k][0]}]"] = ds[k].values[idx]
        return pd.DataFrame(cols)

    @property
    def sobol(self):
        """The Sobol indices as a table (pandas DataFrame: objective, variable, S1, S1_conf, ST, ST_conf), or
        None for a study without a sensitivity."""
        import pandas as pd

        ds = self.dataset
        if "sobol_S1" not in ds:
            return None
        rows = []
        for o in ds["objective"].values:
            for v in ds["variable"].values:
                rows.append({"objective": str(o), "variable": str(v),
                             **{k: float(ds[f"sobol_{k}"].sel(objective=o, variable=v))
                                for k in ("S1", "S1_conf", "ST", "ST_conf")}})
        return pd.DataFrame(rows)

    def summary(self) -> dict:
        """The figures a user reads first: counts, the best designs, the optimum, where the time went.

        Returns
        -------
        dict
            ``study``, ``designs``, ``status`` (count per status), ``feasible``, ``pareto``, ``objectives``,
            ``timings_s``, ``best_sweep``; with an optimum ``optimum`` and ``card``; with a sensitivity
            ``sobol_ST`` (and ``sobol_missing``). What ``summary.json`` holds.
        """
        ds, study = self.dataset, self.study
        status = ds["design_status"].values
        out = {"study": study.name, "designs": int(ds.sizes["design"]),
               "status": {STATUS[c]: int((status == c).sum()) for c in STATUS if (status == c).any()},
               "feasible": int(ds["feasible"].values.sum()), "pareto": int(ds["pareto"].values.sum()),
               "objectives": [g.label for g in study.objectives], "timings_s": self.timings}
        first = study.objectives[0]
        ok = ds["feasible"].values.astype(bool)
        vals = ds[first.metric].values
        best = int(np.flatnonzero(ok)[np.argmax(first.sense * vals[ok])])
        out["best_sweep"] = {"design": best, **{v: float(ds[v].values[best]) for v in study.names},
                             **{g.metric: float(ds[g.metric].values[best]) for g in study.objectives}}
        if self.optimum is not None:
            o = self.optimum
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

    def lines(self) -> list[str]:
        """The summary as text lines (what ``rdea-lab design`` prints).

        Returns
        -------
        list of str
            Counts and the sweep's time, the best design of the sweep, the optimum and the card, the Sobol
            total indices.
        """
        from .outputs import _shown, _var

        s, study = self.summary(), self.study
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

    def write(self, out, *, overwrite: bool = False, figures: bool = True) -> dict[str, Path]:
        """Write every output of the study into the folder ``out``: ``study.nc``, ``pareto.csv``,
        ``sobol.csv`` (with a sensitivity), ``card.yaml`` (with an optimum), ``summary.json`` and the figures.

        Parameters
        ----------
        out : path
            Output folder (created).
        overwrite : bool
            Replace the files of an earlier study in ``out``.
        figures : bool
            Write ``pareto.png``, ``parallel.png`` and ``stroke_map.png``.

        Returns
        -------
        dict of str to Path
            Each file written, under its name, in the order written.

        Raises
        ------
        SpecError
            ``out`` holds a study's files (and not ``overwrite``), is a file, or cannot be written.
        """
        from ..specs.errors import DOCUMENT, SpecError
        from .outputs import check_study_out

        out = check_study_out(out, overwrite)
        out.mkdir(parents=True, exist_ok=True)
        ds, study = self.dataset, self.study
        paths = {}

        def target(name):
            paths[name] = out / name
            return out / name

        tmp = out / ".study.nc.part"
        try:
            ds.to_netcdf(tmp)
            os.replace(tmp, target("study.nc"))
            self.front.to_csv(target("pareto.csv"), index=False)
            if "sobol_S1" in ds:
                self.sobol.to_csv(target("sobol.csv"), index=False)
            if self.card is not None:
                header = (f"# The best design of study {study.name} ({self.optimum['how']}).\n"
                          f"# Test it: rdea-lab run PROTOCOL --specimen THIS_FILE --backend emulator\n")
                target("card.yaml").write_text(header + dump_specimen(self.card), encoding="utf-8")
            target("summary.json").write_text(json.dumps(self.summary(), indent=2, default=float) + "\n",
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


# ------------------------------------------------------------------ sampling

def sample(study: Study, n: int | None = None, seed: int | None = None) -> np.ndarray:
    """Unit-cube coordinates ``(n, variables)`` of the study's designs (grid, Latin hypercube or Sobol)."""
    from scipy.stats import qmc

    d = len(study.variables)
    n = study.n if n is None else n
    seed = study.seed if seed is None else seed
    if study.method == "grid":
        axes = [np.linspace(0.0, 1.0, v.levels) for v in study.variables]
        return np.array(list(itertools.product(*axes)), float).reshape(-1, d)
    if study.method == "lhs":
        return qmc.LatinHypercube(d=d, seed=np.random.default_rng(seed)).random(n)
    sobol = qmc.Sobol(d=d, scramble=True, seed=np.random.default_rng(seed))
    return sobol.random(n)  # scipy warns when n is not a power of 2 (balance); any n is allowed


def table_of(study: Study, unit: np.ndarray) -> dict:
    """``{variable: values}`` (SI) at unit-cube coordinates."""
    return {v.name: v.from_unit(unit[:, j]) for j, v in enumerate(study.variables)}


# ------------------------------------------------------------------ evaluation

def evaluate_table(study: Study, table: dict, *, client=None, progress: bool = False, label: str = "designs",
                   fixed: Fixed | None = None) -> dict:
    """Every metric of the designs ``table``, in chunks of ``study.chunk`` designs.

    ``client``: a `distributed.Client`, or None for dask's synchronous scheduler (in this process).
    """
    import dask

    fixed = fixed or Fixed.of(study)
    n = len(next(iter(table.values())))
    bounds = [(a, min(a + study.chunk, n)) for a in range(0, n, study.chunk)]
    bar = Progress(len(bounds), label, enabled=progress)
    if client is None:
        parts = []
        for a, b in bounds:
            task = dask.delayed(evaluate_chunk, pure=True)(fixed, np.arange(a, b),
                                                           {k: v[a:b] for k, v in table.items()})
            parts.append(dask.compute(task, scheduler="synchronous")[0])
            bar.update()
    else:
        from distributed import as_completed

        shared = client.scatter(fixed, broadcast=True, hash=False)
        # keys from the shared study's own (unique) key and the chunk's rows: no two studies on a shared
        # scheduler can meet under one key
        futures = []
        for a, b in bounds:
            rows = {k: v[a:b] for k, v in table.items()}
            futures.append(client.submit(evaluate_chunk, shared, np.arange(a, b), rows,
                                         key=f"rdea-design-{label}-{a}-{dask.base.tokenize(shared.key, rows)}"))
        with client.as_current():
            for future in as_completed(futures):
                if future.status != "finished":  # lost with a worker, or failed: stop here, not at 100 %
                    future.result()
                bar.update()
        parts = client.gather(futures)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


# ------------------------------------------------------------------ ranking

def feasible(study: Study, metrics: dict) -> np.ndarray:
    """Designs that are rolls with equilibria and meet every constraint."""
    ok = metrics["design_status"] == 0
    for b in study.constraints:
        v = metrics[b.metric]
        with np.errstate(invalid="ignore"):
            ok &= (v >= b.low) & (v <= b.high)
    return ok


def pareto(study: Study, metrics: dict, mask: np.ndarray) -> np.ndarray:
    """The non-dominated feasible designs of the objectives (each maximized or minimized)."""
    idx = np.flatnonzero(mask)
    front = np.zeros(mask.size, bool)
    if idx.size == 0:
        return front
    y = np.stack([g.sense * metrics[g.metric][idx] for g in study.objectives], axis=1)  # larger is better
    order = np.lexsort(tuple(-y[:, j] for j in reversed(range(y.shape[1]))))
    y = y[order]
    keep = np.ones(len(y), bool)
    for i in range(len(y)):  # sorted by the first objective: only earlier points can dominate
        if not keep[i]:
            continue
        dominated = np.all(y[i] >= y[i + 1:], axis=1) & np.any(y[i] > y[i + 1:], axis=1)
        keep[i + 1:] &= ~dominated
    front[idx[order[keep]]] = True
    return front


def sensitivity(study: Study, *, client=None, progress=False, fixed=None) -> dict | None:
    """First-order and total Sobol indices of each objective over the variables (SALib, Saltelli's
    sampling of ``n (D + 2)`` designs, without second order), with their 95 % confidence half-widths."""
    if not study.sensitivity_n:
        return None
    from SALib.analyze import sobol as sobol_analyze
    from SALib.sample import sobol as sobol_sample

    problem = {"num_vars": len(study.variables), "names": list(study.names),
               "bounds": [[0.0, 1.0]] * len(study.variables)}
    unit = sobol_sample.sample(problem, study.sensitivity_n, calc_second_order=False, seed=study.sensitivity_seed)
    fixed = fixed or Fixed.of(study)
    if not protocol_needed(study):  # the objectives need no protocol: the sensitivity's designs skip it
        fixed = Fixed(fixed.study, None)
    nominal = study.model_copy(update={"mc_samples": 0})  # indices of the nominal design's objectives
    metrics = evaluate_table(nominal, table_of(study, unit), client=client, progress=progress, label="sobol",
                             fixed=Fixed(nominal, fixed.history))
    out = {}
    for g in study.objectives:
        y = metrics[g.metric]
        finite = np.isfinite(y)
        if not finite.all():  # Saltelli's estimator needs every sample: the indices are undefined
            out[g.metric] = {"S1": np.full(len(study.variables), np.nan), "ST": np.full(len(study.variables), np.nan),
                             "S1_conf": np.full(len(study.variables), np.nan),
                             "ST_conf": np.full(len(study.variables), np.nan), "missing": int((~finite).sum())}
            continue
        # the bootstrap of the confidence intervals is seeded too (SALib ignores a seed of 0: "if seed:")
        res = sobol_analyze.analyze(problem, y, calc_second_order=False, seed=study.sensitivity_seed + 1,
                                    print_to_console=False)
        out[g.metric] = {k: np.asarray(res[k], float) for k in ("S1", "ST", "S1_conf", "ST_conf")}
        out[g.metric]["missing"] = 0
    return {"indices": out, "designs": int(unit.shape[0])}


# ------------------------------------------------------------------ optimization

def refine(fixed: Fixed, x0, metric: str, sense: int, scale: float, max_iter: int) -> dict:
    """One SLSQP run from the unit-cube point ``x0``: maximize (``sense`` +1) or minimize the metric under the
    study's constraints and, with a protocol, its limits (the card must be testable with it). One task."""
    from scipy.optimize import minimize

    study = fixed.study
    evals = [0]
    cache = {}

    def cached(x):
        x = np.clip(np.asarray(x, float), 0.0, 1.0)
        key = x.tobytes()
        if key not in cache:
            evals[0] += 1
            cache[key] = evaluate(fixed, table_of(study, x[None, :]), protocol=fixed.history is not None)
        return cache[key]

    def objective(x):
        v = cached(x)[metric][0]
        return -sense * v / scale if np.isfinite(v) else 1e3

    cons = []
    for b in _bounds(fixed):
        for lim, sign in ((b.low, 1.0), (b.high, -1.0)):
            if math.isfinite(lim):
                def g(x, m=b.metric, lim=lim, s=abs(lim) or 1.0, sign=sign):
                    v = cached(x)[m][0]
                    return sign * (v - lim) / s if np.isfinite(v) else -1.0
                cons.append({"type": "ineq", "fun": g})
    res = minimize(objective, np.asarray(x0, float), method="SLSQP", bounds=[(0.0, 1.0)] * len(x0),
                   constraints=cons, options={"maxiter": max_iter, "ftol": 1e-6})
    x = np.clip(res.x, 0.0, 1.0)
    return {"x": x, "metrics": cached(x), "message": str(res.message), "nit": int(res.nit), "evaluations": evals[0]}


def _bounds(fixed: Fixed) -> list:
    bounds = list(fixed.study.constraints)
    if fixed.history is not None:
        limits = fixed.history[3]
        bounds += [Bound("limit_field", high=limits.max_field), Bound("peak_force", high=limits.max_force)]
    return bounds


def optimize(study: Study, unit: np.ndarray, metrics: dict, ok: np.ndarray, fixed: Fixed, client=None) -> dict | None:
    """Refine the best feasible sweep points with scipy's SLSQP (bounds and the constraints; nominal radii),
    one task per start; the best feasible result, or the best sweep point if none is better."""
    if study.optimize is None or not ok.any():
        return None
    metric = study.optimize["objective"]
    sense = next(g.sense for g in study.objectives if g.metric == metric)
    best = np.flatnonzero(ok)[np.argsort(-sense * metrics[metric][ok], kind="stable")][: study.optimize["starts"]]
    scale = abs(float(metrics[metric][best[0]])) or 1.0
    args = [(unit[i], metric, sense, scale, study.optimize["max_iter"]) for i in best]
    if client is None:
        runs = [refine(fixed, *a) for a in args]
    else:
        shared = client.scatter(fixed, broadcast=True, hash=False)
        runs = client.gather([client.submit(refine, shared, *a, pure=False) for a in args])
    scored = []
    for i, r in zip(best, runs):
        good = bool(feasible(study, r["metrics"])[0]) and r["metrics"]["design_status"][0] == 0
        scored.append((-sense * r["metrics"][metric][0] if good else np.inf, int(i), r))
    sweep_best = -sense * metrics[metric][best[0]]
    value, start, r = min(scored, key=lambda t: t[0])
    if not value < sweep_best:
        x, m, start = unit[best[0]], {k: v[best[0]:best[0] + 1] for k, v in metrics.items()}, int(best[0])
        how = "the best sweep point (the optimizer found nothing better that meets the constraints)"
    else:
        x, m = r["x"], r["metrics"]
        how = f"SLSQP from sweep design {start}: {r['message']} ({r['nit']} iterations)"
    return {"objective": metric, "unit": x, "variables": {k: float(v[0]) for k, v in table_of(study, x[None]).items()},
            "metrics": {k: float(np.asarray(v)[0]) for k, v in m.items() if not k.endswith("_mc")},
            "start": start, "how": how, "evaluations": int(sum(r["evaluations"] for r in runs)),
            "sweep_best": float(metrics[metric][best[0]]), "starts": [int(i) for i in best]}


#: what a lab can cut: lengths to 0.01 mm; a film's thickness to 0.1 um, rounded up (a thicker film is
#: the safe side of a field limit)
LENGTH_STEP, THICKNESS_STEP = 1e-5, 1e-7


def manufacturable(variables: dict) -> dict:
    """The design's variables with its membrane dimensions rounded to what a lab can cut."""
    out = dict(variables)
    for k in MEMBRANE:
        if k in out:
            if k == "L3":
                out[k] = math.ceil(out[k] / THICKNESS_STEP - 1e-9) * THICKNESS_STEP
            else:
                out[k] = round(out[k] / LENGTH_STEP) * LENGTH_STEP
    return out


def card_of(study: Study, variables: dict, metrics: dict | None = None) -> SpecimenCard:
    """The specimen card of a design: its unwound membrane, ready to cut and roll (`manufacturable`), with the
    bias and the operating point it was designed for in its description."""
    mem = membrane(study, {k: np.array([v]) for k, v in variables.items()})
    dims = {k: float(mem[k][0]) for k in ("L1", "L2", "L3", "L1e", "Lp1", "L2e")}
    # the derived ones too (L1e = L1 - ends, ...), as the decimal a card file says ("59.98 mm")
    dims = {k: parse_quantity(f"{v * 1e6:.1f} um" if k == "L3" else f"{v * 1e3:.2f} mm", "length",
                              source="<design>", field=k) for k, v in dims.items()}
    dims["Ri"] = float(mem["Ri"][0])
    bias = study.bias
    text = (f"design study {study.name}: best design at "
            f"{format_quantity(float(variables.get('voltage', study.voltage)), 'kV', 4)}")
    if metrics is not None and bias.kind == "spring":
        text += (f" against a {format_quantity(float(variables.get('stiffness', bias.stiffness)), 'N/m', 4)}"
                 f" spring that pulls {format_quantity(metrics['rest_force'], 'N', 4)} at the rest stretch "
                 f"{metrics['rest_stretch']:.4g} (its preload {format_quantity(metrics['preload'], 'N', 4)} at "
                 f"stretch 1, the card's own length; stroke {format_quantity(metrics['stroke'], 'mm', 4)})")
    elif metrics is not None and bias.kind == "mass":
        text += (f" under a {format_quantity(metrics['bias_mass'], 'g', 4)} mass (rest stretch "
                 f"{metrics['rest_stretch']:.4g}, stroke {format_quantity(metrics['stroke'], 'mm', 4)})")
    return SpecimenCard(id=f"{study.name}-optimum", kind="roll", membrane=Membrane(**dims), description=text,
                        source=f"rdea-lab design {study.source}")


# ------------------------------------------------------------------ the study

def run_study(study: Study, *, scheduler: str | None = None, workers: int | None = None, synchronous: bool = False,
              client=None, progress: bool = False, quiet: bool = True) -> StudyResult:
    """Run a study: the sweep (and its Monte Carlo), the sensitivity, the optimization.

    Parameters
    ----------
    study : Study
        `rdea_lab.specs.study.load_study`.
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running dask scheduler (default ``DASK_SCHEDULER_ADDRESS``, else a new
        local cluster of ``workers`` processes).
    workers : int, optional
        Processes of the local cluster started when no scheduler is given (default: one per core).
    synchronous : bool
        Every task in this process (dask's synchronous scheduler), no cluster.
    client : distributed.Client, optional
        An open client to use as it is.
    progress : bool
        Show dask's progress bar while the sweep runs.
    quiet : bool
        Keep the local cluster's log lines off the terminal.

    Returns
    -------
    StudyResult
        The frozen result: the sweep's table, the Pareto front and the Sobol indices as DataFrames,
        the optimum and the timings; write it with :meth:`StudyResult.write`.

    Raises
    ------
    StudyError
        No design of the sweep meets the constraints.
    SchedulerError
        The scheduler does not answer.
    """
    import time

    from ..extras import require

    for module in ("dask", "distributed") + (("SALib",) if study.sensitivity_n else ()):
        require(module, "a design study")
    timings = {}
    if synchronous and (scheduler or workers or client is not None):
        raise StudyError("synchronous: runs every task in this process; give no scheduler, workers or client")
    if client is None and not synchronous:
        with connect(scheduler, workers=workers, quiet=quiet) as c:
            return run_study(study, client=c, progress=progress, quiet=quiet)
    fixed = Fixed.of(study)
    unit = sample(study)
    table = table_of(study, unit)
    t0 = time.perf_counter()
    metrics = evaluate_table(study, table, client=client, progress=progress, fixed=fixed)
    timings["sweep_s"] = time.perf_counter() - t0
    ok = feasible(study, metrics)
    if not ok.any():
        raise StudyError(f"{study.source}: constraints: no design of the {unit.shape[0]} sampled meets them "
                         f"({_why(study, metrics)}); widen the ranges or relax the constraints")
    front = pareto(study, metrics, ok)
    t0 = time.perf_counter()
    sens = sensitivity(study, client=client, progress=progress, fixed=fixed)
    timings["sensitivity_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    opt = optimize(study, unit, metrics, ok, fixed, client)
    timings["optimize_s"] = time.perf_counter() - t0
    card = None
    if opt is not None:  # the card as cut: its rounded dimensions evaluated again (what the lab will test)
        cut = manufacturable(opt["variables"])
        m = evaluate(fixed, {k: np.array([v]) for k, v in cut.items()})
        opt["card_variables"] = cut
        opt["card_metrics"] = {k: float(np.asarray(v)[0]) for k, v in m.items()}
        opt["card_feasible"] = bool(feasible(study, m)[0])
        card = card_of(study, cut, opt["card_metrics"])
    ds = dataset(study, unit, table, metrics, ok, front, sens, opt, card)
    return StudyResult(study, ds, opt, card, timings)


def _why(study, metrics) -> str:
    status = metrics["design_status"]
    parts = [f"{int((status == c).sum())} {STATUS[c].replace('_', ' ')}" for c in STATUS if c and (status == c).any()]
    good = status == 0
    for b in study.constraints:
        v = metrics[b.metric][good]
        if v.size:
            si, shown, _ = METRICS[b.metric]
            parts.append(f"{b.metric} spans {np.nanmin(v):.4g} to {np.nanmax(v):.4g} {si}")
    return "; ".join(parts) or "none is a roll"


def dataset(study, unit, table, metrics, ok, front, sens, opt, card) -> xr.Dataset:
    """The study's one Dataset (see the module docstring)."""
    n = unit.shape[0]
    data = {}
    for v in study.variables:
        data[v.name] = ("design", table[v.name], {"units": _si(v.name), "long_name": f"design variable {v.name}",
                                                  "valid_min": v.low, "valid_max": v.high})
    for k in study.metrics:
        si, _, text = METRICS[k]
        data[k] = ("design", metrics[k], {"units": si, "long_name": text})
        if f"{k}_mc" in metrics:
            mc = metrics[f"{k}_mc"]
            data[f"{k}_mc"] = (("design", "mc"), mc, {"units": si, "long_name": f"{text}: Monte Carlo samples"})
            with np.errstate(invalid="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # a design whose rolls are all NaN
                data[f"{k}_mean"] = ("design", np.nanmean(mc, axis=1), {"units": si, "long_name": f"{text}: mean"})
                data[f"{k}_std"] = ("design", np.nanstd(mc, axis=1, ddof=1), {"units": si,
                                                                              "long_name": f"{text}: std"})
                data[f"{k}_p05"] = ("design", np.nanpercentile(mc, 5, axis=1), {"units": si,
                                                                                "long_name": f"{text}: 5th pct"})
                data[f"{k}_p95"] = ("design", np.nanpercentile(mc, 95, axis=1), {"units": si,
                                                                                 "long_name": f"{text}: 95th pct"})
    codes = sorted(STATUS)
    data["design_status"] = ("design", metrics["design_status"].astype(np.int8),
                             {"long_name": "design status", "flag_values": np.array(codes, np.int8),
                              "flag_meanings": " ".join(STATUS[c] for c in codes)})
    data["feasible"] = ("design", ok.astype(np.int8), {"long_name": "a roll meeting every constraint",
                                                       "flag_values": np.array([0, 1], np.int8),
                                                       "flag_meanings": "infeasible feasible"})
    data["pareto"] = ("design", front.astype(np.int8), {"long_name": "on the Pareto front of the objectives",
                                                        "flag_values": np.array([0, 1], np.int8),
                                                        "flag_meanings": "dominated front"})
    if "design_status_mc" in metrics:
        data["design_status_mc"] = (("design", "mc"), metrics["design_status_mc"].astype(np.int8),
                                    {"long_name": "design status of each Monte Carlo roll",
                                     "flag_values": np.array(codes, np.int8),
                                     "flag_meanings": " ".join(STATUS[c] for c in codes)})
        mc_ok = np.ones(metrics["design_status_mc"].shape, bool) & (metrics["design_status_mc"] == 0)
        for b in study.constraints:
            v = metrics[f"{b.metric}_mc"]
            with np.errstate(invalid="ignore"):
                mc_ok &= (v >= b.low) & (v <= b.high)
        data["feasible_fraction"] = ("design", mc_ok.mean(axis=1), {
            "units": "1", "long_name": "share of the Monte Carlo rolls meeting every constraint"})
    coords = {"design": ("design", np.arange(n), {"long_name": "design index"})}
    if study.mc_samples:
        coords["mc"] = ("mc", np.arange(study.mc_samples), {"long_name": "Monte Carlo sample of the radii"})
    if sens is not None:
        coords["objective"] = ("objective", [g.metric for g in study.objectives])
        coords["variable"] = ("variable", list(study.names))
        for key in ("S1", "ST", "S1_conf", "ST_conf"):
            data[f"sobol_{key}"] = (("objective", "variable"),
                                    np.stack([sens["indices"][g.metric][key] for g in study.objectives]),
                                    {"units": "1", "long_name": f"Sobol index {key} (SALib, Saltelli sampling, "
                                     f"{sens['designs']} designs)"})
        data["sobol_missing"] = ("objective",
                                 np.array([sens["indices"][g.metric]["missing"] for g in study.objectives]),
                                 {"long_name": "Saltelli designs without a value (no roll, no equilibrium, past the "
                                  "protocol's limits): the indices are undefined (NaN) where this is not 0"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update({
        "Conventions": "CF-1.8", "title": f"rdea-lab design study {study.name}",
        "study": study.name, "study_file": study.source, "study_yaml": study.text, "model": study.model,
        "sampling": f"{study.method} n={n} seed={study.seed}", "chunk": study.chunk,
        "objectives": ", ".join(g.label for g in study.objectives),
        "constraints": json.dumps([[b.metric, b.low, b.high] for b in study.constraints]),
        "radii_tolerance": study.radii_tolerance, "mc_samples": study.mc_samples, "mc_seed": study.mc_seed,
        "rdea_lab_version": __version__,
    })
    if opt is not None:
        ds.attrs["optimum"] = json.dumps({k: opt[k] for k in ("objective", "variables", "metrics", "start", "how",
                                                              "evaluations", "sweep_best", "card_variables",
                                                              "card_metrics", "card_feasible")})
        ds.attrs["optimum_card"] = dump_specimen(card)
    return ds


def _si(name: str) -> str:
    from ..specs.study import VARIABLES
    from ..specs.units import _DIMENSIONS
    return {"dimensionless": "1"}.get(VARIABLES[name][0], _DIMENSIONS[VARIABLES[name][0]][0])


__all__ = ["StudyError", "StudyResult", "card_of", "evaluate_table", "feasible", "optimize", "pareto", "run_study",
           "sample", "sensitivity", "table_of"]
