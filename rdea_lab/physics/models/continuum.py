"""Continuum roll (CR) model: the axisymmetric limit of the 3R model's lumping.

The 3R model gives each of the regions a (``Ri..Rie``, passive), b
(``Rie..Roe``, active) and c (``Roe..Ro``, passive) one average hoop stretch.
CR keeps its one free coordinate, the deformed inner radius ``r_i``
(``xi = r_i / Ro``), but lets the hoop stretch vary with the undeformed radius
``R``. In units of ``Ro`` (``s = (R / Ro)**2``, ``s_i = (Ri / Ro)**2``),
volume conservation of every thin ring, eq. (5) of [1] taken ring by ring,
gives::

    r(R)**2 / Ro**2 = xi**2 + (s - s_i) / lambda1
    lambda2(R)**2 = r**2 / R**2 = 1 / lambda1 + A / s,    A = xi**2 - s_i / lambda1

with radial stretch ``dr/dR = 1 / (lambda1 lambda2)``. ``A = 0`` is the
uniaxial state (``lambda2 = lambda1**-0.5`` everywhere); ``A > 0`` opens the
hole. With ``B = lambda1 A`` the first invariant is exactly::

    I1 - 3 = x0 + delta(s),   x0 = lambda1**2 + 2 / lambda1 - 3,
                              delta = A B / (s (s + B))   (>= 0, no cancellation)

The elastic energy per unit reference volume is the Yeoh energy (22)
averaged over the cross-section, ``psi = (1 / (1 - s_i)) int_{s_i}^1 W(x0 +
delta) ds``, by Gauss-Legendre quadrature in ``u = ln s`` in each region
(:func:`quadrature`). The active region's capacitance is the sum of its
layers (``dN = dR / L3``, area ``2 pi r alpha_e1 L1 lambda1``, gap ``L3 /
(lambda1 lambda2)``)::

    C = C0 lambda1**2 c,   c = <lambda2**2>_b = 1 / lambda1 + A Lb,
    Lb = ln(s_oe / s_ie) / (s_oe - s_ie)

(``<.>_b`` the volume average over region b), closed form, with ``C0`` of
eq. (29): at ``lambda1 = 1``, ``r_i = Ri`` it is ``C0`` exactly, and at 0 V
(``A = 0``) it is SU's ``C0 lambda1``. ``c`` is CR's analogue of 3R's
``lambda2b**2`` (they differ under voltage: the mean of the square against
the square of a lumped mean). The free enthalpy density and the stress are,
as for 3R (ERRATA),::

    g(xi) = psi(xi) - kappa v**2 lambda1**2 c(xi),   g_xi = 0 at equilibrium
    sigma1 = lambda1 dg/dlambda1 (fixed xi)
           = <W'(x) (2 lambda1**2 (1 - lambda1**-3) + lambda1 (A / (s + B))**2
                     + d_delta/dA s_i / lambda1)>
             - kappa v**2 lambda1 (1 + lambda1 Lb (A + xi**2)),
    d_delta/dA = t (2 - t) / s,   t = B / (s + B)

(``<.>`` the average over the cross-section). The model is derived in
``docs/models-cr.md``.

With ``Ri = 0`` (a solid roll) ``lambda2**2 = 1 / lambda1 + xi**2 / s``: any
open hole ``xi > 0`` makes the hoop stretch unbounded at the axis and the
energy infinite (``int ds / s`` diverges). ``r_i = 0`` is then pinned, every
point is uniaxial, and CR is the SU model exactly; this case is handled
explicitly, without integrating the singular integrand. The 3R model's
hole opening in solid rolls is an artefact of giving the core one average
hoop stretch.

[1] Prechtl et al., Smart Mater. Struct. 30 (2021), doi:10.1088/1361-665X/ac34be.
"""

from __future__ import annotations

import functools

import numpy as np

