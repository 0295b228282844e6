"""Quasi-static stress-stretch curves at fixed voltages (the ``curve`` command)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics.models import solve
from ..specs import SpecError, as_params, as_specimen, field_estimate, format_quantity
from .simulate import as_geometry

#: Per-curve arrays, in output order.
CURVE_FIELDS = ("stretch", "sigma1", "force", "lambda2b", "capacitance", "converged")


#: The field estimate a curve may reach by default [V/m]: 300 V/um, beyond the breakdown strength of any
#: dielectric elastomer (silicones break down at about 50-150 V/um, VHB at 150-300), yet above the paper's
#: own Section 3.4 scenes (3.5 kV on 48 um at stretch 1.75: 96 V/um).
CURVE_MAX_FIELD = 300e6


@dataclass(frozen=True)
class Curve:
    """One voltage's quasi-static curve (:func:`quasi_static_curves`), SI units, NaN where a sample has no
    equilibrium.

    Attributes
    ----------
    voltage : float
        [V].
    stretch : numpy.ndarray, shape (n,)
        Axial stretch [-].
    sigma1 : numpy.ndarray, shape (n,)
        The equilibrium's axial stress at each stretch [Pa] (the paper's curves: negative where the roll
        would push).
    force : numpy.ndarray, shape (n,)
        What the roll carries [N]: 0 where it is slack.
    lambda2b : numpy.ndarray, shape (n,)
        Circumferential stretch of ring b, the active one [-].
    capacitance : numpy.ndarray, shape (n,)
        [F].
    converged : numpy.ndarray of bool, shape (n,)
        False where a sample has no equilibrium (the summary says why).
    summary : str
        One line counting the samples of each status other than OK (slack ones too), or
        ``all n samples converged``.
    """

    voltage: float
    stretch: np.ndarray
    sigma1: np.ndarray
    force: np.ndarray
    lambda2b: np.ndarray
    capacitance: np.ndarray
    converged: np.ndarray
    summary: str


@dataclass(frozen=True)
class Curves:
    """Force-stretch curves of one model at several voltages (:func:`quasi_static_curves`).

    Attributes
    ----------
    model : str
    specimen : str
        The card's id.
    parameters : str
        The parameter set's name.
    curves : tuple of Curve
        One per voltage, in the order given.
    """

    model: str
    specimen: str
    parameters: str
    curves: tuple

    @property
    def table(self):
        """pandas.DataFrame, one row per (voltage, stretch): ``voltage`` [V] and the `CURVE_FIELDS` (SI)."""
        import pandas as pd

        return pd.DataFrame({"voltage": np.concatenate([np.full(c.stretch.shape, c.voltage) for c in self.curves]),
                             **{k: np.concatenate([getattr(c, k) for c in self.curves]) for k in CURVE_FIELDS}})


def quasi_static_curves(card, params, model, stretch, voltages, max_field=CURVE_MAX_FIELD) -> Curves:
    """Force-stretch curves of one model at several voltages.

    Parameters
    ----------
    card : SpecimenCard or path
    params : ParameterSet or path
    model : {"su", "1r", "3r", "cr"}
    stretch : array_like
        Axial stretches [-], >= 1.
    voltages : sequence of float
        Voltages [V].
    max_field : float or None
        Largest field estimate ``|v| sqrt(stretch) / L3`` allowed [V/m] (a membrane breaks down
        long before a model stops giving numbers); None: no check.

    Returns
    -------
    Curves
        ``model``, ``specimen``, ``parameters`` and one `Curve` per voltage (``voltage``, ``stretch``,
        ``sigma1``, ``force``, ``lambda2b``, ``capacitance``, ``converged``, ``summary``), SI units, NaN
        where a sample has no equilibrium (``converged`` false and ``summary`` saying why). ``sigma1``,
        ``lambda2b`` and ``capacitance`` are the equilibrium at each stretch (the paper's curves: a
        negative stress where the roll would push); ``force`` is what the roll carries, 0 where it is
        slack (the summary counts those samples). ``table``: the same as one DataFrame.

    Raises
    ------
    SpecError
        A voltage whose field estimate exceeds ``max_field`` (the value, the limit, and ``--no-field-check``).
    """
    card, params = as_specimen(card), as_params(params)
    geom = as_geometry(card)
    stretch = np.asarray(stretch, float)
    if max_field is not None and len(voltages):
        v = np.asarray(voltages, float)
        E = field_estimate(v[:, None], stretch[None, :], geom.L3)
        if np.nanmax(E) > max_field:
            i, j = np.unravel_index(np.nanargmax(E), E.shape)
            raise SpecError("command line", "--voltage",
                            f"{format_quantity(v[i], 'kV', digits=4)} at stretch {stretch[j]:.4g} on "
                            f"L3 = {format_quantity(geom.L3, 'um', digits=4)} is a field estimate of "
                            f"{format_quantity(E[i, j], 'V/um', digits=4)}, beyond "
                            f"{format_quantity(max_field, 'V/um', digits=4)} where any real membrane has "
                            "broken down; give --no-field-check to compute it anyway")
    curves = []
    for v in voltages:
        res = solve(model, geom, params, stretch, float(v), slack=False)
        carried = solve(model, geom, params, stretch, float(v))
        curves.append(Curve(voltage=float(v), stretch=stretch, sigma1=res.sigma1, force=carried.force,
                            lambda2b=res.lambda2b, capacitance=res.capacitance, converged=res.converged,
                            summary=carried.summary()))
    return Curves(model=model, specimen=card.id, parameters=params.name, curves=tuple(curves))
