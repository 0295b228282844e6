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

from dataclasses import dataclass

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
    if t.size == 0:  # no samples, no strains
        return q
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


@dataclass(frozen=True)
class ViscoState:
    """Where the branches stand after the last finite sample of a block.

    Attributes
    ----------
    t : float
        Its time [s].
    stretch : float
        Its stretch [-].
    q : numpy.ndarray, shape (M,)
        Branch strains ``lambda1 - xi_j`` there [-].
    """

    t: float
    stretch: float
    q: np.ndarray


def overstress_step(t, stretch, k, eta, eta_v0=0.0, *, q0=None, state=None):
    """Viscoelastic stress ``sigma_irr`` [Pa] of eq. (44) in [1] over one block, and the state after it.

    The one composition of eq. (44) in rdea-lab: `overstress`, the twin and the
    calibration all come here.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], strictly increasing (and after ``state.t``).
    stretch : array_like, shape (n,)
        Axial stretch [-].
    k : array_like, shape (M,)
        Branch stiffnesses ``k_vj`` [Pa].
    eta : array_like, shape (M,)
        Branch viscosities ``eta_vj`` [Pa s].
    eta_v0 : float
        Parallel damper ``eta_v0`` [Pa s].
    q0 : array_like, shape (M,), optional
        Branch strains at ``t[0]`` [-] when there is no `state`; default 0 (relaxed).
    state : ViscoState, optional
        The end of the previous block: the interval from it to ``t[0]`` is
        integrated exactly too, so a series cut into blocks gives the numbers of
        the whole series (except ``eta_v0``'s rate at a first block of a single
        finite sample, which has no interval yet and reads 0, where the whole
        series takes the first interval's slope).

    Returns
    -------
    sigma : numpy.ndarray, shape (n,)
        ``sum_j k_j q_j + eta_v0 d lambda1/dt``; vanishes as the rate goes to 0.
        NaN at samples whose stretch is NaN or infinite.
    state : ViscoState or None
        At the last finite sample (`state` unchanged if there is none).

    Notes
    -----
    A sample without a finite stretch has no stress; the branches carry on
    across it as if the stretch were linear between its finite neighbours, so
    one lost sample does not void the rest of a run.
    """
    lam = np.asarray(stretch, float)
    t = check_time(t, lam.shape)
    if state is not None and not t[0] > state.t:
        raise ValueError(f"block starts at t = {float(t[0])!r}, not after the previous block's end")
    k = np.atleast_1d(np.asarray(k, float))
    eta = np.atleast_1d(np.asarray(eta, float))
    ok = np.isfinite(lam)
    tt, ll = t[ok], lam[ok]
    if state is not None:
        tt, ll = np.concatenate([[state.t], tt]), np.concatenate([[state.stretch], ll])
        q0 = state.q
    part = np.zeros(tt.size)
    q = None
    if k.size and tt.size:
        q = branch_strains(tt, ll, eta / k, q0)
        part = k @ q
    if eta_v0 and tt.size > 1:
        part = part + eta_v0 * stretch_rate(tt, ll)
    sigma = np.full(lam.shape, np.nan)
    sigma[ok] = part[1:] if state is not None else part
    if tt.size:
        state = ViscoState(float(tt[-1]), float(ll[-1]), q[:, -1].copy() if q is not None else np.zeros(0))
    return sigma, state


def overstress(t, stretch, k, eta, eta_v0=0.0, q0=None):
    """Viscoelastic stress ``sigma_irr`` [Pa] of eq. (44) in [1] over a whole series.

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
        See `overstress_step`, of which this is the one-block case.
    """
    return overstress_step(t, stretch, k, eta, eta_v0, q0=q0)[0]
