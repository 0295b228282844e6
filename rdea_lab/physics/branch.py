"""Vectorized continuation of the physical equilibrium branch in one coordinate.

Under voltage control the equilibria of the 1R and 3R models are the
stationary points of the free enthalpy density (ERRATA)

    g(y) = psi(y) - K c(y),

in one free coordinate ``y`` at fixed axial stretch, where ``psi`` is the
elastic energy, ``c`` the normalized capacitance and ``K >= 0`` grows with
the voltage squared. The physical equilibrium is the local minimum of ``g``
that a quasi-static voltage ramp reaches from the unloaded state ``y0``:
along that branch ``K = h(y) = psi_y / c_y`` increases with ``y``. Where
``h`` reaches a maximum before reaching ``K`` the branch has folded and the
roll snaps through to the next stable state, if there is one in the
admissible range (a strain-stiffening material re-stabilizes); where there
is none, the voltage is past the limit point (pull-in) and the model has no
stable equilibrium to offer.

The solver brackets each sample's root by stepping ``h`` over a scan in
``y`` (stopping per sample as soon as it is bracketed, so the usual small
loads cost a few evaluations), refines it by Newton's method safeguarded by
bisection, and refines folds by golden-section search on ``h``. Every step
is a numpy operation over all the samples still in work; the Python loops
run over scan nodes and iterations, never over samples.
"""

from __future__ import annotations

import numpy as np

from .result import LIMIT_POINT, NOT_CONVERGED, OK, SNAPPED

_GOLDEN = 0.5 * (np.sqrt(5.0) - 1.0)
_EPS = np.finfo(float).eps


def follow_branch(terms, y0, y_max, K, *, pitchfork=False, n_scan=24, rtol=1e-14, max_iter=100):
    """Find, per sample, the stable equilibrium a voltage ramp reaches from ``y0``.

    Parameters
    ----------
    terms : callable
        ``terms(y, idx, second)`` returns ``(psi_y, psi_yy, c_y, c_yy)`` at
        coordinates ``y`` for the samples ``idx`` (an integer array); with
        ``second=False`` the second derivatives may be None.
    y0 : numpy.ndarray
        Unloaded equilibrium (``psi_y(y0) = 0``).
    y_max : numpy.ndarray
        End of the admissible range; no equilibrium beyond it is sought.
    K : numpy.ndarray
        Load parameter, >= 0 [same unit as psi].
    pitchfork : bool
        True when ``y0`` is stationary for every ``K`` (``c_y(y0) = 0``,
        the 3R model with ``Ri = 0``): ``y0`` stays the equilibrium until
        ``K`` reaches ``psi_yy / c_yy`` at ``y0``, where a branch bifurcates.

    Returns
    -------
    y : numpy.ndarray
        Equilibrium coordinate.
    status : numpy.ndarray of int8
        ``OK``; ``SNAPPED`` where the branch folded on the way and the
        equilibrium is the next stable state (the first minimum of ``g``
        beyond ``y0``); ``LIMIT_POINT`` where there is no stable state in
        the admissible range; ``NOT_CONVERGED``.
    K_crit : numpy.ndarray
        Load parameter at the first fold (or, without a fold, the largest
        ``h`` in range) where ``status`` is ``SNAPPED`` or ``LIMIT_POINT``;
        NaN elsewhere.

    Notes
    -----
    The equilibrium is the first root of ``g_y`` where ``g_y`` turns from
    negative to positive, i.e. the first scan node with ``h >= K``; in
    between ``g`` decreases monotonically from ``y0``. A fold is a node
    where ``h`` falls: the branch from ``y0`` ends there.
    """
    n = K.size
    y = y0.astype(float).copy()
    status = np.full(n, OK, dtype=np.int8)
    K_crit = np.full(n, np.nan)
    if pitchfork:
        _, p_yy, _, c_yy = terms(y0, np.arange(n), True)
        h_start = p_yy / c_yy
    else:
        h_start = np.zeros(n)
    idx = np.flatnonzero(K > h_start)
    if idx.size == 0:
        return y, status, K_crit

    lo = np.empty(n)
    hi = np.empty(n)
    folded = np.zeros(n, dtype=bool)
    fold_lo = np.empty(n)
    fold_hi = np.empty(n)
    fold_h = np.empty(n)
    t = (np.arange(1, n_scan + 1) / n_scan) ** 2
    y_prev2 = y0[idx].copy()
    y_prev = y0[idx].copy()
    h_prev = h_start[idx].copy()
    for k in range(n_scan):
        if idx.size == 0:
            break
        yk = y0[idx] + (y_max[idx] - y0[idx]) * t[k]
        p_y, _, c_y, _ = terms(yk, idx, False)
        h = p_y / c_y
        fell = ~(h >= h_prev) & ~folded[idx]
        if np.any(fell):
            f = idx[fell]
            folded[f] = True
            fold_lo[f] = y_prev2[fell] if k else y_prev[fell]
            fold_hi[f] = yk[fell]
            fold_h[f] = h_prev[fell]
        found = h >= K[idx]
        lo[idx[found]] = y_prev[found]
        hi[idx[found]] = yk[found]
        keep = ~found
        idx, y_prev2, y_prev, h_prev = idx[keep], y_prev[keep], yk[keep], h[keep]
    if idx.size:  # no stable state within the admissible range
        status[idx] = LIMIT_POINT
        K_crit[idx] = np.where(folded[idx], np.nan, h_prev)
    fi = np.flatnonzero(folded)
    if fi.size:
        K_crit[fi], y_top = _fold(terms, fi, fold_lo[fi], fold_hi[fi], fold_h[fi], y0[fi], pitchfork)
        # Just below a fold, h >= K holds only in a window around the maximum that
        # can be narrower than the scan step: the scan then saw h fall. Such a
        # sample has not folded; its root lies between the node before and the top.
        below = K[fi] <= K_crit[fi]
        if np.any(below):
            b = fi[below]
            folded[b] = False
            status[b] = OK
            K_crit[b] = np.nan
            lo[b] = fold_lo[b]
            hi[b] = y_top[below]

    todo = np.flatnonzero((status == OK) & (K > h_start))
    y_new, ok = _refine_root(terms, todo, lo[todo], hi[todo], K[todo], y_max[todo] - y0[todo],
                             rtol, max_iter)
    y[todo] = y_new
    status[todo[folded[todo]]] = SNAPPED
    status[todo[~ok]] = NOT_CONVERGED
    return y, status, K_crit


