"""Design studies: designs per second through a full tensile protocol, on 1 and 2 dask workers.

The study: specimen 2's membrane (``specimens/specimen2.yaml``), Table 3's
material (``params/paper2021_table3.yaml``), model SU; variables L1 in
[20, 60] mm, L2e in [40, 90] mm (L2 follows, the card's Lp1 and Lp2 kept),
L3 in [30, 80] um and the prestretch in [1.05, 1.5] (it sets the preload of a
200 N/m spring bias); 2.6 kV; every design also runs the tensile ramp-sine at
2.6 kV (``protocols/tensile_ramp_sine_2.6kV.yaml``, 5401 samples);
objectives stroke and peak_force; no tolerances, sensitivity or optimize.
Sobol sampling, ``--designs`` designs (1e4), ``--chunk`` designs per task
(250). The study is written as YAML to a temporary folder and read back with
`load_study`, as ``rdea-lab design`` reads one.

Measured, each the median of ``--repeat`` runs with the slowest and fastest
beside it:

- ``cluster``: for each worker count (1 and 2), `evaluate_table` of the whole
  table on a `connect`-ed LocalCluster of single-threaded worker processes.
  The cluster's start-up (``startup_s``) and its warm-up (``warmup_s``: every
  worker evaluates a tiny chunk through ``client.run``, so each loads the
  numba kernels, then one small table of a chunk per worker goes through
  `evaluate_table`) are timed apart and not in the figures. Each timed run has
  its own label, so no task key repeats and nothing comes from a result the
  scheduler still holds. Per run: seconds, designs/s, sample evaluations/s
  (designs x protocol samples), and from dask's task stream the workers'
  busy share (compute time of the tasks / (workers x wall time)) and the
  median compute time of a task; from each worker's ``getrusage`` its CPU
  seconds (user, system) and minor page faults over the run (``cpu_share``:
  CPU seconds / (workers x wall time); a busy worker whose CPU share is low is
  waiting, not computing). ``speedup`` is 1 -> 2 workers on the median
  seconds (and slowest/fastest pairs for its spread). ``others_cpu_share``:
  the share of the machine's CPU (``/proc/stat``, all cores) that processes
  other than this one and its workers took during the run (other work on a
  shared machine: the figures are slower by about that much). ``--dask-malloc-trim``
  (diagnostic, not the headline) spawns the workers with the
  ``MALLOC_TRIM_THRESHOLD_=65536`` dask's nanny sets by default
  (``distributed.nanny.pre-spawn-environ``) and `rdea_lab.design.cluster.connect`
  leaves out, to see what that setting costs.
- ``in_process``: `evaluate_chunk` of the table's first chunk in this process,
  no dask, on a thread other than the main one as a worker's task is (so the
  kernels' serial forms run): the one-core rate a worker's chunk can reach.
- ``loop``: the first ``--loop-designs`` (200) designs as a Python loop over
  ``rdea_lab.simulate(card, params, t, stretch, voltage, model="su")`` on the
  same protocol history, each card built beforehand from the design's
  membrane (`rdea_lab.design.evaluate.membrane`); only the loop of simulate
  calls and the max of each force is timed. Designs/s, the time 1e4 designs
  would take at that rate, and the ratio of the 2-worker study's rate to it.
  ``max_rel_diff``: the loop's max force against the study's peak_force for
  the same designs (max |a - b| / |b|).
- ``chunks`` (``--chunk-sweep 100,250,500,1000``): the cluster figures at each
  chunk size, same workers and clusters.
- ``profile`` (``--profile``): a cProfile of one chunk of `evaluate_chunk`,
  in this process (on a thread) and on a worker of the first cluster (through
  ``client.run``: its process and environment), with the CPU seconds and minor
  page faults of the profiled call (printed to stderr; the top functions and
  the text in the JSON).

``--model 3r`` (or ``cr``) runs the same study with that model, and
``--core-radius 0.5mm`` winds specimen 2's membrane on a mandrel of that radius
(a hollow core, ``Ri`` of the card written beside the study; 0: specimen 2 as
it is, a solid roll). The loop then calls `simulate` with the same model.

The aims (issue 30): SU, 1e5 designs with the 5401-sample protocol in at most
60 s on 2 workers; 3R, 1e4 designs in at most 120 s on 2 workers (CR: none);
and near-linear scaling (a 1 -> 2 speed-up of at least 1.8, 90 % efficiency,
where both worker counts ran). ``aim`` says whether the medians meet them (the
seconds scaled linearly to the aim's designs when fewer ran).

    PYTHONPATH=. python3 benchmarks/bench_design.py [--designs 10000] [--chunk 250] [--repeat 3]
        [--workers 1,2] [--model su] [--core-radius 0] [--loop-designs 200] [--chunk-sweep 100,250,500,1000]
        [--profile] [--dask-malloc-trim] [--json]

Must run as a script (dask's workers are spawned processes).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SPECIMEN = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
PROTOCOL = ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_2.6kV.yaml"
#: per model: (seconds, designs) on 2 workers; and the 1 -> 2 worker speed-up
AIMS = {"su": (60.0, 100_000), "3r": (120.0, 10_000)}
AIM_SPEEDUP = 1.8
#: glibc reads MALLOC_TRIM_THRESHOLD_ at start-up: this process's, before dask's nanny sets it in os.environ
_MALLOC_AT_START = os.environ.get("MALLOC_TRIM_THRESHOLD_")

STUDY = """\
name: bench_design
model: {model}
params: {params}
specimen: {specimen}
variables:
  L1: [20 mm, 60 mm]
  L2e: [40 mm, 90 mm]
  L3: [30 um, 80 um]
  prestretch: [1.05, 1.5]
