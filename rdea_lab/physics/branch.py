"""Equilibria in one free coordinate: the rising-ramp rule and the history-aware path.

Under voltage control the equilibria of the 1R, 3R and CR models are the
stationary points of the free enthalpy density (ERRATA)

    g(y) = psi(y) - K c(y),

in one free coordinate ``y`` at fixed axial stretch, where ``psi`` is the
elastic energy, ``c`` the normalized capacitance and ``K >= 0`` grows with
the voltage squared. With ``c_y > 0``, ``g_y = c_y (h(y) - K)`` where
``h = psi_y / c_y`` is the load at which ``y`` is an equilibrium: the stable
equilibria (minima of ``g``) are where ``h`` crosses ``K`` upwards, the
unstable ones where it crosses downwards, and the folds (limit points) are
the extrema of ``h``. ``h`` depends on the stretch only, not on the voltage.

Two rules pick the state:

- :func:`follow_branch`, for a single (stretch, voltage) with no history: the
  state a quasi-static voltage ramp reaches from the unloaded roll ``y0``,
  i.e. the first upward crossing of ``K`` by ``h`` beyond ``y0`` (along the
  branch ``h`` increases; where ``h`` has a maximum below ``K`` the branch
  has folded and the roll snapped through to the next stable state). It
  stops scanning each sample as soon as it is bracketed, so the usual small
  loads cost a few evaluations.
- :func:`follow_path`, for a time series: each sample's state is the local
  minimum that descent of ``g`` reaches from the previous sample's state (the
  overdamped quasi-static path), so a loop shows the hysteresis the physics
  has and a snap-through is flagged at the sample where it happens, with the
  voltage of the fold it crossed. Every sample's ``h`` is scanned over the
  whole admissible range (folds refined by golden section), all crossings
  are refined, and only the samples with more than one basin (an unstable
  equilibrium exists) are resolved in sequence.

When no stable state lies in the admissible range the sample is either
*past a limit point* (a fold of ``h`` below ``K`` was crossed and nothing
beyond it in the range reaches the fold's load again: pull-in as far as the
model can tell; the fold's voltage is reported) or *outside the solved range*
(``h`` climbs beyond any fold crossed but has not reached ``K`` at the
range's end: the branch continues beyond what the model is solved for; the
largest voltage solved in the range is reported, never as a critical
voltage).

Every step is a numpy operation over all samples still in work; Python loops
run over scan nodes and iterations, and (in a path) over the rare samples
with two basins, never over all samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from .result import LIMIT_POINT, NOT_CONVERGED, OK, OUTSIDE_RANGE, SNAPPED

_GOLDEN = 0.5 * (np.sqrt(5.0) - 1.0)
_EPS = np.finfo(float).eps
#: Regular scan: fractions ``(k / N_SCAN)**2`` of the admissible range.
N_SCAN = 24
#: The refinement's relative tolerance and iterations (every solver's and kernel's default: one value each).
RTOL = 1e-14
MAX_ITER = 100


@dataclass
class Problem:
    """One model's equilibrium problem at fixed stretches (one entry per sample).

    Attributes
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
        Load parameter, >= 0 [unit of psi].
    load : numpy.ndarray
        ``K / v**2``: a load parameter ``K`` is the voltage ``sqrt(K / load)``.
    pitchfork : bool
        True when ``y0`` is stationary for every ``K`` (``c_y(y0) = 0``, the
        3R model with ``Ri = 0``): ``y0`` stays an equilibrium, stable
        until ``K`` reaches ``psi_yy / c_yy`` at ``y0``.
    scale : float, optional
        Length of the structure near ``y0`` (e.g. a small core's radius, in
        ``y`` units): the scan adds nodes graded geometrically toward ``y0``
        from a sixteenth of it, so structure at the core's own scale is
        resolved however small the core is.
    """

    terms: Callable
    y0: np.ndarray
    y_max: np.ndarray
    K: np.ndarray
    load: np.ndarray
    pitchfork: bool = False
    scale: float | None = None
    #: ``(code, constants)`` of the compiled terms (`rdea_lab.physics.kernels`), None where there is none
    kernel: tuple | None = None
    #: the largest span ``y_max - y0`` the scale nodes are graded against (default: this problem's);
    #: a subset of a problem's samples keeps its parent's, so that it is scanned at the same nodes
    span_max: float | None = None
    #: `graded_span` once computed (not an input: `dataclasses.replace` starts afresh)
    _graded: float | None = field(default=None, init=False, repr=False, compare=False)

    def subset(self, sel) -> "Problem":
        """The samples ``sel`` (integer array) as a problem of their own, scanned at the same nodes."""
        terms = self.terms

        def sub_terms(y, idx, second):
            return terms(y, sel[idx], second)

        return Problem(sub_terms, self.y0[sel], self.y_max[sel], self.K[sel], self.load[sel], self.pitchfork,
                       self.scale, None, self.graded_span())

    def graded_span(self) -> float:
        """The span the scale nodes are graded against (see `span_max`), computed once (a solve asks for it
        twice, the scan's nodes and the free states'; each time was some 0.4 ms on 1e5 samples): a problem's
        bounds are not changed after it is made."""
        if self.span_max is not None:
            return self.span_max
        if self._graded is None:
            span = self.y_max - self.y0
            self._graded = float(np.max(span)) if span.size else 0.0
        return self._graded

    def voltage(self, K):
        """The voltage [V] of load parameters ``K`` (NaN stays NaN)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sqrt(K / self.load)

    def h_start(self, idx):
        """``h`` at ``y0``: 0, or at a pitchfork the bifurcation load ``psi_yy / c_yy``."""
        if not self.pitchfork:
            return np.zeros(idx.size)
        _, p_yy, _, c_yy = self.terms(self.y0[idx], idx, True)
        return p_yy / c_yy


