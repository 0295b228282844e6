"""Whole 1R and 3R calls with numba's threads forced on, then forced off, next to ``--busy`` processes that each
keep a core busy: what a second thread costs or saves on busy cores (`kernels._core_free` leaves it off where the
other processes use more than the cores less 1.5).

    python3 benchmarks/threads_under_load.py [--busy 0 2 4] [--samples 4096 100000] [--rounds 3]

Prints one line per (busy processes, samples): per model and mode the median wall time [ms] of each round's
calls (after a warm-up), rounds in turn, so a change of the machine's speed touches both modes alike.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_models as bm  # noqa: E402

from rdea_lab.physics import kernels  # noqa: E402
from rdea_lab.physics.models import solve  # noqa: E402


def measure(n, rounds):
    l1, v = bm._envelope(n, 1.75, 3500.0)
    geom = bm._core("hollow-core")
    for m in ("1r", "3r"):
        solve(m, geom, bm.RIZZELLO, l1, v, kernel="numba")
    reps = max(5, int(2e5 // n))
    out = {}
    for _ in range(rounds):
        for threads in (True, False):
            kernels._core_free = (lambda: True) if threads else (lambda: False)
            for m in ("1r", "3r"):
                t = bm._times(lambda: solve(m, geom, bm.RIZZELLO, l1, v, kernel="numba"), reps)
                out.setdefault((m, threads), []).append(float(np.median(t)) * 1e3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--busy", type=int, nargs="+", default=[0, 2, 4])
    ap.add_argument("--samples", type=int, nargs="+", default=[4096, 100_000])
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    for busy in a.busy:
        spin = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(busy)]
        try:
            time.sleep(0.3)
            for n in a.samples:
                r = measure(n, a.rounds)
                cells = [f"{m} {'threads' if th else 'one'} " + "/".join(f"{x:.2f}" for x in ms)
                         for (m, th), ms in r.items()]
                print(f"busy {busy}, {n} samples [ms]: " + "; ".join(cells), flush=True)
        finally:
            for p in spin:
                p.kill()
                p.wait()


if __name__ == "__main__":
    main()