from .. import yeoh
from ..yeoh import slope
from ..branch import Problem
from ..result import OK, ModelNotApplicable, ModelResult
from . import su
from ._common import (HOOP_STRETCH_CAP, Evaluation, evaluate_free, kappa, ring_kernels, solve_model,
                      yeoh_coefficients)

#: Target relative accuracy of one region's quadrature, used to choose its points (see :func:`quadrature`).
QUAD_TOL = 1e-12
#: Longest panel in ``u = ln s``: a region longer than this is split into equal panels.
PANEL_MAX = 4.0
#: Fewest Gauss points per panel.
MIN_POINTS = 3
#: Samples per block of the vectorized quadrature (its temporaries are samples x nodes).
BLOCK = 4096


def points_for(length, tol=QUAD_TOL):
    """Gauss-Legendre points for one panel of length ``length`` in ``u = ln s`` [-].

    In ``u`` the integrands are analytic except where ``s + B = 0``, i.e. at
    ``u = ln B + i pi``: a distance ``pi`` from the real axis whatever the
    state. Gauss-Legendre with ``n`` points then errs by about
    ``rho**(-2 n)``, ``rho = d + sqrt(d**2 + 1)``, ``d = 2 pi / length``
    (the Bernstein ellipse through the singularity); ``n`` is the least with
    ``rho**(-2 n) <= tol``, at least :data:`MIN_POINTS`.
    """
    d = 2.0 * np.pi / length
    rho = d + np.sqrt(d * d + 1.0)
    return max(MIN_POINTS, int(np.ceil(np.log(1.0 / tol) / (2.0 * np.log(rho)))))


@functools.lru_cache(maxsize=64)
def _legendre(n):
    return np.polynomial.legendre.leggauss(n)


@functools.lru_cache(maxsize=256)
def quadrature(geom, points=None):
    """Quadrature nodes over the roll's cross-section, Gauss-Legendre in each region.

    Parameters
    ----------
    geom : RollGeometry
    points : int, optional
        Gauss points per panel in every region; default: :func:`points_for`
        each panel's length (accuracy :data:`QUAD_TOL`).

    Returns
    -------
    s : numpy.ndarray
        Nodes ``(R / Ro)**2`` [-].
    w : numpy.ndarray
        Weights of the cross-section average (``sum w = 1``): ``<f> = sum w f(s)``.
    region : numpy.ndarray of int
        0, 1, 2 for the node's region a, b, c.

    Notes
    -----
    Each region ``[s_in, s_out]`` is mapped to ``u = ln s`` (``ds = s du``)
    and split into ``ceil(ln(s_out / s_in) / PANEL_MAX)`` equal panels. A
    region of zero volume has no nodes. With ``Ri = 0`` region a has three
    Gauss points in ``s`` itself: there the state is pinned at ``r_i = 0``,
    the integrand is constant, and any rule of total weight ``eta_a`` is exact.
    """
    Ro = geom.Ro
    bounds = [(geom.Ri / Ro) ** 2, (geom.Rie / Ro) ** 2, (geom.Roe / Ro) ** 2, 1.0]
    total = 1.0 - bounds[0]
    S, Wt, reg = [], [], []
    for j in range(3):
        lo, hi = bounds[j], bounds[j + 1]
        if hi <= lo:
            continue
        if lo == 0.0:  # Ri = 0: only the uniaxial state is ever evaluated here
            x, w = _legendre(MIN_POINTS)
            S.append(0.5 * hi * (1.0 + x))
            Wt.append(0.5 * hi * w / total)
            reg.append(np.full(x.size, j))
            continue
        ua, ub = np.log(lo), np.log(hi)
        panels = int(np.ceil((ub - ua) / PANEL_MAX))
        edges = np.linspace(ua, ub, panels + 1)
        n = points if points is not None else points_for((ub - ua) / panels)
        x, w = _legendre(int(n))
        for a, b in zip(edges[:-1], edges[1:]):
            s = np.exp(0.5 * (a + b) + 0.5 * (b - a) * x)
            S.append(s)
            Wt.append(0.5 * (b - a) * w * s / total)
            reg.append(np.full(x.size, j))
    s, w, region = np.concatenate(S), np.concatenate(Wt), np.concatenate(reg)
    for arr in (s, w, region):
        arr.flags.writeable = False
    return s, w, region