sampling: {{method: sobol, n: {n}, seed: 1}}
voltage: 2.6 kV
bias: {{kind: spring, stiffness: 200 N/m, preload: 0 N}}
objectives: [{{maximize: stroke}}, {{maximize: peak_force}}]
protocol: {protocol}
chunk: {chunk}
"""


def load(designs: int, chunk: int, folder: Path, model: str = "su", core_radius: float = 0.0):
    """The study (module docstring), written to ``folder`` and read back as `rdea-lab design` reads it;
    ``core_radius`` [m] > 0: specimen 2's membrane on a mandrel (a card of its own beside the study)."""
    from rdea_lab.specs.study import load_study

    specimen = SPECIMEN
    if core_radius > 0:
        specimen = folder / "specimen2_hollow.yaml"
        text = SPECIMEN.read_text(encoding="utf-8").replace("id: specimen-2", "id: specimen-2-hollow")
        specimen.write_text(text.rstrip("\n") + f"\n  Ri: {core_radius * 1e3!r} mm\n", encoding="utf-8")
    path = folder / "bench_design.yaml"
    path.write_text(STUDY.format(params=PARAMS, specimen=specimen, protocol=PROTOCOL, n=designs, chunk=chunk,
                                 model=model), encoding="utf-8")
    return load_study(path)


def designs_table(study) -> dict:
    from rdea_lab.design.study import sample, table_of

    with warnings.catch_warnings():  # scipy: "balance properties of Sobol' points require n to be a power of 2"
        warnings.simplefilter("ignore", UserWarning)
        return table_of(study, sample(study))


def _spread(values):
    """``(median, slowest, fastest)`` of wall times [s]."""
    v = np.asarray(values, float)
    return float(np.median(v)), float(v.max()), float(v.min())


def _rate(n, times):
    """``(median, slowest, fastest)`` of ``n`` per second over runs of ``times`` [s] (bench_models' _rate)."""
    r = n / np.asarray(times, float)
    return float(np.median(r)), float(r.min()), float(r.max())


def _warm(fixed):
    """On a worker: one tiny chunk, so the process has imported everything and loaded the numba kernels."""
    from rdea_lab.design.evaluate import evaluate_chunk

    table = {v.name: np.full(4, 0.5 * (v.low + v.high)) for v in fixed.study.variables}
    evaluate_chunk(fixed, np.arange(4), table)
    return {"pid": os.getpid(), "MALLOC_TRIM_THRESHOLD_": os.environ.get("MALLOC_TRIM_THRESHOLD_")}


