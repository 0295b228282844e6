"""Three-ring (3R) model: eqs. (27) and (29) of [1], as corrected in ERRATA.

The paper writes 3R as six equations in four stretches and two Lagrange
multipliers. Volume conservation of each ring, eqs. (5)-(7), fixes every
radius once the axial stretch and the deformed inner radius ``r_i`` are
known, so the contact conditions (8)-(9) hold by construction and the model
has one free coordinate. In units of the outer radius ``Ro``
(``xi = r_i / Ro``, ``rho_j = R_j / Ro``)::

    r_ie**2 = xi**2 + (rho_ie**2 - rho_i**2) / lambda1
    r_oe**2 = xi**2 + (rho_oe**2 - rho_i**2) / lambda1
    r_o**2  = xi**2 + (1 - rho_i**2) / lambda1
    lambda2a = (xi + r_ie) / (rho_i + rho_ie), and likewise for b and c

and the equilibria are the stationary points in ``xi`` of the free enthalpy
density ``g = sum_j eta_j psi_m(lambda1, lambda2j) - kappa v**2 lambda1**2
lambda2b**2``. The corrected rows 1 and 3 of (27) are what this gives; the
test suite checks it against the six-equation system solved by fsolve.

With ``Ri = 0`` the bound ``r_i >= 0`` applies and ``g`` is even in
``r_i``: ``r_i = 0`` (every ring uniaxial, which is exactly the SU state)
is stationary at every voltage but stops being a minimum above a
bifurcation voltage, where the inner hole opens. The solver follows the
minimum, not the first stationary point.
"""

from __future__ import annotations

import numpy as np

from .. import yeoh
from ..yeoh import gradient_terms, psi2_first, psi2_terms
from ..branch import Problem
from ..result import ModelNotApplicable, ModelResult
from ._common import (HOOP_STRETCH_CAP, Evaluation, evaluate_free, kappa, ring_kernels, solve_model,
                      with_bounds_buffer, yeoh_coefficients)


def radii(xi, l1, Da, Dab, Dabc):
    """``(r_ie, r_oe, r_o)`` [Ro] at inner radius ``xi`` [Ro]: ``r**2 = xi**2 + D / lambda1``, eqs. (5)-(7)."""
    s = xi * xi
    inv = 1.0 / l1
    return np.sqrt(s + Da * inv), np.sqrt(s + Dab * inv), np.sqrt(s + Dabc * inv)


class _Rings:
    """Kinematics of the three rings at fixed axial stretches (one per sample)."""

    def __init__(self, geom, l1):
        Ro = geom.Ro
        self.rho_i, self.rho_ie, self.rho_oe = geom.Ri / Ro, geom.Rie / Ro, geom.Roe / Ro
        self.Da = self.rho_ie**2 - self.rho_i**2
        self.Dab = self.rho_oe**2 - self.rho_i**2
        self.Dabc = 1.0 - self.rho_i**2
        self.Sa = self.rho_i + self.rho_ie
        self.Sb = self.rho_ie + self.rho_oe
        self.Sc = self.rho_oe + 1.0
        # rings of zero volume carry no energy and are left out
        self.has_a = geom.eta_a > 0.0
        self.has_c = geom.eta_c > 0.0
        self.eta = (geom.eta_a, geom.eta_b, geom.eta_c)
        self.l1 = l1
        #: the ring constants of `ring_terms` (rings of zero volume: eta 0)
        self.constants = tuple(float(c) for c in (self.Da, self.Dab, self.Dabc, self.Sa, self.Sb, self.Sc,
                                                  *(e if e > 0.0 else 0.0 for e in self.eta)))
        #: ``(rho_i, Sb, rho_oe**2 - rho_ie**2, Da)``: what `bounds` needs
        self.bound_constants = tuple(float(c) for c in (self.rho_i, self.Sb, self.rho_oe**2 - self.rho_ie**2,
                                                        self.Da))

    def radii(self, xi, l1):
        return radii(xi, l1, self.Da, self.Dab, self.Dabc)

    def stretches(self, xi, l1):
        """``(lambda2a, lambda2b, lambda2c)`` at inner radius ``xi`` [Ro]."""
        r_ie, r_oe, r_o = self.radii(xi, l1)
        l2a = (xi + r_ie) / self.Sa if self.has_a else None
        l2c = (r_oe + r_o) / self.Sc if self.has_c else None
        return l2a, (r_ie + r_oe) / self.Sb, l2c