class _Roll:
    """Cross-section and per-sample constants at fixed axial stretches."""

    def __init__(self, geom, l1, points=None):
        Ro = geom.Ro
        self.l1 = l1
        self.s_i = (geom.Ri / Ro) ** 2
        self.s_ie = (geom.Rie / Ro) ** 2
        self.s_oe = (geom.Roe / Ro) ** 2
        self.pinned = geom.Ri == 0.0
        self.Lb = np.log(self.s_oe / self.s_ie) / (self.s_oe - self.s_ie)
        self.s, self.w, self.region = quadrature(geom, points)
        self.w_over_s = self.w / self.s
        #: ``(s, w / s, w / s**2, w)``: the nodes and the weights of `_terms`' three integrals
        self.weights = (self.s, self.w_over_s, self.w_over_s * (1.0 / self.s), self.w)
        # region averages: columns of weights summing to 1 over each present region
        self.present = tuple(bool(np.any(self.region == j)) for j in range(3))
        avg = np.zeros((self.s.size, 3))
        for j in range(3):
            if self.present[j]:
                sel = self.region == j
                avg[sel, j] = self.w[sel] / self.w[sel].sum()
        self.avg = avg
        # the unloaded state: r_i = Ri lambda1**-1/2, and I1 - 3 there in a form exact near lambda1 = 1
        self.xi0 = np.sqrt(self.s_i / l1)
        # the SU basis: lambda1 dx0/dlambda1 and x0 (su.basis keeps their digits near lambda1 = 1)
        self.lx0p, self.x0 = su.basis(l1)

    def opening(self, xi, xi0):
        """``A = xi**2 - s_i / lambda1``, factored so that it keeps its digits near the unloaded state."""
        return (xi - xi0) * (xi + xi0)



def node_terms(A, B, x0, s, C10, C20, C30, second=True):
    """What `_terms` integrates at quadrature nodes ``s``: ``(W' tt, W'' tt**2, W' (1 - t) / (s + B)**2)``
    with ``t = B / (s + B)``, ``tt = t (2 - t)``, ``x = x0 + A t / s`` (``A`` the opening, ``B = lambda1 A``).

    Scalar or broadcast arrays; the compiled kernels (:mod:`rdea_lab.physics.kernels`) compile this
    same function for one node. With ``second`` False only the first is computed (0 for the others).
    """
    inv = 1.0 / (s + B)
    t = B * inv
    x = x0 + A * t * (1.0 / s)
    W1, W2 = slope(x, (C10, C20, C30))
    tt = t * (2.0 - t)
    if not second:
        return W1 * tt, 0.0, 0.0
    return W1 * tt, W2 * tt * tt, W1 * (1.0 - t) * inv * inv


def _terms(roll, C):
    """``terms(xi, idx, second)`` for the branch solver: derivatives of psi and c in ``xi``.

    ``psi_A = <W'(x) d_delta/dA>`` with ``d_delta/dA = t (2 - t) / s`` and
    ``d2_delta/dA2 = 2 lambda1 (1 - t) / (s + B)**2``, ``t = B / (s + B)``;
    ``dA/dxi = 2 xi``. ``c = 1 / lambda1 + A Lb`` is linear in ``A``.
    """
    s, ws, ws2, w = roll.weights

    def block(xi, idx, second):
        l1 = roll.l1[idx]
        A = roll.opening(xi, roll.xi0[idx])
        a1, a2, a3 = node_terms(A[:, None], (l1 * A)[:, None], roll.x0[idx][:, None], s, *C, second)
        p_A = a1 @ ws
        if not second:
            return p_A, None
        return p_A, a2 @ ws2 + 2.0 * l1 * (a3 @ w)

    def terms(xi, idx, second):
        p_A, p_AA = _by_blocks(lambda x, i: block(x, i, second), xi, idx)
        c_y = 2.0 * roll.Lb * xi
        if not second:
            return 2.0 * xi * p_A, None, c_y, None
        return 2.0 * xi * p_A, 4.0 * xi * xi * p_AA + 2.0 * p_A, c_y, np.full_like(xi, 2.0 * roll.Lb)

    return terms


