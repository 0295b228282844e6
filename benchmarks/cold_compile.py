"""What a first compiled call costs from a fresh checkout: numba compiling the kernels into an empty cache.

Each target runs in a process of its own with an empty ``NUMBA_CACHE_DIR`` (as a fresh clone, a new machine or
a CI worker has): the first call (compiling) and the second (compiled) are timed.

    PYTHONPATH=. python3 benchmarks/cold_compile.py [--repeat 3] [--only 1r,step]

Targets: ``su``, ``1r``, ``3r``, ``cr`` (`solve` with ``kernel="numba"``, numba's threads), ``step``
(`TwinStep.step` of 3R, a slack sample included), ``design-su`` (`solve_designs` of SU). Printed: seconds,
median [min, max] over the repeats.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS = ("su", "1r", "3r", "cr", "step", "design-su")

CHILD = r"""
import json, sys, time
import numpy as np
from rdea_lab.physics import kernels
from rdea_lab.physics.geometry import RollGeometry
from rdea_lab.specs import load_params, load_specimen

data = sys.argv[2]
target = sys.argv[1]
params = load_params(data + "/params/paper2021_table3.yaml")
hollow = RollGeometry(0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3, L1=34e-3, L1e=34e-3, L3=48e-6)
kernels._other_load = lambda: 0.0  # numba's threads, as on an idle machine
rng = np.random.default_rng(1)
n = kernels.PARALLEL_MIN
l1, v = rng.uniform(1.0, 1.75, n), rng.uniform(0.0, 3500.0, n)
if target in ("su", "1r", "3r", "cr"):
    from rdea_lab.physics.models import solve
    call = lambda: solve(target, hollow, params, l1, v, kernel="numba")
elif target == "step":
    from rdea_lab.twin import TwinStep
    twin = TwinStep(load_specimen(data + "/specimens/specimen2.yaml"), params, "3r")
    t = [0.0]
    def call():
        for lam, u in ((1.2, 2000.0), (1.02, 2600.0), (1.3, 0.0)):
            t[0] += 1e-3
            twin.step(t[0], lam, u)
else:
    from rdea_lab.physics.designs import solve_designs
    call = lambda: solve_designs("su", hollow, params, np.linspace(1.0, 1.5, 40), 2600.0, kernel="numba")
t0 = time.perf_counter(); call(); first = time.perf_counter() - t0
t0 = time.perf_counter(); call(); second = time.perf_counter() - t0
print(json.dumps({"first": first, "second": second}))
"""


def cold(target: str) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache,
               "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
        out = subprocess.run([sys.executable, "-c", CHILD, target, str(ROOT / "rdea_lab" / "data")], env=env,
                             capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--only", default=",".join(TARGETS), help="comma-separated targets")
    args = parser.parse_args(argv)
    for target in args.only.split(","):
        runs = [cold(target) for _ in range(args.repeat)]
        first = [r["first"] for r in runs]
        second = [r["second"] for r in runs]
        print(f"{target:10s} first call {statistics.median(first):7.2f} s [{min(first):.2f}, {max(first):.2f}], "
              f"then {1e3 * statistics.median(second):8.2f} ms", flush=True)


if __name__ == "__main__":
    main()
