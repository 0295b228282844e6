"""Two speed figures of the README beside `rdea-lab bench`: the cost of slack, and solving along a path.

1. SU on the bench's headline scene (hollow core, lambda1 U[1, 1.75], v U[0, 3.5 kV],
   1e5 samples) with and without the free-state search of slack samples.
2. 1R and 3R along the path (``path=True``, what the twin does) of specimen 2's
   2.6 kV ramp-sine run as shipped (datasets/paper2021/, Table 3's material).

Samples per second, median of 5 runs (slowest and fastest beside it), one BLAS thread.

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/slack_and_path.py
"""

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from bench_models import RIZZELLO, _core, _envelope, _rate, _times  # noqa: E402
from rdea_lab.physics.geometry import geometry_from_card  # noqa: E402
from rdea_lab.physics.models import solve  # noqa: E402
from rdea_lab.specs import load_params, load_specimen  # noqa: E402
from rdea_lab.store import open_run  # noqa: E402


def main():
    l1, v = _envelope(100_000, 1.75, 3500.0)
    hollow = _core("hollow-core")
    for label, kw in (("SU, slack", {}), ("SU, slack=False", {"slack": False})):
        print(label, "%.3g (%.3g-%.3g)" % _rate(l1.size, _times(lambda: solve("su", hollow, RIZZELLO, l1, v, **kw), 5)))
    ds = open_run(ROOT / "datasets" / "paper2021" / "specimen-2" / "tensile_ramp_sine_2.6kV.nc")
    geom = geometry_from_card(load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"))
    params = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
    x, volts = np.maximum(ds["stretch"].values, 1.0), ds["voltage"].values
    for model in ("1r", "3r"):
        rate = _rate(x.size, _times(lambda: solve(model, geom, params, x, volts, path=True), 5))
        print(f"path, {model}", "%.3g (%.3g-%.3g)" % rate)


if __name__ == "__main__":
    main()
