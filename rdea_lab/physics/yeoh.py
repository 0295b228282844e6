"""Yeoh hyperelastic energy of an incompressible ring, eq. (22) of [1].

``psi_m(l1, l2) = sum_i C_i0 (I1 - 3)**i`` with
``I1 = l1**2 + l2**2 + l1**-2 l2**-2`` (the third stretch is eliminated by
incompressibility). ``I1 - 3`` and the derivatives of ``I1`` are evaluated
from logarithmic stretches with ``expm1``, so they stay accurate as the
stretches approach 1 (at ``l1 = 1 + 1e-12`` the plain formula loses every
significant digit).

Functions take the coefficients ``C = (C10, C20, C30)`` [Pa] and broadcast
over array stretches.
"""

from __future__ import annotations

import numpy as np


def _invariant_terms(l1, l2):
    """``(x, I_1, I_2)``: ``x = I1 - 3`` and ``dI1/dl1``, ``dI1/dl2`` from logarithmic stretches, the one
    implementation: the logarithms, `invariant_args`, ``expm1`` of each, `invariant_from` (compiled too:
    `rdea_lab.physics.kernels`; `rdea_lab.physics.ring_kernels`' split passes take the logarithms and ``expm1``
    by numpy over blocks and call the two pieces compiled)."""
    e0, e1, e2, e3, e4 = invariant_args(np.log(l1), np.log(l2))
    return invariant_from(l1, l2, _expm1_own(e0), _expm1_own(e1), _expm1_own(e2), _expm1_own(e3), _expm1_own(e4))


def _expm1_own(t):
    """``np.expm1(t)``, in place where ``t`` is an array: `invariant_args`' values are new arrays of
    `_invariant_terms`' own, and five of them held at once with a new array for each ``expm1`` took up to twice
    as long (`one_ring.stress` on 1e5 samples). The same numbers; the compiled forms bind it to ``np.expm1``."""
    return np.expm1(t, out=t) if isinstance(t, np.ndarray) else np.expm1(t)


def invariant_args(a, b):
    """The arguments of the five ``expm1`` of `_invariant_terms` from ``a = log l1``, ``b = log l2``:
    ``2 a``, ``2 b``, ``-2 (a + b)`` (the logarithms of ``l1**2``, ``l2**2``, ``l1**-2 l2**-2``) and
    ``-4 a - 2 b``, ``-2 a - 4 b`` (of ``l1**-4 l2**-2``, ``l1**-2 l2**-4``)."""
    return 2.0 * a, 2.0 * b, -2.0 * (a + b), -4.0 * a - 2.0 * b, -2.0 * a - 4.0 * b


def invariant_from(l1, l2, e0, e1, e2, e3, e4):
    """``(x, I_1, I_2)`` of `_invariant_terms` from the ``expm1`` of `invariant_args`' five values:
    ``x = I1 - 3``, ``dI1/dl1 = 2 l1 (1 - l1**-4 l2**-2)``, ``dI1/dl2 = 2 l2 (1 - l1**-2 l2**-4)``."""
    return e0 + e1 + e2, -2.0 * l1 * e3, -2.0 * l2 * e4


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
    `_invariant_terms`, then `gradient_from` (compiled too: :mod:`rdea_lab.physics.kernels`; the split passes
    of :mod:`rdea_lab.physics.ring_kernels` compose the same pieces)."""
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
