"""The reference's scans, path rule and rising-ramp rule for one sample, compiled (numba, ``cache=True``).

`rdea_lab.physics.branch.follow_path` decides a sample the certified kernel
(`rdea_lab.physics.kernels._one`) cannot (a fold, a snap, pull-in, the end of the
range) from `branch._full_scan`: ``h`` at the scan nodes, its extrema refined by
golden section, the crossings of the load refined by Newton's method, the basin
the previous state lies in; `branch.follow_branch` (the rising-ramp rule, no
history) from its scan up to the first node where ``h`` reaches the load, the first
fold's maximum and one Newton iteration. This module is that code for one sample,
step by step in the same order and the same floating-point operations (the equations
are the compiled `kernels._terms`; ``h`` alone, in a golden section, from the first
derivatives as the reference's ``terms(y, idx, False)``), so that a stepped sample
never leaves compiled code:

- `scan`: the knots ``kx, kh`` (nodes and extrema in order of ``y``) and the
  extrema ``ext_y, ext_h, ext_max`` of `branch._full_scan` (without its padding);
- `path_rule`: `branch.follow_path`'s state, status, ``K_crit`` and ``K_range`` of
  one sample coming from ``y_prev`` (a series, with the previous sample's label where
  it had no state, or an ``origin``);
- `branch_rule`: `branch.follow_branch`'s state, status, ``K_crit`` and ``K_range`` of
  one sample; `follow_branch_at` runs it on samples of a problem in blocks
  (`_branch_block`: each sample's scan, then the golden sections of the block's first
  folds in lockstep, `_golden_lanes`, then each sample's rest; bit for bit
  `branch_rule`), on all cores from `BRANCH_PARALLEL_MIN` samples. A compiled ramp
  solve gives it the samples the certified kernel leaves (`models._common`).

The scan's nodes are the reference's: ``y0``, then `branch.scan_nodes`' regular
nodes merged with the scale offsets the caller takes from `branch.scale_offsets`
(tests compare the knots with `branch._full_scan`'s on the random hard-case families).

Cost, bounded: with ``m`` nodes (``1 + N_SCAN`` plus the scale offsets, at most
``1 + 24 + 60``) the scan evaluates the terms ``m`` times, twice more per hidden dip
hinted, ``82`` times per extremum (at most ``4 m`` extrema, in practice 0-4) and at
most ``max_iter`` (100) times per crossing of the load (at most one per knot); a
3R evaluation takes about 40 ns.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

from .kernels import (_EMPTY_Q, _NO_RING, _arr, _dh, _h_start, _next_node, _psi2_first, _refine, _ring, _root, _start,
                      _table, _terms, _variants)
from .branch import MAX_ITER, RTOL
from .result import LIMIT_POINT, NOT_CONVERGED, OK, OUTSIDE_RANGE, SNAPPED

_GOLDEN = 0.5 * (np.sqrt(5.0) - 1.0)  # as `branch._GOLDEN`
_jit = numba.njit(cache=True, error_model="numpy")
_YES, _NO, _ZERO = np.bool_(True), np.bool_(False), np.int64(0)  # typed: a literal compiles a callee once more


@_jit
def nodes(y0, y_max, offsets, n_scan, Y):
    """``Y[0] = y0``, then the nodes of `branch.scan_nodes` (``offsets``: its scale offsets); returns their
    number. ``Y`` holds at least ``1 + offsets.size + n_scan``."""
    span = y_max - y0
    Y[0] = y0
    i, j, k = 1, 0, 1
    while k <= n_scan or j < offsets.size:
        reg = y0 + span * (k / n_scan) ** 2 if k <= n_scan else math.inf
        if j < offsets.size:
            ext = y0 + min(offsets[j], 0.999 * span)
            if ext <= reg:
                Y[i] = ext
                j += 1
                i += 1
                continue
        Y[i] = reg
        k += 1
        i += 1
    return i


@_jit
def _h(code, y, l1, R, Q, C10, C20, C30):
    """``h = psi_y / c_y`` from the first derivatives alone, as the reference's ``terms(y, idx, False)`` (1R, 3R:
    the same operations as their first derivatives in `_terms`; CR: `_terms`)."""
    if code == 1:
        return _psi2_first(l1, y, C10, C20, C30) / (2.0 * y)
    if code == 3:
        p_y, _, c_y, _ = _ring(y, l1, R, C10, C20, C30, False)
        return p_y / c_y
    p_y, _, c_y, _ = _terms(code, y, l1, R, Q, C10, C20, C30)
    return p_y / c_y


@_jit
def _slope(code, y, l1, R, Q, C10, C20, C30):
    p_y, p_yy, c_y, c_yy = _terms(code, y, l1, R, Q, C10, C20, C30)
    return _dh(p_y, p_yy, c_y, c_yy)


@_jit
def _extremum(code, l1, R, Q, C10, C20, C30, lo, hi, y_node, h_node, is_max, y0, pitchfork):
    """`branch._extremum` for one extremum: ``(y, h)``."""
    s = 1.0 if is_max else -1.0
    a = lo
    if pitchfork and lo <= y0:
        a = lo + 1e-12 * (hi - lo)
    b = hi
    c = b - _GOLDEN * (b - a)
    d = a + _GOLDEN * (b - a)
    fc = s * _h(code, c, l1, R, Q, C10, C20, C30)
    fd = s * _h(code, d, l1, R, Q, C10, C20, C30)
    for _ in range(80):
        if fc > fd:
            b = d
            c_new = b - _GOLDEN * (b - a)
            c, d = c_new, c
            fc, fd = s * _h(code, c_new, l1, R, Q, C10, C20, C30), fc
        else:
            a = c
            d_new = a + _GOLDEN * (b - a)
            c, d = d, d_new
            fc, fd = fd, s * _h(code, d_new, l1, R, Q, C10, C20, C30)
    if fc >= fd:
        y_top, f_top = c, fc
    else:
        y_top, f_top = d, fd
    if s * h_node > f_top:  # the scan node itself (golden section can only improve on it)
        return y_node, s * (s * h_node)
    return y_top, s * f_top


@_jit
def _less(a, b):
    """numpy's sort order: NaN last."""
    return a < b or (b != b and a == a)


