"""Where SU's eager pass gains from numba's threads (`kernels.SU_PARALLEL_MIN`): `kernels.su_solve` of the bench
scene's first ``n`` samples (hollow core, ``lambda1`` U[1, 1.75], ``v`` U[0, 3.5 kV]) on one thread and on
numba's threads, the median of ``--calls`` calls each, back to back and after 2 ms idle (the threads asleep:
what a call after other work pays to wake them).

    python3 benchmarks/su_threads.py [--calls 200]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_models import RIZZELLO, _core, _envelope  # noqa: E402

from rdea_lab.physics import kernels  # noqa: E402
from rdea_lab.physics.models._common import kappa  # noqa: E402
from rdea_lab.physics.models.su import _CODES  # noqa: E402


def median_us(l1, v, C, kap, area, threads, idle, calls):
    """The median [us] of ``calls`` calls of `kernels.su_solve`, numba's threads allowed or not (the load the
    call sees set by hand), each after ``idle`` seconds of sleep."""
    load, least = kernels._other_load, kernels.SU_PARALLEL_MIN
    kernels._other_load = (lambda: 0.0) if threads else (lambda: float(kernels._CORES))
    kernels.SU_PARALLEL_MIN = 0  # threads (where allowed) at any count: the threshold is what this measures
    try:
        kernels.su_solve(l1, v, C, kap, area, True, _CODES)
        out = []
        for _ in range(calls):
            if idle:
                time.sleep(idle)
            t0 = time.perf_counter()
            kernels.su_solve(l1, v, C, kap, area, True, _CODES)
            out.append(time.perf_counter() - t0)
    finally:
        kernels._other_load, kernels.SU_PARALLEL_MIN = load, least
    return 1e6 * float(np.median(out))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=200)
    args = ap.parse_args(argv)
    geom = _core("hollow-core")
    C, kap, area = (RIZZELLO.C10, RIZZELLO.C20, RIZZELLO.C30), float(kappa(geom, RIZZELLO)), float(geom.area)
    l1, v = _envelope(131072, 1.75, 3500.0)
    print(f"su_solve, median of {args.calls} calls [us] (a solve takes threads from {kernels.SU_PARALLEL_MIN} "
          "samples)")
    for n in (8192, 16384, 32768, 65536, 131072):
        a, b = l1[:n].copy(), v[:n].copy()
        row = [median_us(a, b, C, kap, area, threads, idle, args.calls) for idle in (0.0, 0.002)
               for threads in (False, True)]
        print(f"  n {n:6d}  back to back: one thread {row[0]:7.1f}, threads {row[1]:7.1f} | "
              f"after 2 ms idle: one thread {row[2]:7.1f}, threads {row[3]:7.1f}")


if __name__ == "__main__":
    main()