def scale_offsets(problem: Problem) -> np.ndarray:
    """The offsets from ``y0`` of the scale nodes (see `scan_nodes`), increasing; empty without a scale."""
    if not problem.scale:
        return np.zeros(0)
    first = (1.0 / N_SCAN) ** 2 * problem.graded_span()
    j_max = int(np.ceil(2.0 * np.log2(max(first / problem.scale, 1.0)))) + 1
    # a probe at a thousandth of the scale first: whether h falls right after y0 (a subcritical
    # pitchfork whose window is narrower than the core) shows there as h below h(y0)
    offsets = problem.scale * np.r_[1e-3, 2.0 ** (np.arange(-8, j_max) / 2.0)]
    return offsets[offsets < first]


def scan_nodes(problem: Problem) -> np.ndarray:
    """Scan nodes per sample, ``(n, m)``, increasing, in ``(y0, y_max]``.

    ``N_SCAN`` nodes at fractions ``(k / N_SCAN)**2`` of the range and, with a
    ``scale``, nodes ``y0 + scale 2**(j/2)`` (j >= -8) below the first of them,
    led by a probe at ``y0 + scale / 1000`` (`scale_offsets`).
    """
    span = problem.y_max - problem.y0
    t = (np.arange(1, N_SCAN + 1) / N_SCAN) ** 2
    Y = problem.y0[:, None] + span[:, None] * t
    if problem.scale and span.size:
        offsets = scale_offsets(problem)
        if offsets.size:
            extra = problem.y0[:, None] + np.minimum(offsets, 0.999 * span[:, None])
            Y = np.sort(np.concatenate([extra, Y], axis=1), axis=1)
    return Y


class BranchResult(NamedTuple):
    """What :func:`follow_branch` finds, per sample (a tuple too, in this order).

    Attributes
    ----------
    y : numpy.ndarray
        Equilibrium coordinate [unit of the problem's ``y``, e.g. the hoop stretch of 1R, -];
        ``y0`` where there is none.
    status : numpy.ndarray of int8
        ``OK``; ``SNAPPED`` where the branch folded on the way and the
        equilibrium is the next stable state (the first minimum of ``g``
        beyond ``y0``); ``LIMIT_POINT`` where the branch folded and the rest
        of the range never reaches the fold's load again; ``OUTSIDE_RANGE``
        where no state lies in the range otherwise; ``NOT_CONVERGED``.
    K_crit : numpy.ndarray
        Load parameter [unit of psi] at the first fold where ``status`` is
        ``SNAPPED`` or ``LIMIT_POINT``; NaN elsewhere (:meth:`Problem.voltage`
        gives its voltage [V]).
    K_range : numpy.ndarray
        The largest load [unit of psi] solved in the range where ``status`` is
        ``OUTSIDE_RANGE``; NaN elsewhere.
    """

    y: np.ndarray
    status: np.ndarray
    K_crit: np.ndarray
    K_range: np.ndarray


