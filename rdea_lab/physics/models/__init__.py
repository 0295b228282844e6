"""The quasi-static RDEA models: SU, 1R and 3R of [1], and CR, their continuum limit.

Each ``solve(geom, material, stretch, voltage, *, path=False, start=None,
slack=True)`` is vectorized over arrays of stretch and voltage and returns a
:class:`~rdea_lab.physics.result.ModelResult` (``docs/models-cr.md`` derives CR).
"""

from __future__ import annotations

import os

import numpy as np

from .._backend import auto_kernel
from . import continuum, one_ring, su, three_ring

#: Model names, cheapest first.
MODELS = {"su": su, "1r": one_ring, "3r": three_ring, "cr": continuum}


def solve(model: str, geom, material, stretch, voltage, *, path=False, start=None, slack=True, kernel="auto"):
    """Solve the quasi-static model ``model`` (``"su"``, ``"1r"``, ``"3r"`` or ``"cr"``).

    With ``path=False`` (default) each (stretch, voltage) sample is solved on
    its own, in the state a quasi-static voltage ramp from 0 V reaches from
    the unloaded roll at that stretch. With ``path=True`` the samples are a
    time series and each continues from the previous sample's state (from
    ``start``, a previous block's ``ModelResult.end``, if given): loops show
    hysteresis and snap-throughs are flagged at the samples where they happen.
    A roll whose tension would be negative is slack (force 0, status
    ``SLACK``, the free state's stretches); ``slack=False`` returns the
    equilibrium at the given stretch with its negative stress instead.
    ``kernel``: ``auto``, ``numba`` (the compiled kernels of `rdea_lab.physics.kernels`) or ``numpy``
    (the reference); they agree to 1e-12. ``auto`` takes the kernels where numba is installed,
    ``RDEA_LAB_KERNELS`` is not ``numpy`` and the call is worth loading numba (once per process), decided by
    the call alone (`rdea_lab.physics._backend.auto_kernel`): from 16384 samples, except CR on a solid roll
    (never: its compiled path is the numpy one). With numba loaded the kernels are faster below that count
    too,
    so a process that solves many small calls may pass ``numba``. As the
    choice follows the sample count, a series solved in blocks may take both paths (equal to 1e-12);
    a fixed ``kernel`` gives blocks equal to one call bit for bit.
    """
    try:
        module = MODELS[model.lower()]
    except KeyError:
        raise ValueError(f"unknown model {model!r}; allowed: {', '.join(MODELS)}") from None
    for name, value, loader in (("geom", geom, "rdea_lab.geometry(path)"), ("material", material,
                                                                           "rdea_lab.load_params(path)")):
        if isinstance(value, (str, os.PathLike)):
            raise TypeError(f"solve: {name} must be an object, not the path {str(value)!r}: physics reads no files; "
                            f"load it with {loader}")
    if kernel == "auto":  # decided once per call, by what the call holds
        kernel = auto_kernel(kernel, model.lower(), geom, np.broadcast(np.asarray(stretch), np.asarray(voltage)).size)
    return module.solve(geom, material, stretch, voltage, path=path, start=start, slack=slack, kernel=kernel)
