"""Viscoelastic overstress: M Maxwell branches and a parallel damper, eq. (44) of [1].

``d xi_j/dt = (k_j / eta_j) (lambda1 - xi_j)`` and
``sigma_irr = sum_j k_j (lambda1 - xi_j) + eta_v0 d lambda1/dt``.

With ``q_j = lambda1 - xi_j`` and ``tau_j = eta_j / k_j``, a stretch that is
linear over a sample interval (slope ``s``, length ``dt``) gives the exact
update ``q(t + dt) = q(t) exp(-dt / tau) + s tau (1 - exp(-dt / tau))``.
It is stable for every ``tau / dt`` (the factor never exceeds 1) and exact
for piecewise-linear stretch, however stiff. The recurrence is affine, so it
is evaluated for all samples at once by a parallel prefix scan over the
composition of affine maps (``log2(n)`` vectorized passes), not by a Python
loop over samples.
"""

from __future__ import annotations

import numpy as np


def _affine_prefix(a, b):
    """Inclusive prefix composition of ``q -> a_n q + b_n`` along the last axis.

    Returns ``(A, B)`` with ``q_{n+1} = A_n q_0 + B_n`` (Hillis-Steele scan).
    """
    A = a.copy()
    B = b.copy()
    n = A.shape[-1]
    shift = 1
    while shift < n:
        B[..., shift:] = A[..., shift:] * B[..., :-shift] + B[..., shift:]
        A[..., shift:] = A[..., shift:] * A[..., :-shift]
        shift *= 2
    return A, B


def check_time(t, shape):
    """Check a time axis [s]: 1-D, finite, strictly increasing, matching ``shape``.

    Returns it as a float array; raises ValueError naming the first bad sample.
    """
    t = np.asarray(t, float)
    if t.ndim != 1 or t.shape != tuple(shape):
        raise ValueError(f"time and stretch must be 1-D arrays of one length, got {t.shape} and {tuple(shape)}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"time must be finite; t[{int(bad[0])}] = {float(t[bad[0]])!r}")
    dt = np.diff(t)
    if not np.all(dt > 0):
        i = int(np.flatnonzero(~(dt > 0))[0])
        raise ValueError(f"time must be strictly increasing; t[{i + 1}] = {float(t[i + 1])!r} "
                         f"follows t[{i}] = {float(t[i])!r}")
    return t


def branch_strains(t, stretch, tau, q0=None):
    """Strain ``q_j = lambda1 - xi_j`` of each Maxwell branch at every sample.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], strictly increasing.
    stretch : array_like, shape (n,)
        Axial stretch [-], taken as linear between samples.
    tau : array_like, shape (M,)
        Relaxation times ``eta_j / k_j`` [s], > 0.
    q0 : array_like, shape (M,), optional
        Branch strains at ``t[0]`` [-]; default 0 (relaxed at the start).

    Returns
    -------
    numpy.ndarray, shape (M, n)

    Notes
    -----
    Exact solution of eq. (44) in [1] for piecewise-linear stretch.
    """
    t = check_time(t, np.shape(stretch))
    lam = np.asarray(stretch, float)
    tau = np.atleast_1d(np.asarray(tau, float))[:, None]
    if not np.all(tau > 0):
        raise ValueError(f"relaxation times must be > 0, got {tau.ravel()}")
    q = np.empty((tau.shape[0], t.size))
    q[:, 0] = 0.0 if q0 is None else np.asarray(q0, float)
    if t.size < 2:
        return q
    dt = np.diff(t)
    slope = np.diff(lam) / dt
    r = dt / tau
    a = np.exp(-r)
    b = slope * tau * -np.expm1(-r)
    A, B = _affine_prefix(a, b)
    q[:, 1:] = A * q[:, :1] + B
    return q


def stretch_rate(t, stretch):
    """``d lambda1 / dt`` [1/s] at each sample: the slope of the interval that ends there.

    The first sample takes the slope of the first interval.
    """
    t = np.asarray(t, float)
    lam = np.asarray(stretch, float)
    if t.size < 2:
        return np.zeros_like(lam)
    slope = np.diff(lam) / np.diff(t)
    return np.concatenate([slope[:1], slope])


def overstress(t, stretch, k, eta, eta_v0=0.0, q0=None):
    """Viscoelastic stress ``sigma_irr`` [Pa] of eq. (44) in [1].

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], strictly increasing.
    stretch : array_like, shape (n,)
        Axial stretch [-].
    k : array_like, shape (M,)
        Branch stiffnesses ``k_vj`` [Pa].
    eta : array_like, shape (M,)
        Branch viscosities ``eta_vj`` [Pa s].
    eta_v0 : float
        Parallel damper ``eta_v0`` [Pa s].
    q0 : array_like, shape (M,), optional
        Initial branch strains [-]; default 0.

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``sum_j k_j q_j + eta_v0 d lambda1/dt``; vanishes as the rate goes to 0.
        NaN at samples whose stretch is NaN or infinite.

    Notes
    -----
    A sample without a finite stretch has no stress; the branches carry on
    across it as if the stretch were linear between its finite neighbours, so
    one lost sample does not void the rest of a run.
    """
    t = check_time(t, np.shape(stretch))
    k = np.atleast_1d(np.asarray(k, float))
    eta = np.atleast_1d(np.asarray(eta, float))
    lam = np.asarray(stretch, float)
    ok = np.isfinite(lam)
    if not ok.all():
        sigma = np.full_like(lam, np.nan)
        sigma[ok] = overstress(t[ok], lam[ok], k, eta, eta_v0, q0)
        return sigma
    sigma = np.zeros_like(lam)
    if k.size:
        sigma = k @ branch_strains(t, lam, eta / k, q0)
    if eta_v0:
        sigma = sigma + eta_v0 * stretch_rate(t, lam)
    return sigma
