"""The inverse of the capacitance model: the stretch at which ``C(lambda1, v)`` is a given capacitance.

`stretch_from_capacitance` inverts the model's ``C(lambda1, v)``: SU's ``C =
C0 lambda1`` (eq. 41 of [1]) in closed form; 1R, 3R and CR (which depend on
the voltage through the hoop stretch) by a bracketed, vectorized regula falsi
on the clamped state's capacitance (``slack=False``: a slack roll's free state
has a capacitance that does not depend on the clamps' distance, so no stretch
of the clamps follows from it).

[1] J. Prechtl et al., Smart Mater. Struct. (2021), doi:10.1088/1361-665X/ac34be.
"""

from __future__ import annotations

import numpy as np

from ..physics.models import solve

#: Stretch bracket of the numerical inverse [-].
STRETCH_BRACKET = (1.0, 3.0)
#: Convergence of the numerical inverse, in stretch [-].
STRETCH_TOL = 1e-10


def stretch_from_capacitance(capacitance, voltage, geom, material, model: str = "su", *,
                             bracket=STRETCH_BRACKET) -> np.ndarray:
    """The stretch at which the model's capacitance ``C(lambda1, v)`` equals `capacitance`.

    Parameters
    ----------
    capacitance : array_like
        [F].
    voltage : array_like
        [V], broadcast against `capacitance` (SU does not use it).
    geom : RollGeometry
        The (nominal) geometry; ``C0`` from it and ``material.eps_r``.
    material : ParameterSet
    model : {"su", "1r", "3r", "cr"}
    bracket : (float, float)
        Stretches searched [-].

    Returns
    -------
    numpy.ndarray
        ``lambda1`` [-]. SU: ``C / C0`` (eq. 41 of [1]; below 1 where the
        capacitance is below ``C0``: returned as is, the caller judges it).
        Other models: NaN where the capacitance lies outside the clamped
        state's ``C`` over `bracket` at that voltage, or the model has no
        equilibrium there.

    Notes
    -----
    The other models' ``C = C0 (lambda1 lambda2b)**2`` (eqs. 29, 34 and the
    continuum's) is increasing in ``lambda1`` at fixed voltage wherever the
    roll is stable (at 0 V it is SU's ``C0 lambda1``); the bracket's ends are
    checked, not assumed.
    """
    C = np.asarray(capacitance, float)
    v = np.broadcast_to(np.asarray(voltage, float), C.shape)
    C0 = geom.C0(material.eps_r)
    if model == "su":
        return C / C0
    out = np.full(C.shape, np.nan)
    ok = np.isfinite(C) & np.isfinite(v)
    c, vv = C[ok], v[ok]

    def f(lam):
        return solve(model, geom, material, lam, vv, slack=False).capacitance - c

    lo, hi = np.full(c.shape, bracket[0]), np.full(c.shape, bracket[1])
    flo, fhi = f(lo), f(hi)
    inside = (flo <= 0.0) & (fhi >= 0.0)
    side = np.zeros(c.shape, int)  # Illinois: which end stayed last time
    x = lo.copy()
    for _ in range(100):
        with np.errstate(invalid="ignore", divide="ignore"):
            x = np.where(fhi != flo, hi - fhi * (hi - lo) / (fhi - flo), 0.5 * (lo + hi))
        x = np.where(np.isfinite(x) & (x > lo) & (x < hi), x, 0.5 * (lo + hi))
        fx = f(x)
        left = fx < 0.0
        lo, flo = np.where(left, x, lo), np.where(left, fx, flo)
        hi, fhi = np.where(left, hi, x), np.where(left, fhi, fx)
        # Illinois: halve the value at the end that stays twice in a row
        fhi = np.where(left & (side == 1), 0.5 * fhi, fhi)
        flo = np.where(~left & (side == -1), 0.5 * flo, flo)
        side = np.where(left, 1, -1)
        if np.all((hi - lo <= STRETCH_TOL) | (fx == 0.0) | ~inside):
            break
    out[ok] = np.where(inside, x, np.nan)
    return out


__all__ = ["STRETCH_BRACKET", "STRETCH_TOL", "stretch_from_capacitance"]