@_jit
def scan(code, l1, y0, y_max, h0, R, Q, C10, C20, C30, offsets, n_scan, pitchfork, kx, kh, ext_y, ext_h,
         ext_max):
    """`branch._full_scan` for one sample: fills ``kx, kh`` (knots, sorted) and ``ext_y, ext_h, ext_max``
    (extrema, in the reference's order); returns ``(n_knots, n_ext)``. The arrays hold at least ``5 m``
    (knots) and ``4 m`` (extrema) with ``m = 1 + offsets.size + n_scan``."""
    m_cap = 1 + offsets.size + n_scan
    Y = np.empty(m_cap)
    m = nodes(y0, y_max, offsets, n_scan, Y)
    H = np.empty(m)
    S = np.empty(m)  # h' at the nodes (NaN at y0)
    H[0], S[0] = h0, math.nan
    for k in range(1, m):
        p_y, p_yy, c_y, c_yy = _terms(code, Y[k], l1, R, Q, C10, C20, C30)
        H[k] = p_y / c_y
        S[k] = _dh(p_y, p_yy, c_y, c_yy)
    # the extrema to refine, in the reference's order: node extrema, dips' maxima, dips' minima,
    # pairs' first, pairs' second, the pitchfork's
    cap = 4 * m
    lo_y, hi_y, node_y, node_h = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
    is_max = np.empty(cap, dtype=np.bool_)
    ne = 0
    for k in range(1, m - 1):
        inc_a, inc_b = H[k] - H[k - 1] >= 0.0, H[k + 1] - H[k] >= 0.0
        if inc_a != inc_b:
            lo_y[ne], hi_y[ne], node_y[ne], node_h[ne], is_max[ne] = Y[k - 1], Y[k + 1], Y[k], H[k], inc_a
            ne += 1
    n_dip = 0
    dip_c = np.empty(m)
    dip_y = np.empty(m)
    for c in range(m - 1):
        if not (H[c + 1] - H[c] >= 0.0):
            continue
        dy = Y[c + 1] - Y[c]
        m0, m1, d = S[c] * dy, S[c + 1] * dy, H[c + 1] - H[c]
        b = 6.0 * d - 4.0 * m0 - 2.0 * m1
        a = 3.0 * m0 + 3.0 * m1 - 6.0 * d
        if (b < 0.0) and (-b < 2.0 * a) and (b * b > 4.0 * a * m0) and (m0 >= 0.0) and (m1 >= 0.0):
            y_mid = Y[c] + (-b / (2.0 * a)) * (Y[c + 1] - Y[c])
            if _slope(code, y_mid, l1, R, Q, C10, C20, C30) < 0.0:  # a fit is only a hint
                dip_c[n_dip], dip_y[n_dip] = c, y_mid
                n_dip += 1
    for i in range(n_dip):
        c = int(dip_c[i])
        lo_y[ne], hi_y[ne], node_y[ne], node_h[ne], is_max[ne] = Y[c], dip_y[i], Y[c], H[c], True
        ne += 1
    for i in range(n_dip):
        c = int(dip_c[i])
        lo_y[ne], hi_y[ne], node_y[ne], node_h[ne], is_max[ne] = dip_y[i], Y[c + 1], Y[c + 1], H[c + 1], False
        ne += 1
    n_pair = 0
    pair_c = np.empty(m)
    for k in range(1, m - 1):
        inc_a, inc_b = H[k] - H[k - 1] >= 0.0, H[k + 1] - H[k] >= 0.0
        rising = not (S[k] < 0.0)
        if (inc_a and inc_b and not rising) or (not inc_a and not inc_b and rising):
            pair_c[n_pair] = k
            n_pair += 1
    for second in (False, True):
        for i in range(n_pair):
            k = int(pair_c[i])
            first_max = S[k] < 0.0
            if second:
                lo_y[ne], hi_y[ne], is_max[ne] = Y[k], Y[k + 1], not first_max
            else:
                lo_y[ne], hi_y[ne], is_max[ne] = Y[k - 1], Y[k], first_max
            node_y[ne], node_h[ne] = Y[k], H[k]
            ne += 1
    for i in range(ne):
        ext_y[i], ext_h[i] = _extremum(code, l1, R, Q, C10, C20, C30, lo_y[i], hi_y[i], node_y[i], node_h[i],
                                       is_max[i], y0, pitchfork)
        ext_max[i] = is_max[i]
    if pitchfork and m > 1 and not (H[1] - H[0] >= 0.0):  # a subcritical pitchfork: a maximum at y0
        ext_y[ne], ext_h[ne], ext_max[ne] = np.nextafter(y0, math.inf), H[0], True
        ne += 1
    # knots: nodes, then extrema (a NaN one stands at the last node), sorted stably
    for k in range(m):
        kx[k], kh[k] = Y[k], H[k]
    for i in range(ne):
        finite = abs(ext_y[i]) < math.inf
        kx[m + i] = ext_y[i] if finite else Y[m - 1]
        kh[m + i] = ext_h[i] if finite else H[m - 1]
    nk = m + ne
    for i in range(1, nk):  # insertion sort: stable, and the extrema are few
        x, h = kx[i], kh[i]
        j = i - 1
        while j >= 0 and _less(x, kx[j]):
            kx[j + 1], kh[j + 1] = kx[j], kh[j]
            j -= 1
        kx[j + 1], kh[j + 1] = x, h
    return nk, ne