def follow_branch(problem: Problem, *, rtol=RTOL, max_iter=MAX_ITER) -> BranchResult:
    """Per sample, the stable equilibrium a voltage ramp reaches from ``y0`` (no history).

    Parameters
    ----------
    problem : Problem
        The samples (independent of each other).
    rtol : float
        Relative tolerance of the refined roots and folds [-].
    max_iter : int
        Iterations of each refinement.

    Returns
    -------
    BranchResult
        ``y``, ``status``, ``K_crit``, ``K_range`` per sample (see `BranchResult`).

    Notes
    -----
    The equilibrium is the first scan node with ``h >= K``, refined between
    it and the node before (from `newton_start` where ``h`` rose at every
    node, else from the midpoint); in between ``g`` decreases monotonically
    from ``y0``. A fold is a node where ``h`` falls: the branch from ``y0`` ends
    there (refined by golden section; just below a fold ``h >= K`` may hold
    only in a window narrower than the scan step, which is then searched).
    """
    terms, y0, K = problem.terms, problem.y0, problem.K
    n = K.size
    y = y0.astype(float).copy()
    status = np.full(n, OK, dtype=np.int8)
    K_crit = np.full(n, np.nan)
    K_range = np.full(n, np.nan)
    h_start = problem.h_start(np.arange(n))
    idx = np.flatnonzero(K > h_start)
    if idx.size == 0:
        return BranchResult(y, status, K_crit, K_range)

    Y = scan_nodes(problem)
    lo = np.empty(n)
    hi = np.empty(n)
    start = np.empty(n)  # where Newton starts in [lo, hi]
    folded = np.zeros(n, dtype=bool)
    fold_lo = np.empty(n)
    fold_hi = np.empty(n)
    fold_y = np.empty(n)  # the scan node the fold's maximum is searched around
    fold_h = np.empty(n)
    # the largest h scanned (for a sample left without a state): its node and the nodes either side
    top_y, top_h, top_lo, top_hi = y0.astype(float).copy(), h_start.copy(), y0.astype(float).copy(), np.full(n, np.nan)
    y_prev2 = y0[idx].copy()
    y_prev = y0[idx].copy()
    h_prev = h_start[idx].copy()
    s_prev = np.full(idx.size, np.nan)  # slope dh/dy at the last node (unknown at y0)
    for k in range(Y.shape[1]):
        if idx.size == 0:
            break
        yk = Y[idx, k]
        p_y, p_yy, c_y, c_yy = terms(yk, idx, True)
        h = p_y / c_y
        slope = _h_slope(p_y, p_yy, c_y, c_yy)
        # h falls from the last node, or is falling at this one; or a shallow fold pair hides
        # between two nodes that both rise (a cubic Hermite fit of h falls in between)
        dip, t_dip = _hidden_dip(h_prev, s_prev, h, slope, yk - y_prev)
        fell = ~((h >= h_prev) & (slope >= 0.0)) & ~folded[idx]
        hidden = dip & ~fell & ~folded[idx]
        if np.any(hidden):  # a fit is only a hint: h must really fall at the steepest point
            hi_ = np.flatnonzero(hidden)
            y_mid = y_prev[hi_] + t_dip[hi_] * (yk[hi_] - y_prev[hi_])
            hidden[hi_] = _slope(terms, y_mid, idx[hi_]) < 0.0
        if np.any(fell):
            f = idx[fell]
            folded[f] = True
            fold_lo[f] = y_prev2[fell] if k else y_prev[fell]
            fold_hi[f] = yk[fell]
            fold_y[f] = y_prev[fell]
            fold_h[f] = h_prev[fell]
        if np.any(hidden):  # the maximum lies before the steepest fall
            f = idx[hidden]
            folded[f] = True
            fold_lo[f] = y_prev[hidden]
            fold_hi[f] = y_prev[hidden] + t_dip[hidden] * (yk[hidden] - y_prev[hidden])
            fold_y[f] = y_prev[hidden]
            fold_h[f] = h_prev[hidden]
        pending = np.isnan(top_hi[idx])
        top_hi[idx[pending]] = yk[pending]  # the node after the top so far
        new_top = h > top_h[idx]
        t = idx[new_top]
        top_y[t], top_h[t], top_lo[t], top_hi[t] = yk[new_top], h[new_top], y_prev[new_top], np.nan
        found = h >= K[idx]
        lo[idx[found]] = y_prev[found]
        hi[idx[found]] = yk[found]
        # Newton from `newton_start` where h rose at every node so far (a fold's bracket may hold more
        # than one root: from the midpoint, as ever)
        f = idx[found]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            start[f] = np.where(folded[f], 0.5 * (y_prev[found] + yk[found]),
                                newton_start(y_prev[found], yk[found], h_prev[found], h[found], s_prev[found],
                                             slope[found], K[f]))
        keep = ~found
        idx, y_prev2, y_prev, h_prev = idx[keep], y_prev[keep], yk[keep], h[keep]
        s_prev = slope[keep]
    lost = idx  # no stable state within the admissible range
    status[lost] = LIMIT_POINT
    fi = np.flatnonzero(folded)
    if fi.size:
        y_top, K_crit[fi] = _extremum(terms, fi, fold_lo[fi], fold_hi[fi], fold_y[fi], fold_h[fi],
                                      np.ones(fi.size, bool), y0[fi], problem.pitchfork)
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
            start[b] = 0.5 * (lo[b] + hi[b])
    if lost.size:
        # past a limit point where the largest load in range is a fold's (pull-in there); outside
        # the solved range where it is the range end's (the branch climbs on beyond the range)
        lost = lost[status[lost] == LIMIT_POINT]
        interior = np.isfinite(top_hi[lost])
        past, out = lost[interior], lost[~interior]
        status[out] = OUTSIDE_RANGE
        K_range[out] = top_h[out]
        K_crit[out] = np.nan
        if past.size:
            _, K_crit[past] = _extremum(terms, past, top_lo[past], top_hi[past], top_y[past], top_h[past],
                                        np.ones(past.size, bool), y0[past], problem.pitchfork)

    todo = np.flatnonzero((status == OK) & (K > h_start))
    y_new, ok = _refine_root(terms, todo, lo[todo], hi[todo], K[todo],
                             problem.y_max[todo] - y0[todo], rtol, max_iter, start=start[todo])
    y[todo] = y_new
    status[todo[folded[todo]]] = SNAPPED
    status[todo[~ok]] = NOT_CONVERGED
    return BranchResult(y, status, K_crit, K_range)


class PathResult(NamedTuple):
    """What :func:`follow_path` finds, per sample of the series (a tuple too, in this order).

    Attributes
    ----------
    y : numpy.ndarray
        Equilibrium coordinate [unit of the problem's ``y``, e.g. the hoop stretch of 1R, -];
        ``y0`` where there is none.
    status : numpy.ndarray of int8
        ``OK``; ``SNAPPED`` where the state jumped across a fold since the previous sample;
        ``LIMIT_POINT`` or ``OUTSIDE_RANGE`` where the sample has no stable state; ``NOT_CONVERGED``.
    K_crit : numpy.ndarray
        Load parameter [unit of psi] of the fold crossed (``SNAPPED``) or of the pull-in
        (``LIMIT_POINT``); NaN elsewhere (:meth:`Problem.voltage` gives its voltage [V]).
    K_range : numpy.ndarray
        The largest load [unit of psi] solved in the range where ``OUTSIDE_RANGE``; NaN elsewhere.
    end : tuple
        ``(y, label)``: the coordinate to continue from (``y_max`` where no state was found) and, if the
        last sample had none, its ``(status, K_crit)`` for the next block's ``start_label``.
    """

    y: np.ndarray
    status: np.ndarray
    K_crit: np.ndarray
    K_range: np.ndarray
    end: tuple


