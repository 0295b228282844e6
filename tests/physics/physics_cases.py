"""The paper's materials and geometries (SI) shared by the physics tests.

A module of its own name: test modules import it, not ``conftest`` (tests/design has a ``conftest`` too, and a
subset of both run together with xdist could import the wrong one)."""

from types import SimpleNamespace

import numpy as np
import pytest

from rdea_lab.physics.geometry import RollGeometry

#: Material of ref. [36], used in Section 3.4 of the paper.
RIZZELLO = SimpleNamespace(C10=241e3, C20=-33.2e3, C30=20.1e3, eps_r=2.8)
#: Table 3 of the paper as corrected in ERRATA.
TABLE3 = SimpleNamespace(C10=242e3, C20=-69e3, C30=47e3, eps_r=2.8)

#: The three rolls of Section 3.4 [m]; L3 = 48 um and alpha_e1 = 1.
CORES = {
    "hollow": (0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3),
    "active": (0.0, 0.088e-3, 1.76e-3, 1.8e-3),
    "passive": (0.0, 0.81e-3, 1.76e-3, 1.8e-3),
}


#: A test's ``threads`` parameter: the compiled loops on one thread in the default run, on numba's threads (as
#: on an idle machine) under ``-m slow``. A threaded variant is the same loop body under ``prange``
#: (`kernels._variants`), compiled once more: some 20 s of CPU with an empty numba cache, which the default run
#: (the test session keeps to one thread, tests/conftest.py) leaves to the slow one.
THREADS = [pytest.param(False, id="one-thread"), pytest.param(True, id="threads", marks=pytest.mark.slow)]


def on_threads(monkeypatch, threads):
    """Calls large enough for numba's threads run on them (``threads``), as on an idle machine, or on one thread:
    `kernels._core_free` reads the other processes' CPU use (`kernels._other_load`, which the other test worker
    raises), whatever the call's own threshold (`kernels.PARALLEL_MIN`, SU's `SU_PARALLEL_MIN`,
    `ring_kernels.FREE_PARALLEL_MIN` slack samples, `scan_kernel.BRANCH_PARALLEL_MIN`)."""
    from rdea_lab.physics import kernels

    monkeypatch.setattr(kernels, "_other_load", (lambda: 0.0) if threads else (lambda: float(kernels._CORES)))


def core(name_or_radii, L1=34e-3, L1e=34e-3, L3=48e-6):
    radii = CORES[name_or_radii] if isinstance(name_or_radii, str) else name_or_radii
    return RollGeometry(*radii, L1=L1, L1e=L1e, L3=L3)


def assert_close(x, y, what, rtol):
    """``x`` equals the reference ``y`` where it is finite to ``rtol`` of ``y``'s largest finite magnitude, with
    the same NaN pattern."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    assert np.array_equal(np.isnan(x), np.isnan(y)), f"{what}: NaN pattern differs"
    fin = np.isfinite(y)
    if fin.any():
        scale = np.max(np.abs(y[fin]))
        err = np.max(np.abs(x[fin] - y[fin]))
        assert err <= rtol * scale + 1e-300, f"{what}: differs by {err / max(scale, 1e-300):.2e} relative"
