"""The compiled field passes of 1R and 3R (`ring_kernels.fields1`, `fields3`) timed in one or more checkouts, each in
a process of its own, in turn: the bench scene (hollow core, 1e5 samples, lambda1 U[1, 1.75], v U[0, 3.5 kV]) at
its equilibria, median of ``--repeat`` calls [fastest, slowest].

    python3 benchmarks/fields_ab.py TREE [TREE ...] [--rounds 2] [--repeat 101]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

_ONE = """
import sys
import numpy as np
tree, repeat = sys.argv[1], int(sys.argv[2])
sys.path.insert(0, tree + "/benchmarks")
import rdea_lab
assert rdea_lab.__file__.startswith(tree), rdea_lab.__file__
from bench_models import RIZZELLO, _core, _envelope, _times
from rdea_lab.physics import ring_kernels
from rdea_lab.physics.models import solve, three_ring
from rdea_lab.physics.models._common import kappa
g = _core("hollow-core")
l1, v = _envelope(100_000, 1.75, 3500.0)
C, kap, C0 = (RIZZELLO.C10, RIZZELLO.C20, RIZZELLO.C30), kappa(g, RIZZELLO), g.C0(RIZZELLO.eps_r)
l2 = solve("1r", g, RIZZELLO, l1, v, slack=False).lambda2b.copy()
xi = solve("3r", g, RIZZELLO, l1, v, slack=False).r_i / g.Ro
R = three_ring._Rings(g, l1).constants

def timed(fn):
    ts = 1e3 * _times(fn, repeat)
    return f"{np.median(ts):.3f} ms [{ts.min():.3f}, {ts.max():.3f}]"

print(tree, "fields1", timed(lambda: ring_kernels.fields1(l2, l1, v, C, kap, C0, g.Ro, g.Ri)),
      " fields3", timed(lambda: ring_kernels.fields3(xi, l1, v, R, C, kap, C0, g.Ro)), flush=True)
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("trees", nargs="+")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=101)
    args = ap.parse_args(argv)
    for _ in range(args.rounds):
        for tree in args.trees:
            tree = os.path.abspath(tree)
            env = dict(os.environ, PYTHONPATH=tree)
            subprocess.run([sys.executable, "-c", _ONE, tree, str(args.repeat)], env=env, check=True)


if __name__ == "__main__":
    main()