def _usage():
    """On a worker: its process's CPU seconds (user, system) and minor page faults so far."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime, r.ru_stime, r.ru_minflt


def _machine():
    """``(busy, total)`` CPU seconds of the whole machine so far (``/proc/stat``; None off Linux)."""
    try:
        with open("/proc/stat") as f:
            v = [int(x) for x in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    tick = os.sysconf("SC_CLK_TCK")
    idle = v[3] + (v[4] if len(v) > 4 else 0)
    return (sum(v[:8]) - idle) / tick, sum(v[:8]) / tick


def _self_cpu():
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _others(m0, m1, ours_s, wall):
    """Share of the machine's CPU (all cores) taken during ``wall`` by processes other than ours."""
    if m0 is None or m1 is None:
        return float("nan")
    busy, total = m1[0] - m0[0], m1[1] - m0[1]
    return float(max(0.0, busy - ours_s) / total) if total > 0 else float("nan")


def _usage_delta(before, after) -> dict:
    d = np.sum([np.subtract(after[w], before[w]) for w in after], axis=0)
    return {"user_s": float(d[0]), "sys_s": float(d[1]), "minor_faults": int(d[2])}


def _busy(stream) -> tuple[float, list[float]]:
    """Total compute seconds of the tasks in a dask task stream, and each task's."""
    per = []
    for task in stream:
        per.append(sum(s["stop"] - s["start"] for s in task.get("startstops", ()) if s.get("action") == "compute"))
    return float(sum(per)), per


