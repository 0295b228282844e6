"""Two checkouts of rdea-lab timed in turn on the bench's scenes: a before/after comparison that a change of the
machine's speed during the session does not bias.

Each round runs one process per tree (``PYTHONPATH`` set to it), old first, each timing `bench_models._scene` (the
median of ``--repeat`` whole `solve` calls per model, after a warm-up) on the bench scene (hollow core, 1e5 samples)
and 3R on the active core, and prints one JSON line per process with the load average before it.

    python3 benchmarks/ab_scenes.py OLD_TREE NEW_TREE [--rounds 3] [--repeat 5] [--as-idle] [--sustain S]

``--sustain S``: each process solves 3R for S seconds before it times the scenes, as a long job (``rdea-lab
bench``, a design study) does: the load average that such work raises on its own (what `kernels._core_free` read
before 2026-12-06) turned numba's threads off after some 40 s.

``--as-idle``: numba's threads run from their sample counts on whatever the machine's load (as on an idle
machine; `kernels._core_free` reads the other processes' CPU use, the load average in trees before 2026-12-06,
which other work on the machine raises): with other work running and this script under ``nice -n -20``, how the
threads fare next to it.

e.g. ``git worktree add /tmp/old <rev>`` for OLD_TREE and this checkout for NEW_TREE.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

_ONE = """
import json, os, sys, time
sys.path.insert(0, os.path.join(sys.argv[1], "benchmarks"))
import bench_models as bm
if sys.argv[3] == "1":
    from rdea_lab.physics import kernels
    if not hasattr(kernels, "_core_free"):
        sys.exit(f"--as-idle: {sys.argv[1]} has no load rule for numba's threads (kernels._core_free)")
    kernels._core_free = lambda: True
l1, v = bm._envelope(100_000, 1.75, 3500.0)
t_end = time.monotonic() + float(sys.argv[4])  # --sustain: a long job's work before the timed calls
while time.monotonic() < t_end:
    bm.solve("3r", bm._core("hollow-core"), bm.RIZZELLO, l1, v)
out = bm._scene(bm._core("hollow-core"), bm.RIZZELLO, l1, v, int(sys.argv[2]))
act = bm._scene(bm._core("active-core"), bm.RIZZELLO, l1, v, int(sys.argv[2]), ("3r",))
r = {m: out[m]["samples_per_s"] for m in out}
r["su_every_field_read_ratio"] = out["su"]["every_field_read_ratio"]
r["3r_active_core"] = act["3r"]["samples_per_s"]
r["rdea_lab"] = os.path.dirname(sys.modules["rdea_lab"].__file__)  # which tree was measured
print(json.dumps(r))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--as-idle", action="store_true", help="numba's threads whatever the load")
    ap.add_argument("--sustain", type=float, default=0.0,
                    help="seconds of 3R solves in each process before the timed calls (a long job)")
    a = ap.parse_args()
    for _ in range(a.rounds):
        for name, tree in (("old", a.old), ("new", a.new)):
            tree = os.path.abspath(tree)
            load = os.getloadavg()[0]
            env = dict(os.environ, PYTHONPATH=tree)
            # run in the tree: ``python -c`` puts the working directory first on the path
            out = subprocess.run([sys.executable, "-c", _ONE, tree, str(a.repeat), str(int(a.as_idle)),
                                  str(a.sustain)], env=env,
                                 cwd=tree, capture_output=True, text=True, check=True).stdout.strip().splitlines()[-1]
            print(json.dumps({"tree": name, "load_before": load, **json.loads(out)}), flush=True)


if __name__ == "__main__":
    main()
