"""Where a whole `solve` call of 1R or 3R spends its time, on the bench scene (hollow core, 1e5 samples,
lambda1 U[1, 1.75], v U[0, 3.5 kV]): the median ms per call of its parts (each part's calls wrapped by a timer;
"the rest" is the call less them), then the root scan on one thread and on numba's threads (whatever the machine's
load), its setup (the scan with no load:
every sample decided before any node), and what one evaluation of the terms costs (one node's terms and ``h`` for
every sample, vectorized as the scan computes them): a sample takes some five evaluations (scan nodes and Newton
steps); the rest of the scan is each sample's verdicts and bookkeeping.

    python3 benchmarks/call_breakdown.py [--model 1r|3r] [--calls 60]
"""

from __future__ import annotations

import argparse
import collections
import functools
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_models import RIZZELLO, _core, _envelope, _times  # noqa: E402

from rdea_lab.physics import kernels, ring_kernels  # noqa: E402
from rdea_lab.physics.models import _common, one_ring, solve, three_ring  # noqa: E402

PARTS = [(_common, "prepare_inputs"), (ring_kernels, "bounds"), (kernels, "branch_roots"), (ring_kernels, "fields1"),
         (ring_kernels, "fields3"), (ring_kernels, "free_states"), (_common, "finish")]


def parts(model, calls):
    spent = collections.defaultdict(list)
    for module, name in PARTS:
        fn = getattr(module, name)

        @functools.wraps(fn)
        def timed(*a, _fn=fn, _name=name, **k):
            t0 = time.perf_counter()
            try:
                return _fn(*a, **k)
            finally:
                spent[_name].append(time.perf_counter() - t0)

        setattr(module, name, timed)
    geom, (l1, v) = _core("hollow-core"), _envelope(100_000, 1.75, 3500.0)
    for _ in range(5):
        solve(model, geom, RIZZELLO, l1, v)
    spent.clear()
    total = []
    for _ in range(calls):
        t0 = time.perf_counter()
        solve(model, geom, RIZZELLO, l1, v)
        total.append(time.perf_counter() - t0)
    print(f"{model}: whole call {1e3 * np.median(total):.3f} ms median of {calls} "
          f"({1e5 / np.median(total):.3g} samples/s)")
    known = 0.0
    for name, ts in spent.items():
        per_call = 1e3 * sum(ts) / calls
        known += per_call
        print(f"  {name:15s} {len(ts) // calls} a call  {per_call:.3f} ms")
    print(f"  {'the rest':15s}          {1e3 * np.mean(total) - known:.3f} ms (mean call less the parts)")


@numba.njit(cache=False)
def _node_terms(W, n, R, Q, code, C10, C20, C30, reps):
    """One scan node's terms and ``h``, slope of ``n`` samples, ``reps`` times, as `kernels._scan_block` computes
    them (`kernels._terms_block`, then `kernels._h_slope`), block by block."""
    for _ in range(reps):
        for lo in range(0, n, 256):
            m = min(256, n - lo)
            kernels._terms_block(code, m, W, R, Q, C10, C20, C30)
            for a in range(m):
                W[16, a], W[17, a] = kernels._h_slope(W[10, a], W[11, a], W[12, a], W[13, a])


def scan(model, repeat=25):
    geom, (l1, v) = _core("hollow-core"), _envelope(100_000, 1.75, 3500.0)
    problem = (one_ring if model == "1r" else three_ring).problem(geom, RIZZELLO, l1, v)
    args = list(kernels._roots_args(problem, False))
    n = l1.size

    def median(a, threads=0):
        return 1e3 * np.median(_times(
            lambda: kernels._roots[threads](*a, np.empty(n), np.zeros(n, np.int8), np.empty(n)), repeat))

    full = median(args)
    threads = median(args, 1)
    no_load = list(args)
    no_load[4] = np.zeros(n)  # K: every sample is its unloaded state, decided before any node
    setup = median(no_load)
    W = np.empty((23, 256 + 24))
    W[6, :] = problem.y0[:W.shape[1]] * 1.05
    W[7, :] = l1[:W.shape[1]]
    R, Q = args[7], args[8]
    _node_terms(W, n, R, Q, args[0], *args[9:12], 1)
    t0 = time.perf_counter()
    _node_terms(W, n, R, Q, args[0], *args[9:12], repeat)
    node = 1e3 * (time.perf_counter() - t0) / repeat
    print(f"  serial root scan {full:.2f} ms ({1e6 * full / n:.0f} ns a sample), of it the setup {setup:.2f} ms "
          f"(no load); one node's terms and h for every sample {node:.2f} ms ({1e6 * node / n:.1f} ns a sample); "
          f"the scan on numba's threads {threads:.2f} ms")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", choices=("1r", "3r"), default="1r")
    ap.add_argument("--calls", type=int, default=60)
    args = ap.parse_args(argv)
    parts(args.model, args.calls)
    scan(args.model)


if __name__ == "__main__":
    main()
