"""The calibration objective on specimen 2: its cost per evaluation and the fits it makes, by eq. (44) kernel.

Data: specimen 2's two tensile runs (0 V and 2.6 kV, 5401 samples each) on the emulator, as
``rdea-lab bench`` makes them (`bench_models.bench_calibration`). Fits, from the start estimated from
the data (`initial_guess`, one branch, eps_r 2.8), SU model:

- ``m1``: `calibrate` with one branch and eta_v0 (Nelder-Mead, its least-squares warm start and
  polish): the fit ``rdea-lab bench`` times ("calibration of specimen 2").
- ``auto``: `calibrate_auto` with 0 to 3 branches (least squares per M, Nelder-Mead polish of the
  chosen one): ``rdea-lab reproduce``'s calibration stage.

Per kernel of eq. (44)'s linear update (``RDEA_LAB_KERNELS``: ``numba``, the compiled sequential
update a `History` takes; ``numpy``, the prefix scan, the reference): the cost of one counted
evaluation (`Objective.__call__` at the start, median of 200 after a warm-up, wall and CPU), then
``repeat`` fits of each kind after one untimed warm-up (numba's loading is not in them; ``--fresh``
measures it: a new process's import and first compiled evaluation). Fit times are the result's
``wall_time`` (as ``rdea-lab bench``) with the process's CPU time beside them; medians with the
spread (fastest and slowest). Evaluations, objective and the optimum are printed per kernel, and
the largest relative difference of a parameter between the kernels' optima. The load average
before each fit is recorded: on a shared machine the wall times mean little without it.

    python3 benchmarks/bench_calibration.py [--repeat 5] [--fits m1,auto] [--kernels numba,numpy]
                                            [--fresh] [--json]

One BLAS thread, as the ``rdea-lab`` command sets (least squares' SVD of a 10802 x 8 Jacobian ran
16x slower threaded on a busy 2-core machine), unless ``OPENBLAS_NUM_THREADS`` says otherwise.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads, as rdea_lab.cli does

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PROTOCOLS = ("tensile_ramp_sine_0V", "tensile_ramp_sine_2.6kV")
FITS = ("m1", "auto")
KERNELS = ("numba", "numpy")
#: ``rdea-lab reproduce``'s largest M (`rdea_lab.reports.reproduce.REPRODUCE_MAX_BRANCHES`).
AUTO_MAX_BRANCHES = 3


def specimen2_runs(folder: Path) -> list[Path]:
    """Specimen 2's two tensile runs on the emulator, written into ``folder``."""
    from rdea_lab.backends.rig import RigBackend
    from rdea_lab.physics.geometry import geometry_from_card
    from rdea_lab.protocols import load_plan
    from rdea_lab.runs import checked_plan, execute
    from rdea_lab.runs import emulated_rig as _emulator
    from rdea_lab.specs import load_specimen
    from rdea_lab.specs.truth import load_truth

    data = ROOT / "rdea_lab" / "data"
    card = load_specimen(data / "specimens" / "specimen2.yaml")
    geom = geometry_from_card(card)
    paths = []
    with _emulator(card, load_truth(data / "truth" / "paper2021.yaml"), realtime=False) as address:
        for name in PROTOCOLS:
            out = folder / f"{name}.nc"
            plan = checked_plan(load_plan(data / "protocols" / f"{name}.yaml"), card, geom)
            execute(plan, card, RigBackend(address, card, geometry=geom), out)
            paths.append(out)
    return paths


def _stat(values) -> dict:
    values = sorted(values)
    return {"median": statistics.median(values), "min": values[0], "max": values[-1]}


def evaluation_cost(runs, start, n: int = 200) -> dict:
    """One counted evaluation of the objective at ``start`` (all parameters free): wall and CPU [ms]."""
    from rdea_lab.calibration.fit import constrain_start, fit_parameters
    from rdea_lab.calibration.methods import Objective
    from rdea_lab.calibration.parameters import values_of

    start = constrain_start(start, "yeoh")
    obj = Objective(runs, start, fit_parameters(start, set(values_of(start)), "yeoh"), "su", "rms", 10**9, 1e9)
    z = np.array([p.to_internal(p.start) for p in obj.free])
    for _ in range(20):
        obj(z)
    wall, cpu = [], []
    for _ in range(n):
        t, c = time.perf_counter(), time.process_time()
        obj(z)
        wall.append(1e3 * (time.perf_counter() - t))
        cpu.append(1e3 * (time.process_time() - c))
    return {"wall_ms": _stat(wall), "cpu_ms": _stat(cpu)}


def one_fit(kind: str, runs, start):
    from rdea_lab.calibration import calibrate
    from rdea_lab.calibration.branches import calibrate_auto

    if kind == "m1":
        return calibrate(runs, start, model="su")
    return calibrate_auto(runs, start, AUTO_MAX_BRANCHES, model="su")