def xi_at_hoop_stretch(l2b, l1, Sb, dB, Da):
    """Inverse of ``lambda2b(xi)`` (closed form), clipped at ``xi >= 0`` (``dB = rho_oe**2 - rho_ie**2``)."""
    total = l2b * Sb
    diff = dB / (l1 * total)
    r_ie = 0.5 * (total - diff)
    return np.sqrt(np.maximum(r_ie * r_ie - Da / l1, 0.0))


def bounds(l1, kap, B):
    """``(y0, y_max, load)`` of the 3R problem at stretch ``l1``: the unloaded ``xi = rho_i l1**-0.5``, the
    ``xi`` where the active ring's hoop stretch is `HOOP_STRETCH_CAP` times uniaxial, and ``K / v**2``
    (``B``: `_Rings.bound_constants`)."""
    rho_i, Sb, dB, Da = B
    root = np.sqrt(l1)
    return rho_i / root, xi_at_hoop_stretch(HOOP_STRETCH_CAP / root, l1, Sb, dB, Da), kap * l1 * l1


def _radius(s, xi, D, inv):
    """``(r, dr/dxi, d2r/dxi2)`` of ``r**2 = xi**2 + D / l1`` (``s = xi**2``, ``inv = 1 / l1``):
    ``dr/dxi = xi / r``, ``d2r/dxi2 = (D / l1) / r**3``; with ``D = 0`` (no ring a) ``r = xi``."""
    if D == 0.0:
        return xi, 1.0, 0.0
    r = np.sqrt(s + D * inv)
    q = 1.0 / r
    return r, xi * q, D * inv * q * q * q


def ring_terms(xi, l1, R, C10, C20, C30, second=True):
    """``(psi_y, psi_yy, c_y, c_yy)`` of the 3R problem in ``xi = r_i / Ro`` (``c = lambda2b**2``).

    ``R = (Da, Dab, Dabc, Sa, Sb, Sc, eta_a, eta_b, eta_c)`` (`_Rings.constants`); scalar or
    array ``xi`` and ``l1``. The reference solver calls it on arrays, the compiled kernels
    (:mod:`rdea_lab.physics.kernels`) compile this same function for one sample. With ``second``
    False the second derivatives are not computed (0).
    """
    Da, Dab, Dabc, Sa, Sb, Sc, eta_a, eta_b, eta_c = R
    inv = 1.0 / l1
    s = xi * xi
    r_ie, d_ie, dd_ie = _radius(s, xi, Da, inv)
    r_oe, d_oe, dd_oe = _radius(s, xi, Dab, inv)
    r_o, d_o, dd_o = _radius(s, xi, Dabc, inv)
    p_y = 0.0
    p_yy = 0.0
    if eta_a > 0.0:  # rings of zero volume carry no energy and are left out
        l2, d, dd = (xi + r_ie) / Sa, (1.0 + d_ie) / Sa, dd_ie / Sa
        psi_2, psi_22 = psi2_terms(l1, l2, C10, C20, C30) if second else (psi2_first(l1, l2, C10, C20, C30), 0.0)
        p_y = p_y + eta_a * psi_2 * d
        if second:
            p_yy = p_yy + eta_a * (psi_22 * d * d + psi_2 * dd)
    l2b = (r_ie + r_oe) / Sb
    d_b = (d_ie + d_oe) / Sb
    dd_b = (dd_ie + dd_oe) / Sb
    psi_2, psi_22 = psi2_terms(l1, l2b, C10, C20, C30) if second else (psi2_first(l1, l2b, C10, C20, C30), 0.0)
    p_y = p_y + eta_b * psi_2 * d_b
    if second:
        p_yy = p_yy + eta_b * (psi_22 * d_b * d_b + psi_2 * dd_b)
    if eta_c > 0.0:
        l2, d, dd = (r_oe + r_o) / Sc, (d_oe + d_o) / Sc, (dd_oe + dd_o) / Sc
        psi_2, psi_22 = psi2_terms(l1, l2, C10, C20, C30) if second else (psi2_first(l1, l2, C10, C20, C30), 0.0)
        p_y = p_y + eta_c * psi_2 * d
        if second:
            p_yy = p_yy + eta_c * (psi_22 * d * d + psi_2 * dd)
    return p_y, p_yy, 2.0 * l2b * d_b, 2.0 * (d_b * d_b + l2b * dd_b)


