"""Independent, deliberately straightforward reference solver for the 3R model.

Written directly from Prechtl et al., Smart Mater. Struct. (2021), Section 3.1,
equations (1)-(29), with the corrections listed in /work/shared/paper/ERRATA.md:

* (25): ``R_e`` is read as ``R_o``;
* (27) row 1: ``sigma1 = l1 * (sum_j eta_j dpsi_j/dl1 + p1 dc1/dl1 + p2 dc2/dl1)
  - alpha_e1 eta_b eps E^2``;
* (27) row 3: the Maxwell term is divided by ``l2b``;
* ``E = l1 * l2b * v / L3`` and ``sigma1`` is a true (Cauchy) stress,
  ``F = sigma1 * pi (Ro^2 - Ri^2) / l1``.

Nothing here is imported from ``rdea_lab``: this file exists to check and to
benchmark the fast solver in ``rdea_lab/physics`` against a plain
``scipy.optimize.fsolve`` loop over samples.

Run ``python -m rdea_lab.reports.baseline_3r_fsolve`` for a throughput figure on the
passive-core geometry of Section 3.4.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.constants
from scipy.optimize import brentq, fsolve

EPS0 = scipy.constants.epsilon_0

__all__ = [
    "solve_3r_fsolve",
    "solve_1r_lambda2",
    "force_from_sigma1",
    "capacitance_3r",
    "psi_m",
    "dpsi_dl1",
    "dpsi_dl2",
]


# --------------------------------------------------------------------------
# Yeoh free energy (22) and its partial derivatives, (l1, l2) independent.
# --------------------------------------------------------------------------
def psi_m(l1, l2, C10, C20, C30):
    """Yeoh strain-energy density (22): sum_i C_i0 (l1^2 + l2^2 + l1^-2 l2^-2 - 3)^i."""
    J = l1**2 + l2**2 + 1.0 / (l1**2 * l2**2) - 3.0
    return C10 * J + C20 * J**2 + C30 * J**3


def _dpsi_dJ(l1, l2, C10, C20, C30):
    J = l1**2 + l2**2 + 1.0 / (l1**2 * l2**2) - 3.0
    return C10 + 2.0 * C20 * J + 3.0 * C30 * J**2


def dpsi_dl1(l1, l2, C10, C20, C30):
    """Partial derivative of psi_m w.r.t. l1 at fixed l2."""
    return _dpsi_dJ(l1, l2, C10, C20, C30) * (2.0 * l1 - 2.0 / (l1**3 * l2**2))


def dpsi_dl2(l1, l2, C10, C20, C30):
    """Partial derivative of psi_m w.r.t. l2 at fixed l1."""
    return _dpsi_dJ(l1, l2, C10, C20, C30) * (2.0 * l2 - 2.0 / (l1**2 * l2**3))


# --------------------------------------------------------------------------
# Small helpers
# --------------------------------------------------------------------------
def force_from_sigma1(sigma1, lambda1, Ri, Ro):
    """Axial force [N] from the true stress sigma1 [Pa], eq. (16): F = sigma1 pi (Ro^2 - Ri^2) / l1."""
    return np.asarray(sigma1) * math.pi * (Ro**2 - Ri**2) / np.asarray(lambda1)


def capacitance_3r(lambda1, lambda2b, C0):
    """Capacitance of the 3R model, eq. (29): C = C0 l1^2 l2b^2."""
    return C0 * np.asarray(lambda1) ** 2 * np.asarray(lambda2b) ** 2


def solve_1r_lambda2(l1, v, *, eta_b, L3, alpha_e1, C10, C20, C30, eps_r):
    """lambda2 of the 1R model (33) at one sample, by brentq.

    Solves 0 = l2 dpsi/dl2 - alpha_e1 eta_b eps (l1 l2 v / L3)^2 on
    [l1**-0.5, 10 * l1**-0.5]; at the left end (uniaxial point) dpsi/dl2 = 0, so
    the residual there is -(Maxwell stress) <= 0.
    """
    eps = EPS0 * eps_r

    def f(l2):
        E = l1 * l2 * v / L3
        return l2 * dpsi_dl2(l1, l2, C10, C20, C30) - alpha_e1 * eta_b * eps * E**2

    a = l1**-0.5
    if v == 0.0:
        return a
    return brentq(f, a, 10.0 * a, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)


# --------------------------------------------------------------------------
# The 3R system (27), corrected
# --------------------------------------------------------------------------
def solve_3r_fsolve(
    lambda1,
    voltage,
    *,
    Ri,
    Rie,
    Roe,
    Ro,
    L3,
    alpha_e1,
    C10,
    C20,
    C30,
    eps_r,
    guess="1r",
    xtol=1e-13,
):
    """Solve the corrected 3R model (27) sample by sample with scipy.optimize.fsolve.

    Parameters
    ----------
    lambda1, voltage : 1-D arrays of equal length
        Axial stretch [-] and voltage [V] of each sample.
    Ri, Rie, Roe, Ro : float
        Undeformed radii [m] (inner, inner electrode, outer electrode, outer).
    L3 : float
        Layer thickness [m].  alpha_e1 : electrode length fraction [-].
    C10, C20, C30 : float
        Yeoh coefficients [Pa].  eps_r : relative permittivity [-].
    guess : "1r", "su" or array of shape (n, 6)
        "1r": lambda2a = lambda2b = lambda2c = lambda2 of the 1R model (33) at
        that sample (brentq), p1 = p2 = 0.  "su": all lambda2 = l1**-0.5,
        p1 = p2 = 0.  An array gives (sigma1, l2a, l2b, l2c, p1, p2) per sample
        (sigma1 is ignored: row 1 of (27) is explicit; p in Pa/m).
    xtol : float
        Passed to fsolve.

    Returns
    -------
    dict of numpy arrays (length n): ``sigma1`` [Pa], ``lambda2a``,
    ``lambda2b``, ``lambda2c``, ``p1``, ``p2`` [Pa/m], ``converged`` (bool).
    For a vanished ring (see below) its lambda2 is NaN and its multiplier 0.

    Method
    ------
    Unknowns l2a, l2b, l2c, p1, p2 solve rows 2-6 of (27):

        0 = eta_a dpsi(l1,l2a)/dl2a + p1 dc1/dl2a
        0 = eta_b dpsi(l1,l2b)/dl2b + p1 dc1/dl2b + p2 dc2/dl2b - alpha eta_b eps E^2 / l2b
        0 = eta_c dpsi(l1,l2c)/dl2c + p2 dc2/dl2c
        0 = c1,   0 = c2,

    with E = l1 l2b v / L3, eps = eps0 eps_r; then row 1 gives sigma1 explicitly.
    Internally the rows are made dimensionless (stress rows / C10, constraint
    rows / Ro, multipliers p * Ro / C10) so fsolve sees O(1) numbers.

    Vanished rings: if Ri == Rie (eta_a = 0) ring a, its multiplier p1 and
    constraint c1 are dropped; likewise ring c, p2, c2 if Roe == Ro; with both
    gone the system is exactly the 1R model (33) in lambda2b.

    converged = (fsolve ier == 1) and max |rows 2-6| < 1e-9 in the scaled
    units above (stress rows / C10, constraint rows / Ro).  When fsolve stops
    with ier != 1 it is called again (at most twice) from the point it
    returned; ``converged`` uses the ier of the last call.

    Caveat (ERRATA): this is a *baseline*, not the product.  It returns
    whichever stationary point fsolve lands on from the guess.  With Ri = 0
    the all-uniaxial state (every lambda2 = l1**-0.5, i.e. r_i = 0) is ALWAYS a
    stationary point of this system, but at higher voltage it can be an energy
    maximum in the radial direction (the physical equilibrium then has
    r_i != 0).  Nothing here checks stability or picks the minimum of the
    free enthalpy; ``converged`` only means "a stationary point was found".
    """
    lambda1 = np.atleast_1d(np.asarray(lambda1, dtype=float))
    voltage = np.atleast_1d(np.asarray(voltage, dtype=float))
    if lambda1.ndim != 1 or lambda1.shape != voltage.shape:
        raise ValueError("lambda1 and voltage must be 1-D arrays of equal length")
    n = lambda1.size

    # Volume fractions (10)-(12)
    Omega = Ro**2 - Ri**2
    eta_a = (Rie**2 - Ri**2) / Omega
    eta_b = (Roe**2 - Rie**2) / Omega
    eta_c = (Ro**2 - Roe**2) / Omega
    if eta_b <= 0.0:
        raise ValueError("the active ring b must have positive volume (Roe > Rie)")
    has_a = Ri != Rie
    has_c = Roe != Ro
    eps = EPS0 * eps_r

    if isinstance(guess, str):
        if guess not in ("1r", "su"):
            raise ValueError("guess must be '1r', 'su' or an (n, 6) array")
        guess_arr = None
    else:
        guess_arr = np.asarray(guess, dtype=float)
        if guess_arr.shape != (n, 6):
            raise ValueError(f"array guess must have shape ({n}, 6)")

    out = {k: np.full(n, np.nan) for k in ("sigma1", "lambda2a", "lambda2b", "lambda2c", "p1", "p2")}
    out["converged"] = np.zeros(n, dtype=bool)

    p_scale = C10 / Ro  # multipliers are solved as p * Ro / C10

    for k in range(n):
        l1 = float(lambda1[k])
        v = float(voltage[k])

        # ---- unpack an unknown vector x = [l2a?, l2b, l2c?, p1?, p2?] ----
        def unpack(x):
            i = 0
            l2a = l2c = np.nan
            p1 = p2 = 0.0
            if has_a:
                l2a = x[i]
                i += 1
            l2b = x[i]
            i += 1
            if has_c:
                l2c = x[i]
                i += 1
            if has_a:
                p1 = x[i] * p_scale
                i += 1
            if has_c:
                p2 = x[i] * p_scale
                i += 1
            return l2a, l2b, l2c, p1, p2

        def maxwell(l2b):
            E = l1 * l2b * v / L3
            return alpha_e1 * eta_b * eps * E**2

        # Partial derivatives of the constraints (24), (25) (ERRATA: R_e -> R_o)
        def dc1(l2a, l2b):
            d_l1 = -(Rie - Ri) / (l1**2 * l2a) - (Roe - Rie) / (l1**2 * l2b)
            d_l2a = (Rie + Ri) - (Rie - Ri) / (l1 * l2a**2)
            d_l2b = -(Roe + Rie) - (Roe - Rie) / (l1 * l2b**2)
            return d_l1, d_l2a, d_l2b

        def dc2(l2b, l2c):
            d_l1 = -(Roe - Rie) / (l1**2 * l2b) - (Ro - Roe) / (l1**2 * l2c)
            d_l2b = (Roe + Rie) - (Roe - Rie) / (l1 * l2b**2)
            d_l2c = -(Ro + Roe) - (Ro - Roe) / (l1 * l2c**2)
            return d_l1, d_l2b, d_l2c

        def residual(x):
            l2a, l2b, l2c, p1, p2 = unpack(x)
            row3 = eta_b * dpsi_dl2(l1, l2b, C10, C20, C30) - maxwell(l2b) / l2b
            rows = []
            if has_a:
                _, c1_a, c1_b = dc1(l2a, l2b)
                rows.append((eta_a * dpsi_dl2(l1, l2a, C10, C20, C30) + p1 * c1_a) / C10)
                row3 += p1 * c1_b
            if has_c:
                _, c2_b, c2_c = dc2(l2b, l2c)
                row3 += p2 * c2_b
            rows.append(row3 / C10)
            if has_c:
                rows.append((eta_c * dpsi_dl2(l1, l2c, C10, C20, C30) + p2 * c2_c) / C10)
            if has_a:
                c1 = (Rie + Ri) * l2a + (Rie - Ri) / (l1 * l2a) - (Roe + Rie) * l2b + (Roe - Rie) / (l1 * l2b)
                rows.append(c1 / Ro)
            if has_c:
                c2 = (Roe + Rie) * l2b + (Roe - Rie) / (l1 * l2b) - (Ro + Roe) * l2c + (Ro - Roe) / (l1 * l2c)
                rows.append(c2 / Ro)
            return np.array(rows)

        # ---- initial guess ----
        if guess_arr is not None:
            g_l2a, g_l2b, g_l2c, g_p1, g_p2 = guess_arr[k, 1:]
        else:
            if guess == "1r":
                l2 = solve_1r_lambda2(l1, v, eta_b=eta_b, L3=L3, alpha_e1=alpha_e1,
                                      C10=C10, C20=C20, C30=C30, eps_r=eps_r)
            else:  # "su"
                l2 = l1**-0.5
            g_l2a = g_l2b = g_l2c = l2
            g_p1 = g_p2 = 0.0
        x0 = []
        if has_a:
            x0.append(g_l2a)
        x0.append(g_l2b)
        if has_c:
            x0.append(g_l2c)
        if has_a:
            x0.append(g_p1 / p_scale)
        if has_c:
            x0.append(g_p2 / p_scale)
        x0 = np.array(x0, dtype=float)

        # ---- solve rows 2-6 ----
        x, info, ier, _msg = fsolve(residual, x0, xtol=xtol, full_output=True)
        # MINPACK's hybrd reports ier = 5 ("not making good progress") when it
        # reaches the root early and round-off keeps its trust radius above
        # xtol.  Restarting from the returned point lets its first step size
        # the trust radius, so a genuine root then reports ier = 1.
        for _restart in range(2):
            if ier == 1:
                break
            x, info, ier, _msg = fsolve(residual, x, xtol=xtol, full_output=True)
        res = np.max(np.abs(residual(x)))
        l2a, l2b, l2c, p1, p2 = unpack(x)

        # ---- row 1 (explicit) ----
        s = eta_b * dpsi_dl1(l1, l2b, C10, C20, C30)
        if has_a:
            s += eta_a * dpsi_dl1(l1, l2a, C10, C20, C30) + p1 * dc1(l2a, l2b)[0]
        if has_c:
            s += eta_c * dpsi_dl1(l1, l2c, C10, C20, C30) + p2 * dc2(l2b, l2c)[0]
        sigma1 = l1 * s - maxwell(l2b)

        out["sigma1"][k] = sigma1
        out["lambda2a"][k] = l2a
        out["lambda2b"][k] = l2b
        out["lambda2c"][k] = l2c
        out["p1"][k] = p1
        out["p2"][k] = p2
        out["converged"][k] = (ier == 1) and bool(res < 1e-9)

    return out


# Geometries and material of Section 3.4 (ERRATA: ref. [36] material)
MATERIAL_SEC34 = dict(L3=48e-6, alpha_e1=1.0, C10=241e3, C20=-33.2e3, C30=20.1e3, eps_r=2.8)
GEOMETRIES_SEC34 = {
    "hollow": dict(Ri=0.86e-3, Rie=0.88e-3, Roe=1.76e-3, Ro=1.8e-3),
    "active": dict(Ri=0.0, Rie=0.088e-3, Roe=1.76e-3, Ro=1.8e-3),
    "passive": dict(Ri=0.0, Rie=0.81e-3, Roe=1.76e-3, Ro=1.8e-3),
}


def _benchmark(n=1000, geometry="passive", seed=0):
    import time

    rng = np.random.default_rng(seed)
    l1 = rng.uniform(1.0, 1.75, n)
    v = rng.uniform(0.0, 3500.0, n)
    kw = dict(GEOMETRIES_SEC34[geometry], **MATERIAL_SEC34)
    t0 = time.perf_counter()
    sol = solve_3r_fsolve(l1, v, **kw)
    dt = time.perf_counter() - t0
    print(f"{geometry} core, {n} random samples (l1 in [1, 1.75], v in [0, 3.5 kV]): "
          f"{dt:.3f} s -> {n / dt:.0f} samples/s; converged {sol['converged'].sum()}/{n}")
    return n / dt


if __name__ == "__main__":
    for _ in range(3):
        _benchmark()