def _by_blocks(fn, *arrays):
    """``fn`` over slices of :data:`BLOCK` samples, its 1-D outputs joined (None stays None).

    The quadrature's temporaries are (samples, nodes); in blocks they stay in
    cache (one pass over 1e5 samples is about five times slower).
    """
    n = arrays[0].size
    if n <= BLOCK:
        return fn(*arrays)
    parts = [fn(*(a[i:i + BLOCK] for a in arrays)) for i in range(0, n, BLOCK)]
    return tuple(None if p[0] is None else np.concatenate(p) for p in zip(*parts))


def check_applicable(geom) -> None:
    """Raise ModelNotApplicable unless ``geom`` is a roll."""
    if getattr(geom, "kind", "roll") != "roll":
        raise ModelNotApplicable("the CR model describes a roll's cross-section; a strip is the 1R model (eq. 33): "
                                 "use --model 1r (or su, equal at 0 V)")


def _energy(roll, C, l1, xi, xi0, x0):
    """Cross-section average of the Yeoh energy at ``xi`` (arrays broadcast; nodes on a new last axis)."""
    A = roll.opening(xi, xi0)
    B = (l1 * A)[..., None]
    t = B / (roll.s + B)
    x = x0[..., None] + A[..., None] * t / roll.s
    return yeoh.energy_of(x, C) @ roll.w


def enthalpy(geom, material, stretch, voltage, r_i, *, points=None):
    """Free enthalpy density ``g = psi - kappa v**2 lambda1**2 c`` [Pa] at a deformed inner radius.

    Parameters
    ----------
    geom : RollGeometry
    material : parameter set
        ``C10, C20, C30`` [Pa], ``eps_r`` [-].
    stretch : array_like
        Axial stretch ``lambda1`` [-].
    voltage : array_like
        Voltage [V].
    r_i : array_like
        Deformed inner radius [m]; the arguments broadcast.
    points : int, optional
        Gauss points per panel (default: the rule of :func:`quadrature`).

    Notes
    -----
    The equilibria of the CR model are the stationary points of ``g`` in
    ``r_i`` at fixed stretch and voltage. With ``Ri = 0`` an open hole
    (``r_i > 0``) costs infinite energy: ``g`` is ``inf`` there and the SU
    value at ``r_i = 0``. Accurate (to :data:`QUAD_TOL`) for
    ``r_i >= Ri lambda1**-0.5``, the admissible range.
    """
    l1, v, r = np.broadcast_arrays(np.asarray(stretch, float), np.asarray(voltage, float), np.asarray(r_i, float))
    roll = _Roll(geom, l1, points)
    xi = r / geom.Ro
    open_ = roll.pinned & (xi != 0.0)
    xi = np.where(open_, 0.0, xi)
    psi = _energy(roll, yeoh_coefficients(material), l1, xi, roll.xi0, roll.x0)
    c = 1.0 / l1 + roll.opening(xi, roll.xi0) * roll.Lb
    g = psi - kappa(geom, material) * v * v * l1 * l1 * c
    return np.where(open_, np.inf, g)


def problem(geom, material, l1, v, *, points=None) -> Problem:
    """The CR equilibrium in ``xi = r_i / Ro`` at clean 1-D inputs (a roll with ``Ri > 0``).

    The admissible range ends where the hoop stretch at ``R = Rie`` (the
    largest in the active region) is ``HOOP_STRETCH_CAP`` times the uniaxial
    value. With ``Ri = 0`` there is no free coordinate (``r_i = 0`` is pinned)
    and no problem to solve: ValueError.
    """
    return _problem(_Roll(geom, l1, points), geom, material, l1, v)