def ring_state(xi, l1, v, R, C10, C20, C30, kap):
    """``(sigma1 [Pa], lambda2a, lambda2b, lambda2c)`` at the equilibrium ``xi``: ``sigma1 = lambda1
    dg/dlambda1`` at fixed ``xi`` (eq. (27) row 1 as corrected in ERRATA); a ring of zero volume has a
    NaN stretch. ``R`` as in `ring_terms`; scalar or array arguments (compiled too). Composed of
    `ring_geometry`, `yeoh.gradient_terms` of each ring and `ring_stress`, the one implementation of each
    part."""
    eta_a, eta_c = R[6], R[8]
    l2a, l2b, l2c, dr_ie, dr_oe, dr_o = ring_geometry(xi, l1, R)
    grad_b = gradient_terms(l1, l2b, C10, C20, C30)
    grad_a = gradient_terms(l1, l2a, C10, C20, C30) if eta_a > 0.0 else grad_b  # (zero volume: not read)
    grad_c = gradient_terms(l1, l2c, C10, C20, C30) if eta_c > 0.0 else grad_b
    return ring_stress(l1, v, R, kap, l2b, dr_ie, dr_oe, dr_o, grad_a, grad_b, grad_c), l2a, l2b, l2c


def ring_geometry(xi, l1, R):
    """``(lambda2a, lambda2b, lambda2c, dr_ie, dr_oe, dr_o)`` at inner radius ``xi`` [Ro]: the hoop stretches
    (NaN for a ring of zero volume) and ``dr/dlambda1`` at fixed ``xi`` of the radii (`radii`), what
    `ring_stress` needs besides the rings' energy gradients."""
    Da, Dab, Dabc, Sa, Sb, Sc, eta_a, eta_b, eta_c = R
    r_ie, r_oe, r_o = radii(xi, l1, Da, Dab, Dabc)
    # dr/dlambda1 at fixed xi: -D / (2 l1**2 r)
    w = -0.5 / (l1 * l1)
    dr_ie = 0.0 if Da == 0.0 else w * Da / r_ie
    dr_oe = 0.0 if Dab == 0.0 else w * Dab / r_oe
    dr_o = 0.0 if Dabc == 0.0 else w * Dabc / r_o
    l2b = (r_ie + r_oe) / Sb
    l2a = (xi + r_ie) / Sa if eta_a > 0.0 else l2b * np.nan
    l2c = (r_oe + r_o) / Sc if eta_c > 0.0 else l2b * np.nan
    return l2a, l2b, l2c, dr_ie, dr_oe, dr_o