def _refine_root(terms, idx, lo, hi, K, scale, rtol, max_iter):
    """Newton's method on ``g_y = 0`` inside ``[lo, hi]``, bisection when it strays."""
    y = 0.5 * (lo + hi)
    out = np.empty_like(y)
    ok = np.zeros(y.size, dtype=bool)
    active = np.arange(y.size)
    tol = rtol * scale
    for _ in range(max_iter):
        if active.size == 0:
            break
        p_y, p_yy, c_y, c_yy = terms(y, idx[active], True)
        Ka = K[active]
        g1 = p_y - Ka * c_y
        g2 = p_yy - Ka * c_yy
        below = g1 < 0.0
        lo = np.where(below, y, lo)
        hi = np.where(below, hi, y)
        with np.errstate(divide="ignore", invalid="ignore"):
            y_new = y - g1 / g2
        # stop once the residual is at the rounding floor of its two terms
        # (Newton cannot improve on it; bisection would crawl): keep y itself
        floor = np.abs(g1) <= 64.0 * _EPS * (np.abs(p_y) + np.abs(Ka * c_y))
        stray = ~((y_new >= lo) & (y_new <= hi))
        y_new = np.where(floor, y, np.where(stray, 0.5 * (lo + hi), y_new))
        done = floor | (np.abs(y_new - y) <= tol[active]) | (hi - lo <= tol[active])
        out[active[done]] = y_new[done]
        ok[active[done]] = True
        keep = ~done
        active, y, lo, hi = active[keep], y_new[keep], lo[keep], hi[keep]
    out[active] = y
    return out, ok


def _fold(terms, idx, lo, hi, h_guess, y0, pitchfork, iters=80):
    """The fold: maximum of ``h`` on ``[lo, hi]`` by golden section.

    Returns the load parameter at the maximum and where it is.
    """
    K = h_guess.copy()
    y_top = lo.copy()
    if pitchfork:
        # a subcritical pitchfork folds at y0 itself: h_start is the critical load
        rest = ~((lo <= y0) & (h_guess > 0))
    else:
        rest = np.ones(idx.size, dtype=bool)
    sel = np.flatnonzero(rest)
    if sel.size == 0:
        return K, y_top
    a, b, ids = lo[sel].copy(), hi[sel].copy(), idx[sel]
    a = np.where(a <= y0[sel], a + 1e-12 * (b - a), a)  # h is 0/0 exactly at a pitchfork's y0

    def h(yy):
        p_y, _, c_y, _ = terms(yy, ids, False)
        return p_y / c_y

    c = b - _GOLDEN * (b - a)
    d = a + _GOLDEN * (b - a)
    hc, hd = h(c), h(d)
    for _ in range(iters):
        left = hc > hd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        c_new = b - _GOLDEN * (b - a)
        d_new = a + _GOLDEN * (b - a)
        # reuse the surviving interior point
        c, d = np.where(left, c_new, d), np.where(left, c, d_new)
        hc, hd = np.where(left, h(c_new), hd), np.where(left, hc, h(d_new))
    top_c = hc >= hd
    K[sel] = np.maximum(np.where(top_c, hc, hd), h_guess[sel])
    y_top[sel] = np.where(top_c, c, d)
    return K, y_top
