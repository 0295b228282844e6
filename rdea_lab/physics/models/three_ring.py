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
from ..branch import Problem
from ..result import ModelNotApplicable, ModelResult
from ._common import HOOP_STRETCH_CAP, Evaluation, evaluate_free, kappa, solve_model, yeoh_coefficients


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

    def radii(self, xi, l1):
        s = xi * xi
        inv = 1.0 / l1
        return np.sqrt(s + self.Da * inv), np.sqrt(s + self.Dab * inv), np.sqrt(s + self.Dabc * inv)

    def radius_derivatives(self, xi, l1):
        """``(r, dr/dxi, d2r/dxi2)`` for ``r_ie, r_oe, r_o`` at fixed ``l1``.

        ``r**2 = xi**2 + D / l1`` gives ``dr/dxi = xi / r`` and
        ``d2r/dxi2 = (D / l1) / r**3``; with ``D = 0`` (no ring a) ``r = xi``.
        """
        inv = 1.0 / l1
        s = xi * xi
        out = []
        for D in (self.Da, self.Dab, self.Dabc):
            if D == 0.0:
                out.append((xi, 1.0, 0.0))
                continue
            r = np.sqrt(s + D * inv)
            q = 1.0 / r
            out.append((r, xi * q, D * inv * q * q * q))
        return out

    def radius_stretch_rates(self, radii, l1):
        """``dr/dlambda1`` at fixed ``xi`` for ``r_ie, r_oe, r_o``: ``-D / (2 l1**2 r)``."""
        w = -0.5 / (l1 * l1)
        return [0.0 if D == 0.0 else w * D / r for D, r in zip((self.Da, self.Dab, self.Dabc), radii)]

    def stretches(self, xi, l1):
        """``(lambda2a, lambda2b, lambda2c)`` at inner radius ``xi`` [Ro]."""
        r_ie, r_oe, r_o = self.radii(xi, l1)
        l2a = (xi + r_ie) / self.Sa if self.has_a else None
        l2c = (r_oe + r_o) / self.Sc if self.has_c else None
        return l2a, (r_ie + r_oe) / self.Sb, l2c

    def xi_at_hoop_stretch(self, l2b, l1):
        """Inverse of ``lambda2b(xi)`` (closed form), clipped at ``xi >= 0``."""
        total = l2b * self.Sb
        diff = (self.rho_oe**2 - self.rho_ie**2) / (l1 * total)
        r_ie = 0.5 * (total - diff)
        return np.sqrt(np.maximum(r_ie * r_ie - self.Da / l1, 0.0))


def _terms(rings, C):
    """``terms(xi, idx, second)`` for :func:`follow_branch`: derivatives of psi and c = lambda2b**2."""

    def terms(xi, idx, second):
        l1 = rings.l1[idx]
        (r_ie, d_ie, dd_ie), (r_oe, d_oe, dd_oe), (r_o, d_o, dd_o) = rings.radius_derivatives(xi, l1)
        parts = []  # (eta, lambda2, d lambda2 / d xi, d2 lambda2 / d xi2)
        if rings.has_a:
            parts.append((rings.eta[0], (xi + r_ie) / rings.Sa, (1.0 + d_ie) / rings.Sa, dd_ie / rings.Sa))
        l2b = (r_ie + r_oe) / rings.Sb
        d_b = (d_ie + d_oe) / rings.Sb
        dd_b = (dd_ie + dd_oe) / rings.Sb
        parts.append((rings.eta[1], l2b, d_b, dd_b))
        if rings.has_c:
            parts.append((rings.eta[2], (r_oe + r_o) / rings.Sc, (d_oe + d_o) / rings.Sc, (dd_oe + dd_o) / rings.Sc))
        p_y = 0.0
        p_yy = 0.0
        for eta, l2, d, dd in parts:
            psi_2, psi_22 = yeoh.d_psi_d_l2(l1, l2, C, second)
            p_y = p_y + eta * psi_2 * d
            if second:
                p_yy = p_yy + eta * (psi_22 * d * d + psi_2 * dd)
        c_y = 2.0 * l2b * d_b
        if not second:
            return p_y, None, c_y, None
        return p_y, p_yy, c_y, 2.0 * (d_b * d_b + l2b * dd_b)

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


def problem(geom, material, l1, v) -> Problem:
    """The 3R equilibrium in ``xi = r_i / Ro`` at clean 1-D inputs."""
    rings = _Rings(geom, l1)
    load = kappa(geom, material) * l1 * l1
    pitchfork = rings.rho_i == 0.0 and rings.has_a
    return Problem(_terms(rings, yeoh_coefficients(material)), rings.rho_i / np.sqrt(l1),
                   rings.xi_at_hoop_stretch(HOOP_STRETCH_CAP / np.sqrt(l1), l1), load * v * v, load,
                   pitchfork=pitchfork, scale=rings.rho_ie if pitchfork else None)


def evaluate(geom, material, l1, v, *, path=False, start=None, origin=None) -> Evaluation:
    """3R equilibria at clean 1-D inputs: the rising-ramp rule, or the path from ``start``."""
    C = yeoh_coefficients(material)
    kap = kappa(geom, material)
    rings = _Rings(geom, l1)

    def state(xi):
        # sigma1 = lambda1 dg/dlambda1 at fixed xi
        r_ie, r_oe, r_o = rings.radii(xi, l1)
        dr_ie, dr_oe, dr_o = rings.radius_stretch_rates((r_ie, r_oe, r_o), l1)
        l2b = (r_ie + r_oe) / rings.Sb
        dl2b = (dr_ie + dr_oe) / rings.Sb
        psi_1, psi_2 = yeoh.gradient(l1, l2b, C)
        dg = geom.eta_b * (psi_1 + psi_2 * dl2b)
        l2a = l2c = np.full_like(l1, np.nan)
        if rings.has_a:
            l2a = (xi + r_ie) / rings.Sa
            psi_1, psi_2 = yeoh.gradient(l1, l2a, C)
            dg = dg + geom.eta_a * (psi_1 + psi_2 * dr_ie / rings.Sa)
        if rings.has_c:
            l2c = (r_oe + r_o) / rings.Sc
            psi_1, psi_2 = yeoh.gradient(l1, l2c, C)
            dg = dg + geom.eta_c * (psi_1 + psi_2 * (dr_oe + dr_o) / rings.Sc)
        return {"sigma1": l1 * dg - 2.0 * kap * v * v * l1 * l1 * l2b * (l2b + l1 * dl2b),
                "lambda2a": l2a, "lambda2b": l2b, "lambda2c": l2c,
                "capacitance": geom.C0(material.eps_r) * (l1 * l2b) ** 2, "r_i": xi * geom.Ro}

    return evaluate_free(problem(geom, material, l1, v), state, path=path, start=start, origin=origin)


def solve(geom, material, stretch, voltage, *, path=False, start=None, slack=True) -> ModelResult:
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
    return solve_model("3r", evaluate, geom, material, stretch, voltage, path=path, start=start, slack=slack)