def ring_stress(l1, v, R, kap, l2b, dr_ie, dr_oe, dr_o, grad_a, grad_b, grad_c):
    """``sigma1 = lambda1 dg/dlambda1`` [Pa] at fixed ``xi`` (eq. (27) row 1 as corrected in ERRATA) from
    `ring_geometry`'s ``lambda2b`` and ``dr/dlambda1`` and each ring's ``(psi_1, psi_2)``
    (`yeoh.gradient_terms`; that of a ring of zero volume is not read)."""
    Da, Dab, Dabc, Sa, Sb, Sc, eta_a, eta_b, eta_c = R
    dl2b = (dr_ie + dr_oe) / Sb
    psi_1, psi_2 = grad_b
    dg = eta_b * (psi_1 + psi_2 * dl2b)
    if eta_a > 0.0:
        psi_1, psi_2 = grad_a
        dg = dg + eta_a * (psi_1 + psi_2 * dr_ie / Sa)
    if eta_c > 0.0:
        psi_1, psi_2 = grad_c
        dg = dg + eta_c * (psi_1 + psi_2 * (dr_oe + dr_o) / Sc)
    return l1 * dg - 2.0 * kap * v * v * l1 * l1 * l2b * (l2b + l1 * dl2b)


def ring_fields(xi, l1, v, R, C10, C20, C30, kap, C0, Ro):
    """``(sigma1 [Pa], lambda2a, lambda2b, lambda2c, capacitance [F], r_i [m])`` at the equilibrium ``xi``:
    `ring_state`, then `fields_from`. Scalar or array arguments (compiled as it is: `rdea_lab.physics.kernels`
    for one sample, `rdea_lab.physics.ring_kernels.fields3` over the samples)."""
    sigma1, l2a, l2b, l2c = ring_state(xi, l1, v, R, C10, C20, C30, kap)
    return fields_from(xi, l1, sigma1, l2a, l2b, l2c, C0, Ro)


def fields_from(xi, l1, sigma1, l2a, l2b, l2c, C0, Ro):
    """`ring_fields` from `ring_state`'s values: they, eq. (29) ``C = C0 lambda1**2 lambda2b**2`` and
    ``r_i = xi Ro``."""
    return sigma1, l2a, l2b, l2c, C0 * (l1 * l2b) ** 2, xi * Ro


def _terms(rings, C):
    """``terms(xi, idx, second)`` for :func:`follow_branch`: derivatives of psi and c = lambda2b**2."""
    R = rings.constants

    def terms(xi, idx, second):
        p_y, p_yy, c_y, c_yy = ring_terms(xi, rings.l1[idx], R, *C, second)
        return (p_y, p_yy, c_y, c_yy) if second else (p_y, None, c_y, None)

    return terms


def check_applicable(geom) -> None:
    """Raise ModelNotApplicable unless ``geom`` is a roll."""
    if getattr(geom, "kind", "roll") != "roll":
        raise ModelNotApplicable("the 3R model describes a roll's three rings; a strip is the 1R model (eq. 33): "
                                 "use --model 1r (or su, equal at 0 V)")


def enthalpy(geom, material, stretch, voltage, r_i):
    """Free enthalpy density ``g`` [Pa] at a given deformed inner radius ``r_i`` [m].

    The equilibria of the corrected eq. (27) of [1] are its stationary points
    in ``r_i`` at fixed stretch and voltage.
    """
    l1 = np.asarray(stretch, float)
    rings = _Rings(geom, l1)
    C = yeoh_coefficients(material)
    l2a, l2b, l2c = rings.stretches(np.asarray(r_i, float) / geom.Ro, l1)
    g = geom.eta_b * yeoh.energy(l1, l2b, C)
    if l2a is not None:
        g = g + geom.eta_a * yeoh.energy(l1, l2a, C)
    if l2c is not None:
        g = g + geom.eta_c * yeoh.energy(l1, l2c, C)
    return g - kappa(geom, material) * (l1 * l2b * np.asarray(voltage, float)) ** 2