def bounds(l1, kap, s_i, s_ie):
    """``(y0, y_max, load)`` of the CR problem at stretch ``l1``: the unloaded ``xi = (s_i / lambda1)**0.5``, the
    ``xi`` where the hoop stretch at ``R = Rie`` (the largest in the active region) is `HOOP_STRETCH_CAP` times
    uniaxial and ``K / v**2``. Scalar or array arguments (compiled too)."""
    xi0 = np.sqrt(s_i / l1)
    l2 = HOOP_STRETCH_CAP / np.sqrt(l1)
    return xi0, np.sqrt(xi0 * xi0 + s_ie * (l2 * l2 - 1.0 / l1)), kap * l1 * l1


def _problem(roll, geom, material, l1, v, fast=None):
    if roll.pinned:
        raise ValueError("CR with Ri = 0 has no free coordinate: r_i = 0 is pinned (an open hole costs infinite "
                         "energy); evaluate() handles it without a problem")
    if fast is not None:
        _, y_max, load, K = fast.bounds(4, l1, v, kappa(geom, material), (roll.s_i, roll.s_ie, 0.0, 0.0))
    else:
        _, y_max, load = bounds(l1, kappa(geom, material), roll.s_i, roll.s_ie)
        K = load * v * v
    C = yeoh_coefficients(material)
    kernel = (4, {"l1": np.ascontiguousarray(l1, float), "C": C, "xi0": np.ascontiguousarray(roll.xi0, float),
                  "x0": np.ascontiguousarray(roll.x0, float), "Lb": float(roll.Lb),
                  "Q": np.ascontiguousarray(np.stack(roll.weights), float)})
    return Problem(_terms(roll, C), roll.xi0, y_max, K, load, scale=np.sqrt(roll.s_i), kernel=kernel)


def node_mechanics(A, B, x0, lx0p, l1, s, s_i_over_s, C10, C20, C30):
    """What `_mechanics` averages at quadrature nodes ``s``: ``W'(x) lambda1 dx/dlambda1`` at fixed ``xi`` and
    the hoop stretch ``lambda2 = ((1 + B / s) / lambda1)**0.5`` (``A`` the opening, ``B = lambda1 A``, ``x0``
    and ``lx0p = lambda1 dx0/dlambda1`` of `su.basis`). Scalar or broadcast arrays (compiled too:
    `rdea_lab.physics.ring_kernels` sums it per sample)."""
    inv = 1.0 / (s + B)
    t = B * inv
    x = x0 + A * t / s
    W1, _ = slope(x, (C10, C20, C30))
    # lambda1 d(I1 - 3)/dlambda1 at fixed xi: x0, B and A (through s_i / lambda1) all move
    dx = lx0p + l1 * (A * inv) ** 2 + t * (2.0 - t) * s_i_over_s / l1
    return W1 * dx, np.sqrt((1.0 + B / s) / l1)


def closing(mech, xi, xi0, l1, v, Lb, kap, C0, Ro):
    """``(sigma1 [Pa], capacitance [F], r_i [m])`` at the equilibrium ``xi`` from the elastic stress ``mech``
    (`_mechanics`): the electrical part of ``sigma1`` and ``C = C0 lambda1**2 c``, ``c = 1 / lambda1 + A Lb``
    (see the module docstring). Scalar or array arguments (compiled too)."""
    A = (xi - xi0) * (xi + xi0)  # `_Roll.opening`
    elec = kap * v * v * l1 * (1.0 + l1 * Lb * (A + xi * xi))
    c = 1.0 / l1 + A * Lb
    return mech - elec, C0 * l1 * l1 * c, xi * Ro


