"""One-ring (1R) model: eqs. (33)-(34) of [1], one free stretch."""

from __future__ import annotations

import numpy as np

from .. import yeoh
from ..yeoh import gradient_terms
from ..branch import Problem
from ..result import ModelResult
from ._common import (HOOP_STRETCH_CAP, Evaluation, evaluate_free, kappa, ring_kernels, solve_model,
                      with_bounds_buffer, yeoh_coefficients)


def enthalpy(geom, material, stretch, voltage, lambda2):
    """Free enthalpy density ``g = psi_m(l1, l2) - kappa l1**2 l2**2 v**2`` [Pa].

    Its stationary points in ``lambda2`` at fixed stretch and voltage are
    the equilibria of eq. (33) of [1].
    """
    l1 = np.asarray(stretch, float)
    l2 = np.asarray(lambda2, float)
    return (yeoh.energy(l1, l2, yeoh_coefficients(material))
            - kappa(geom, material) * (l1 * l2 * np.asarray(voltage, float)) ** 2)


def stress(l2, l1, v, C10, C20, C30, kap):
    """Axial stress [Pa] at the equilibrium ``lambda2 = l2``: ``lambda1 dpsi_m/dlambda1 - alpha_e1
    eta_b eps E**2`` (eq. (33) of [1]): `yeoh.gradient_terms`, then `stress_from`. Scalar or array arguments
    (compiled too: `rdea_lab.physics.ring_kernels`)."""
    psi_1, _ = gradient_terms(l1, l2, C10, C20, C30)
    return stress_from(l2, l1, v, kap, psi_1)


def stress_from(l2, l1, v, kap, psi_1):
    """`stress` from ``psi_1 = dpsi_m/dlambda1`` (`yeoh.gradient_terms`), the one implementation of eq. (33)'s
    stress."""
    return l1 * psi_1 - 2.0 * kap * (l1 * v) ** 2 * l2 * l2


def fields(l2, l1, v, C10, C20, C30, kap, C0, Ro, Ri):
    """``(sigma1 [Pa], capacitance [F], r_i [m])`` at the equilibrium ``lambda2 = l2``: `stress`, then
    `fields_from`. Scalar or array arguments (compiled as it is: `rdea_lab.physics.ring_kernels.fields1`)."""
    return fields_from(l2, l1, stress(l2, l1, v, C10, C20, C30, kap), C0, Ro, Ri)


def fields_from(l2, l1, sigma1, C0, Ro, Ri):
    """`fields` from the stress ``sigma1`` (`stress`), the one implementation of the rest: eq. (34)
    ``C = C0 lambda1**2 lambda2**2``, and the inner radius of one hollow cylinder of mean hoop stretch ``l2``
    and radial stretch ``1 / (l1 l2)``."""
    return sigma1, C0 * (l1 * l2) ** 2, 0.5 * (l2 * (Ro + Ri) - (Ro - Ri) / (l1 * l2))


def bounds(l1, kap):
    """``(y0, y_max, load)`` of the 1R problem at stretch ``l1``: the unloaded ``lambda2 = l1**-0.5``,
    the hoop-stretch cap and ``K / v**2``."""
    y0 = 1.0 / np.sqrt(l1)
    return y0, HOOP_STRETCH_CAP * y0, kap * l1 * l1


def problem(geom, material, l1, v, fast=None, out=None) -> Problem:
    """The 1R equilibrium in ``y = lambda2`` at clean 1-D inputs (eq. 33 as a stationary point); ``fast``:
    `rdea_lab.physics.ring_kernels`, which computes its bounds in one pass (into ``out``, four rows, if given)."""
    C = yeoh_coefficients(material)
    kap = kappa(geom, material)

    def terms(y, idx, second):
        p_y, p_yy = yeoh.d_psi_d_l2(l1[idx], y, C, second)
        return p_y, p_yy, 2.0 * y, 2.0

    if fast is not None:
        y0, y_max, load, K = fast.bounds(1, l1, v, kap, out=out)
    else:
        y0, y_max, load = bounds(l1, kap)
        K = load * v * v
    return Problem(terms, y0, y_max, K, load, kernel=(1, {"l1": np.ascontiguousarray(l1, float), "C": C}))


def evaluate(geom, material, l1, v, *, path=False, start=None, origin=None, kernel="auto") -> Evaluation:
    """1R equilibria at clean 1-D inputs: the rising-ramp rule, or the path from ``start``."""
    C = yeoh_coefficients(material)
    kap = kappa(geom, material)
    C0 = geom.C0(material.eps_r)
    fast = ring_kernels(kernel, l1.size, *C, kap, C0)

    def at(l2, l1, v):
        if fast is not None:  # one number per coefficient
            sigma1, cap, r_i = fast.fields1(l2, l1, v, C, kap, C0, geom.Ro, geom.Ri)
        else:
            sigma1, cap, r_i = fields(l2, l1, v, *C, kap, C0, geom.Ro, geom.Ri)
        return {"sigma1": sigma1, "lambda2a": l2, "lambda2b": l2, "lambda2c": l2, "capacitance": cap, "r_i": r_i}

    def free(prob):
        return fast.free_hook(1, prob, l1, v, C, kap, at)

    def solved(out=None):
        return evaluate_free(problem(geom, material, l1, v, fast, out), lambda l2: at(l2, l1, v), path=path,
                             start=start, origin=origin, kernel=kernel, free=free if fast is not None else None)

    return with_bounds_buffer(fast, l1.size, path, origin, solved)


def solve(geom, material, stretch, voltage, *, path=False, start=None, slack=True,
          kernel="auto") -> ModelResult:
    """Axial stress, force, circumferential stretch and capacitance of the 1R model.

    Parameters
    ----------
    geom : RollGeometry
        Undeformed roll geometry.
    material : parameter set
        ``C10, C20, C30`` [Pa], ``eps_r`` [-].
    stretch : array_like
        Axial stretch ``lambda1`` [-], >= 1.
    voltage : array_like
        Voltage [V].
    path, start, slack
        The equilibrium rule, a path's continuation and slack: see
        :func:`rdea_lab.physics.models.solve`.

    Returns
    -------
    ModelResult
        ``lambda2a = lambda2b = lambda2c = lambda2``.

    Notes
    -----
    Eq. (33) in [1]: ``lambda2 d psi_m / d lambda2 = alpha_e1 eta_b eps E**2``
    with ``E = lambda1 lambda2 v / L3``, solved on the branch continued from
    ``lambda2 = lambda1**-0.5`` at 0 V (see :mod:`rdea_lab.physics.branch`);
    ``sigma1 = lambda1 d psi_m / d lambda1 - alpha_e1 eta_b eps E**2``;
    capacitance eq. (34), ``C = C0 lambda1**2 lambda2**2``.
    """
    return solve_model("1r", evaluate, geom, material, stretch, voltage, path=path, start=start, slack=slack,
                       kernel=kernel)
