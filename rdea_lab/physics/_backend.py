"""Which implementation runs: the compiled kernels (`rdea_lab.physics.kernels`) or the numpy reference."""

from __future__ import annotations

import os
import sys

#: Kernel choices of `rdea_lab.physics.models.solve` and the branch updates.
KERNELS = ("auto", "numba", "numpy")
#: ``auto`` uses the compiled kernels for calls of at least this many samples: loading numba and the
#: cached machine code costs a process about 1.5 s once, more than the kernels save on small calls.
#: The choice depends on the call alone (not on what the process loaded before), so a result does not
#: depend on the history of the process (the two agree to 1e-12 anyway, mostly to the last bit).
AUTO_MIN_SAMPLES = 16384


_SAID = set()


def _say_once(line: str) -> None:
    """One line on stderr, once per process (where speed matters and the fast path is missing)."""
    if line not in _SAID:
        _SAID.add(line)
        print(line, file=sys.stderr)


def compiled(kernel, n=None):
    """The `rdea_lab.physics.kernels` module if ``kernel`` asks for it and it can be had, else None
    (``n``: the call's samples, for ``auto``)."""
    if kernel not in KERNELS:
        raise ValueError(f"kernel {kernel!r}; allowed: {', '.join(KERNELS)}")
    if kernel == "numpy" or (kernel == "auto" and (n is None or n < AUTO_MIN_SAMPLES)):
        return None
    if kernel == "auto" and os.environ.get("RDEA_LAB_KERNELS", "numba").lower() == "numpy":
        return None  # turned off (`kernels.enabled`): numba is not even loaded
    try:
        from . import kernels
    except ImportError:  # numba missing: the reference is the fallback
        if kernel == "numba":
            from ..extras import MissingExtra

            raise MissingExtra("numba", "kernel='numba' (the compiled kernels)") from None
        _say_once("rdea-lab: numba is not installed, so the models run at numpy speed "
                  "(python3 -m pip install 'rdea-lab[fast]' compiles them)")
        return None
    return kernels if (kernel == "numba" or kernels.enabled()) else None