@numba.njit(cache=True, error_model="numpy", inline="always")
def _own(code, i, R, xi0, x0, C10, C20, C30):
    """Sample ``i``'s constants: its ring constants ``R`` (CR: its own unloaded state and ``x0``) and its Yeoh
    coefficients (one per sample or one for all)."""
    Ri = R
    if code == 4:  # CR: the unloaded state and x0 are the sample's own
        Ri = (xi0[i], x0[i], R[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    return Ri, (C10[min(i, C10.size - 1)], C20[min(i, C20.size - 1)], C30[min(i, C30.size - 1)])


@_jit
def path_rule(code, l1, y0, y_max, K, h0, R, Q, C10, C20, C30, offsets, n_scan, pitchfork, y_prev, label,
              label_status, label_K, origin, rtol, max_iter):
    """`branch.follow_path` for one sample coming from ``y_prev`` (the state before it; ``label``: the sample
    before had no state, with ``(label_status, label_K)``; ``origin``: descent from ``y_prev`` alone, no
    label). Returns ``(y, status, K_crit, K_range, lost)``; ``y`` is ``y_max`` where ``lost``."""
    m = 1 + offsets.size + n_scan
    kx, kh = np.empty(5 * m), np.empty(5 * m)
    ext_y, ext_h = np.empty(4 * m), np.empty(4 * m)
    ext_max = np.empty(4 * m, dtype=np.bool_)
    nk, ne = scan(code, l1, y0, y_max, h0, R, Q, C10, C20, C30, offsets, n_scan, pitchfork, kx, kh, ext_y,
                  ext_h, ext_max)
    scale = y_max - y0
    # crossings of K between knots: up = a stable root, down = an unstable one, in order of y
    at_start = K <= kh[0]
    stable = np.empty(nk)
    unstable = np.empty(nk)
    n_s, n_u = 0, 0
    if at_start:
        stable[0] = y0
        n_s = 1
    bad_root = False
    for j in range(nk - 1):
        a_h, b_h = kh[j], kh[j + 1]
        up = (a_h < K) and (b_h >= K)
        down = (a_h >= K) and (b_h < K)
        if up or down:
            r, ok = _root(code, l1, R, Q, C10, C20, C30, kx[j], kx[j + 1], K, scale, rtol, max_iter,
                          1.0 if up else -1.0)
            bad_root = bad_root or not ok
            if up:
                stable[n_s] = r
                n_s += 1
            else:
                unstable[n_u] = r
                n_u += 1
    lost = False
    if n_s == 0:
        y, lost = y_max, True
    elif n_u == 0:
        y = stable[0]
    else:
        j = 0  # the basin y_prev lies in: np.searchsorted(U, y_prev, side="right")
        while j < n_u and unstable[j] <= y_prev:
            j += 1
        if j < n_s:
            y = stable[j]
        else:
            y, lost = y_max, True
    status, K_crit, K_range = OK, math.nan, math.nan
    if not lost:  # snap-through: the first fold strictly between y_prev and y in the direction of travel
        lo, hi = min(y_prev, y), max(y_prev, y)
        rising = y >= y_prev
        best = math.inf
        for i in range(ne):
            if ext_y[i] > lo and ext_y[i] < hi:
                dist = ext_y[i] - y_prev if rising else y_prev - ext_y[i]
                if dist < best:
                    best = dist
                    status, K_crit = SNAPPED, ext_h[i]
    else:  # past a limit point (the highest load ahead is a fold's) or outside the range (the range end's)
        start = min(y_prev, y_max)
        top, best = 0, -math.inf
        for j in range(nk):
            v = kh[j] if kx[j] >= start else -math.inf
            if v != v:  # np.argmax stops at the first NaN
                top, best = j, v
                break
            if j == 0 or v > best:
                top, best = j, v
        if kx[top] >= y_max:
            status = OUTSIDE_RANGE
            K_range = -math.inf
            for j in range(nk):  # np.max: NaN wins
                if kh[j] != kh[j]:
                    K_range = math.nan
                    break
                K_range = max(K_range, kh[j])
        else:
            status, K_crit = LIMIT_POINT, best
        if label and not origin:  # a run of lost samples keeps the label (and fold) of its first
            status = label_status
            K_crit = label_K if label_status == LIMIT_POINT else math.nan
            K_range = K_range if label_status == OUTSIDE_RANGE else math.nan
    if bad_root and not lost:
        status = NOT_CONVERGED
    return y, status, K_crit, K_range, lost


@_jit
def _runs(code, l1, y0, y_max, K, h0, R, xi0, x0, Q, C10, C20, C30, offsets, n_scan, pitchfork, y, ok, y_start,
          label, label_status, label_K, status, K_crit, K_range, rtol, max_iter):
    # the samples not certified (ok False), in time order, each from the state before it; returns whether
    # the last sample was lost, and its label
    lost = label
    prev = y_start
    for i in range(y.size):
        if ok[i]:
            lost, prev = False, y[i]
            continue
        Ri, C = _own(code, i, R, xi0, x0, C10, C20, C30)
        y[i], status[i], K_crit[i], K_range[i], was_lost = path_rule(
            code, l1[i], y0[i], y_max[i], K[i], h0[i], Ri, Q, C[0], C[1], C[2], offsets, n_scan, pitchfork,
            y0[i] if prev != prev else prev, lost, label_status, label_K, _NO, rtol, max_iter)
        if was_lost:
            label_status, label_K = status[i], K_crit[i]
        lost, prev = was_lost, y[i]
    return lost, label_status, label_K


def _constants(code, consts, n):
    """``(C, R, xi0, x0, Q)`` of a `~rdea_lab.physics.branch.Problem`'s kernel constants ``consts`` (``n``
    samples) as the compiled rules take them: the Yeoh coefficients as arrays (one or one per sample), the ring
    constants, CR's per-sample unloaded state and ``x0`` and its quadrature table (empty for 1R and 3R)."""
    C = tuple(np.atleast_1d(_arr(c)) for c in consts["C"])
    if code == 4:
        return C, (0.0, 0.0, consts["Lb"]) + (0.0,) * 6, _arr(consts["xi0"], (n,)), _arr(consts["x0"], (n,)), \
            _table(consts["Q"])
    return C, consts.get("R", _NO_RING), np.zeros(0), np.zeros(0), _EMPTY_Q


def follow_runs(problem, y, ok, y_start, label, status, K_crit, K_range, rtol=RTOL, max_iter=MAX_ITER):
    """`branch.follow_path` of a problem with a compiled ``kernel`` at the samples ``ok`` does not certify (the
    others keep their state ``y``): ``y``, ``status``, ``K_crit``, ``K_range`` written in place. Returns
    the path's end ``(y, label)`` as `follow_path`'s."""
    from .branch import N_SCAN, scale_offsets
    code, consts = problem.kernel
    n = y.size
    h0 = problem.h_start(np.arange(n))
    C, R, xi0, x0, Q = _constants(code, consts, n)
    has_label = label is not None
    lab_s, lab_k = label if has_label else (0, np.nan)
    start = np.nan if y_start is None else float(y_start)
    lost, lab_s, lab_k = _runs(code, _arr(consts["l1"], (n,)), _arr(problem.y0, (n,)), _arr(problem.y_max, (n,)),
                               _arr(problem.K, (n,)), _arr(h0, (n,)), tuple(float(r) for r in R), xi0, x0, Q, *C,
                               _arr(scale_offsets(problem)), N_SCAN, bool(problem.pitchfork), y, ok, start,
                               has_label, int(lab_s), float(lab_k), status, K_crit, K_range, rtol, max_iter)
    return float(y[-1]), ((int(lab_s), float(lab_k)) if lost else None)


# --- the rising-ramp rule (`branch.follow_branch`)


@_jit
def _ramp_scan(code, l1, y0, y_max, K, h0, R, Q, C10, C20, C30, offsets, n_scan):
    """`branch.follow_branch`'s scan of one sample with ``K > h0``, to the first node with ``h >= K``:
    ``(found, folded, lo, hi, start, fold_lo, fold_hi, fold_y, fold_h, top_y, top_h, top_lo, top_hi)``."""
    span = y_max - y0
    folded = False
    fold_lo, fold_hi, fold_y, fold_h = math.nan, math.nan, math.nan, math.nan
    # the largest h scanned (for a sample left without a state): its node and the nodes either side
    top_y, top_h, top_lo, top_hi = y0, h0, y0, math.nan
    y_prev2, y_prev, h_prev, s_prev = y0, y0, h0, math.nan
    lo, hi, start = math.nan, math.nan, math.nan
    found = False
    first = True
    j = 0  # next scale offset
    k = 1  # next regular node
    while k <= n_scan:
        more = j < offsets.size
        yk, j, k = _next_node(y0, span, more, offsets[j] if more else 0.0, j, k, n_scan)
        p_y, p_yy, c_y, c_yy = _terms(code, yk, l1, R, Q, C10, C20, C30)
        h = p_y / c_y
        slope = _dh(p_y, p_yy, c_y, c_yy)
        # h falls from the last node, or is falling at this one; or a shallow fold pair hides between two
        # nodes that both rise (a cubic Hermite fit of h falls in between: `branch._hidden_dip`)
        dy = yk - y_prev
        m0, m1, d = s_prev * dy, slope * dy, h - h_prev
        b = 6.0 * d - 4.0 * m0 - 2.0 * m1
        a = 3.0 * m0 + 3.0 * m1 - 6.0 * d
        dip = (b < 0.0) and (-b < 2.0 * a) and (b * b > 4.0 * a * m0) and (m0 >= 0.0) and (m1 >= 0.0)
        fell = not ((h >= h_prev) and (slope >= 0.0)) and not folded
        hidden = dip and not fell and not folded
        y_mid = math.nan
        if hidden:  # a fit is only a hint: h must really fall at the steepest point
            y_mid = y_prev + (-b / (2.0 * a)) * (yk - y_prev)
            hidden = _slope(code, y_mid, l1, R, Q, C10, C20, C30) < 0.0
        if fell:
            folded = True
            fold_lo = y_prev2 if not first else y_prev
            fold_hi, fold_y, fold_h = yk, y_prev, h_prev
        if hidden:  # the maximum lies before the steepest fall
            folded = True
            fold_lo, fold_hi, fold_y, fold_h = y_prev, y_mid, y_prev, h_prev
        if top_hi != top_hi:
            top_hi = yk  # the node after the top so far
        if h > top_h:
            top_y, top_h, top_lo, top_hi = yk, h, y_prev, math.nan
        if h >= K:
            lo, hi = y_prev, yk
            # Newton from `newton_start` where h rose at every node so far, else from the midpoint
            start = 0.5 * (y_prev + yk) if folded else _start(y_prev, yk, h_prev, h, s_prev, slope, K)
            found = True
            break
        y_prev2, y_prev, h_prev, s_prev = y_prev, yk, h, slope
        first = False
    return found, folded, lo, hi, start, fold_lo, fold_hi, fold_y, fold_h, top_y, top_h, top_lo, top_hi


@_jit
def _ramp_finish(code, l1, y0, y_max, K, R, Q, C10, C20, C30, pitchfork, rtol, max_iter, found, folded, lo, hi,
                 start, fold_lo, y_top, K_fold, top_y, top_h, top_lo, top_hi):
    """`branch.follow_branch` after the scan (`_ramp_scan`) and the first fold's maximum ``(y_top, K_fold)`` where
    it folded: ``(y, status, K_crit, K_range)``."""
    status, K_crit, K_range = OK, math.nan, math.nan
    if not found:  # no stable state within the admissible range
        status = LIMIT_POINT
    if folded:
        K_crit = K_fold
        # just below a fold h >= K holds only in a window around the maximum that can be narrower than
        # the scan step: such a sample has not folded; its root lies between the node before and the top
        if K <= K_crit:
            folded = False
            status = OK
            K_crit = math.nan
            lo, hi = fold_lo, y_top
            start = 0.5 * (lo + hi)
    if status == LIMIT_POINT:
        # past a limit point where the largest load in range is a fold's (pull-in there); outside the
        # solved range where it is the range end's (the branch climbs on beyond the range)
        if not (abs(top_hi) < math.inf):
            return y0, OUTSIDE_RANGE, math.nan, top_h
        _, K_crit = _extremum(code, l1, R, Q, C10, C20, C30, top_lo, top_hi, top_y, top_h, _YES, y0, pitchfork)
        return y0, LIMIT_POINT, K_crit, math.nan
    y, ok = _refine(code, l1, R, Q, C10, C20, C30, start, lo, hi, K, y_max - y0, rtol, max_iter, 1.0)
    if not ok:
        status = NOT_CONVERGED
    elif folded:
        status = SNAPPED
    return y, status, K_crit, K_range


@_jit
def branch_rule(code, l1, y0, y_max, K, h0, R, Q, C10, C20, C30, offsets, n_scan, pitchfork, rtol, max_iter):
    """`branch.follow_branch` for one sample: ``(y, status, K_crit, K_range)``, the same steps in the same
    order (``h0``: `branch.Problem.h_start`; ``offsets``: `branch.scale_offsets` of the problem)."""
    if not (K > h0):
        return y0, OK, math.nan, math.nan
    found, folded, lo, hi, start, fold_lo, fold_hi, fold_y, fold_h, top_y, top_h, top_lo, top_hi = _ramp_scan(
        code, l1, y0, y_max, K, h0, R, Q, C10, C20, C30, offsets, n_scan)
    y_top, K_fold = math.nan, math.nan
    if folded:
        y_top, K_fold = _extremum(code, l1, R, Q, C10, C20, C30, fold_lo, fold_hi, fold_y, fold_h, _YES, y0,
                                  pitchfork)
    return _ramp_finish(code, l1, y0, y_max, K, R, Q, C10, C20, C30, pitchfork, rtol, max_iter, found, folded, lo,
                        hi, start, fold_lo, y_top, K_fold, top_y, top_h, top_lo, top_hi)


@_jit
def _h_lanes(code, n, X, L1, R, C10, C20, C30, F):
    """``F[a] = h(X[a])`` at stretch ``L1[a]`` for ``a < n`` (1R, 3R), as `_h`: one loop the compiler vectorizes."""
    if code == 1:
        for a in range(n):
            F[a] = _psi2_first(L1[a], X[a], C10, C20, C30) / (2.0 * X[a])
    else:
        for a in range(n):
            p_y, _, c_y, _ = _ring(X[a], L1[a], R, C10, C20, C30, False)
            F[a] = p_y / c_y


@_jit
def _golden_lanes(code, n, G, R, C10, C20, C30, left):
    """`_extremum`'s golden section for a maximum (``s = 1``) in lanes ``a < n`` in lockstep, the same steps:
    ``G[0], G[1]``: the brackets' ends ``a, b`` (a pitchfork's ``a`` moved as `_extremum` moves it), ``G[2]``
    the stretches; leaves ``c, d, f(c), f(d)`` in ``G[3:7]`` (``G[7], G[8]``: scratch)."""
    A, B, L1, C, D, FC, FD, X, F = G[0], G[1], G[2], G[3], G[4], G[5], G[6], G[7], G[8]
    for a in range(n):
        C[a] = B[a] - _GOLDEN * (B[a] - A[a])
        D[a] = A[a] + _GOLDEN * (B[a] - A[a])
    _h_lanes(code, n, C, L1, R, C10, C20, C30, FC)
    _h_lanes(code, n, D, L1, R, C10, C20, C30, FD)
    for _ in range(80):
        for a in range(n):
            if FC[a] > FD[a]:
                B[a] = D[a]
                x = B[a] - _GOLDEN * (B[a] - A[a])
                D[a], C[a], FD[a] = C[a], x, FC[a]
                left[a] = True
            else:
                A[a] = C[a]
                x = A[a] + _GOLDEN * (B[a] - A[a])
                C[a], D[a], FC[a] = D[a], x, FD[a]
                left[a] = False
            X[a] = x
        _h_lanes(code, n, X, L1, R, C10, C20, C30, F)
        for a in range(n):
            if left[a]:
                FC[a] = F[a]
            else:
                FD[a] = F[a]


#: Samples of a block of `_branch_block`: their first folds' golden sections run in lockstep.
LANES = 64


@_jit
def _branch_block(code, sel, t0, t1, l1, y0, y_max, K, R, xi0, x0, Q, C10, C20, C30, offsets, n_scan, pitchfork,
                  rtol, max_iter, y, status, K_crit, K_range):
    """`branch_rule` of the samples ``sel[t0:t1]``: each sample's scan (`_ramp_scan`), then the golden sections of
    their first folds in lockstep (`_golden_lanes`; CR's, and a design study's per-sample materials, one by one
    by `_extremum`), then each sample's rest (`_ramp_finish`): the same steps, so the same numbers bit for bit."""
    nl = t1 - t0
    S = np.empty((nl, 13))  # the scans' results; S[., 0] < 0: decided before the scan
    G = np.empty((9, nl))
    left = np.empty(nl, np.bool_)
    lane = np.empty(nl, np.int64)
    top = np.full((nl, 2), math.nan)  # (y_top, K_fold) of the first fold
    lanes = code != 4 and C10.size == 1 and C20.size == 1 and C30.size == 1
    ng = _ZERO
    for t in range(t0, t1):
        i = sel[t]
        Ri, C = _own(code, i, R, xi0, x0, C10, C20, C30)
        h0 = _h_start(code, y0[i], l1[i], Ri, Q, C[0], C[1], C[2], pitchfork)
        r = t - t0
        if not (K[i] > h0):
            y[t], status[t], K_crit[t], K_range[t] = y0[i], OK, math.nan, math.nan
            S[r, 0] = -1.0
            continue
        found, folded, lo, hi, start, fold_lo, fold_hi, fold_y, fold_h, top_y, top_h, top_lo, top_hi = _ramp_scan(
            code, l1[i], y0[i], y_max[i], K[i], h0, Ri, Q, C[0], C[1], C[2], offsets, n_scan)
        S[r, 0], S[r, 1], S[r, 2], S[r, 3], S[r, 4] = 1.0 if found else 0.0, 1.0 if folded else 0.0, lo, hi, start
        S[r, 5], S[r, 6], S[r, 7], S[r, 8] = fold_lo, fold_hi, fold_y, fold_h
        S[r, 9], S[r, 10], S[r, 11], S[r, 12] = top_y, top_h, top_lo, top_hi
        if folded:  # the fold's maximum
            if lanes:
                lo_, hi_ = fold_lo, fold_hi
                G[0, ng] = lo_ + 1e-12 * (hi_ - lo_) if pitchfork and lo_ <= y0[i] else lo_
                G[1, ng], G[2, ng] = hi_, l1[i]
                lane[ng] = r
                ng += 1
            else:
                top[r, 0], top[r, 1] = _extremum(code, l1[i], Ri, Q, C[0], C[1], C[2], fold_lo, fold_hi, fold_y,
                                                 fold_h, _YES, y0[i], pitchfork)
    if ng:
        _golden_lanes(code, ng, G, R, C10[0], C20[0], C30[0], left)
        for g in range(ng):  # `_extremum`'s end: the better of c and d, or the scan node itself
            r = lane[g]
            y_top, f_top = (G[3, g], G[5, g]) if G[5, g] >= G[6, g] else (G[4, g], G[6, g])
            if S[r, 8] > f_top:
                y_top, f_top = S[r, 7], 1.0 * (1.0 * S[r, 8])
            top[r, 0], top[r, 1] = y_top, 1.0 * f_top
    for t in range(t0, t1):
        r = t - t0
        if S[r, 0] < 0.0:
            continue
        i = sel[t]
        Ri, C = _own(code, i, R, xi0, x0, C10, C20, C30)
        y[t], status[t], K_crit[t], K_range[t] = _ramp_finish(
            code, l1[i], y0[i], y_max[i], K[i], Ri, Q, C[0], C[1], C[2], pitchfork, rtol, max_iter, S[r, 0] > 0.0,
            S[r, 1] > 0.0, S[r, 2], S[r, 3], S[r, 4], S[r, 5], top[r, 0], top[r, 1], S[r, 9], S[r, 10], S[r, 11],
            S[r, 12])


def _branch_loop(code, sel, l1, y0, y_max, K, R, xi0, x0, Q, C10, C20, C30, offsets, n_scan, pitchfork, rtol,
                 max_iter, y, status, K_crit, K_range):
    m = sel.size
    for c in prange((m + LANES - 1) // LANES):
        _branch_block(code, sel, c * LANES, min(m, (c + 1) * LANES), l1, y0, y_max, K, R, xi0, x0, Q, C10, C20, C30,
                      offsets, n_scan, pitchfork, rtol, max_iter, y, status, K_crit, K_range)


def _branch_one_loop(code, sel, l1, y0, y_max, K, R, xi0, x0, Q, C10, C20, C30, offsets, n_scan, pitchfork, rtol,
                     max_iter, y, status, K_crit, K_range):
    for t in prange(sel.size):
        i = sel[t]
        Ri, C = _own(code, i, R, xi0, x0, C10, C20, C30)
        h0 = _h_start(code, y0[i], l1[i], Ri, Q, C[0], C[1], C[2], pitchfork)
        y[t], status[t], K_crit[t], K_range[t] = branch_rule(code, l1[i], y0[i], y_max[i], K[i], h0, Ri, Q, C[0],
                                                             C[1], C[2], offsets, n_scan, pitchfork, rtol, max_iter)


_branch = _variants(_branch_loop)
_branch_one = _variants(_branch_one_loop)
#: A sample the certified kernel leaves costs some 3-5 us (a scan to its fold and beyond, 80 golden-section steps,
#: Newton's), some 30 certified samples' worth: calls of this many run on all cores (`kernels._parallel`).
BRANCH_PARALLEL_MIN = 128


def follow_branch_at(problem, sel, rtol=RTOL, max_iter=MAX_ITER, one_by_one=False):
    """`branch.follow_branch` of ``problem.subset(sel)`` (a problem with a compiled ``kernel``; ``sel`` an integer
    array): `branch.BranchResult` of the samples ``sel``. The samples run in blocks (`_branch_block`);
    ``one_by_one``: each by `branch_rule` (the same numbers, bit for bit; the tests' check of the blocks)."""
    from .branch import N_SCAN, BranchResult, scale_offsets
    from .kernels import PARALLEL_MIN, _parallel

    code, consts = problem.kernel
    n = problem.K.size
    sel = np.ascontiguousarray(sel, dtype=np.int64)
    C, R, xi0, x0, Q = _constants(code, consts, n)
    m = sel.size
    y, status, K_crit, K_range = np.empty(m), np.empty(m, np.int8), np.empty(m), np.empty(m)
    par = int(m >= BRANCH_PARALLEL_MIN and _parallel(PARALLEL_MIN))
    (_branch_one if one_by_one else _branch)[par](
        code, sel, _arr(consts["l1"], (n,)), _arr(problem.y0, (n,)), _arr(problem.y_max, (n,)), _arr(problem.K, (n,)),
        tuple(float(r) for r in R), xi0, x0, Q, *C, _arr(scale_offsets(problem)), N_SCAN, bool(problem.pitchfork), rtol,
        max_iter, y, status, K_crit, K_range)
    return BranchResult(y, status, K_crit, K_range)