def cluster_runs(study, table, fixed, workers: int, repeat: int, chunks=(), malloc_trim=False,
                 with_profile=False) -> dict:
    """Start a cluster of ``workers``, warm it, time ``repeat`` runs of `evaluate_table` (per chunk size).

    ``malloc_trim=True`` (diagnostic): the workers are spawned with the ``MALLOC_TRIM_THRESHOLD_=65536``
    that dask's nanny sets by default (``distributed.nanny.pre-spawn-environ``) and `connect` leaves out."""
    import contextlib
    import dataclasses

    import dask
    from distributed import get_task_stream

    from rdea_lab.design import connect, evaluate_table

    n = len(next(iter(table.values())))
    samples = int(fixed.history[0].size)
    env = contextlib.nullcontext()
    if malloc_trim:  # diagnostic: dask's own default, which `connect` leaves out
        spawn = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
        spawn["MALLOC_TRIM_THRESHOLD_"] = 65536
        env = dask.config.set({"distributed.nanny.pre-spawn-environ": spawn})
    t0 = time.perf_counter()
    with env, connect(workers=workers, quiet=True) as client:
        client.wait_for_workers(workers)
        startup = time.perf_counter() - t0
        t0 = time.perf_counter()
        pids = client.run(_warm, fixed)
        warm_n = min(n, study.chunk * workers)
        evaluate_table(study, {k: v[-warm_n:] for k, v in table.items()}, client=client, label="warmup",
                       fixed=fixed)
        warmup = time.perf_counter() - t0
        info = list(pids.values())
        out = {"workers": workers, "startup_s": startup, "warmup_s": warmup,
               "worker_pids": sorted(i["pid"] for i in info),
               "worker_MALLOC_TRIM_THRESHOLD_": sorted({str(i["MALLOC_TRIM_THRESHOLD_"]) for i in info})}
        metrics = None
        for chunk in (study.chunk, *[c for c in chunks if c != study.chunk]):
            st = study.model_copy(update={"chunk": chunk})  # a pydantic model (Study)
            fx = dataclasses.replace(fixed, study=st)
            secs, busy, task_s, usage = [], [], [], []
            for i in range(repeat):
                u0 = client.run(_usage)
                with get_task_stream(client) as ts:
                    m0, c0, a = _machine(), _self_cpu(), time.perf_counter()
                    res = evaluate_table(st, table, client=client, label=f"w{workers}-c{chunk}-r{i}", fixed=fx)
                    secs.append(time.perf_counter() - a)
                    m1, c1 = _machine(), _self_cpu()
                usage.append(_usage_delta(u0, client.run(_usage)))
                usage[-1]["others_cpu_share"] = _others(m0, m1, usage[-1]["user_s"] + usage[-1]["sys_s"] + c1 - c0,
                                                        secs[-1])
                total, per = _busy(ts.data)
                busy.append(total / (workers * secs[-1]))
                task_s.extend(per)
            if metrics is None:
                metrics = res
            entry = {"chunk": chunk, "tasks": -(-n // chunk), "seconds": _spread(secs),
                     "designs_per_s": _rate(n, secs), "sample_evals_per_s": _rate(n * samples, secs),
                     "busy_share": _spread(busy)[0], "busy_share_range": [min(busy), max(busy)],
                     "task_compute_s_median": float(np.median(task_s)) if task_s else float("nan"),
                     "runs_s": secs, "worker_cpu": usage,
                     "cpu_share": float(np.median([(u["user_s"] + u["sys_s"]) / (workers * t)
                                                   for u, t in zip(usage, secs)])),
                     "sys_share_of_cpu": float(np.median([u["sys_s"] / max(u["user_s"] + u["sys_s"], 1e-9)
                                                          for u in usage])),
                     "others_cpu_share": float(np.median([u["others_cpu_share"] for u in usage]))}
            out.setdefault("by_chunk", {})[str(chunk)] = entry
        out.update({k: v for k, v in out["by_chunk"][str(study.chunk)].items() if k != "chunk"})
        if with_profile:  # one chunk on one worker, in its process and environment (after the timed runs)
            m = min(study.chunk, n)
            first = sorted(client.scheduler_info()["workers"])[0]
            out["profile"] = client.run(_profile_chunk, fixed, {k: v[:m] for k, v in table.items()},
                                        workers=[first])[first]
    return out, metrics


def in_process(study, table, fixed, repeat: int) -> dict:
    """One chunk in this process, on a thread other than the main one (as a worker runs a task: the
    kernels' serial forms, `rdea_lab.physics.kernels._parallel`)."""
    import threading

    from rdea_lab.design.evaluate import evaluate_chunk

    m = min(study.chunk, len(next(iter(table.values()))))
    sub = {k: v[:m] for k, v in table.items()}
    secs, others = [], []

    def runs():
        evaluate_chunk(fixed, np.arange(m), sub)  # warm-up: the kernels load
        for _ in range(repeat):
            m0, c0, a = _machine(), _self_cpu(), time.perf_counter()
            evaluate_chunk(fixed, np.arange(m), sub)
            secs.append(time.perf_counter() - a)
            others.append(_others(m0, _machine(), _self_cpu() - c0, secs[-1]))

    thread = threading.Thread(target=runs)
    thread.start()
    thread.join()
    return {"designs": m, "seconds": _spread(secs), "designs_per_s": _rate(m, secs),
            "sample_evals_per_s": _rate(m * int(fixed.history[0].size), secs),
            "others_cpu_share": float(np.median(others))}


def loop(study, table, fixed, designs: int, repeat: int):
    """The Python loop over `rdea_lab.simulate`, one design at a time (cards built before the clock)."""
    import rdea_lab
    from rdea_lab.design.evaluate import membrane
    from rdea_lab.specs.specimen import Membrane, SpecimenCard

    m = min(designs, len(next(iter(table.values()))))
    mem = membrane(study, {k: v[:m] for k, v in table.items()})
    keys = ("L1", "L2", "L3", "L1e", "Lp1", "L2e", "Ri")
    cards = [SpecimenCard(id=f"design-{i}", kind="roll", membrane=Membrane(**{k: float(mem[k][i]) for k in keys}))
             for i in range(m)]
    t, stretch, voltage, _ = fixed.history
    params = study.params
    model = study.model
    rdea_lab.simulate(cards[0], params, t, stretch, voltage, model=model)  # warm-up

    def run():
        return np.array([float(rdea_lab.simulate(c, params, t, stretch, voltage, model=model)["force"].max())
                         for c in cards])

    secs, peak, others = [], None, []
    for _ in range(repeat):
        m0, c0, a = _machine(), _self_cpu(), time.perf_counter()
        peak = run()
        secs.append(time.perf_counter() - a)
        others.append(_others(m0, _machine(), _self_cpu() - c0, secs[-1]))
    rate = _rate(m, secs)
    return {"designs": m, "seconds": _spread(secs), "designs_per_s": rate,
            "others_cpu_share": float(np.median(others)),
            "sample_evals_per_s": _rate(m * int(t.size), secs),
            "extrapolated_1e4_s": [1e4 / rate[0], 1e4 / rate[1], 1e4 / rate[2]]}, peak


def _profile_chunk(fixed, table, top: int = 25) -> dict:
    """cProfile of `evaluate_chunk` on ``table`` (after one untimed call), with its minor page faults; runs
    wherever it is called (this process, or a worker through ``client.run``)."""
    import cProfile
    import io
    import pstats
    import resource

    from rdea_lab.design.evaluate import evaluate_chunk

    m = len(next(iter(table.values())))
    evaluate_chunk(fixed, np.arange(m), table)
    prof = cProfile.Profile()
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    prof.enable()
    evaluate_chunk(fixed, np.arange(m), table)
    prof.disable()
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    text = io.StringIO()
    stats = pstats.Stats(prof, stream=text)
    stats.sort_stats("cumulative").print_stats(top)
    stats.sort_stats("tottime").print_stats(top)
    rows = [{"function": f"{Path(file).name}:{line}({fn})", "calls": nc, "tottime": tt, "cumtime": ct}
            for (file, line, fn), (cc, nc, tt, ct, _) in stats.stats.items()]
    return {"designs": m, "total_s": max(r["cumtime"] for r in rows),
            "user_s": r1.ru_utime - r0.ru_utime, "sys_s": r1.ru_stime - r0.ru_stime,
            "minor_faults": r1.ru_minflt - r0.ru_minflt,
            "MALLOC_TRIM_THRESHOLD_": os.environ.get("MALLOC_TRIM_THRESHOLD_"),
            "cumulative": sorted(rows, key=lambda r: -r["cumtime"])[:top],
            "tottime": sorted(rows, key=lambda r: -r["tottime"])[:top], "text": text.getvalue()}


def profile_in_process(study, table, fixed) -> dict:
    """`_profile_chunk` of the first chunk on a thread of this process (the kernels' serial forms)."""
    import threading

    m = min(study.chunk, len(next(iter(table.values()))))
    out = {}
    thread = threading.Thread(target=lambda: out.update(_profile_chunk(fixed, {k: v[:m] for k, v in table.items()})))
    thread.start()
    thread.join()
    out["MALLOC_TRIM_THRESHOLD_"] = _MALLOC_AT_START
    return out


def _show_profile(where, p):
    print(f"cProfile of evaluate_chunk {where}, {p['designs']} designs: {p['total_s']:.2f} s, CPU user "
          f"{p['user_s']:.2f} s + system {p['sys_s']:.2f} s, {p['minor_faults']} minor page faults, "
          f"MALLOC_TRIM_THRESHOLD_={p['MALLOC_TRIM_THRESHOLD_']}\n{p['text']}", file=sys.stderr)


def run(designs=10_000, chunk=250, repeat=3, workers=(1, 2), loop_designs=200, chunk_sweep=(),
        with_profile=False, malloc_trim=False, model="su", core_radius=0.0) -> dict:
    from rdea_lab import __version__
    from rdea_lab.design.evaluate import STATUS, Fixed

    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        study = load(designs, chunk, Path(tmp), model, core_radius)
    fixed = Fixed.of(study)
    table = designs_table(study)
    samples = int(fixed.history[0].size)
    result = {"designs": designs, "chunk": chunk, "repeat": repeat, "protocol_samples": samples, "model": model,
              "core_radius_m": core_radius,
              "dask_malloc_trim": malloc_trim,
              "study": STUDY.format(params=PARAMS.relative_to(ROOT), specimen=SPECIMEN.relative_to(ROOT),
                                    protocol=PROTOCOL.relative_to(ROOT), n=designs, chunk=chunk, model=model),
              "in_process": in_process(study, table, fixed, repeat), "cluster": {}}
    metrics = {}
    for w in workers:
        result["cluster"][str(w)], metrics[w] = cluster_runs(study, table, fixed, w, repeat, chunk_sweep,
                                                             malloc_trim, with_profile and w == workers[0])
    ref = metrics[workers[0]]
    status = ref["design_status"]
    result["design_status"] = {STATUS[c]: int((status == c).sum()) for c in STATUS if (status == c).any()}
    result["same_across_workers"] = all(
        all(np.array_equal(ref[k], m[k], equal_nan=True) for k in ref) for m in metrics.values())
    c = result["cluster"]
    if "1" in c and "2" in c:
        s1, s2 = c["1"]["seconds"], c["2"]["seconds"]
        result["speedup"] = [s1[0] / s2[0], s1[2] / s2[1], s1[1] / s2[2]]  # median; worst pair; best pair
        for size in c["2"].get("by_chunk", {}):
            if size in c["1"].get("by_chunk", {}):
                c["2"]["by_chunk"][size]["speedup"] = (c["1"]["by_chunk"][size]["seconds"][0]
                                                       / c["2"]["by_chunk"][size]["seconds"][0])
    if loop_designs > 0:  # 0: the study alone
        lp, peak = loop(study, table, fixed, loop_designs, repeat)
        study_peak = ref["peak_force"][:lp["designs"]]
        ok = np.isfinite(study_peak)
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.abs(peak[ok] - study_peak[ok]) / np.abs(study_peak[ok])
        lp["max_rel_diff"] = float(rel.max()) if rel.size else float("nan")
        lp["compared"] = int(ok.sum())
        best = c[str(max(workers))]
        lp["study_over_loop"] = best["designs_per_s"][0] / lp["designs_per_s"][0]
        lp["study_workers"] = max(workers)
        result["loop"] = lp
    if "2" in c and model in AIMS:
        aim_s, aim_n = AIMS[model]
        t_aim = c["2"]["seconds"][0] * aim_n / designs
        sp = result["speedup"][0] if "speedup" in result else None
        result["aim"] = {"designs": aim_n, "seconds": aim_s, "seconds_on_2_workers": t_aim,
                         "scaled_from": designs, "in_time": t_aim <= aim_s, "speedup": sp,
                         "near_linear": None if sp is None else sp >= AIM_SPEEDUP,
                         "met": t_aim <= aim_s and (sp is None or sp >= AIM_SPEEDUP)}
    if with_profile:
        result["profile"] = {"in_process": profile_in_process(study, table, fixed),
                             "worker": result["cluster"][str(workers[0])].pop("profile")}
        _show_profile("in process (a thread)", result["profile"]["in_process"])
        _show_profile(f"on a worker of the {workers[0]}-worker cluster", result["profile"]["worker"])
    result["machine"] = {"cpus": os.cpu_count(), "python": platform.python_version(),
                         "processor": platform.machine(), "numpy": np.__version__,
                         "loadavg_before": list(load_before), "loadavg_after": list(os.getloadavg())}
    try:
        import dask
        import distributed
        result["machine"].update(dask=dask.__version__, distributed=distributed.__version__)
    except ImportError:  # pragma: no cover
        pass
    result["rdea_lab_version"] = __version__
    return result


def format_text(r: dict) -> str:
    n, s = r["designs"], r["protocol_samples"]
    core = f" on a {r['core_radius_m'] * 1e3:g} mm core" if r.get("core_radius_m") else ""
    lines = [f"design study, {n} designs (Sobol) x {s}-sample tensile protocol, {r['model'].upper()}, "
             f"specimen 2's membrane{core}; "
             f"chunk {r['chunk']}; median (slowest-fastest) of {r['repeat']} runs:"]
    head = f"  {'':<22}{'seconds':>22}{'designs/s':>24}{'sample evals/s':>26}{'busy':>7}{'others':>8}"
    lines.append(head)

    def row(label, x, busy=None):
        sec, rate, sev = x["seconds"], x["designs_per_s"], x["sample_evals_per_s"]
        b = f"{busy:6.0%}" if busy is not None else "      "
        b += f"{x['others_cpu_share']:8.0%}" if "others_cpu_share" in x else ""
        return (f"  {label:<22}{sec[0]:8.2f} ({sec[2]:.2f}-{sec[1]:.2f}){'':>1}"
                f"{rate[0]:10.0f} ({rate[1]:.0f}-{rate[2]:.0f}){sev[0]:12.3e} ({sev[1]:.2e}-{sev[2]:.2e}){b}")

    ip = r["in_process"]
    lines.append(row("in process, 1 chunk", ip))
    for w, x in r["cluster"].items():
        lines.append(row(f"{w} worker{'s' if w != '1' else ''}", x, x["busy_share"]))
    for w, x in r["cluster"].items():
        lines.append(f"  {w} worker(s): cluster start-up {x['startup_s']:.1f} s, warm-up {x['warmup_s']:.1f} s "
                     f"(not in the figures); {x['tasks']} tasks, "
                     f"median task compute {x['task_compute_s_median']:.2f} s; "
                     f"workers' CPU {x['cpu_share']:.0%} of workers x wall "
                     f"({x['sys_share_of_cpu']:.0%} of it system); "
                     f"other processes {x['others_cpu_share']:.0%} of the machine; "
                     f"MALLOC_TRIM_THRESHOLD_ {', '.join(x['worker_MALLOC_TRIM_THRESHOLD_'])}")
    if "speedup" in r:
        sp = r["speedup"]
        lines.append(f"  1 -> 2 workers: {sp[0]:.2f}x (worst-best pairs {sp[1]:.2f}-{sp[2]:.2f}x)")
    sweep = {w: x["by_chunk"] for w, x in r["cluster"].items() if len(x.get("by_chunk", {})) > 1}
    if sweep:
        lines.append("  by chunk size [s, median (fastest-slowest)]:")
        for w, by in sweep.items():
            parts = [f"{c}: {e['seconds'][0]:.2f} ({e['seconds'][2]:.2f}-{e['seconds'][1]:.2f})"
                     + (f" {e['speedup']:.2f}x" if "speedup" in e else "") for c, e in by.items()]
            lines.append(f"    {w} worker(s): " + ", ".join(parts))
    lp = r.get("loop")
    if lp is not None:
        lines.append(row(f"loop simulate(), {lp['designs']}", lp))
        e = lp["extrapolated_1e4_s"]
        lines.append(f"  loop: 1e4 designs would take {e[0]:.0f} s ({e[2]:.0f}-{e[1]:.0f}); "
                     f"the {lp['study_workers']}-worker study is {lp['study_over_loop']:.1f}x the loop's rate")
        lines.append(f"  loop max force vs study peak_force, {lp['compared']} designs: max rel. diff "
                     f"{lp['max_rel_diff']:.1e}")
    lines.append(f"  results identical across worker counts: {r['same_across_workers']}; "
                 f"design status: {r['design_status']}")
    if "aim" in r:
        a = r["aim"]
        sp = "" if a["speedup"] is None else f", {a['speedup']:.2f}x (aim >= {AIM_SPEEDUP})"
        lines.append(f"  aim ({a['designs']:.0e} designs <= {a['seconds']:.0f} s on 2 workers): "
                     f"{a['seconds_on_2_workers']:.1f} s (scaled from {a['scaled_from']} designs){sp} -> "
                     f"{'met' if a['met'] else 'NOT met'}")
    m = r["machine"]
    lines.append(f"  machine: {m['cpus']} cpus, load average before {m['loadavg_before'][0]:.2f}, after "
                 f"{m['loadavg_after'][0]:.2f}")
    return "\n".join(lines)


def _length(text: str) -> float:
    """``--core-radius``: a length with its unit [m] (0 alone: none)."""
    from rdea_lab.specs.units import parse_quantity

    return 0.0 if text.strip() in ("0", "") else parse_quantity(text, "length", source="--core-radius", field="")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, default=10_000)
    ap.add_argument("--chunk", type=int, default=250)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", default="1,2", help="worker counts, comma-separated (default 1,2)")
    ap.add_argument("--loop-designs", type=int, default=200)
    ap.add_argument("--chunk-sweep", default="", help="chunk sizes to time too, e.g. 100,250,500,1000")
    ap.add_argument("--profile", action="store_true", help="cProfile one chunk of evaluate_chunk (to stderr)")
    ap.add_argument("--dask-malloc-trim", action="store_true",
                    help="diagnostic: spawn the workers with dask's default MALLOC_TRIM_THRESHOLD_=65536")
    ap.add_argument("--model", default="su", choices=("su", "1r", "3r", "cr"))
    ap.add_argument("--core-radius", default="0", help="a mandrel's radius under specimen 2's membrane, e.g. 0.5mm "
                    "(0: a solid roll)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    workers = tuple(int(w) for w in a.workers.split(",") if w)
    sweep = tuple(int(c) for c in a.chunk_sweep.split(",") if c)
    result = run(a.designs, a.chunk, a.repeat, workers, a.loop_designs, sweep, a.profile, a.dask_malloc_trim,
                 a.model, _length(a.core_radius))
    print(json.dumps(result, indent=2) if a.json else format_text(result))


if __name__ == "__main__":
    main()
