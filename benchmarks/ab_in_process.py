"""Two checkouts of rdea-lab timed in one process, in turn, call by call: a before/after comparison that this
machine's changes of speed (a factor of up to 1.5 from minute to minute, which separate processes see as a
difference between the trees) do not bias. Each round times each tree's calls once (the fastest of ``--calls``),
old first in odd rounds, new first in even ones; the figures are the median over rounds and the ratio new/old per
round (its median and range).

The old tree's package is copied to a temporary folder under another name (``rdea_lab_old``; every ``rdea_lab``
in its sources renamed) and imported beside this one's, each with its own numba cache (the copy compiles once:
some 30 s). What is timed, on the bench scene (hollow core, 1e5 samples, ``lambda1`` U[1, 1.75], ``v`` U[0, 3.5
kV]) unless said:

- ``scan``: the 1R, 3R and CR root scan alone (`kernels._roots`, one thread);
- ``solve``: whole `solve` calls of SU, 1R, 3R and CR (numba's threads as the call decides);
- ``design``: `solve_designs` of 3R on a path for ``--designs`` rolls of the bench scene's core (outer radius
  +-10 %) through the bench's 10 kHz tensile ramp-sine (5401 samples), on one thread (numba's threads off for
  the call in both trees), its CPU time.

    python3 benchmarks/ab_in_process.py OLD_TREE [--new NEW_TREE] [--what scan,solve,design] [--rounds 15]

e.g. ``git worktree add /tmp/old <rev>`` for OLD_TREE; NEW_TREE is this checkout by default.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _import_old(tree: Path, into: Path):
    """The package of ``tree`` as ``rdea_lab_old`` (a renamed copy in ``into``, without numba's cache files)."""
    dst = into / "rdea_lab_old"
    shutil.copytree(tree / "rdea_lab", dst, ignore=shutil.ignore_patterns("*.nbi", "*.nbc", "*.pyc"))
    for p in dst.rglob("*.py"):
        p.write_text(re.sub(r"\brdea_lab\b", "rdea_lab_old", p.read_text()))
    sys.path.insert(0, str(into))
    return "rdea_lab_old"


def _fastest(f, calls, clock=time.perf_counter):
    best = np.inf
    for _ in range(calls):
        t0 = clock()
        f()
        best = min(best, clock() - t0)
    return best


def _cases(pkg, what, designs):
    """``{name: callable}`` of package ``pkg``, each called once (compiled, warm)."""
    from bench_kernels import tensile_10khz
    from bench_models import RIZZELLO, _core, _envelope

    kernels = importlib.import_module(pkg + ".physics.kernels")
    models = importlib.import_module(pkg + ".physics.models")
    geometry = importlib.import_module(pkg + ".physics.geometry")
    base = _core("hollow-core")
    geom = geometry.RollGeometry(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)})
    l1, v = _envelope(100_000, 1.75, 3500.0)
    mods = {"1r": models.one_ring, "3r": models.three_ring, "cr": models.continuum}
    out = {}
    if "scan" in what:
        for m, mod in mods.items():
            args = list(kernels._roots_args(mod.problem(geom, RIZZELLO, l1, v), False))
            bufs = (np.empty(l1.size), np.zeros(l1.size, np.int8), np.empty(l1.size))
            out[f"scan {m}"] = lambda a=args, b=bufs: kernels._roots[0](*a, *b)
    if "solve" in what:
        for m in ("su", *mods):
            out[f"solve {m}"] = lambda m=m: models.solve(m, geom, RIZZELLO, l1, v)
    if "design" in what:
        designs_mod = importlib.import_module(pkg + ".physics.designs")
        _, lam, volt = (np.array(x) for x in tensile_10khz(5401))
        Ro = geom.Ro * np.random.default_rng(1).uniform(0.9, 1.1, designs)
        rolls = dataclasses.replace(geom, Ro=Ro, Roe=Ro - (geom.Ro - geom.Roe))
        L, V = np.broadcast_to(lam, (designs, lam.size)), np.broadcast_to(volt, (designs, volt.size))
        def design():
            free = kernels._core_free
            kernels._core_free = lambda: False  # one thread: CPU time is then the call's work
            try:
                designs_mod.solve_designs("3r", rolls, RIZZELLO, L, V, path=True)
            finally:
                kernels._core_free = free

        out["design 3r path"] = design
    for f in out.values():
        f()
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old", type=Path)
    ap.add_argument("--new", type=Path, default=HERE.parent)
    ap.add_argument("--what", default="scan,solve,design")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--calls", type=int, default=5)
    ap.add_argument("--designs", type=int, default=40)
    args = ap.parse_args(argv)
    what = set(args.what.split(","))
    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(args.new.resolve()))
    with tempfile.TemporaryDirectory() as tmp:
        old = _cases(_import_old(args.old.resolve(), Path(tmp)), what, args.designs)
        new = _cases("rdea_lab", what, args.designs)
        times = {k: ([], []) for k in old}
        for r in range(args.rounds):
            for k in old:
                clock = time.process_time if k.startswith("design") else time.perf_counter
                calls = 1 if k.startswith("design") else args.calls
                for which in ((0, 1) if r % 2 == 0 else (1, 0)):
                    times[k][which].append(_fastest((old, new)[which][k], calls, clock))
    print(f"old {args.old}, new {args.new}; {args.rounds} rounds, each the fastest of {args.calls} calls "
          "(design: one call's CPU time, one thread)")
    for k, (o, n) in times.items():
        o, n = np.array(o), np.array(n)
        r = n / o
        print(f"  {k:16s} old {1e3 * np.median(o):9.2f} ms, new {1e3 * np.median(n):9.2f} ms; new/old per round "
              f"median {np.median(r):.3f} [{r.min():.3f}, {r.max():.3f}]")


if __name__ == "__main__":
    main()