def follow_path(problem: Problem, start=None, *, start_label=None, origin=None, rtol=RTOL,
                max_iter=MAX_ITER) -> PathResult:
    """Per sample of a time series, the state descent of ``g`` reaches from the previous state.

    Parameters
    ----------
    problem : Problem
        Samples in time order.
    start : float, optional
        Coordinate of the state before the first sample (the previous block's
        last state); default: the unloaded roll ``y0`` of the first sample, so
        the first sample follows the rising-ramp rule of :func:`follow_branch`.
    start_label : tuple, optional
        ``(status, K_crit)`` when the previous block ended without a state
        (a run of lost samples continues with that label).
    origin : numpy.ndarray, optional
        Instead of a series: per sample, the coordinate each one descends from
        (independent samples, e.g. a state followed to another stretch).

    rtol : float
        Relative tolerance of the refined roots and folds [-].
    max_iter : int
        Iterations of each refinement.

    Returns
    -------
    PathResult
        ``y``, ``status``, ``K_crit``, ``K_range`` as :func:`follow_branch`, except that ``SNAPPED``
        marks the samples where the state jumped across a fold since the previous sample
        (``K_crit``: the load of the first fold crossed in the direction of travel), and a sample
        without a stable state is ``LIMIT_POINT`` where the highest load beyond the previous state is
        at a fold (``K_crit``: that pull-in load), ``OUTSIDE_RANGE`` where it is at the range's end (a
        run of such samples keeps the label and load of its first); ``end``: ``(y, label)``, the
        coordinate to continue from (``y_max`` where no state was found) and, if the last sample had
        none, its ``(status, K_crit)`` for ``start_label``.
    """
    terms, y0, K = problem.terms, problem.y0, problem.K
    n = K.size
    y = np.empty(n)
    status = np.full(n, OK, dtype=np.int8)
    K_crit = np.full(n, np.nan)
    K_range = np.full(n, np.nan)
    if n == 0:
        return PathResult(y, status, K_crit, K_range, (start, start_label))
    scan = _full_scan(problem)
    kx, kh, ext_y, ext_h, ext_max = scan
    # crossings of K between consecutive knots: up = stable root, down = unstable
    Kc = K[:, None]
    a_h, b_h = kh[:, :-1], kh[:, 1:]
    up = (a_h < Kc) & (b_h >= Kc)
    down = (a_h >= Kc) & (b_h < Kc)
    at_start = K <= kh[:, 0]  # y0 itself is a (boundary) minimum
    roots_lo, roots_hi, sign, owner, col = [], [], [], [], []
    for mask, s in ((up, 1.0), (down, -1.0)):
        r, c = np.nonzero(mask)
        roots_lo.append(kx[r, c])
        roots_hi.append(kx[r, c + 1])
        sign.append(np.full(r.size, s))
        owner.append(r)
        col.append(c)
    lo_, hi_, sg, own, cl = (np.concatenate(a) for a in (roots_lo, roots_hi, sign, owner, col))
    root_y, ok = _refine_root(terms, own, lo_, hi_, K[own], problem.y_max[own] - y0[own], rtol, max_iter,
                              sign=sg)
    # per sample: stable roots S (y0 first where it is one) and unstable roots U, in order
    stable = sg > 0
    n_up = np.bincount(own[stable], minlength=n)
    n_down = np.bincount(own[~stable], minlength=n)
    n_stable = n_up + at_start
    first_up = np.full(n, np.nan)
    order = np.lexsort((cl[stable], own[stable]))
    s_own, s_y = own[stable][order], root_y[stable][order]
    head = np.flatnonzero(np.r_[True, s_own[1:] != s_own[:-1]]) if s_own.size else np.array([], int)
    first_up[s_own[head]] = s_y[head]
    first_stable = np.where(at_start, y0, first_up)
    bad_root = np.zeros(n, dtype=bool)
    np.logical_or.at(bad_root, own[~ok], True)

    none = n_stable == 0
    y_end = problem.y_max
    # one basin: the state is its minimum whatever came before
    single = (n_down == 0) & ~none
    y[single] = first_stable[single]
    y[none] = y_end[none]
    lost = none.copy()
    multi = np.flatnonzero(n_down > 0)
    if origin is not None:
        origin = np.asarray(origin, float)
        if multi.size:
            S, U = _roots_by_sample(multi, own, root_y, stable, cl, at_start, y0)
            for i in multi.tolist():
                j = int(np.searchsorted(U[i], origin[i], side="right"))
                y[i] = S[i][j] if j < len(S[i]) else y_end[i]
                lost[i] = j >= len(S[i])
        multi = multi[:0]
    if multi.size:
        S, U = _roots_by_sample(multi, own, root_y, stable, cl, at_start, y0)
        prev = float(y0[0]) if start is None else float(start)
        for i in multi.tolist():  # in time order: each needs the state before it
            yp = prev if i == 0 else float(y[i - 1])
            s_i, u_i = S[i], U[i]
            j = int(np.searchsorted(u_i, yp, side="right"))  # the basin yp lies in
            if j < len(s_i):
                y[i] = s_i[j]
            else:  # above the last unstable root with no minimum beyond: out of the range
                y[i] = y_end[i]
                lost[i] = True
    if origin is not None:
        y_prev = origin
    else:
        y_prev = np.empty(n)
        y_prev[0] = float(y0[0]) if start is None else float(start)
        y_prev[1:] = y[:-1]

    # snap-through: a fold of h lies strictly between the previous state and this one
    lo_y = np.minimum(y_prev, y)
    hi_y = np.maximum(y_prev, y)
    has_ext = np.flatnonzero(np.any(np.isfinite(ext_y), axis=1))
    snapped = np.zeros(n, dtype=bool)
    if has_ext.size:
        e_y, e_h = ext_y[has_ext], ext_h[has_ext]
        rising = (y[has_ext] >= y_prev[has_ext])[:, None]
        inside = (e_y > lo_y[has_ext, None]) & (e_y < hi_y[has_ext, None])
        valid = ~lost[has_ext]
        crossed = inside & valid[:, None]
        any_c = np.any(crossed, axis=1)
        # first fold met from the previous state in the direction of travel
        dist = np.where(crossed, np.where(rising, e_y - y_prev[has_ext, None], y_prev[has_ext, None] - e_y), np.inf)
        first = np.argmin(dist, axis=1)
        rows = np.flatnonzero(any_c)
        snapped[has_ext[rows]] = True
        K_crit[has_ext[rows]] = e_h[rows, first[rows]]
    status[snapped] = SNAPPED
    # lost samples: past a limit point where the highest load beyond the previous state is a fold's
    # (pull-in there), outside the solved range where it is the range end's (the branch goes on)
    li = np.flatnonzero(lost)
    if li.size:
        ahead = np.where(kx[li] >= np.minimum(y_prev[li], problem.y_max[li])[:, None], kh[li], -np.inf)
        top = np.argmax(ahead, axis=1)
        at_end = kx[li, top] >= problem.y_max[li]
        K_top = ahead[np.arange(li.size), top]
        status[li] = np.where(at_end, OUTSIDE_RANGE, LIMIT_POINT)
        K_crit[li] = np.where(at_end, np.nan, K_top)
        K_range[li] = np.where(at_end, np.max(kh[li], axis=1), np.nan)  # the largest load solved in range
    if origin is None:  # a run of lost samples keeps the label (and fold) of its first
        run_start = lost & ~np.r_[start_label is not None, lost[:-1]]
        label_idx = np.maximum.accumulate(np.where(run_start, np.arange(n), -1))
        inherit = lost & (label_idx >= 0)
        status[inherit] = status[label_idx[inherit]]
        K_crit[inherit] = K_crit[label_idx[inherit]]
        K_range[inherit] = np.where(status[inherit] == OUTSIDE_RANGE, K_range[inherit], np.nan)
        carried = lost & (label_idx < 0)  # the run began in the previous block
        if np.any(carried):
            status[carried] = start_label[0]
            K_crit[carried] = start_label[1] if start_label[0] == LIMIT_POINT else np.nan
            K_range[carried] = np.where(start_label[0] == OUTSIDE_RANGE, K_range[carried], np.nan)
    fail = bad_root & ~lost
    status[fail] = NOT_CONVERGED
    end_label = (int(status[-1]), float(K_crit[-1])) if lost[-1] else None
    return PathResult(y, status, K_crit, K_range, (float(y[-1]), end_label))


