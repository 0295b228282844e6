"""Yeoh hyperelastic energy of an incompressible ring, eq. (22) of [1].

``psi_m(l1, l2) = sum_i C_i0 (I1 - 3)**i`` with
``I1 = l1**2 + l2**2 + l1**-2 l2**-2`` (the third stretch is eliminated by
incompressibility). ``I1 - 3`` and the derivatives of ``I1`` are evaluated
in a form where nothing cancels to first order (`_invariant_terms`), so they
stay accurate as the stretches approach 1 (at ``l1 = 1 + 1e-12`` the plain
formula loses every significant digit).

Functions take the coefficients ``C = (C10, C20, C30)`` [Pa] and broadcast
over array stretches.
"""

from __future__ import annotations

import numpy as np


def _invariant_terms(l1, l2):
    """``(x, I_1, I_2)``: ``x = I1 - 3`` and ``dI1/dl1``, ``dI1/dl2``, the one implementation, in plain algebra
    arranged so that nothing cancels to first order as the stretches approach 1 (scalar or array arguments;
    compiled too: `rdea_lab.physics.kernels`, `rdea_lab.physics.ring_kernels`).

    With ``P = l1 l2`` and ``r = P - 1 = (l1 - 1) + l1 (l2 - 1)`` (``l - 1`` is exact for a stretch in
    [0.5, 2], Sterbenz, and rounded relative to itself above; ``P - 1`` itself where ``l2`` is outside
    [0.5, 1.5]: below 0.5 ``l2 - 1`` loses ``l2``'s digits, and there ``(l1 - l2)**2`` or ``l1 - 1`` is large
    beside ``r``, whose rounding then does not matter):
    ``I1 - 3 = l1**2 + l2**2 + P**-2 - 3 = (l1 - l2)**2 + r**2 (1 + 2 P) / P**2``, two terms never negative,
    so ``x`` keeps its relative accuracy (a few ulps) however small the strain. The plain sum loses every
    digit at ``l1 = 1 + 1e-12``; the logarithmic form this replaced (``expm1`` of logarithmic stretches)
    kept them relative to its terms only (``~2e`` against ``x ~ 3 e**2``), and cost a logarithm or ``expm1``
    per term. ``dI1/dl1 = 2 l1 (1 - l1**-4 l2**-2) = 2 l1 s (S + 1) / S**2`` with ``S = l1 P``,
    ``s = S - 1 = (l1 - 1) + l1 r``; ``dI1/dl2`` likewise with ``T = l2 P``, ``t = (l2 - 1) + l2 r``."""
    p = l1 - 1.0
    q = l2 - 1.0
    P = l1 * l2
    r = _where(abs(q) <= 0.5, p + l1 * q, P - 1.0)
    d = l1 - l2
    x = d * d + r * r * (1.0 + 2.0 * P) / (P * P)
    S = l1 * P
    T = l2 * P
    I_1 = 2.0 * l1 * (p + l1 * r) * (S + 1.0) / (S * S)
    I_2 = 2.0 * l2 * (q + l2 * r) * (T + 1.0) / (T * T)
    return x, I_1, I_2


def _where(c, a, b):
    """``a`` where ``c``, else ``b``: `numpy.where`, a scalar for scalars (compiled: a conditional expression)."""
    out = np.where(c, a, b)
    return out if out.ndim else out[()]


def slope(x, C):
    """First and second derivative of the Yeoh energy in ``I1``.

    Parameters
    ----------
    x : array_like
        ``I1 - 3`` [-].
    C : tuple of float
        ``(C10, C20, C30)`` [Pa].

    Returns
    -------
    W1, W2 : numpy.ndarray
        ``dW/dI1`` and ``d2W/dI1**2`` [Pa].
    """
    C10, C20, C30 = C
    return C10 + x * (2.0 * C20 + 3.0 * C30 * x), 2.0 * C20 + 6.0 * C30 * x


def energy_of(x, C):
    """Yeoh energy ``W(x) = C10 x + C20 x**2 + C30 x**3`` [Pa] of ``x = I1 - 3``."""
    C10, C20, C30 = C
    return x * (C10 + x * (C20 + x * C30))