def _mechanics(roll, C):
    """``block(xi, l1, xi0, x0, lx0p)``: the elastic stress ``lambda1 dpsi/dlambda1`` at fixed ``xi``
    and the volume-averaged hoop stretch of regions a, b, c."""
    s, w = roll.s, roll.w
    s_i_over_s = roll.s_i / s

    def block(xi, l1, xi0, x0, lx0p):
        A = roll.opening(xi, xi0)
        W1dx, hoop = node_mechanics(A[:, None], (l1 * A)[:, None], x0[:, None], lx0p[:, None], l1[:, None], s,
                                    s_i_over_s, *C)
        hoop = hoop @ roll.avg  # each region's volume average
        return W1dx @ w, hoop[:, 0], hoop[:, 1], hoop[:, 2]

    return block


def evaluate(geom, material, l1, v, *, path=False, start=None, origin=None, points=None,
             kernel="auto") -> Evaluation:
    """CR equilibria at clean 1-D inputs: the rising-ramp rule, or the path from ``start``.

    With ``Ri = 0`` the state is the pinned ``r_i = 0`` at every voltage
    (status OK; a path changes nothing).
    """
    kap = kappa(geom, material)
    C = yeoh_coefficients(material)
    C0 = geom.C0(material.eps_r)
    roll = _Roll(geom, l1, points)
    fast = ring_kernels(kernel, l1.size, *C, kap, C0)
    tables = fast.cr_tables(roll) if fast is not None else None

    def at(xi, roll, v):
        l1 = roll.l1
        if fast is not None:
            fields = fast.fields_cr(xi, l1, v, roll, C, kap, C0, geom.Ro, tables)
            return dict(zip(("sigma1", "lambda2a", "lambda2b", "lambda2c", "capacitance", "r_i"), fields))
        mech, *hoop = _by_blocks(_mechanics(roll, C), xi, l1, roll.xi0, roll.x0, roll.lx0p)
        l2 = [h if there else np.full_like(l1, np.nan) for h, there in zip(hoop, roll.present)]
        sigma1, cap, r_i = closing(mech, xi, roll.xi0, l1, v, roll.Lb, kap, C0, geom.Ro)
        return {"sigma1": sigma1, "lambda2a": l2[0], "lambda2b": l2[1], "lambda2c": l2[2], "capacitance": cap,
                "r_i": r_i}

    def state(xi):
        return at(xi, roll, v)

    def free(prob):
        return fast.free_hook(4, prob, l1, v, C, kap, lambda y, lam, vv: at(y, _Roll(geom, lam, points), vv),
                              cr=(*tables[:2], roll.s_i, roll.s_ie, roll.Lb))

    if roll.pinned:
        n = l1.size
        y = np.zeros(n)
        return Evaluation(np.full(n, OK, np.int8), np.full(n, np.nan), np.full(n, np.nan), state(y),
                          0.0 if path else None, y)
    return evaluate_free(_problem(roll, geom, material, l1, v, fast), state, path=path, start=start, origin=origin,
                         kernel=kernel, free=free if fast is not None else None)


def solve(geom, material, stretch, voltage, *, path=False, start=None, slack=True,
          kernel="auto") -> ModelResult:
    """Axial stress, force, region hoop stretches and capacitance of the CR model.

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
        ``lambda2a``, ``lambda2b``, ``lambda2c``: the volume-averaged hoop
        stretch of each region; ``r_i`` the deformed inner radius.

    Notes
    -----
    The exact axisymmetric limit of the 3R model (eqs. (5)-(7), (22), (27),
    (29) of [1] with the regions' hoop stretches resolved in ``R``):
    ``sigma1 = lambda1 dg/dlambda1`` at fixed ``r_i`` at the equilibrium,
    ``C = C0 lambda1**2 <lambda2**2>_b``; see the module docstring and
    ``docs/models-cr.md``. With ``Ri = 0`` it equals the SU model (39)-(41).
    """
    check_applicable(geom)
    return solve_model("cr", evaluate, geom, material, stretch, voltage, path=path, start=start, slack=slack,
                       kernel=kernel)
