"""Which implementation runs: the compiled kernels (`rdea_lab.physics.kernels`) or the numpy reference."""

from __future__ import annotations

import os
import sys

import numpy as np

#: Kernel choices of `rdea_lab.physics.models.solve` and the branch updates.
KERNELS = ("auto", "numba", "numpy")
#: ``auto`` uses the compiled kernels for calls that save at least what this many SU samples save: loading
#: numba and the cached machine code costs a process 0.4-0.8 s once (measured by
#: ``benchmarks/auto_vs_numpy.py --fresh``), more than the kernels save on small calls. The choice depends
#: on the call alone (not on what the process loaded before), so a result does not depend on the history
#: of the process (the two agree to 1e-12 anyway, mostly to the last bit).
AUTO_MIN_SAMPLES = 16384

#: Which calls ``auto`` compiles, by model and roll (solid: ``Ri = 0``; hollow: a core): 1 from
#: `AUTO_MIN_SAMPLES` samples, 0 never. CR on a solid roll never: its compiled path does the numpy work
#: (the SU state) and would only load numba. The other models compile from the same count: the kernels
#: save a 1R, 3R or CR sample more than an SU one (``benchmarks/auto_vs_numpy.py``), but a lower count
#: made one-shot commands on a few hundred samples pay numba's loading (a CLI `curve` of a hollow 3R
#: roll went from 0.9 to 1.3 s) to save about a millisecond.
AUTO_WEIGHT = {("su", False): 1, ("su", True): 1, ("1r", False): 1, ("1r", True): 1,
               ("3r", False): 1, ("3r", True): 1, ("cr", False): 0, ("cr", True): 1}


_SAID = set()
#: `rdea_lab.physics.kernels` once `compiled` has imported it.
_KERNELS = []


def _say_once(line: str) -> None:
    """One line on stderr, once per process (where speed matters and the fast path is missing)."""
    if line not in _SAID:
        _SAID.add(line)
        print(line, file=sys.stderr)


def compiled(kernel, n=None):
    """The `rdea_lab.physics.kernels` module if ``kernel`` asks for it and it can be had, else None.

    ``n``: for ``auto``, the call's samples as SU samples (what they save compiled; `auto_kernel` weighs a
    model's samples): the kernels from `AUTO_MIN_SAMPLES` on. `rdea_lab.physics.models.solve` resolves
    ``auto`` once per call (`auto_kernel`), so its models see ``numba`` or ``numpy``; design studies and
    the viscoelastic update ask with their own counts."""
    if kernel not in KERNELS:
        raise ValueError(f"kernel {kernel!r}; allowed: {', '.join(KERNELS)}")
    if kernel == "numpy" or (kernel == "auto" and (n is None or n < AUTO_MIN_SAMPLES)):
        return None
    if kernel == "auto" and os.environ.get("RDEA_LAB_KERNELS", "numba").lower() == "numpy":
        return None  # turned off: numba is not even loaded
    if _KERNELS:  # imported before (the import statement costs microseconds a call)
        return _KERNELS[0]
    try:
        from . import kernels
    except ImportError:  # numba missing: the reference is the fallback
        if kernel == "numba":
            from ..extras import MissingExtra

            raise MissingExtra("numba", "kernel='numba' (the compiled kernels)") from None
        _say_once("rdea-lab: numba is not installed, so the models run at numpy speed "
                  "(python3 -m pip install 'rdea-lab[fast]' compiles them)")
        return None
    _KERNELS.append(kernels)  # ``auto`` has been checked against RDEA_LAB_KERNELS above
    return kernels


def auto_kernel(kernel, model, geom, n):
    """``kernel`` for one solve of ``model`` on ``geom`` with ``n`` samples: ``"auto"`` resolved to
    ``"numba"`` where the call saves enough compiled (``n`` times the model's `AUTO_WEIGHT` on this
    roll reaches `AUTO_MIN_SAMPLES`) and the kernels can be had (`compiled`), else ``"numpy"``; any
    other choice as it is. Decided by what the call holds (model, roll, samples), never by what the
    process did before."""
    if kernel != "auto":
        return kernel
    Ri = getattr(geom, "Ri", 0.0)
    hollow = bool(Ri > 0.0) if isinstance(Ri, float) else bool(np.any(np.asarray(Ri) > 0.0))
    weight = AUTO_WEIGHT.get((model, hollow), 1)
    return "numba" if weight and compiled("auto", n * weight) is not None else "numpy"