def fits(kind: str, runs, start, repeat: int) -> dict:
    """``repeat`` timed fits of ``kind`` after an untimed one."""
    one_fit(kind, runs, start)
    each = []
    for _ in range(repeat):
        load = os.getloadavg()[0]
        c = time.process_time()
        res = one_fit(kind, runs, start)
        each.append({"wall_time_s": res.wall_time, "cpu_s": time.process_time() - c, "load_before": load,
                     "nfev": res.nfev, "objective": res.objective})
    return {"wall_time_s": _stat([e["wall_time_s"] for e in each]), "cpu_s": _stat([e["cpu_s"] for e in each]),
            "load_before": _stat([e["load_before"] for e in each]), "nfev": res.nfev,
            "nfev_each": [e["nfev"] for e in each], "objective": res.objective,
            "values": {k: float(v) for k, v in res.values.items()}, "message": res.message}


_FRESH = """
import os, sys, time
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
t0 = time.perf_counter()
from pathlib import Path
from rdea_lab.calibration import initial_guess, load_run
from rdea_lab.calibration.objective import residuals
runs = [load_run(p) for p in sys.argv[1:]]
params = initial_guess(runs, 1, 2.8)
t1 = time.perf_counter()
residuals(runs, params, "su")
t2 = time.perf_counter()
residuals(runs, params, "su")
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, "numba" in sys.modules)
"""


def fresh(paths, kernel: str) -> dict:
    """A new process: its imports and data [s], then its first and second evaluation [s]."""
    env = dict(os.environ, RDEA_LAB_KERNELS=kernel)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [env.get("PYTHONPATH")] if p])
    out = subprocess.run([sys.executable, "-c", _FRESH, *map(str, paths)], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    return {"setup_s": float(out[0]), "first_evaluation_s": float(out[1]), "second_evaluation_s": float(out[2]),
            "numba_loaded": out[3] == "True"}


def run(repeat: int = 5, fit_kinds=FITS, kernels=KERNELS, fresh_process: bool = False) -> dict:
    from rdea_lab.calibration import initial_guess, load_run

    out = {"repeat": repeat, "cores": os.cpu_count(), "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
           "kernels": {}}
    with tempfile.TemporaryDirectory(prefix="bench-calibration-") as tmp:
        paths = specimen2_runs(Path(tmp))
        runs = [load_run(p) for p in paths]
        out["samples_per_evaluation"] = int(sum(r.n for r in runs))
        start = initial_guess(runs, 1, 2.8)
        before = os.environ.get("RDEA_LAB_KERNELS")
        try:
            for kernel in kernels:
                os.environ["RDEA_LAB_KERNELS"] = kernel  # read at every call (`_backend.compiled`)
                k = out["kernels"][kernel] = {"evaluation": evaluation_cost(runs, start)}
                if fresh_process:
                    k["fresh_process"] = fresh(paths, kernel)
                for kind in fit_kinds:
                    k[kind] = fits(kind, runs, start, repeat)
        finally:
            if before is None:
                os.environ.pop("RDEA_LAB_KERNELS", None)
            else:
                os.environ["RDEA_LAB_KERNELS"] = before
    if len(out["kernels"]) == 2:
        a, b = (out["kernels"][k] for k in kernels)
        out["optimum_max_rel_diff"] = {
            kind: max(abs(a[kind]["values"][n] - v) / abs(v) for n, v in b[kind]["values"].items() if v)
            for kind in fit_kinds}
    return out


def format_text(r: dict) -> str:
    def ms(s):
        return f"{s['median']:.3f} ms ({s['min']:.3f}-{s['max']:.3f})"

    def sec(s):
        return f"{s['median']:.3f} s ({s['min']:.3f}-{s['max']:.3f})"

    lines = [f"calibration of specimen 2 (SU, {r['samples_per_evaluation']} samples per evaluation; "
             f"{r['cores']} cores, {r['blas_threads']} BLAS thread(s); medians (fastest-slowest) of {r['repeat']})"]
    for kernel, k in r["kernels"].items():
        e = k["evaluation"]
        lines.append(f"eq. (44) kernel {kernel}: one evaluation {ms(e['wall_ms'])} wall, {ms(e['cpu_ms'])} CPU")
        if "fresh_process" in k:
            f = k["fresh_process"]
            lines.append(f"  fresh process: first evaluation {f['first_evaluation_s']:.3f} s, second "
                         f"{1e3 * f['second_evaluation_s']:.2f} ms (numba loaded: {f['numba_loaded']})")
        for kind in FITS:
            if kind in k:
                x = k[kind]
                lines.append(f"  {kind:<4}: wall_time {sec(x['wall_time_s'])}, CPU {sec(x['cpu_s'])}, "
                             f"{x['nfev']} evaluations, objective {x['objective']:.15e}, load before "
                             f"{x['load_before']['median']:.1f}")
    for kind, d in r.get("optimum_max_rel_diff", {}).items():
        lines.append(f"{kind}: largest relative difference of a parameter between the kernels' optima {d:.1e}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fits", default=",".join(FITS), help="m1, auto or both")
    ap.add_argument("--kernels", default=",".join(KERNELS), help="numba, numpy or both")
    ap.add_argument("--fresh", action="store_true", help="also a new process's first evaluation (numba's loading)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    kinds, kernels = a.fits.split(","), a.kernels.split(",")
    if not set(kinds) <= set(FITS) or not set(kernels) <= set(KERNELS):
        ap.error(f"--fits from {', '.join(FITS)}; --kernels from {', '.join(KERNELS)}")
    result = run(a.repeat, kinds, kernels, a.fresh)
    print(json.dumps(result, indent=2) if a.json else format_text(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