def core_scale(rings) -> float | None:
    """The length [Ro] of the structure of ``h`` next to the unloaded state, graded toward by the scan
    (`rdea_lab.physics.branch.scale_offsets`); None where there is none below the regular nodes.

    - ``Ri = 0`` with a ring a: the hole opens at a pitchfork at ``xi = 0`` and ``h`` bends on the scale of
      ring a, ``Rie / Ro``.
    - ``Ri > 0``: ``h`` rises from 0 at ``y0 = rho_i l1**-0.5`` to about the pitchfork's value over a few
      ``y0`` (``psi_y`` grows as ``xi - y0``, ``c_y`` as ``xi``), and a subcritical pitchfork of the solid roll
      becomes a fold there, between ``rho_i`` and ``rho_ie``: ``rho_i``. (A micro-core of 1e-6 Ro folds far
      below the first regular node, ``span / 576``, which the scan stepped over before.)
    """
    if rings.rho_i > 0.0:
        return float(rings.rho_i)
    return float(rings.rho_ie) if rings.has_a else None


def problem(geom, material, l1, v, fast=None, out=None) -> Problem:
    """The 3R equilibrium in ``xi = r_i / Ro`` at clean 1-D inputs; ``fast``: `rdea_lab.physics.ring_kernels`,
    which computes its bounds in one pass (into ``out``, four rows, if given)."""
    rings = _Rings(geom, l1)
    if fast is not None:
        y0, y_max, load, K = fast.bounds(3, l1, v, kappa(geom, material), rings.bound_constants, out)
    else:
        y0, y_max, load = bounds(l1, kappa(geom, material), rings.bound_constants)
        K = load * v * v
    pitchfork = rings.rho_i == 0.0 and rings.has_a
    C = yeoh_coefficients(material)
    return Problem(_terms(rings, C), y0, y_max, K, load, pitchfork=pitchfork,
                   scale=core_scale(rings),
                   kernel=(3, {"l1": np.ascontiguousarray(l1, float), "R": rings.constants, "C": C}))


def evaluate(geom, material, l1, v, *, path=False, start=None, origin=None, kernel="auto") -> Evaluation:
    """3R equilibria at clean 1-D inputs: the rising-ramp rule, or the path from ``start``."""
    C = yeoh_coefficients(material)
    kap = kappa(geom, material)
    rings = _Rings(geom, l1)

    C0 = geom.C0(material.eps_r)
    # compiled fields from as many samples as `evaluate_free` compiles the roots (also for a free state's
    # descent, whose roots are numpy's: the two agree to 1e-12); per-sample coefficients stay in numpy
    fast = ring_kernels(kernel, l1.size, *C, kap, C0)

    def at(xi, l1, v):
        if fast is not None:
            fields = fast.fields3(xi, l1, v, rings.constants, C, kap, C0, geom.Ro)
        else:
            fields = ring_fields(xi, l1, v, rings.constants, *C, kap, C0, geom.Ro)
        return dict(zip(("sigma1", "lambda2a", "lambda2b", "lambda2c", "capacitance", "r_i"), fields))

    def free(prob):
        return fast.free_hook(3, prob, l1, v, C, kap, at, R=rings.constants, B=rings.bound_constants)

    def solved(out=None):
        return evaluate_free(problem(geom, material, l1, v, fast, out), lambda xi: at(xi, l1, v), path=path,
                             start=start, origin=origin, kernel=kernel, free=free if fast is not None else None)

    return with_bounds_buffer(fast, l1.size, path, origin, solved)


def solve(geom, material, stretch, voltage, *, path=False, start=None, slack=True,
          kernel="auto") -> ModelResult:
    """Axial stress, force, ring stretches and capacitance of the 3R model.

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

    Notes
    -----
    Eqs. (27) and (29) in [1], rows 1 and 3 of (27) as corrected in ERRATA:
    ``sigma1 = lambda1 dg/dlambda1`` at the equilibrium (the derivative at
    fixed ``r_i``, which is the total derivative there because ``g`` is
    stationary in ``r_i``); ``C = C0 lambda1**2 lambda2b**2``.
    """
    check_applicable(geom)
    return solve_model("3r", evaluate, geom, material, stretch, voltage, path=path, start=start, slack=slack,
                       kernel=kernel)
