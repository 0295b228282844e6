"""numba compiles each kernel once per argument types, not once more per constant a compiled caller passes.

A compiled function that calls another with a Python constant (``0``, ``False``, a module's int) or with a counter
that starts at ``0`` hands numba a literal type, and numba compiles the callee again for it: the 1R root scan
was compiled three times and the step kernel's state chain up to five (a cold 1R solve 31 s, 19 s without;
CHANGELOG 2026-12-07). Checked here on the compiled calls the package makes, in a process of its own with an
empty numba cache (a kernel loaded from the cache brings none of its callees' signatures, and what other tests
compiled in a worker must not hide or add one): after them no dispatcher of the package holds a signature with
a literal argument. Checked by type, not by time: independent of the machine. Slow: it compiles every kernel
(some 40 s).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[2]

CALLS = r"""
import json, sys
import numpy as np
from numba.core import types
from numba.core.registry import CPUDispatcher

from physics_cases import RIZZELLO, TABLE3, core
from rdea_lab.physics import kernels
from rdea_lab.physics.designs import solve_designs
from rdea_lab.physics.models import solve
from rdea_lab.specs import load_params, load_specimen
from rdea_lab.twin import TwinStep

data = sys.argv[1]
n = kernels.PARALLEL_MIN
rng = np.random.default_rng(1)
l1, v = rng.uniform(1.0, 1.75, n), rng.uniform(0.0, 7000.0, n)  # folds, snaps, slack
for load in (0.0, 1e9):  # numba's threads, one thread
    kernels._other_load = lambda load=load: load
    for model in ("su", "1r", "3r", "cr"):
        solve(model, core("hollow"), RIZZELLO, l1, v, kernel="numba")
    solve("3r", core("active"), RIZZELLO, l1, v, kernel="numba")
for model in ("1r", "3r", "cr"):
    solve(model, core("hollow"), TABLE3, np.sort(l1[:300]), v[:300], path=True, kernel="numba")
card = load_specimen(data + "/specimens/specimen2.yaml")
params = load_params(data + "/params/paper2021_table3.yaml")
for model in ("su", "1r", "3r"):
    twin = TwinStep(card, params, model)
    for i, (lam, u) in enumerate(((1.2, 2000.0), (1.02, 2600.0), (1.3, 0.0))):  # the second one slack
        twin.step(1e-3 * i, lam, u)
for model in ("su", "3r"):
    solve_designs(model, core("hollow"), params, np.linspace(1.0, 1.5, 40), 2600.0, kernel="numba")

seen, dispatchers, found = set(), 0, []
for name, module in list(sys.modules.items()):
    if not name.startswith("rdea_lab"):
        continue
    for obj in vars(module).values():
        if isinstance(obj, CPUDispatcher) and id(obj) not in seen:
            seen.add(id(obj))
            dispatchers += bool(obj.signatures)
            for sig in obj.signatures:
                if any(isinstance(a, types.Literal) for a in sig):
                    found.append(f"{obj.py_func.__module__}.{obj.py_func.__qualname__}{tuple(map(str, sig))}")
print(json.dumps({"compiled": dispatchers, "literal": found}))
"""


@pytest.mark.slow
def test_no_kernel_is_compiled_for_a_literal_argument():
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache,
               "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), str(ROOT / "tests" / "physics"),
                                                           os.environ.get("PYTHONPATH")]))}
        done = subprocess.run([sys.executable, "-c", CALLS, str(ROOT / "rdea_lab" / "data")], env=env,
                              capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["compiled"] > 30  # compiled here, callees and all (not loaded from a cache: a vacuous check)
    assert result["literal"] == []