def h_slope(p_y, p_yy, c_y, c_yy):
    """``dh/dy`` of ``h = psi_y / c_y``: ``(psi_yy c_y - psi_y c_yy) / c_y**2``; scalar or array arguments (the
    one form: the compiled kernels compile it)."""
    return (p_yy * c_y - p_y * c_yy) / (c_y * c_y)


def _h_slope(p_y, p_yy, c_y, c_yy):
    """`h_slope` of arrays, without warnings."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return h_slope(p_y, p_yy, c_y, c_yy)


def _slope(terms, y, idx):
    """``dh/dy`` at ``y`` for the samples ``idx``."""
    return _h_slope(*terms(y, idx, True))


def _hidden_dip(h_a, s_a, h_b, s_b, dy):
    """Where a cubic Hermite fit of ``h`` on an interval (values ``h``, slopes ``s`` at its ends,
    width ``dy``) has a falling stretch although both ends rise: returns (flag, t) with ``t`` in
    (0, 1) the point of steepest fall (a fold pair straddles it), NaN where there is none.

    With ``m = s dy`` and ``d = h_b - h_a`` the fit's slope is ``m0 + b t + a t**2``,
    ``b = 6 d - 4 m0 - 2 m1``, ``a = 3 m0 + 3 m1 - 6 d``: it dips below 0 inside the interval
    where ``a > 0``, ``0 < -b < 2 a`` and ``b**2 > 4 a m0``.
    """
    with np.errstate(invalid="ignore", over="ignore"):
        m0, m1, d = s_a * dy, s_b * dy, h_b - h_a
        b = 6.0 * d - 4.0 * m0 - 2.0 * m1
        a = 3.0 * m0 + 3.0 * m1 - 6.0 * d
        dip = (b < 0.0) & (-b < 2.0 * a) & (b * b > 4.0 * a * m0) & (m0 >= 0.0) & (m1 >= 0.0)
    t = np.full(np.shape(dip), np.nan)
    t[dip] = -b[dip] / (2.0 * a[dip])
    return dip, t

def _roots_by_sample(samples, own, root_y, stable, col, at_start, y0):
    """Sorted stable and unstable roots (Python lists) of each sample in ``samples``."""
    want = np.isin(own, samples)
    o, ry, st, c = own[want], root_y[want], stable[want], col[want]
    order = np.lexsort((c, o))
    o, ry, st = o[order], ry[order], st[order]
    S = {int(i): ([float(y0[i])] if at_start[i] else []) for i in samples}
    U = {int(i): [] for i in samples}
    for i, yy, s in zip(o.tolist(), ry.tolist(), st.tolist()):
        (S if s else U)[i].append(yy)
    return S, U


def _full_scan(problem: Problem):
    """``h`` over the whole range for every sample, with its extrema refined.

    ``h`` depends on the stretch only, so samples that share a stretch share
    one scan. Returns knots (nodes and extrema, sorted) ``kx, kh`` of shape
    ``(n, m)`` (padded at the end with ``y_max``), and the extrema ``ext_y,
    ext_h`` (NaN-padded) with ``ext_max`` (True for a maximum of ``h``).
    """
    terms = problem.terms
    # one scan per distinct stretch (y0 and y_max are functions of it): `rows` are the samples scanned
    _, rows, inverse = np.unique(np.stack([problem.y0, problem.y_max], axis=1), axis=0, return_index=True,
                                 return_inverse=True)
    inverse = inverse.ravel()
    y0 = problem.y0[rows]
    Y = np.concatenate([y0[:, None], scan_nodes(problem)[rows]], axis=1)
    n, m = Y.shape
    H = np.empty((n, m))
    slopes = np.full((n, m), np.nan)  # h' at the nodes
    H[:, 0] = problem.h_start(rows)
    for k in range(1, m):
        p_y, p_yy, c_y, c_yy = terms(Y[:, k], rows, True)
        H[:, k] = p_y / c_y
        slopes[:, k] = _h_slope(p_y, p_yy, c_y, c_yy)
    rising = ~(slopes < 0.0)
    dH = np.diff(H, axis=1)
    inc = dH >= 0.0
    # interior extrema at node k: the slope changes sign between intervals k-1 and k
    is_max = np.zeros((n, m), dtype=bool)
    is_min = np.zeros((n, m), dtype=bool)
    is_max[:, 1:-1] = inc[:, :-1] & ~inc[:, 1:]
    is_min[:, 1:-1] = ~inc[:, :-1] & inc[:, 1:]
    # a shallow fold pair between nodes whose values keep rising (or falling) shows in the slope at
    # the node between: falling inside a rise = a maximum before it and a minimum after it
    pair = np.zeros((n, m), dtype=bool)
    pair[:, 1:-1] = (inc[:, :-1] & inc[:, 1:] & ~rising[:, 1:-1]) | (~inc[:, :-1] & ~inc[:, 1:] & rising[:, 1:-1])
    # a subcritical pitchfork: h falls right away from y0 (a maximum at y0 itself)
    pf_max = ~inc[:, 0] if problem.pitchfork else np.zeros(n, dtype=bool)
    r, c = np.nonzero(is_max | is_min)
    lo_y, hi_y, node_y, node_h, e_is_max = Y[r, c - 1], Y[r, c + 1], Y[r, c], H[r, c], is_max[r, c]
    # ... or inside one interval whose ends both rise (a cubic Hermite fit falls in between)
    S = np.empty((n, m))
    S[:, 0] = np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        S[:, 1:] = slopes[:, 1:]
    dip, t_dip = _hidden_dip(H[:, :-1], S[:, :-1], H[:, 1:], S[:, 1:], np.diff(Y, axis=1))
    dip &= inc
    dr, dc = np.nonzero(dip)
    if dr.size:  # a fit is only a hint: h must really fall at the steepest point
        y_mid = Y[dr, dc] + t_dip[dr, dc] * (Y[dr, dc + 1] - Y[dr, dc])
        real = _slope(terms, y_mid, rows[dr]) < 0.0
        dr, dc, y_mid = dr[real], dc[real], y_mid[real]
    if dr.size:
        h_mid = H[dr, dc]  # a value on the rising side (golden section improves on it)
        r = np.concatenate([r, dr, dr])
        lo_y = np.concatenate([lo_y, Y[dr, dc], y_mid])
        hi_y = np.concatenate([hi_y, y_mid, Y[dr, dc + 1]])
        node_y = np.concatenate([node_y, Y[dr, dc], Y[dr, dc + 1]])
        node_h = np.concatenate([node_h, h_mid, H[dr, dc + 1]])
        e_is_max = np.concatenate([e_is_max, np.ones(dr.size, bool), np.zeros(dr.size, bool)])
    pr_, pc_ = np.nonzero(pair)
    if pr_.size:  # each pair: one extremum on each side of the node
        first_max = ~rising[pr_, pc_]
        r = np.concatenate([r, pr_, pr_])
        lo_y = np.concatenate([lo_y, Y[pr_, pc_ - 1], Y[pr_, pc_]])
        hi_y = np.concatenate([hi_y, Y[pr_, pc_], Y[pr_, pc_ + 1]])
        node_y = np.concatenate([node_y, Y[pr_, pc_], Y[pr_, pc_]])
        node_h = np.concatenate([node_h, H[pr_, pc_], H[pr_, pc_]])
        e_is_max = np.concatenate([e_is_max, first_max, ~first_max])
    e_y = np.empty(r.size)
    e_h = np.empty(r.size)
    if r.size:
        e_y, e_h = _extremum(terms, rows[r], lo_y, hi_y, node_y, node_h, e_is_max, y0[r], problem.pitchfork)
    # the pitchfork maximum sits at y0; place it a hair above so that a move up from y0 crosses it
    pr = np.flatnonzero(pf_max)
    r = np.concatenate([r, pr])
    e_y = np.concatenate([e_y, np.nextafter(y0[pr], np.inf)])
    e_h = np.concatenate([e_h, H[pr, 0]])
    e_is_max = np.concatenate([e_is_max, np.ones(pr.size, dtype=bool)])
    counts = np.bincount(r, minlength=n)
    e_max_n = int(counts.max()) if n else 0
    ext_y = np.full((n, e_max_n), np.nan)
    ext_h = np.full((n, e_max_n), np.nan)
    ext_max = np.zeros((n, e_max_n), dtype=bool)
    if r.size:
        order = np.argsort(r, kind="stable")
        rs = r[order]
        slot = np.arange(rs.size) - np.searchsorted(rs, rs, side="left")
        ext_y[rs, slot] = e_y[order]
        ext_h[rs, slot] = e_h[order]
        ext_max[rs, slot] = e_is_max[order]
    # knots: nodes and extrema in order of y (the pitchfork's y0 hair-extremum replaces nothing)
    kx = np.concatenate([Y, np.where(np.isfinite(ext_y), ext_y, Y[:, -1:])], axis=1)
    kh = np.concatenate([H, np.where(np.isfinite(ext_y), ext_h, H[:, -1:])], axis=1)
    order = np.argsort(kx, axis=1, kind="stable")
    kx = np.take_along_axis(kx, order, axis=1)
    kh = np.take_along_axis(kh, order, axis=1)
    return kx[inverse], kh[inverse], ext_y[inverse], ext_h[inverse], ext_max[inverse]


def _extremum(terms, idx, lo, hi, y_node, h_node, is_max, y0, pitchfork, iters=80):
    """Extremum of ``h`` on ``[lo, hi]`` by golden section: ``(y, h)`` there."""
    s = np.where(is_max, 1.0, -1.0)
    a = np.where(lo <= y0, lo + 1e-12 * (hi - lo), lo) if pitchfork else lo.copy()
    b = hi.copy()

    def f(yy):
        p_y, _, c_y, _ = terms(yy, idx, False)
        return s * (p_y / c_y)

    c = b - _GOLDEN * (b - a)
    d = a + _GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        left = fc > fd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        c_new = b - _GOLDEN * (b - a)
        d_new = a + _GOLDEN * (b - a)
        c, d = np.where(left, c_new, d), np.where(left, c, d_new)
        fc, fd = np.where(left, f(c_new), fd), np.where(left, fc, f(d_new))
    top_c = fc >= fd
    y_top = np.where(top_c, c, d)
    f_top = np.where(top_c, fc, fd)
    better = s * h_node > f_top  # the scan node itself (golden section can only improve on it)
    return np.where(better, y_node, y_top), s * np.where(better, s * h_node, f_top)


def _pick(c, a, b):
    return np.where(c, a, b)


def newton_start(lo, hi, h_lo, h_hi, s_lo, s_hi, K):
    """Where Newton's iteration starts in a bracket ``[lo, hi]`` of a rising crossing (``h(lo) < K <= h(hi)``)
    between two scan nodes where ``h`` rises: the inverse ``y(h)`` interpolated at ``K`` from the nodes'
    values and slopes ``s`` (a cubic Hermite; a quadratic where the slope at ``lo`` is not known, at
    ``y0``), or the midpoint where that is not inside the bracket. Scalars or arrays (compiled too:
    `rdea_lab.physics.kernels`).

    Any start inside a bracket with one root ends at that root; from here in fewer steps than from the
    midpoint (on the bench scene, 20000 samples, with `newton_step`'s quadratic rule: 2.0 instead of 3.6 for
    1R, 2.0 instead of 3.3 for 3R): the error of the interpolation is of the fourth order in the node spacing.
    """
    dh = h_hi - h_lo
    t = (K - h_lo) / dh
    u = t - 1.0
    cubic = lo + (hi - lo) * (t * t * (3.0 - 2.0 * t)) + dh * t * u * (u / s_lo + t / s_hi)
    quad = hi + (dh / s_hi) * u + (lo - hi + dh / s_hi) * (u * u)
    y = _pick(s_lo == s_lo, cubic, quad)
    return _pick((y >= lo) & (y <= hi), y, 0.5 * (lo + hi))


def newton_step(y, lo, hi, p_y, p_yy, c_y, c_yy, K, tol, sgn, dx_before, dn_last, g2_last):
    """One step of the refinement of a root: Newton on ``g_y = p_y - K c_y`` (``p_y ... c_yy``: the terms at
    ``y``) in the bracket ``[lo, hi]`` of a root (``sgn`` +1 where ``g_y`` rises through it, -1 where it
    falls), bisection where it leaves the bracket or does not shrink: ``(y_new, lo, hi, dx, done, dn, g2)``,
    the bracket narrowed to the side of ``y`` that keeps the sign change, ``dx = |y_new - y|``, ``dn`` that
    step if it was Newton's (inf otherwise) and ``g2`` the slope of ``g_y`` at ``y`` (the next call's
    ``dn_last`` and ``g2_last``). Scalars or arrays (compiled too: `rdea_lab.physics.kernels`).

    Newton's step is taken where it stays in the bracket and (the safeguard, see `_refine_root`) is at most
    half ``dx_before``, the step before the last (inf: no safeguard). Done where ``g_y`` is at the rounding
    floor of its two terms (finite; ``y`` kept: Newton cannot improve on it, bisection would crawl), where the step or
    the bracket is within ``tol``, where the bracket is two adjacent floats (a ``tol`` below the float
    spacing at ``y``: Newton would cycle between them), or where the iteration has converged quadratically
    and this step's own error is far below ``tol`` (the quadratic rule). That takes two Newton steps in a row
    (the last, ``dn_last``, and this one, ``d``) in the regime where Newton's model holds: the slope of
    ``g_y`` changed by at most a tenth over the last step (``|g2 - g2_last| <= 0.1 |g2|``: ``g_y`` nearly
    linear across it, not the far side of a steep rise that an overshoot lands on, where Newton crawls in
    small steps that would pass the other tests) and the step shrank a hundredfold (``d <= 1e-2 dn_last``).
    Then the error of ``y`` is about ``d``, and after the step about ``M d**2`` with ``M = d / dn_last**2``
    (``e' = M e**2``); the rule asks ``(d / dn_last)**2 d <= 1e-3 tol``. Without it the iteration took one
    more step (one more evaluation of the terms) whose own size was zero or below the float spacing at the
    root in 90 % of the bench scene's 1R roots.
    """
    g1 = p_y - K * c_y
    g2 = p_yy - K * c_yy
    below = sgn * g1 < 0.0
    lo = _pick(below, y, lo)
    hi = _pick(below, hi, y)
    y_n = y - g1 / g2
    d = abs(y_n - y)
    mid = 0.5 * (lo + hi)
    newton = (y_n >= lo) & (y_n <= hi) & ((d <= 0.5 * dx_before) | (d <= tol))
    # (an infinite g_y is no floor, though inf <= inf: an overflowing evaluation bisects)
    floor = (abs(g1) <= 64.0 * _EPS * (abs(p_y) + abs(K * c_y))) & (abs(g1) < np.inf)
    y_new = _pick(floor, y, _pick(newton, y_n, mid))
    dx = abs(y_new - y)
    dn = _pick(newton & ~floor, d, np.inf)
    ratio = dn / dn_last
    quadratic = ((dn_last < np.inf) & (ratio <= 1e-2) & (abs(g2 - g2_last) <= 0.1 * abs(g2))
                 & (ratio * ratio * dn <= 1e-3 * tol))
    done = floor | (dx <= tol) | (hi - lo <= tol) | (mid == lo) | (mid == hi) | quadratic
    return y_new, lo, hi, dx, done, dn, g2


def _refine_root(terms, idx, lo, hi, K, scale, rtol, max_iter, sign=None, start=None):
    """The root of ``g_y`` inside ``[lo, hi]``: ``(y, converged)``. `newton_step` from ``start`` (the midpoint
    by default) for up to ``max_iter`` steps; where that has not converged (Newton may wander on a bracket
    holding several roots), up to ``max_iter`` more from the middle of the bracket it narrowed, safeguarded:
    bisection wherever Newton's step is more than half the step before the last (so it shrinks).

    ``sign`` is +1 where ``g_y`` rises through the root (a minimum of ``g``:
    the default) and -1 where it falls (a maximum).
    """
    y = 0.5 * (lo + hi) if start is None else start
    tol = rtol * scale
    sgn = np.ones(y.size) if sign is None else np.asarray(sign, float)
    y, lo, hi, ok = _iterate(terms, idx, y, lo, hi, K, tol, sgn, max_iter, False)
    again = np.flatnonzero(~ok)
    if again.size:
        a_lo, a_hi = lo[again], hi[again]
        y[again], _, _, ok[again] = _iterate(terms, idx[again], 0.5 * (a_lo + a_hi), a_lo, a_hi, K[again],
                                             tol[again], sgn[again], max_iter, True)
    return y, ok


def _iterate(terms, idx, y, lo, hi, K, tol, sgn, max_iter, safeguard):
    """`newton_step` until done, at most ``max_iter`` times: ``(y, lo, hi, done)`` (the brackets as they
    ended); ``safeguard``: with the steps before the last (else inf)."""
    out = np.empty_like(y)
    lo, hi = lo.copy(), hi.copy()
    ok = np.zeros(y.size, dtype=bool)
    active = np.arange(y.size)
    a_lo, a_hi = lo, hi
    dx1 = np.full(y.size, np.inf)  # the last step and the one before it
    dx2 = np.full(y.size, np.inf)
    dn = np.full(y.size, np.inf)  # the last step, if it was Newton's (inf otherwise), and g_y's slope before it
    g2 = np.full(y.size, np.nan)
    for _ in range(max_iter):
        if active.size == 0:
            break
        p_y, p_yy, c_y, c_yy = terms(y, idx[active], True)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            y_new, a_lo, a_hi, dx, done, dn, g2 = newton_step(y, a_lo, a_hi, p_y, p_yy, c_y, c_yy, K[active],
                                                              tol[active], sgn[active], dx2, dn, g2)
        out[active[done]] = y_new[done]
        ok[active[done]] = True
        keep = ~done
        lo[active], hi[active] = a_lo, a_hi
        active, y, a_lo, a_hi, dn, g2 = active[keep], y_new[keep], a_lo[keep], a_hi[keep], dn[keep], g2[keep]
        if safeguard:
            dx2, dx1 = dx1[keep], dx[keep]
        else:
            dx2 = dx2[keep]
    out[active] = y
    return out, lo, hi, ok

