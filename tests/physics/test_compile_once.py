"""numba compiles each kernel once per argument types, not once more per constant a compiled caller passes.

A compiled function that calls another with a Python constant (``0``, ``False``, a module's int) or with a counter
that starts at ``0`` hands numba a literal type, and numba compiles the callee again for it: the 1R root scan
was compiled three times and the step kernel's state chain up to five (a cold 1R solve 31 s, 19 s without;
CHANGELOG 2026-12-07). Checked here on the compiled calls the package makes: after them no dispatcher of the
package holds a signature with a literal argument. Checked by type, not by time: independent of the machine.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from physics_cases import RIZZELLO, TABLE3, core

pytest.importorskip("numba")

from numba.core import types  # noqa: E402
from numba.core.registry import CPUDispatcher  # noqa: E402

PROJECT = Path(__file__).resolve().parents[2] / "rdea_lab" / "data"


def _literal_signatures():
    seen, found = set(), []
    for name, module in list(sys.modules.items()):
        if not name.startswith("rdea_lab"):
            continue
        for obj in vars(module).values():
            if isinstance(obj, CPUDispatcher) and id(obj) not in seen:
                seen.add(id(obj))
                for sig in obj.signatures:
                    if any(isinstance(a, types.Literal) for a in sig):
                        found.append(f"{obj.py_func.__module__}.{obj.py_func.__qualname__}{tuple(map(str, sig))}")
    return found


def test_no_kernel_is_compiled_for_a_literal_argument(monkeypatch):
    from rdea_lab.physics import kernels
    from rdea_lab.physics.designs import solve_designs
    from rdea_lab.physics.models import solve
    from rdea_lab.specs import load_params, load_specimen
    from rdea_lab.twin import TwinStep

    n = kernels.PARALLEL_MIN
    rng = np.random.default_rng(1)
    l1, v = rng.uniform(1.0, 1.75, n), rng.uniform(0.0, 7000.0, n)  # folds, snaps, slack
    for load in (0.0, 1e9):  # numba's threads, one thread
        monkeypatch.setattr(kernels, "_other_load", lambda load=load: load)
        for model in ("su", "1r", "3r", "cr"):
            solve(model, core("hollow"), RIZZELLO, l1, v, kernel="numba")
        solve("3r", core("active"), RIZZELLO, l1, v, kernel="numba")
    for model in ("1r", "3r", "cr"):
        solve(model, core("hollow"), TABLE3, np.sort(l1[:300]), v[:300], path=True, kernel="numba")
    card = load_specimen(PROJECT / "specimens" / "specimen2.yaml")
    params = load_params(PROJECT / "params" / "paper2021_table3.yaml")
    for model in ("su", "1r", "3r"):
        twin = TwinStep(card, params, model)
        for i, (lam, u) in enumerate(((1.2, 2000.0), (1.02, 2600.0), (1.3, 0.0))):  # the second one slack
            twin.step(1e-3 * i, lam, u)
    for model in ("su", "3r"):
        solve_designs(model, core("hollow"), params, np.linspace(1.0, 1.5, 40), 2600.0, kernel="numba")
    assert _literal_signatures() == []
