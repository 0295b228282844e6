"""Is ``kernel="auto"``'s compiled path ever slower than ``kernel="numpy"``? Both timed on the same scenes.

Scenes: specimen 2 (Table 3 material) taut (stretch 1.05-1.5, 0-1.5 kV), all but a few samples slack
(stretch 1-1.02 at 2.6 kV), about a sixth slack (stretch 1-1.1 at 2.6 kV), and the hollow core of
Section 3.4 (stretch 1-1.75, 0-3.5 kV). Each at the given sample counts, per model: the median of
``--repeat`` calls after one warm-up, with numba already loaded (so the figures compare the calls, not
numba's start-up, which ``auto`` avoids below `rdea_lab.physics._backend.AUTO_MIN_SAMPLES` samples).

    python3 benchmarks/auto_vs_numpy.py [--models su,1r,3r,cr] [--samples 256,2048,16384] [--repeat 15]
"""

from __future__ import annotations

import argparse

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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="su,1r,3r,cr")
    ap.add_argument("--samples", default="256,2048,16384")
    ap.add_argument("--repeat", type=int, default=15)
    a = ap.parse_args()
    print(f"{'scene':26s} {'n':>6s} model slack  compiled [ms]  numpy [ms]  numpy/compiled")
    lowest = np.inf
    for n in (int(float(x)) for x in a.samples.split(",")):
        for name, (geom, material, l1, v) in scenes(n).items():
            for model in a.models.split(","):
                slack = float(np.mean(solve(model, geom, material, l1, v).status == SLACK))
                fast = _median(lambda: solve(model, geom, material, l1, v, kernel="numba"), a.repeat)
                ref = _median(lambda: solve(model, geom, material, l1, v, kernel="numpy"), a.repeat)
                lowest = min(lowest, ref / fast)
                print(f"{name:26s} {n:6d} {model:5s} {slack:5.2f} {fast * 1e3:13.3f} {ref * 1e3:11.3f} "
                      f"{ref / fast:15.2f}")
    print(f"lowest numpy/compiled: {lowest:.2f}")


if __name__ == "__main__":
    main()
