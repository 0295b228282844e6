"""Quasi-static stress-stretch curves at fixed voltages (the ``curve`` command)."""

from __future__ import annotations

import numpy as np

from ..physics.geometry import geometry_from_card
from ..physics.models import solve
from ..specs import as_params, as_specimen

#: Per-curve arrays, in output order.
CURVE_FIELDS = ("stretch", "sigma1", "force", "lambda2b", "capacitance", "converged")


def quasi_static_curves(card, params, model, stretch, voltages) -> dict:
    """Force-stretch curves of one model at several voltages.

    Parameters
    ----------
    card : SpecimenCard or path
    params : ParameterSet or path
    model : {"su", "1r", "3r"}
    stretch : array_like
        Axial stretches [-], >= 1.
    voltages : sequence of float
        Voltages [V].

    Returns
    -------
    dict
        ``{"model", "specimen", "parameters", "curves": [{"voltage", "stretch",
        "sigma1", "force", "lambda2b", "capacitance", "converged",
        "summary"}]}``, SI units, NaN where a sample has no equilibrium
        (``converged`` false and ``summary`` saying why).
    """
    card, params = as_specimen(card), as_params(params)
    geom = geometry_from_card(card)
    stretch = np.asarray(stretch, float)
    curves = []
    for v in voltages:
        res = solve(model, geom, params, stretch, float(v))
        curves.append({
            "voltage": float(v), "stretch": stretch, "sigma1": res.sigma1, "force": res.force,
            "lambda2b": res.lambda2b, "capacitance": res.capacitance, "converged": res.converged,
            "summary": res.summary(),
        })
    return {"model": model, "specimen": card.id, "parameters": params.name, "curves": curves}
