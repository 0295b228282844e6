"""Compiled kernels of :mod:`rdea_lab.physics.viscoelastic` (numba, ``cache=True``).

Imported on first use, so that commands which never integrate a branch do not
import numba. See that module's docstring for the equations and the integrator.
Without numba (the ``[fast]`` extra) the same functions run as plain Python: one
5401-sample run with two branches takes about 0.2 s instead of 2 ms.
"""

import math

try:
    import numba

    _njit = numba.njit(cache=True)
except ImportError:  # no [fast] extra: the very same code, interpreted
    def _njit(function):
        return function

from .viscoelastic import _RADAU_A, _RADAU_C

#: Radau IIA coefficients as module constants (numba freezes globals into the machine code).

(c1, c2, _), ((a11, a12, a13), (a21, a22, a23), (a31, a32, a33)) = _RADAU_C, _RADAU_A


@_njit
def radau(u0, e, r1, r2, r3, hr, hs):
    # stages U_i = u0 + hs sum_j A_ij r_j - hr sum_j A_ij f(U_j), e = exp(u0); returns U_3 (stiffly accurate)
    d1 = hs * (a11 * r1 + a12 * r2 + a13 * r3)
    d2 = hs * (a21 * r1 + a22 * r2 + a23 * r3)
    d3 = hs * (a31 * r1 + a32 * r2 + a33 * r3)
    f0 = (e * e - 1.0 / e) / 3.0
    k = hr * (2.0 * e * e + 1.0 / e) / 3.0
    # predictor: the exact solution of the ODE linearized at u0 (right in both limits)
    g = d3 - hr * f0
    if k < 0.1:  # (1 - exp(-k c)) / k to O((k c)^3): Newton removes the rest
        U1 = u0 + g * c1 / (1.0 + 0.5 * k * c1 + k * k * c1 * c1 / 12.0)
        U2 = u0 + g * c2 / (1.0 + 0.5 * k * c2 + k * k * c2 * c2 / 12.0)
        U3 = u0 + g / (1.0 + 0.5 * k + k * k / 12.0)
    else:
        U1 = u0 + g * -math.expm1(-k * c1) / k
        U2 = u0 + g * -math.expm1(-k * c2) / k
        U3 = u0 + g * -math.expm1(-k) / k
    last = math.inf
    for _ in range(60):
        e1, e2, e3 = math.exp(U1), math.exp(U2), math.exp(U3)
        F1, F2, F3 = (e1 * e1 - 1.0 / e1) / 3.0, (e2 * e2 - 1.0 / e2) / 3.0, (e3 * e3 - 1.0 / e3) / 3.0
        D1, D2, D3 = (hr * (2.0 * e1 * e1 + 1.0 / e1) / 3.0, hr * (2.0 * e2 * e2 + 1.0 / e2) / 3.0,
                      hr * (2.0 * e3 * e3 + 1.0 / e3) / 3.0)
        G1 = U1 - u0 - d1 + hr * (a11 * F1 + a12 * F2 + a13 * F3)
        G2 = U2 - u0 - d2 + hr * (a21 * F1 + a22 * F2 + a23 * F3)
        G3 = U3 - u0 - d3 + hr * (a31 * F1 + a32 * F2 + a33 * F3)
        j11, j12, j13 = 1.0 + a11 * D1, a12 * D2, a13 * D3
        j21, j22, j23 = a21 * D1, 1.0 + a22 * D2, a23 * D3
        j31, j32, j33 = a31 * D1, a32 * D2, 1.0 + a33 * D3
        c11, c12, c13 = j22 * j33 - j23 * j32, j23 * j31 - j21 * j33, j21 * j32 - j22 * j31
        det = j11 * c11 + j12 * c12 + j13 * c13
        x1 = (G1 * c11 + j12 * (G3 * j23 - G2 * j33) + j13 * (G2 * j32 - G3 * j22)) / det
        x2 = (j11 * (G2 * j33 - G3 * j23) + G1 * c12 + j13 * (G3 * j21 - G2 * j31)) / det
        x3 = (j11 * (G3 * j22 - G2 * j32) + j12 * (G2 * j31 - G3 * j21) + G1 * c13) / det
        U1, U2, U3 = U1 - x1, U2 - x2, U3 - x3
        big = max(abs(x1), abs(x2), abs(x3)) / (1.0 + abs(U3))
        if not big < 1e3:  # diverging or NaN
            return math.nan
        # Newton converges quadratically (its constant ~ h kappa): a correction below 1e-9 / (1 + h kappa)
        # leaves an error of its square, below rounding
        if big * (1.0 + k) < 1e-9 or (big >= last and big < 1e-13):
            return U3
        last = big
    return U3 if last < 1e-12 else math.nan


@_njit
def interval(u, t0, t1, lam0, lam1, tau, step0, grow, dstep):
    """The elastic log-stretch ``u`` of one branch carried from ``t0`` to ``t1`` [s] (stretch linear
    from ``lam0`` to ``lam1`` in between) on the graded Radau substeps of the module docstring."""
    h = t1 - t0
    s = (lam1 - lam0) / h  # d lambda1/dt on the interval
    done, x = 0.0, 0.0  # time and decay (integral of kappa) since the sample
    while done < h and u == u:
        la = lam0 + s * done
        e = math.exp(u)
        kappa = (2.0 * e * e + 1.0 / e) / (3.0 * tau)
        hs = (step0 if x == 0.0 else step0 * math.exp(min(x * grow, 600.0))) / kappa
        if s != 0.0:
            hs = min(hs, dstep * la / abs(s))
        if done + hs >= h * (1.0 - 1e-12):
            hs = h - done
        r1 = s / (la + s * c1 * hs)
        r2 = s / (la + s * c2 * hs)
        r3 = s / (la + s * hs)
        u = radau(u, e, r1, r2, r3, hs / tau, hs)
        done += hs
        x += kappa * hs
    return u


@_njit
def finite(t, lam, tau, u0, out, step0, grow, dstep):
    for j in range(tau.size):
        u = u0[j]
        out[j, 0] = u
        for i in range(1, t.size):
            u = interval(u, t[i - 1], t[i], lam[i - 1], lam[i], tau[j], step0, grow, dstep)
            out[j, i] = u


KERNELS = {"finite_strain": finite}
