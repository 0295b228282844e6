"""The three quasi-static RDEA models of [1]: SU, 1R and 3R.

Each ``solve(geom, material, stretch, voltage)`` is vectorized over arrays
of stretch and voltage and returns a :class:`~rdea_lab.physics.result.ModelResult`.
"""

from __future__ import annotations

import os

from . import one_ring, su, three_ring

#: Model names, cheapest first.
MODELS = {"su": su, "1r": one_ring, "3r": three_ring}


def solve(model: str, geom, material, stretch, voltage):
    """Solve the quasi-static model ``model`` (``"su"``, ``"1r"`` or ``"3r"``)."""
    try:
        module = MODELS[model.lower()]
    except KeyError:
        raise ValueError(f"unknown model {model!r}; allowed: {', '.join(MODELS)}") from None
    for name, value, loader in (("geom", geom, "rdea_lab.geometry(path)"), ("material", material,
                                                                           "rdea_lab.load_params(path)")):
        if isinstance(value, (str, os.PathLike)):
            raise TypeError(f"solve: {name} must be an object, not the path {str(value)!r}: physics reads no files; "
                            f"load it with {loader}")
    return module.solve(geom, material, stretch, voltage)