def energy(l1, l2, C):
    """Yeoh free-energy density ``psi_m`` [Pa = J/m^3].

    Parameters
    ----------
    l1 : array_like
        Axial stretch [-].
    l2 : array_like
        Circumferential stretch [-].
    C : tuple of float
        ``(C10, C20, C30)`` [Pa].

    Notes
    -----
    Eq. (22) in [1].
    """
    x, _, _ = _invariant_terms(np.asarray(l1, float), np.asarray(l2, float))
    return energy_of(x, C)


def gradient(l1, l2, C):
    """Partial derivatives ``(d psi/d l1, d psi/d l2)`` [Pa].

    The two stretches are independent variables (the third follows from
    incompressibility), as eq. (39) of [1] requires.
    """
    return gradient_terms(np.asarray(l1, float), np.asarray(l2, float), *C)


def gradient_terms(l1, l2, C10, C20, C30):
    """`gradient` for scalar or array stretches and the coefficients as three numbers, the one implementation:
    `_invariant_terms`, then `gradient_from` (compiled too: :mod:`rdea_lab.physics.kernels`,
    :mod:`rdea_lab.physics.ring_kernels`)."""
    x, I_1, I_2 = _invariant_terms(l1, l2)
    return gradient_from(x, I_1, I_2, C10, C20, C30)


def gradient_from(x, I_1, I_2, C10, C20, C30):
    """`gradient_terms` from `_invariant_terms`' ``(x, I_1, I_2)``: ``(W1 I_1, W1 I_2)`` (``W1 = dW/dI1``, `slope`)."""
    W1, _ = slope(x, (C10, C20, C30))
    return W1 * I_1, W1 * I_2


def hessian(l1, l2, C):
    """Second partial derivatives ``(psi_11, psi_12, psi_22)`` [Pa]."""
    l1 = np.asarray(l1, float)
    l2 = np.asarray(l2, float)
    x, I_1, I_2 = _invariant_terms(l1, l2)
    W1, W2 = slope(x, C)
    inv = 1.0 / (l1 * l2)
    inv2 = inv * inv
    I_11 = 2.0 + 6.0 * inv2 / (l1 * l1)
    I_22 = 2.0 + 6.0 * inv2 / (l2 * l2)
    I_12 = 4.0 * inv2 * inv
    return W2 * I_1 * I_1 + W1 * I_11, W2 * I_1 * I_2 + W1 * I_12, W2 * I_2 * I_2 + W1 * I_22


def psi2_terms(l1, l2, C10, C20, C30):
    """``(psi_2, psi_22)`` [Pa]: the first and second derivative of psi_m in ``l2``.

    Plain algebra (no logarithms): the 1-D equilibrium solvers need the root
    of a sum of such terms, not their relative accuracy near zero strain, and
    this is the hot path. Scalar or array arguments; the compiled kernels
    (:mod:`rdea_lab.physics.kernels`) compile this same function.
    """
    e, inv2, x, W1, I_2 = _psi2_parts(l1, l2, C10, C20, C30)
    W2 = 2.0 * C20 + 6.0 * C30 * x
    return W1 * I_2, W2 * I_2 * I_2 + W1 * (2.0 + 6.0 * e * inv2)


def psi2_first(l1, l2, C10, C20, C30):
    """``psi_2`` [Pa] alone (:func:`psi2_terms` without the second derivative)."""
    _, _, _, W1, I_2 = _psi2_parts(l1, l2, C10, C20, C30)
    return W1 * I_2


def _psi2_parts(l1, l2, C10, C20, C30):
    e = 1.0 / (l1 * l2) ** 2  # (l1 l2)**-2
    inv2 = 1.0 / (l2 * l2)
    x = l1 * l1 + l2 * l2 + e - 3.0
    W1 = C10 + x * (2.0 * C20 + 3.0 * C30 * x)
    return e, inv2, x, W1, 2.0 * l2 * (1.0 - e * inv2)


def d_psi_d_l2(l1, l2, C, second=True):
    """``(psi_2, psi_22)`` of :func:`psi2_terms` for coefficients ``C``; ``psi_22`` is None (and not
    computed) when ``second`` is False."""
    if not second:
        return psi2_first(l1, l2, C[0], C[1], C[2]), None
    return psi2_terms(l1, l2, C[0], C[1], C[2])
