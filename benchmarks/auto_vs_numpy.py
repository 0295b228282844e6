"""Is ``kernel="auto"``'s compiled path ever slower than ``kernel="numpy"``? Both timed on the same scenes.

Scenes: specimen 2 (Table 3 material) taut (stretch 1.05-1.5, 0-1.5 kV), all but a few samples slack
(stretch 1-1.02 at 2.6 kV), about a sixth slack (stretch 1-1.1 at 2.6 kV), and the hollow core of
Section 3.4 (stretch 1-1.75, 0-3.5 kV). Each at the given sample counts, per model: the median of
``--repeat`` calls after one warm-up, with numba already loaded (so the figures compare the calls, not
numba's start-up). Each call reads every field of its result (a compiled SU result computes most of them
when first read). The column ``auto`` says which path ``kernel="auto"`` takes (`_backend.auto_kernel`).

With ``--fresh`` each call is instead the first of a new process (``--repeat`` processes per path, the
median): the compiled path's time then includes loading numba and the kernels' machine code, which is
what ``auto`` weighs against the call's numpy time.

    python3 benchmarks/auto_vs_numpy.py [--models su,1r,3r,cr] [--samples 256,2048,16384] [--repeat 15]
        [--fresh] [--scenes 'hollow core,...']
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.physics.models import solve
from rdea_lab.physics.result import SLACK
from rdea_lab.specs import load_params, load_specimen

from bench_models import RIZZELLO, ROOT, _core, _times


def _median(fn, repeat):
    """Median wall time [s] of ``repeat`` calls after a warm-up (`bench_models._times`)."""
    return float(np.median(_times(fn, repeat)))


def scenes(n, seed=0):
    """``name -> (geom, material, stretch, voltage)`` of the four scenes at ``n`` samples."""
    rng = np.random.default_rng(seed)
    table3 = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
    spec2 = geometry_from_card(load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"))
    hollow = _core("hollow-core")
    return {
        "specimen 2 taut": (spec2, table3, rng.uniform(1.05, 1.5, n), rng.uniform(0.0, 1500.0, n)),
        "specimen 2 mostly slack": (spec2, table3, rng.uniform(1.0, 1.02, n), np.full(n, 2600.0)),
        "specimen 2 a sixth slack": (spec2, table3, rng.uniform(1.0, 1.1, n), np.full(n, 2600.0)),
        "hollow core": (hollow, RIZZELLO, rng.uniform(1.0, 1.75, n), rng.uniform(0.0, 3500.0, n)),
    }


FIELDS = ("sigma1", "force", "tension", "lambda2a", "lambda2b", "lambda2c", "capacitance", "converged", "r_i",
          "free_stretch", "status")


def _solve_all(model, geom, material, l1, v, kernel):
    """`solve` and every field of its result read."""
    res = solve(model, geom, material, l1, v, kernel=kernel)
    for name in FIELDS:
        getattr(res, name)
    return res


_FRESH = """
import sys, time
sys.path.insert(0, {bench!r})
import auto_vs_numpy as a
geom, material, l1, v = a.scenes({n})[{scene!r}]
t0 = time.perf_counter()
a._solve_all({model!r}, geom, material, l1, v, {kernel!r})
print(time.perf_counter() - t0)
"""


def _fresh(model, scene, n, kernel, repeat):
    """Median wall time [s] of the call as the first of a new process (numba not loaded before it)."""
    code = _FRESH.format(bench=str(Path(__file__).resolve().parent), n=n, scene=scene, model=model, kernel=kernel)
    return float(np.median([float(subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                                                 text=True).stdout.split()[-1]) for _ in range(repeat)]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="su,1r,3r,cr")
    ap.add_argument("--samples", default="256,2048,16384")
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--fresh", action="store_true", help="each call the first of a new process")
    ap.add_argument("--scenes", default="", help="comma-separated scene names (default: all)")
    a = ap.parse_args()
    from rdea_lab.physics._backend import auto_kernel

    print(f"{'scene':26s} {'n':>6s} model slack  compiled [ms]  numpy [ms]  numpy/compiled  auto")
    lowest = np.inf
    for n in (int(float(x)) for x in a.samples.split(",")):
        for name, (geom, material, l1, v) in scenes(n).items():
            if a.scenes and name not in a.scenes.split(","):
                continue
            for model in a.models.split(","):
                slack = float(np.mean(solve(model, geom, material, l1, v, kernel="numpy").status == SLACK))
                if a.fresh:
                    fast, ref = (_fresh(model, name, n, k, a.repeat) for k in ("numba", "numpy"))
                else:
                    fast, ref = (_median(lambda: _solve_all(model, geom, material, l1, v, k), a.repeat)
                                 for k in ("numba", "numpy"))
                auto = "compiled" if auto_kernel("auto", model, geom, n) == "numba" else "numpy"
                lowest = min(lowest, ref / fast)
                print(f"{name:26s} {n:6d} {model:5s} {slack:5.2f} {fast * 1e3:13.3f} {ref * 1e3:11.3f} "
                      f"{ref / fast:15.2f}  {auto}")
    print(f"lowest numpy/compiled: {lowest:.2f}")


if __name__ == "__main__":
    main()
