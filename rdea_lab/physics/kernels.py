"""Compiled kernels of the hot paths (numba, ``cache=True``), with the numpy code as reference and fallback.

The equations are not written again here: the plain functions of the model
modules that state them (`yeoh.psi2_terms`, `su.basis`, `yeoh.slope`,
`three_ring.ring_terms`, `continuum.node_terms`) are compiled as they are
(:func:`_jit` re-binds their helpers to compiled ones). What is compiled is
the work around them, fused per sample with no temporaries:

- `su_state`: the SU stress, hoop stretch and capacitance (eqs. (39), (41)).
- `branch_roots`: the 1R / 3R / CR equilibrium of one sample, *certified*:
  ``h = psi_y / c_y`` is scanned at the reference solver's own nodes
  (:func:`rdea_lab.physics.branch.scan_nodes`) and the root is refined by its
  own Newton iteration (`branch._refine_root`: `branch.newton_step` compiled, with
  its safeguarded second pass, from `branch.newton_start` on the ramp rule, as
  `branch.follow_branch`), but a sample is accepted only
  where ``h`` rises strictly at every node scanned (its slope > 0, no value
  falls, no hidden dip of the cubic fit between nodes): one basin, no fold,
  so the state is the one root whatever the history. Every other sample (a
  fold, a snap, pull-in, outside the range, not converged, NaN) goes back to
  the reference's rule (compiled step by step in `scan_kernel`: its ramp rule
  and its path rule), so the hard cases are the reference's by
  construction. With ``whole=False`` (the rising-ramp rule) the scan stops at
  the bracketing node, as the reference's does; with ``whole=True`` (a path)
  it covers the whole range, which certifies the sample's single basin.
  The samples are scanned in blocks (`_scan_block`): node by node, the terms
  of every sample of the block still scanning in one vectorized loop
  (`_terms_block`), then each sample's steps, the same functions as the
  one-sample scan `_one` (the step kernel's) takes, so the same certificates
  and roots to the bit.
- `linear_strains`: eq. (44)'s exact update as the sequential recurrence, its coefficients
  (`viscoelastic._linear_update`) computed once per distinct interval length.
- `su_solve`: what a whole SU solve computes up front (the tension, status and convergence, the inputs
  checked) in one pass, into one block of memory for every field; `su_fields` the fields computed when
  first read (every field at the state stretch in one pass, then the slack rolls' free states, `su_free`).
- `su_linear_residual`: a calibration run's scaled force errors under eq. (44)'s linear law in one pass
  (`rdea_lab.physics.models.su.residual_pass`).
- `free_stretch`: the reference `free_state`'s bracketing and Illinois iteration for one sample (the
  step kernel's and `ring_kernels`' slack states), one step at a time (`_free_step`: the one compiled
  form of a step); `_su_free_lanes` takes the same steps for 16 SU samples in lockstep. `free_check` is
  the reference's final check (`models._common.free_check`) compiled.

Importing this module imports numba and loads the cached machine code
(a fraction of a second to seconds); the first call in a fresh install compiles (about 25 s for
every kernel, measured by ``rdea-lab bench``: ``compile_s``). numba checks a
cached function only against its own file, so a kernel that calls an
equation from another module would keep an old copy of it after an edit:
`_check_cache` clears the physics package's numba cache whenever any of its
sources changed. Set ``RDEA_LAB_KERNELS=numpy`` to run the reference everywhere.
"""

from __future__ import annotations

import math
import os
import threading
import time
import types

# numba's OpenMP threads (libgomp) spin after each parallel loop by default, on the cores the next pass needs: the
# passes after a parallel loop waited for them (then the ring models' fields on two Python threads), a 3R call of
# 1e5 samples 5-40 % slower (`benchmarks/ab_scenes.py`). Waiting threads sleep instead, unless the process says
# otherwise. The setting is the process's (its child processes and any other OpenMP runtime read it too) and is
# read when libgomp is first loaded in the process (here: numba's first parallel loop, unless another library
# loaded it before).
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numba  # noqa: E402
import numpy as np  # noqa: E402
from numba import prange  # noqa: E402

from . import branch, viscoelastic, yeoh  # noqa: E402
from .models import _common, continuum, su, three_ring  # noqa: E402


def _check_cache():
    """Clear the numba cache of `rdea_lab.physics` when any of its sources differs from the last build's."""
    import hashlib
    from pathlib import Path

    root = Path(__file__).resolve().parent
    sources = sorted(root.rglob("*.py"))
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()
    stamp = root / "__pycache__" / "kernels.sources.sha256"
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        for f in list(root.rglob("__pycache__/*.nbi")) + list(root.rglob("__pycache__/*.nbc")):
            f.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(digest)
    except OSError:  # a read-only install: numba then compiles in memory or its own cache dir
        pass


_check_cache()


def _jit(func, parallel=False, inline="never", **deps):
    """``func`` compiled, its global helpers ``deps`` replaced by their compiled forms (one source);
    ``inline="always"`` inlines it at numba's level into its callers (constant arguments fold)."""
    scope = dict(func.__globals__)
    scope.update(deps)
    clone = types.FunctionType(func.__code__, scope, func.__name__, func.__defaults__, func.__closure__)
    clone.__module__, clone.__qualname__, clone.__doc__ = func.__module__, func.__qualname__, func.__doc__
    return numba.njit(cache=True, error_model="numpy", parallel=parallel, inline=inline)(clone)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _pick(c, a, b):
    return a if c else b


_parts = _jit(yeoh._psi2_parts)
_psi2 = _jit(yeoh.psi2_terms, _psi2_parts=_parts)
_psi2_first = _jit(yeoh.psi2_first, _psi2_parts=_parts)
_slope = _jit(yeoh.slope)
_basis = _jit(su.basis)
_radius = _jit(three_ring._radius)
_ring = _jit(three_ring.ring_terms, inline="always", _radius=_radius, psi2_terms=_psi2, psi2_first=_psi2_first)
_node = _jit(continuum.node_terms, inline="always", slope=_slope)
_invariant = _jit(yeoh._invariant_terms, inline="always", _where=_pick)
_gradient = _jit(yeoh.gradient_terms, inline="always", _invariant_terms=_invariant,
                 gradient_from=_jit(yeoh.gradient_from, inline="always", slope=_slope))
_radii = _jit(three_ring.radii)
_state3 = _jit(three_ring.ring_state, ring_geometry=_jit(three_ring.ring_geometry, radii=_radii),
               ring_stress=_jit(three_ring.ring_stress), gradient_terms=_gradient)
_fields3 = _jit(three_ring.ring_fields, inline="always", ring_state=_state3, fields_from=_jit(three_ring.fields_from))

#: Model codes of `branch_roots`.
CODES = {"1r": 1, "3r": 3, "cr": 4}
_EPS = float(np.finfo(float).eps)
_NO_RING = (0.0,) * 9


@numba.njit(cache=True, error_model="numpy", inline="always")
def _terms1(y, l1, C10, C20, C30):
    p, pp = _psi2(l1, y, C10, C20, C30)
    return p, pp, 2.0 * y, 2.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _opening(y, xi0, l1):
    """CR's ``(A, B)``: the opening ``A = y**2 - xi0**2`` and ``B = l1 A``."""
    A = (y - xi0) * (y + xi0)
    return A, l1 * A


@numba.njit(cache=True, error_model="numpy", inline="always")
def _cr_sums(y, l1, p_A, p_AA1, p_AA2, Lb):
    """CR's ``(psi_y, psi_yy, c_y, c_yy)`` from the quadrature sums of `_node`'s three terms."""
    p_AA = p_AA1 + 2.0 * l1 * p_AA2
    return 2.0 * y * p_A, 4.0 * y * y * p_AA + 2.0 * p_A, 2.0 * Lb * y, 2.0 * Lb


@numba.njit(cache=True, error_model="numpy")
def _terms(code, y, l1, R, Q, C10, C20, C30):
    """``(psi_y, psi_yy, c_y, c_yy)`` of model ``code`` at one sample (see `CODES`)."""
    if code == 1:
        return _terms1(y, l1, C10, C20, C30)
    if code == 3:
        return _ring(y, l1, R, C10, C20, C30, True)
    # CR: Q = (s, w / s, w / s**2, w) of the quadrature nodes; R = (xi0, x0, Lb, ...)
    A, B = _opening(y, R[0], l1)
    x0 = R[1]
    p_A = 0.0
    p_AA1 = 0.0
    p_AA2 = 0.0
    for j in range(Q.shape[1]):
        a1, a2, a3 = _node(A, B, x0, Q[0, j], C10, C20, C30, True)
        p_A += a1 * Q[1, j]
        p_AA1 += a2 * Q[2, j]
        p_AA2 += a3 * Q[3, j]
    return _cr_sums(y, l1, p_A, p_AA1, p_AA2, R[2])


@numba.njit(cache=True, error_model="numpy")
def _terms_block(code, na, W, R, Q, C10, C20, C30):
    """`_terms` at ``y = W[6, a]`` for ``a < na`` (stretch ``W[7, a]``; CR: ``xi0 = W[8, a]``, ``x0 = W[9, a]``,
    ``Lb = R[2]``) into rows 10-13 of ``W`` (rows 14, 15: CR's scratch). One loop over the samples (for CR,
    one per quadrature node) that the compiler vectorizes: the same operations in the same order as
    `_terms`, so the same bits (no fastmath). (One array: each array argument of a call costs two atomic
    reference counts.)"""
    if code == 1:
        for a in range(na):
            W[10, a], W[11, a], W[12, a], W[13, a] = _terms1(W[6, a], W[7, a], C10, C20, C30)
    elif code == 3:
        for a in range(na):
            W[10, a], W[11, a], W[12, a], W[13, a] = _ring(W[6, a], W[7, a], R, C10, C20, C30, True)
    else:
        for a in range(na):
            W[10, a] = 0.0
            W[14, a] = 0.0
            W[15, a] = 0.0
        for j in range(Q.shape[1]):
            s, w1, w2, w3 = Q[0, j], Q[1, j], Q[2, j], Q[3, j]
            for a in range(na):
                A, B = _opening(W[6, a], W[8, a], W[7, a])
                a1, a2, a3 = _node(A, B, W[9, a], s, C10, C20, C30, True)
                W[10, a] += a1 * w1
                W[14, a] += a2 * w2
                W[15, a] += a3 * w3
        Lb = R[2]
        for a in range(na):
            W[10, a], W[11, a], W[12, a], W[13, a] = _cr_sums(W[6, a], W[7, a], W[10, a], W[14, a], W[15, a], Lb)


# --- the scan's steps, shared by the one-sample scan (`_one`) and the batched one (`_scan_block`)
_GO, _FALL, _DIP, _CROSS = 0, 1, 2, 3


@numba.njit(cache=True, error_model="numpy", inline="always")
def _begin(span, K, h0, whole):
    """The certificate decided before any node (0 or 1, the state ``y0``), or -1: scan."""
    if not (span > 0.0) or not (K == K) or not (h0 == h0):
        return 0
    if not (K > h0) and not whole:
        return 1
    return -1


@numba.njit(cache=True, error_model="numpy", inline="always")
def _next_node(y0, span, more, off, j, k, n_scan):
    """``(y, j, k)``: the next scan node after ``j`` scale offsets and ``k - 1`` regular nodes (`branch.scan_nodes`'
    merge; the scan ends when ``k > n_scan``); ``more``: whether offset ``j`` exists, ``off`` its value. (Scalars:
    an array argument costs two atomic reference counts per node, more than the node's terms.)"""
    reg = y0 + span * (k / n_scan) ** 2
    if more:
        ext = y0 + min(off, 0.999 * span)
        if ext <= reg:
            return ext, j + 1, k
    return reg, j, k + 1


_dh = _jit(branch.h_slope, inline="always")


@numba.njit(cache=True, error_model="numpy", inline="always")
def _h_slope(p_y, p_yy, c_y, c_yy):
    """``h = psi_y / c_y`` and its slope in ``y`` (`branch.h_slope`)."""
    return p_y / c_y, _dh(p_y, p_yy, c_y, c_yy)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _verdict(y_prev, h_prev, s_prev, y, h, slope, K):
    """A scan node's verdict: `_FALL` (``h`` not rising), `_DIP` (the reference's hidden-dip hint: a cubic
    Hermite fit falls between two rising nodes), `_CROSS` (``h >= K``) or `_GO`."""
    if not (slope > 0.0 and h >= h_prev):
        return _FALL
    dy = y - y_prev
    m0, m1, d = s_prev * dy, slope * dy, h - h_prev
    b = 6.0 * d - 4.0 * m0 - 2.0 * m1
    a = 3.0 * m0 + 3.0 * m1 - 6.0 * d
    if (b < 0.0) and (-b < 2.0 * a) and (b * b > 4.0 * a * m0) and (m0 >= 0.0) and (m1 >= 0.0):
        return _DIP
    if h >= K:
        return _CROSS
    return _GO


#: `branch.newton_step`: one step of the refinement of a root, ``(y_new, lo, hi, dx, done, dn, g2)`` (`_refine`,
#: `_guarded` and `_newton_lanes`).
_newton = _jit(branch.newton_step, inline="always", _pick=_pick)


@numba.njit(cache=True, error_model="numpy")
def _newton_lanes(n, T, done):
    """One `_newton` step of each lane ``a < n`` of `_scan_block`'s refinement. ``T``: its lane rows; the step
    reads the terms ``T[10:14]``, the load ``T[18]`` and the tolerance ``T[19]``, and updates the iterate ``T[6]``,
    the bracket ``T[16:18]`` and the last Newton step and slope ``T[21:23]`` in place; ``done[a]``: the lane's
    step converged. Its own loop, with nothing else in it, so that the compiler vectorizes it (it did not inside
    `_scan_block`'s loop, which also keeps the lanes' results)."""
    for a in range(n):
        y_new, T[16, a], T[17, a], _, done[a], T[21, a], T[22, a] = _newton(
            T[6, a], T[16, a], T[17, a], T[10, a], T[11, a], T[12, a], T[13, a], T[18, a], T[19, a], 1.0, np.inf,
            T[21, a], T[22, a])
        T[6, a] = y_new


_GOLDEN = 0.5 * (np.sqrt(5.0) - 1.0)


@numba.njit(cache=True, error_model="numpy")
def _above(code, l1, y0, span, K, h0, R, Q, C10, C20, C30, offsets, n_scan, pitchfork):
    """Whether ``h`` stays above ``K <= h(y0)`` over the whole range though it is not monotone: the
    reference's knots (the nodes and its golden-section minima, `branch._full_scan`) all above ``K``, so
    ``y0`` is the one state and no root exists. Shapes it refines otherwise (a fold pair at one node, a
    hidden dip) are left to the reference."""
    m = offsets.size + n_scan + 1
    Y = np.empty(m)
    H = np.empty(m)
    S = np.empty(m)
    Y[0], H[0], S[0] = y0, h0, np.nan
    j, k, i = 0, 1, 1
    while k <= n_scan:
        more = j < offsets.size
        Y[i], j, k = _next_node(y0, span, more, offsets[j] if more else 0.0, j, k, n_scan)
        p_y, p_yy, c_y, c_yy = _terms(code, Y[i], l1, R, Q, C10, C20, C30)
        H[i], S[i] = _h_slope(p_y, p_yy, c_y, c_yy)
        if not (H[i] > K) or S[i] != S[i]:
            return False
        i += 1
    margin = K + 1e-9 * abs(K) + 1e-300
    for i in range(1, m):
        inc_b = H[i] - H[i - 1] >= 0.0
        # a hidden dip between two rising nodes (the reference refines it): not ours
        dy = Y[i] - Y[i - 1]
        m0, m1, d = S[i - 1] * dy, S[i] * dy, H[i] - H[i - 1]
        b = 6.0 * d - 4.0 * m0 - 2.0 * m1
        a = 3.0 * m0 + 3.0 * m1 - 6.0 * d
        if inc_b and (b < 0.0) and (-b < 2.0 * a) and (b * b > 4.0 * a * m0) and (m0 >= 0.0) and (m1 >= 0.0):
            return False
        if i == m - 1:
            break
        inc_a = H[i + 1] - H[i] >= 0.0
        rising = not (S[i] < 0.0)
        if (inc_b and inc_a and not rising) or (not inc_b and not inc_a and rising):
            return False  # a fold pair at one node
        if not inc_b and inc_a:  # an interior minimum near node i: golden section as `branch._extremum`
            lo, hi = Y[i - 1], Y[i + 1]
            a_, b_ = lo, hi
            if pitchfork and lo <= y0:
                a_ = lo + 1e-12 * (hi - lo)
            c = b_ - _GOLDEN * (b_ - a_)
            e = a_ + _GOLDEN * (b_ - a_)
            pc, _, cc, _ = _terms(code, c, l1, R, Q, C10, C20, C30)
            pe, _, ce, _ = _terms(code, e, l1, R, Q, C10, C20, C30)
            fc, fe = -pc / cc, -pe / ce
            for _ in range(80):
                if fc > fe:
                    b_ = e
                    e = c
                    fe = fc
                    c = b_ - _GOLDEN * (b_ - a_)
                    pc, _, cc, _ = _terms(code, c, l1, R, Q, C10, C20, C30)
                    fc = -pc / cc
                else:
                    a_ = c
                    c = e
                    fc = fe
                    e = a_ + _GOLDEN * (b_ - a_)
                    pe, _, ce, _ = _terms(code, e, l1, R, Q, C10, C20, C30)
                    fe = -pe / ce
            h_min = min(H[i], -max(fc, fe))
            if not (h_min > margin):
                return False
    return True


@numba.njit(cache=True, error_model="numpy")
def _fallen(code, l1, y0, span, K, h0, R, Q, C10, C20, C30, offsets, whole, n_scan, pitchfork):
    """The certificate of a sample whose ``h`` stops rising: 2 (``y0``, if the previous state is not above
    ``y0``: checked by the caller) where ``h`` stays above ``K <= h0`` (`_above`), else 0."""
    if whole and not (K > h0) and _above(code, l1, y0, span, K, h0, R, Q, C10, C20, C30, offsets, n_scan,
                                         pitchfork):
        return 2
    return 0


@numba.njit(cache=True, error_model="numpy")
def _root(code, l1, R, Q, C10, C20, C30, lo, hi, K, scale, rtol, max_iter, sgn):
    """`branch._refine_root` for one root: ``(y, ok)``. Newton on ``g_y = psi_y - K c_y`` inside ``[lo, hi]``
    (``sgn`` -1: a falling crossing), bisection where it strays or slows (`branch.newton_step`), to
    ``rtol scale``."""
    return _refine(code, l1, R, Q, C10, C20, C30, 0.5 * (lo + hi), lo, hi, K, scale, rtol, max_iter, sgn)


@numba.njit(cache=True, error_model="numpy")
def _refine(code, l1, R, Q, C10, C20, C30, y, lo, hi, K, scale, rtol, max_iter, sgn):
    """`_root` from ``y`` in ``[lo, hi]``: `newton_step` up to ``max_iter`` times, then `_guarded` (as
    `branch._refine_root`)."""
    tol = rtol * scale
    dn, g2 = np.inf, np.nan  # the last step, if it was Newton's (inf otherwise), and g_y's slope before it
    for _ in range(max_iter):
        p_y, p_yy, c_y, c_yy = _terms(code, y, l1, R, Q, C10, C20, C30)
        y, lo, hi, _, done, dn, g2 = _newton(y, lo, hi, p_y, p_yy, c_y, c_yy, K, tol, sgn, np.inf, dn, g2)
        if done:
            return y, True
    return _guarded(code, l1, R, Q, C10, C20, C30, lo, hi, K, tol, max_iter, sgn)


@numba.njit(cache=True, error_model="numpy")
def _guarded(code, l1, R, Q, C10, C20, C30, lo, hi, K, tol, max_iter, sgn):
    """The refinement's second pass where the first has not converged (`branch._refine_root`): from the
    middle of the bracket left, safeguarded (bisection where Newton's step is more than half the step
    before the last): ``(y, ok)``."""
    y = 0.5 * (lo + hi)
    dx1, dx2 = np.inf, np.inf  # the last step and the one before it
    dn, g2 = np.inf, np.nan  # the last step, if it was Newton's (inf otherwise), and g_y's slope before it
    for _ in range(max_iter):
        p_y, p_yy, c_y, c_yy = _terms(code, y, l1, R, Q, C10, C20, C30)
        y_new, lo, hi, dx, done, dn, g2 = _newton(y, lo, hi, p_y, p_yy, c_y, c_yy, K, tol, sgn, dx2, dn, g2)
        if done:
            return y_new, True
        y, dx2, dx1 = y_new, dx1, dx
    return y, False


#: `branch.newton_start`: where the certified Newton iteration starts in its bracket.
_start = _jit(branch.newton_start, inline="always", _pick=_pick)


@numba.njit(cache=True, error_model="numpy")
def _one(code, l1, y0, y_max, K, h0, R, Q, C10, C20, C30, offsets, whole, rtol, max_iter, n_scan, pitchfork):
    """One sample: ``(y, certified)``, certified 1 (yes), 2 (if the previous state is not above y0) or 0;
    see the module docstring. `_scan_block` takes the same steps for a block of samples at once."""
    span = y_max - y0
    first = _begin(span, K, h0, whole)
    if first >= 0:
        return y0, first
    if whole:
        return _one_whole(code, l1, y0, span, K, h0, R, Q, C10, C20, C30, offsets, whole, rtol, max_iter, n_scan,
                          pitchfork)
    # the rising-ramp rule (`_begin` decided the samples whose load is at or below h(y0)): the scan ends at
    # the bracketing node
    y_prev, h_prev, s_prev = y0, h0, np.nan
    j = 0  # next scale offset
    k = 1  # next regular node
    while k <= n_scan:
        more = j < offsets.size
        yk, j, k = _next_node(y0, span, more, offsets[j] if more else 0.0, j, k, n_scan)
        p_y, p_yy, c_y, c_yy = _terms(code, yk, l1, R, Q, C10, C20, C30)
        h, slope = _h_slope(p_y, p_yy, c_y, c_yy)
        verdict = _verdict(y_prev, h_prev, s_prev, yk, h, slope, K)
        if verdict == _FALL:
            return y0, _fallen(code, l1, y0, span, K, h0, R, Q, C10, C20, C30, offsets, whole, n_scan, pitchfork)
        if verdict == _DIP:
            return y0, 0
        if verdict == _CROSS:
            # Newton on g_y inside [lo, hi], bisection where it strays (or slows): `branch._refine_root` from
            # `branch.newton_start` (as `branch.follow_branch`)
            y, ok = _refine(code, l1, R, Q, C10, C20, C30, _start(y_prev, yk, h_prev, h, s_prev, slope, K), y_prev,
                            yk, K, span, rtol, max_iter, 1.0)
            return (y, 1) if ok else (y0, 0)
        y_prev, h_prev, s_prev = yk, h, slope
    return y0, 0  # no crossing in the range: the reference says what it is


@numba.njit(cache=True, error_model="numpy")
def _one_whole(code, l1, y0, span, K, h0, R, Q, C10, C20, C30, offsets, whole, rtol, max_iter, n_scan, pitchfork):
    """`_one` on a path (``whole``: the scan covers the whole range, so every node is scanned unless a verdict
    ends it): the nodes' terms first, all in one loop that the compiler vectorizes (`_terms_block`: the same
    bits as `_terms`, called once a node before), then `_one`'s verdicts node by node.
    The same nodes, verdicts, bracket and root as `_one`'s loop; a sample that a verdict ends early has had
    the terms of its later nodes computed for nothing (at most one scan's: a fold's sample then takes
    `_fallen`, whose cost is many scans'; computing them 8 at a time, to stop sooner, made the design loop of
    3R 6 % slower, `benchmarks/ab_in_process.py`)."""
    m = offsets.size + n_scan
    W = np.empty((16, m))  # `_terms_block`'s rows: 6 the node, 7 the stretch, 8-9 CR's xi0 and x0, 10-13 terms
    cnt = np.int64(0)  # (not `0`: a literal count would compile `_terms_block` once more)
    j, k = 0, 1
    while k <= n_scan:
        more = j < offsets.size
        W[6, cnt], j, k = _next_node(y0, span, more, offsets[j] if more else 0.0, j, k, n_scan)
        W[7, cnt], W[8, cnt], W[9, cnt] = l1, R[0], R[1]
        cnt += 1
    _terms_block(code, cnt, W, R, Q, C10, C20, C30)
    done_at_start = not (K > h0)
    y_prev, h_prev, s_prev = y0, h0, np.nan
    lo, hi = np.nan, np.nan
    for t in range(cnt):
        yk = W[6, t]
        h, slope = _h_slope(W[10, t], W[11, t], W[12, t], W[13, t])
        verdict = _verdict(y_prev, h_prev, s_prev, yk, h, slope, K)
        if verdict == _FALL:
            return y0, _fallen(code, l1, y0, span, K, h0, R, Q, C10, C20, C30, offsets, whole, n_scan, pitchfork)
        if verdict == _DIP:
            return y0, 0
        if verdict == _CROSS and lo != lo and not done_at_start:
            lo, hi = y_prev, yk
        y_prev, h_prev, s_prev = yk, h, slope
    if done_at_start:
        return y0, 1
    if lo != lo:
        return y0, 0  # no crossing in the range: the reference says what it is
    # from the midpoint of the bracket, as `branch.follow_path`
    y, ok = _refine(code, l1, R, Q, C10, C20, C30, 0.5 * (lo + hi), lo, hi, K, span, rtol, max_iter, 1.0)
    return (y, 1) if ok else (y0, 0)


@numba.njit(cache=True, error_model="numpy")
def _h_start(code, y0, l1, R, Q, C10, C20, C30, pitchfork):
    """`branch.Problem.h_start` of one sample: 0, or at a pitchfork the bifurcation load ``psi_yy / c_yy``."""
    if not pitchfork:
        return 0.0
    _, p_yy, _, c_yy = _terms(code, y0, l1, R, Q, C10, C20, C30)
    return p_yy / c_yy


@numba.njit(cache=True, error_model="numpy")
def _scan_block(code, l1, y0, y_max, K, xi0, x0, R, Q, C10, C20, C30, offsets, whole, rtol, max_iter, n_scan,
                pitchfork, y, ok, h0, b0, b1):
    """`_h_start` and `_one` of the samples ``b0 <= i < b1``, node by node for all of them at once: at each
    node the terms of every sample still scanning in one vectorized call (`_terms_block`), then each sample's
    steps (`_begin`, `_next_node`, `_verdict`, `_fallen`) as `_one` takes them, so the same nodes, verdicts
    and brackets; the samples that end drop out. The Newton refinement likewise (`_newton`, as `_one`'s
    `_refine`, a step of every lane in one vectorized loop: `_newton_lanes`), its lanes packed once a quarter of
    them converged (a converged lane runs on unused, its result kept: packing after every step cost a third of
    the refinement).
    CR: ``xi0``, ``x0`` per sample, ``R = (0, 0, Lb, ...)``; the others ignore them."""
    nb = b1 - b0
    n_off = offsets.size
    W = np.empty((2, 23, nb + 24))  # one allocation: rows as 1-D views (padded: rows 4 KiB apart alias)
    S, T = W[0], W[1]
    span, y_prev, h_prev, s_prev, lo, hi = S[0], S[1], S[2], S[3], S[4], S[5]
    # per sample still in play, compacted: the node, its arguments and terms (rows 6-15: `_terms_block`'s)
    Y, L, XI, X0, P, PP, CY, CYY, H, SL = S[6], S[7], S[8], S[9], S[10], S[11], S[12], S[13], S[16], S[17]
    ys = S[18]  # where the Newton iteration starts (`_start`)
    # the Newton iteration's lanes (rows 10-13: the terms, `_terms_block`'s; `_newton_lanes` indexes T's rows by number)
    TY, TL, TXI, TX0 = T[6], T[7], T[8], T[9]
    TLO, THI, TK, TTOL, TOUT, TDN, TG2 = T[16], T[17], T[18], T[19], T[20], T[21], T[22]
    N = np.empty((4, nb + 24), np.int64)
    jj, kk = N[0], N[1]
    ref = N[2]  # the samples to refine
    LIVE = N[3]  # whether a Newton lane still iterates
    U = np.empty((2, nb + 24), np.uint64)  # block indices, unsigned (no index checked for a negative value):
    act, TB = U[0], U[1]  # the samples still scanning; the samples refined, packed
    b0u = np.uint64(b0)
    at_start = np.empty(nb, np.bool_)
    DONE = np.empty(nb + 24, np.bool_)  # whether a lane's Newton step converged (`_newton_lanes`)
    if pitchfork:  # `_h_start`
        for b in range(nb):
            Y[b], L[b], XI[b], X0[b] = y0[b0 + b], l1[b0 + b], xi0[b0 + b], x0[b0 + b]
        _terms_block(code, nb, S, R, Q, C10, C20, C30)
        for b in range(nb):
            h0[b0 + b] = PP[b] / CYY[b]
    else:
        for b in range(nb):
            h0[b0 + b] = 0.0
    na = np.int64(0)  # not `0`: numba would compile `_terms_block` once more for a literal 0 (see `_free_lanes`)
    for b in range(nb):
        i = b0 + b
        span[b] = y_max[i] - y0[i]
        first = _begin(span[b], K[i], h0[i], whole)
        if first >= 0:
            y[i], ok[i] = y0[i], first
            continue
        at_start[b] = not (K[i] > h0[i])
        y_prev[b], h_prev[b], s_prev[b] = y0[i], h0[i], np.nan
        lo[b], hi[b] = np.nan, np.nan
        more = n_off > 0
        Y[na], jj[b], kk[b] = _next_node(y0[i], span[b], more, offsets[0] if more else 0.0, 0, 1, n_scan)
        L[na], XI[na], X0[na] = l1[i], xi0[i], x0[i]
        act[na] = b
        na += 1
    nr = np.int64(0)
    while na > 0:
        _terms_block(code, na, S, R, Q, C10, C20, C30)
        for a in range(na):
            H[a], SL[a] = _h_slope(P[a], PP[a], CY[a], CYY[a])
        keep = 0
        for a in range(na):
            b = act[a]
            i = b0u + b
            yk, h, slope = Y[a], H[a], SL[a]
            verdict = _verdict(y_prev[b], h_prev[b], s_prev[b], yk, h, slope, K[i])
            if verdict == _FALL:
                y[i], ok[i] = y0[i], _fallen(code, l1[i], y0[i], span[b], K[i], h0[i],
                                             (xi0[i], x0[i], R[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) if code == 4
                                             else R, Q, C10, C20, C30, offsets, whole, n_scan, pitchfork)
                continue
            if verdict == _DIP:
                y[i], ok[i] = y0[i], 0
                continue
            if verdict == _CROSS and lo[b] != lo[b] and not at_start[b]:
                lo[b], hi[b] = y_prev[b], yk
                ys[b] = (0.5 * (lo[b] + hi[b]) if whole
                         else _start(y_prev[b], yk, h_prev[b], h, s_prev[b], slope, K[i]))
                if not whole:
                    ref[nr] = b
                    nr += 1
                    continue
            y_prev[b], h_prev[b], s_prev[b] = yk, h, slope
            if kk[b] > n_scan:  # the end of the range
                if at_start[b]:
                    y[i], ok[i] = y0[i], 1
                elif lo[b] != lo[b]:
                    y[i], ok[i] = y0[i], 0  # no crossing in the range: the reference says what it is
                else:
                    ref[nr] = b
                    nr += 1
                continue
            # the next node, at the sample's packed place (the node before at ``a >= keep`` is done with)
            j = jj[b]
            more = j < n_off
            Y[keep], jj[b], kk[b] = _next_node(y0[i], span[b], more, offsets[j] if more else 0.0, j, kk[b], n_scan)
            L[keep], XI[keep], X0[keep] = l1[i], xi0[i], x0[i]
            act[keep] = b
            keep += 1
        na = keep
    # Newton on g_y inside [lo, hi], bisection where it strays: `_refine`'s first pass for all at once (each
    # iteration's steps in one vectorized loop); a lane that converged keeps its result (TOUT) and runs on
    # unused until a quarter of the lanes converged and they are packed. The lanes left unconverged take
    # `_refine`'s second pass (`_guarded`) one by one.
    for a in range(nr):
        b = ref[a]
        i = b0 + b
        TB[a] = b
        TY[a], TLO[a], THI[a] = ys[b], lo[b], hi[b]
        TK[a], TTOL[a], TL[a], TXI[a], TX0[a] = K[i], rtol * span[b], l1[i], xi0[i], x0[i]
    for a in range(nr):
        LIVE[a] = 1
        TDN[a], TG2[a] = np.inf, np.nan
    live = nr
    for _ in range(max_iter):
        if live == 0:
            break
        _terms_block(code, nr, T, R, Q, C10, C20, C30)
        _newton_lanes(nr, T, DONE)
        live = 0
        for a in range(nr):
            if LIVE[a] != 0 and DONE[a]:
                TOUT[a] = TY[a]
                LIVE[a] = 0
            live += LIVE[a]
        if 4 * live <= 3 * nr:  # pack: the converged lanes' results out
            keep = 0
            for a in range(nr):  # no branch: every lane written out (a provisional result where it goes on)
                b = TB[a]
                i = b0u + b
                y[i], ok[i] = TOUT[a], 1
                TY[keep], TLO[keep], THI[keep], TK[keep], TTOL[keep] = TY[a], TLO[a], THI[a], TK[a], TTOL[a]
                TL[keep], TXI[keep], TX0[keep], TB[keep] = TL[a], TXI[a], TX0[a], b
                TDN[keep], TG2[keep] = TDN[a], TG2[a]
                keep += LIVE[a]
            for a in range(keep):
                LIVE[a] = 1
            nr = keep
    for a in range(nr):
        i = b0u + TB[a]
        if LIVE[a] == 0:
            y[i], ok[i] = TOUT[a], 1
        else:  # not converged: `_refine`'s second pass (`_guarded`) for this sample
            yg, good = _guarded(code, TL[a], (TXI[a], TX0[a], R[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) if code == 4 else R,
                                Q, C10, C20, C30, TLO[a], THI[a], TK[a], TTOL[a], max_iter, 1.0)
            y[i], ok[i] = (yg, 1) if good else (y0[i], 0)


#: Samples per block of the batched scan (`_scan_block`).
BLOCK = 256


def _roots_loop(code, l1, y0, y_max, K, xi0, x0, R, Q, C10, C20, C30, offsets, whole, rtol, max_iter, n_scan,
                pitchfork, y, ok, h0):
    n = l1.size
    for c in prange((n + BLOCK - 1) // BLOCK):
        _scan_block(code, l1, y0, y_max, K, xi0, x0, R, Q, C10, C20, C30, offsets, whole, rtol, max_iter, n_scan,
                    pitchfork, y, ok, h0, c * BLOCK, min(n, (c + 1) * BLOCK))


def _table(q):
    """A quadrature table ``Q`` as the compiled kernels take it: a read-only C-contiguous float64 copy. Every
    ``Q`` is read-only (`_EMPTY_Q`, `ring_kernels.cr_tables`, the step kernel's compiled global), so that numba
    compiles the kernels once, not once for read-only and once for writable tables."""
    q = np.array(q, np.float64, order="C")
    q.setflags(write=False)
    return q


def _arr(x, shape=None):
    """``x`` as a writable C-contiguous float64 array (copied only if it is not one): numba compiles a
    slower variant for read-only or strided arrays (a broadcast view ran 40x slower)."""
    a = np.asarray(x, dtype=float)
    if shape is not None and a.shape != shape:
        a = np.broadcast_to(a, shape)
    if not (a.flags.c_contiguous and a.flags.writeable):
        a = np.array(a, dtype=float, order="C")
    return a


def _variants(loop):
    """``(serial, parallel)`` compiled forms of one loop (``prange`` is ``range`` in the serial one).

    The parallel one is a clone under its own name: numba's cache keys a function by its name, line and
    signature, not by ``parallel``, so one name would let each variant load the other's machine code."""
    twin = types.FunctionType(loop.__code__, loop.__globals__, loop.__name__ + "_parallel", loop.__defaults__,
                              loop.__closure__)
    twin.__qualname__ = loop.__qualname__ + "_parallel"
    return (numba.njit(cache=True, error_model="numpy")(loop),
            numba.njit(cache=True, error_model="numpy", parallel=True)(twin))



#: Calls of at least this many samples run on all cores (numba's threads), from the main thread only:
#: a server's or a client's thread never enters the thread pool, so no two threads share it.
PARALLEL_MIN = 4096


def _parallel(n) -> int:
    return int(n >= PARALLEL_MIN and threading.current_thread() is threading.main_thread() and _core_free())


def _core_free() -> bool:
    """Whether the machine has a core to spare for numba's second thread: the other processes' CPU use
    (`_other_load`, in cores) at most the cores less one and a half (this process's own thread and half a
    core of slack). On busy cores a second thread gains little: it waits for its turn on a core (while
    numba's waiting threads spun, 2 cores at load 4 made 1R and 3R calls of 4096 samples 7-14x slower than one
    thread; asleep, as now, about as fast as one, and 1e5-sample calls 0.5-2x its time, mostly less), and what it takes
    it takes from the other work. The result is the same either way: each sample is computed on its own."""
    return _other_load() <= _CORES - 1.5


#: The machine's cores, read once (`os.cpu_count` costs some 6 us, and `_core_free` is asked several times a call).
_CORES = os.cpu_count() or 1

#: `_other_load`'s window: its start ``(time, machine busy, process CPU)``, the last estimate and this
#: process's CPU use [cores] averaged over a minute.
_LOAD = {"pid": -1, "start": None, "last": 0.0, "others": None, "own": 0.0}
#: [s]: the shortest window an estimate is taken over, when a window starts afresh, and past which it is stale
_WINDOW = (0.2, 1.0, 5.0)


def _busy() -> float | None:
    """The machine's CPU time spent on anything but idling [s], all cores (``/proc/stat``'s first line:
    user, nice, system, irq, softirq and steal, the hypervisor's share; guest time is in user), or None."""
    try:
        with open("/proc/stat", "rb") as f:
            ticks = f.readline().split()[1:9]
        user, nice, system, _idle, _iowait, irq, softirq, steal = map(int, ticks)
    except (OSError, ValueError):
        return None
    return (user + nice + system + irq + softirq + steal) / _HZ


try:
    _HZ = float(os.sysconf("SC_CLK_TCK"))
except (AttributeError, OSError, ValueError):  # not on a POSIX system: `_busy` reads nothing there
    _HZ = 100.0


def _other_load() -> float:
    """The CPU use of every process but this one, in cores: the machine's busy time (`_busy`) less this
    process's CPU time (all its threads: numba's included) over the last 0.2-1 s, the latest such estimate
    between windows (read at most every 0.1 s). Not the load average, which counts this process's own
    threads (a run that keeps both cores busy raised it until it took itself for other work and left one
    core idle) and lags a minute behind. The first window opens when this module loads. Before it closes
    (and where ``/proc/stat`` is not readable) the 1-minute load average less one (this process's running
    thread) stands in; after this process was idle for over 5 s (other work may have begun since), the load
    average less this process's share of it (its CPU use averaged as the load average averages, over a
    minute), where that is larger than the window's figure. This process's other threads count as its own,
    not as other work: numba's cannot be told apart from them.

    ``RDEA_LAB_THREADS=1`` says the other cores are taken (a batch queue that gives each job one core, a
    test run that puts a worker on each): then every core counts as busy, and every compiled call keeps to
    one thread, so numba's threaded variants are never compiled. Exactly ``1``: any other value leaves the
    choice to this estimate."""
    if os.environ.get("RDEA_LAB_THREADS") == "1":
        return float(_CORES)
    state = _LOAD
    now = time.monotonic()
    if state["pid"] != os.getpid():  # a forked child: its parent's window is not its own
        state.update(pid=os.getpid(), start=None, last=0.0, others=None, own=0.0)
    start = state["start"]
    if start is None or (now - start[0] >= _WINDOW[0] and now - state["last"] >= 0.5 * _WINDOW[0]):
        busy = _busy()
        if busy is not None:
            own = time.process_time()
            if start is not None:
                span = now - start[0]
                others = max(0.0, (busy - start[1]) - (own - start[2])) / span
                keep = math.exp(-span / 60.0)  # the load average's minute
                state["own"] = keep * state["own"] + (1.0 - keep) * (own - start[2]) / span
                if span > _WINDOW[2]:  # this process was idle a while: what the last minute's load says
                    others = _load_average(others, state["own"])
                state["others"] = others
                state["last"] = now
            if start is None or now - start[0] >= _WINDOW[1]:
                state["start"] = (now, busy, own)
    if state["others"] is not None:
        return state["others"]
    return _load_average(0.0, 1.0)  # the load average counts this process's running thread


def _load_average(others, own):
    """The 1-minute load average less ``own`` (this process's share, in cores), or ``others`` where it is
    larger or there is no load average."""
    try:
        return max(others, os.getloadavg()[0] - own)
    except OSError:  # no load average here
        return others


_other_load()  # its first window opens as the module loads


@numba.njit(cache=True)
def _chain(ok, y, y0, y_start):
    # a conditionally certified sample (2): certified where the sample before is and its state is not above y0
    for i in range(ok.size):
        if ok[i] == 2:
            prev_ok = True if i == 0 else ok[i - 1] == 1
            prev_y = y_start if i == 0 else y[i - 1]
            ok[i] = 1 if (prev_ok and prev_y <= y0[i]) else 0


def _roots_args(problem, whole, rtol=branch.RTOL, max_iter=branch.MAX_ITER):
    """The arguments of `_roots_loop` (without the outputs) for a `~rdea_lab.physics.branch.Problem`."""
    from .branch import N_SCAN, scale_offsets

    code, consts = problem.kernel
    n = problem.K.size
    l1 = _arr(consts["l1"])
    if code == CODES["cr"]:
        cr = (_arr(consts["xi0"]), _arr(consts["x0"]), (0.0, 0.0, float(consts["Lb"])) + (0.0,) * 6,
              _table(consts["Q"]))
    else:
        cr = (l1, l1, tuple(float(r) for r in consts.get("R", _NO_RING)), _EMPTY_Q)  # (xi0, x0 unused)
    return (code, l1, _arr(problem.y0, (n,)), _arr(problem.y_max, (n,)), _arr(problem.K, (n,)), *cr,
            *(float(c) for c in consts["C"]), _arr(scale_offsets(problem)), bool(whole), rtol, max_iter, N_SCAN,
            bool(problem.pitchfork))


def branch_roots(problem, *, whole, start=None, rtol=branch.RTOL, max_iter=branch.MAX_ITER):
    """``(y, certified)`` of every sample of a `~rdea_lab.physics.branch.Problem` with a ``kernel``.

    ``certified`` marks the samples whose state is the one root of a strictly
    rising ``h`` (up to the bracketing node, or over the whole range with
    ``whole``), or, on a path (``whole``, ``start`` the coordinate before the
    first sample), ``y0`` where ``h`` stays above the load everywhere and the
    state before is not above ``y0`` (so no fold lies between them); the
    others must be solved by the reference.
    """
    n = problem.K.size
    y = np.empty(n)
    ok = np.zeros(n, dtype=np.int8)
    if n == 0:
        return y, ok.astype(bool)
    args = _roots_args(problem, whole, rtol, max_iter)
    h0 = np.empty(n)  # `Problem.h_start`, computed in the loop (in numpy it was most of a solid roll's call)
    _roots[_parallel(n)](*args, y, ok, h0)
    if whole:
        _chain(ok, y, args[2], float(problem.y0[0]) if start is None else float(start))
    return y, ok == 1


_EMPTY_Q = np.zeros((4, 0))
_EMPTY_Q.setflags(write=False)  # read-only, as the step kernel's global `_Q` is: one compiled signature


def _su_loop(l1, v, C10, C20, C30, kap, C0, sigma, l2, cap):
    C = (C10, C20, C30)
    for i in prange(l1.size):
        lam = l1[i]
        b, x = _basis(lam)
        W1, _ = _slope(x, C)
        sigma[i] = b * W1 - kap * (lam * v[i] ** 2)
        l2[i] = 1.0 / np.sqrt(lam)
        cap[i] = C0 * lam


_basis_inline = _jit(su.basis, inline="always")
_slope_inline = _jit(yeoh.slope, inline="always")


@numba.njit(cache=True, error_model="numpy", inline="always")
def _su_stress(lam, v, C10, C20, C30, kap):
    b, x = _basis_inline(lam)
    W1, _ = _slope_inline(x, (C10, C20, C30))
    return b * W1 - kap * (lam * v ** 2)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _free_start(l1, s1, free_max):
    """The state of `free_stretch`'s iteration for one slack sample (stretch ``l1``, stress ``s1 < 0``
    there) and its first trial stretch: ``(phase, lo, s_lo, a, b, fa, fb, tol, side, count, trial)``. Phase 0
    brackets by 25 % steps up from ``lo`` (its stress ``s_lo``), phase 1 is the Illinois iteration on
    ``[a, b]`` (``fa < 0 <= fb``; ``side``: the end replaced last, -1 or 1, ``count``: its trials so far).
    Floats all, passed one by one: numba's parallel loops (`ring_kernels`) fail to analyse a tuple state."""
    return 0.0, l1, s1, l1, l1, s1, s1, 1e-10 * abs(s1), 0.0, 0.0, min(l1 * 1.25, free_max)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _free_step(phase, lo, s_lo, a, b, fa, fb, tol, side, count, trial, y, valid, free_max):
    """One step of `free_stretch`'s iteration (the state of `_free_start`): the trial stretch ``trial`` gave
    the stress ``y`` (``valid``: the model has a state there). Returns the state, the next trial, whether
    done and the free stretch (NaN where none is found), that only where done. `models._common.free_state`'s
    steps, in its order: bracketing by 25 % steps up to ``free_max``, then the Illinois iteration, at most
    200 trials, until the stress is within 1e-10 of the clamped one's or the bracket within 1e-13 of its
    end."""
    if not (valid and np.isfinite(y)):
        return phase, lo, s_lo, a, b, fa, fb, tol, side, count, trial, True, np.nan
    if phase == 0.0:
        if y < 0.0:  # not bracketed yet: 25 % further, up to free_max
            if trial >= free_max:
                return phase, lo, s_lo, a, b, fa, fb, tol, side, count, trial, True, np.nan
            return 0.0, trial, y, a, b, fa, fb, tol, side, count, min(trial * 1.25, free_max), False, np.nan
        a, b, fa, fb = lo, trial, s_lo, y  # bracketed: the Illinois iteration on [lo, trial]
        phase = 1.0
    else:  # replace the end on the root's side; halve the kept end's value when it is kept twice
        neg = y < 0.0  # (selects, not branches: the side is a coin toss to the branch predictor)
        fb = (0.5 * fb if side == -1.0 else fb) if neg else y
        fa = y if neg else (0.5 * fa if side == 1.0 else fa)
        a = trial if neg else a
        b = b if neg else trial
        side = -1.0 if neg else 1.0
        count += 1.0
        if abs(y) <= tol or b - a <= 1e-13 * b:
            return phase, lo, s_lo, a, b, fa, fb, tol, side, count, trial, True, trial
        if count >= 200.0:
            return phase, lo, s_lo, a, b, fa, fb, tol, side, count, trial, True, np.nan
    xn = (a * fb - b * fa) / (fb - fa)
    if not (xn > a and xn < b):
        xn = 0.5 * (a + b)
    return phase, lo, s_lo, a, b, fa, fb, tol, side, count, xn, False, np.nan


@numba.njit(cache=True, error_model="numpy", inline="always")
def free_stretch(stress, args, l1, s1, free_max):
    """The free (F = 0) stretch above ``l1`` of one slack sample (stress ``s1 < 0`` at ``l1``), NaN where
    none is found: `models._common.free_state`'s steps for one sample, in the same order (`_free_start`,
    then `_free_step` per trial: the one compiled form of them, which `_su_free_lanes` takes too).

    ``stress(stretch, args)`` is the compiled model at a trial stretch, ``(stress [Pa], valid)``; a trial
    that is not valid (not converged, non-finite) ends the search with NaN. The caller checks the stress
    at the returned stretch (the reference's final check, `free_check`), with the model's fields there in
    hand. Inlined into each caller at numba's level: a call would pass ``stress`` as a pointer to the
    Python object, which numba cannot cache.
    """
    phase, lo, s_lo, a, b, fa, fb, tol, side, count, x = _free_start(l1, s1, free_max)
    while True:
        y, valid = stress(x, args)
        phase, lo, s_lo, a, b, fa, fb, tol, side, count, x, done, found = _free_step(
            phase, lo, s_lo, a, b, fa, fb, tol, side, count, x, y, valid, free_max)
        if done:
            return found


#: `models._common.free_check` compiled: the free state's final check (its tolerance stated once).
free_check = _jit(_common.free_check, inline="always")


@numba.njit(cache=True, error_model="numpy")
def _su_trial(lam, args):
    v, C10, C20, C30, kap = args
    return _su_stress(lam, v, C10, C20, C30, kap), True


@numba.njit(cache=True, error_model="numpy")
def _su_free(l1, v, s1, C10, C20, C30, kap, free_max):
    """The SU free stretch above ``l1`` (`free_stretch`), NaN where there is none or where the stress
    there fails the reference's final check."""
    x = free_stretch(_su_trial, (v, C10, C20, C30, kap), l1, s1, free_max)
    if x == x and not free_check(_su_stress(x, v, C10, C20, C30, kap), s1):
        return np.nan
    return x


@numba.njit(cache=True, error_model="numpy")
def _su_tension(l1, v, C10, C20, C30, kap, area, slack, codes, tension, state, status, converged):
    """What a whole SU solve computes up front, in one loop over the inputs as given (a block of them:
    `_su_pass_loop`): the tension (eq. (39) at the given stretch), the stretch of the state (the given one; a
    slack sample's free stretch comes later), the status and whether it converged; NaN where the sample has
    no state (a NaN or infinite input: `BAD_INPUT`). Returns ``(slack samples, finite samples with a stretch
    below 1)``."""
    OK_, SLACK_, BAD_, OVER_ = codes[0], codes[1], codes[2], codes[3]
    n_slack = 0
    n_low = 0
    # without branches (`&`, selects), so that the compiler vectorizes the loop; over the arrays' own length
    # (a loop over ``lo:hi`` of longer arrays, its index possibly negative to the compiler, was not vectorized)
    for i in range(l1.size):
        lam = l1[i]
        w = v[i]
        given = (np.abs(lam) < np.inf) & (np.abs(w) < np.inf)
        n_low += np.int64(given & (lam < 1.0))
        # a NaN or infinite input gives a stress that is not kept (not ``given``): no unloaded state to put in
        s = _su_stress(lam, w, C10, C20, C30, kap)
        neg = slack & (s < 0.0)
        # a slack roll's stress and force are 0: only its tension must be finite. The force ``s area /
        # lam`` is finite where ``s area`` is, for lam >= 1 (a stretch below 1 is the caller's error)
        ok = (np.abs(s) < np.inf) & (neg | (np.abs(s * area) < np.inf)) & given
        tension[i] = s if ok else np.nan
        state[i] = lam if ok else np.nan
        a, b, c = np.int8(ok), np.int8(neg), np.int8(given)
        status[i] = a * (b * SLACK_ + (1 - b) * OK_) + (1 - a) * (c * OVER_ + (1 - c) * BAD_)
        converged[i] = ok  # OK or SLACK
        n_slack += np.int64(ok & neg)
    return n_slack, n_low


#: Samples per block of SU's eager pass (`_su_pass_loop`): a block's slack samples are found while its status
#: is in the cache, and numba's threads take blocks (a scene's slack samples may crowd in one part of it).
SU_BLOCK = 4096
#: SU's eager pass runs on numba's threads from this many samples (where `_parallel` allows): an SU sample costs
#: a few ns, so below it waking the threads costs what they save. Measured here (`benchmarks/su_threads.py`:
#: medians of 200 calls, one thread / threads): 8192 samples 41-46 / 44-53 us back to back and 79-98 / 140-143 us
#: after 2 ms idle; 16384 70-77 / 65-71 and 130-148 / 140-162 us; 32768 139-150 / 93-120 and 186-219 / 183-187 us.
SU_PARALLEL_MIN = 32768


def _su_pass_loop(l1, v, C10, C20, C30, kap, area, slack, codes, work, status, converged, scratch, counts):
    """`_su_tension` of every sample into the rows of ``work`` (the tension, the state stretch), block by
    block (`SU_BLOCK`); each block's counts into ``counts[c]`` (slack samples, stretches below 1) and its slack
    samples' indices, in order, into ``scratch`` from the block's first index on (`_su_slack_take` collects
    them)."""
    n = l1.size
    code = codes[1]
    for c in prange(counts.shape[0]):
        lo = c * SU_BLOCK
        hi = min(n, lo + SU_BLOCK)
        ns, nl = _su_tension(l1[lo:hi], v[lo:hi], C10, C20, C30, kap, area, slack, codes, work[0, lo:hi],
                             work[1, lo:hi], status[lo:hi], converged[lo:hi])
        counts[c, 0] = ns
        counts[c, 1] = nl
        if ns:
            k = lo
            for i in range(lo, hi):
                if status[i] == code:
                    scratch[k] = i
                    k += 1


@numba.njit(cache=True, error_model="numpy")
def _su_slack_take(scratch, counts, v):
    """``(idx, v[idx], low)``: the slack samples' indices that `_su_pass_loop` left in ``scratch``, in order,
    their voltages and the number of finite samples with a stretch below 1."""
    total = 0
    low = 0
    for c in range(counts.shape[0]):
        total += counts[c, 0]
        low += counts[c, 1]
    idx = np.empty(total, np.intp)
    v_slack = np.empty(total)
    k = 0
    for c in range(counts.shape[0]):
        lo = c * SU_BLOCK
        for j in range(counts[c, 0]):
            i = scratch[lo + j]
            idx[k] = i
            v_slack[k] = v[i]
            k += 1
    return idx, v_slack, low


@numba.njit(cache=True, error_model="numpy")
def _su_free_all(l1, v, s1, C10, C20, C30, kap, free_max, out):
    """`_su_free` of every sample, one after the other (the reference of `_su_free_lanes`)."""
    for i in range(l1.size):
        out[i] = _su_free(l1[i], v[i], s1[i], C10, C20, C30, kap, free_max)


_LANES = 16  # 16 lanes: 20 % faster than 8 (more divisions in flight), 32 no faster


@numba.njit(cache=True, error_model="numpy", inline="always")
def _put(state, k, st):
    for j in range(10):  # unrolled: ``st`` is a tuple
        state[k, j] = st[j]


@numba.njit(cache=True, error_model="numpy")
def _su_free_lanes(l1, v, s1, C10, C20, C30, kap, free_max, out, start, stop):
    """`_su_free` of the samples ``start:stop``, `_LANES` samples in lockstep: each lane takes
    `free_stretch`'s steps (`_free_start`, `_free_step`) for its sample, and the stress of all lanes is
    evaluated together, so that the lanes' chains of dependent divisions overlap. A lane that is done
    takes the next sample. The final check uses the stress of the last trial, which is the stress at the
    returned stretch."""
    B = _LANES
    idx = np.full(B, -1)
    x_try = np.ones(B)
    vv = np.zeros(B)
    s1v = np.zeros(B)
    sig = np.empty(B)
    state = np.empty((B, 10))  # each lane's `_free_step` state
    nxt = start
    busy = 0
    while True:
        for k in range(B):  # an idle lane takes the next sample
            if idx[k] < 0:
                if nxt < stop:
                    idx[k] = nxt
                    st = _free_start(l1[nxt], s1[nxt], free_max)
                    _put(state, k, st)
                    x_try[k] = st[10]
                    s1v[k] = s1[nxt]
                    vv[k] = v[nxt]
                    nxt += 1
                    busy += 1
                else:
                    x_try[k] = 1.0  # an idle lane evaluates a harmless stretch
                    vv[k] = 0.0
        if busy == 0:
            break
        for k in range(B):
            sig[k] = _su_stress(x_try[k], vv[k], C10, C20, C30, kap)
        for k in range(B):
            if idx[k] < 0:
                continue
            st = state[k]
            p0, p1, p2, p3, p4, p5, p6, p7, p8, p9, x, done, found = _free_step(
                st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7], st[8], st[9], x_try[k], sig[k], True, free_max)
            if done:
                out[idx[k]] = found if free_check(sig[k], s1v[k]) else np.nan  # `_su_free`'s final check
                idx[k] = -1
                busy -= 1
            else:
                _put(state, k, (p0, p1, p2, p3, p4, p5, p6, p7, p8, p9))
                x_try[k] = x


@numba.njit(cache=True, error_model="numpy")
def _su_state_pass(tension, state, slack, area, C0, Ri, sigma, force, l2, cap, r_i):
    """The fields of an SU solve at the stretch of each sample's state (``state``: the given one; NaN where
    the sample has no state: its tension is NaN too), in one pass: the stress (the tension; 0 where
    slack), the force ``sigma area / lambda1``, the hoop stretch, capacitance and inner radius. Slack where
    ``slack`` (the solve's) and the tension is negative, as `_su_tension` has it; the force there is 0, as
    ``0 area / lambda1`` is, and the other fields are the clamped state's until `_su_free_fields`."""
    for i in range(tension.size):
        t = tension[i]
        at = state[i]
        free = slack & (t < 0.0)
        sigma[i] = 0.0 if free else t
        force[i] = 0.0 if free else t * area / at
        q = 1.0 / np.sqrt(at)
        l2[i] = q
        cap[i] = C0 * at
        r_i[i] = Ri * q


@numba.njit(cache=True, error_model="numpy")
def _su_free_fields(state, idx, found, C0, Ri, l2, cap, r_i):
    """At the slack samples ``idx``: their free stretch ``found`` into ``state`` (which becomes the free
    stretch field), and where there is one (not NaN) the fields there (NaN: the clamped state's fields
    stay, the free stretch is NaN)."""
    for k in range(idx.size):
        i = idx[k]
        at = found[k]
        state[i] = at
        if at == at:
            q = 1.0 / np.sqrt(at)
            l2[i] = q
            cap[i] = C0 * at
            r_i[i] = Ri * q


_roots = _variants(_roots_loop)
_su = _variants(_su_loop)
_su_pass = _variants(_su_pass_loop)


def su_state(l1, v, C, kap, C0, out=None):
    """``(sigma1 [Pa], lambda2 [-], capacitance [F])`` of the SU model, fused (eqs. (39), (41) of [1]).

    ``l1``, ``v``: float arrays of one shape; ``out``: three arrays of that
    shape to write into (none is allocated then).
    """
    l1 = _arr(l1)
    v = _arr(v, l1.shape)
    if out is None:
        out = (np.empty_like(l1), np.empty_like(l1), np.empty_like(l1))
    # one thread: memory-bound, and threads on a loaded machine made it slower than numpy
    _su[0](l1.ravel(), v.ravel(), C[0], C[1], C[2], kap, C0, *(o.reshape(-1) for o in out))
    return out


#: The rows of `su_solve`'s one float block: the tension and state stretch, then the fields `su_fields` fills.
SU_ROWS = ("tension", "state", "sigma1", "force", "lambda2", "capacitance", "r_i")


@numba.njit(cache=True, error_model="numpy")
def _su_state_rows(work, slack, area, C0, Ri):
    _su_state_pass(work[0], work[1], slack, area, C0, Ri, work[2], work[3], work[4], work[5], work[6])


@numba.njit(cache=True, error_model="numpy")
def _su_free_rows(work, idx, found, C0, Ri):
    _su_free_fields(work[1], idx, found, C0, Ri, work[4], work[5], work[6])


def su_solve(l1, v, C, kap, area, slack, codes):
    """The eager part of a whole SU solve of 1-D float inputs as given, one compiled pass: ``(block, work,
    status, converged, idx, v_slack, low)``. ``block``: one (7, n) float array for every float field of the
    solve (`SU_ROWS`), not writeable (nor can a view of it be made so); ``work``: a writeable view of it, for
    the kernels only. The pass fills the tension [Pa] (eq. (39) at the given stretch) and the stretch of the
    state [-] (the given one, NaN where the sample has no state); ``status`` (``codes``: ``(OK, SLACK,
    BAD_INPUT, OVERFLOW)``; a NaN or infinite input is ``BAD_INPUT``), where it is OK or SLACK, the indices
    of the slack samples and their voltages (copies: the caller may change its arrays before it reads a field
    computed from them) and the number of finite samples with a stretch below 1 (the caller's error). The
    slack samples' free stretch is `su_free`'s, every other field `su_fields`' (`rdea_lab.physics.models.su`
    computes them when they are asked for).

    One allocation for every row: a result's fields are one chunk of memory, which the allocator hands to
    the next result when this one is dropped, where seven arrays freed at once were given back to the system
    and taken again, page by page (750 page faults, a third of the time, per call of 1e5 samples with every
    field read). The rows not computed yet are not touched (reserved, not in memory, where the chunk is new).

    The pass runs on numba's threads from `SU_PARALLEL_MIN` samples where `_parallel` allows (the main thread,
    a core free), block by block (`SU_BLOCK`): each sample is computed on its own, so the result is the same to
    the bit either way.
    """
    n = l1.size
    # read-only views whatever the caller's are: one compiled variant of the pass (numba compiles one per
    # writability of each array argument)
    l1, v = _readonly(l1, float), _readonly(v, float)
    block = np.empty((len(SU_ROWS), n))
    work = block.view()
    block.flags.writeable = False  # ``work``, a view taken before, stays writeable: the kernels fill it
    status = np.empty(n, np.int8)
    converged = np.empty(n, np.bool_)
    codes = np.asarray(codes, np.int8)
    counts = np.empty(((n + SU_BLOCK - 1) // SU_BLOCK, 2), np.int64)
    scratch = np.empty(n, np.intp)  # each block's slack samples' indices, from the block's first index on
    _su_pass[int(n >= SU_PARALLEL_MIN and _parallel(n))](l1, v, C[0], C[1], C[2], kap, area, bool(slack), codes,
                                                         work, status, converged, scratch, counts)
    idx, v_slack, low = _su_slack_take(scratch, counts, v)
    return block, work, status, converged, idx, v_slack, low


def su_free(l1, v, s1, C, kap, free_max):
    """The free stretch of slack SU samples (1-D ``l1``, ``v`` and their stress ``s1 < 0``), NaN where
    there is none (`free_stretch`: the reference `free_state`'s steps), several samples in lockstep
    (`_su_free_lanes`)."""
    out = np.empty(l1.size)
    _su_free_lanes(_arr(l1), _arr(v), _arr(s1), C[0], C[1], C[2], kap, free_max, out, 0, l1.size)
    return out


def su_fields(work, idx, v_slack, C, kap, free_max, slack, area, C0, Ri, which):
    """The fields of an SU solve (`su_solve` with ``slack``: its ``work``) computed when first read, into
    their rows: ``which`` 0, the stress, force, hoop stretch, capacitance and inner radius at the state
    stretch, in one pass (`_su_state_pass`); 1 (after 0), the slack samples' free stretches by `su_free`
    (``v_slack``: their voltages) and the fields there (`_su_free_fields`): the state stretch becomes the
    free stretch. One thread: the passes are memory-bound, and on a shared machine's busy cores numba's
    threads waited some 8 ms per pass (24 ms for every field of 1e5 samples, against 1 ms on one thread;
    measured before `_core_free` kept calls off busy cores, which `su_solve` now relies on)."""
    if which == 0:
        _su_state_rows(work, slack, area, C0, Ri)
    elif idx.size:
        found = su_free(work[1][idx], v_slack, work[0][idx], C, kap, free_max)
        _su_free_rows(work, idx, found, C0, Ri)


_update = _jit(viscoelastic._linear_update, inline="always")


@numba.njit(cache=True, error_model="numpy")
def _coefficients(lengths, tau, a, c):
    for k in range(lengths.size):  # the coefficients of each distinct interval, b per unit slope
        a[k], c[k] = _update(lengths[k], 1.0, tau)


@numba.njit(cache=True, error_model="numpy")
def _linear(lengths, index, slope, tau, q0, q):
    # each branch's update is a chain of dependent multiply-adds, bound by their latency: up to three
    # branches' chains go through one loop side by side, each in its own order (the same numbers), in
    # about the time of one
    L = lengths.size
    a0, c0, a1, c1, a2, c2 = (np.empty(L), np.empty(L), np.empty(L), np.empty(L), np.empty(L), np.empty(L))
    M = tau.size
    j = 0
    while M - j >= 3:
        _coefficients(lengths, tau[j], a0, c0)
        _coefficients(lengths, tau[j + 1], a1, c1)
        _coefficients(lengths, tau[j + 2], a2, c2)
        x, y, z = q0[j], q0[j + 1], q0[j + 2]
        q[j, 0], q[j + 1, 0], q[j + 2, 0] = x, y, z
        for i in range(index.size):
            k = index[i]
            x = a0[k] * x + slope[i] * c0[k]
            y = a1[k] * y + slope[i] * c1[k]
            z = a2[k] * z + slope[i] * c2[k]
            q[j, i + 1] = x
            q[j + 1, i + 1] = y
            q[j + 2, i + 1] = z
        j += 3
    if M - j == 2:
        _coefficients(lengths, tau[j], a0, c0)
        _coefficients(lengths, tau[j + 1], a1, c1)
        x, y = q0[j], q0[j + 1]
        q[j, 0], q[j + 1, 0] = x, y
        for i in range(index.size):
            k = index[i]
            x = a0[k] * x + slope[i] * c0[k]
            y = a1[k] * y + slope[i] * c1[k]
            q[j, i + 1] = x
            q[j + 1, i + 1] = y
    elif M - j == 1:
        _coefficients(lengths, tau[j], a0, c0)
        x = q0[j]
        q[j, 0] = x
        for i in range(index.size):
            k = index[i]
            x = a0[k] * x + slope[i] * c0[k]
            q[j, i + 1] = x


@numba.njit(cache=True, error_model="numpy")
def _su_linear_residual(b, x, lv2, C, kap, k, eta, lengths, index, slope, eta_v0, rate, area, stretch, force,
                       scale, q, out):
    """``out[i]``: the scaled force error at sample i (module docstring); ``eta_v0 == 0``: no damper term.

    ``lengths``, ``index``, ``slope``, ``rate``: the run's `History` (its distinct interval lengths, each
    interval's, the stretch slopes and rates); ``q``: scratch of shape (M, n) for the branch strains.
    """
    M = k.size
    n = b.size
    if M:
        _linear(lengths, index, slope, eta / k, np.zeros(M), q)
    # in passes without branches inside (the compiler vectorizes them), in the numpy composition's order:
    # q[0] becomes the overstress k_1 q_1 + ... + k_M q_M (+ eta_v0 rate); out the reversible stress
    for i in range(n):
        W1, _ = _slope_inline(x[i], C)
        out[i] = b[i] * W1 - kap * lv2[i]
    if M:
        k0 = k[0]
        for i in range(n):
            q[0, i] = k0 * q[0, i]
        for j in range(1, M):
            kj = k[j]
            for i in range(n):
                q[0, i] += kj * q[j, i]
        if eta_v0 != 0.0:
            for i in range(n):
                q[0, i] += eta_v0 * rate[i]
        for i in range(n):
            out[i] = out[i] + q[0, i]
    elif eta_v0 != 0.0:
        for i in range(n):
            out[i] = out[i] + (0.0 + eta_v0 * rate[i])
    else:
        for i in range(n):
            out[i] = out[i] + 0.0
    for i in range(n):
        f = out[i] * area / stretch[i]
        f = 0.0 if f < 0.0 else f  # np.maximum(f, 0.0): slack; NaN stays NaN
        out[i] = (f - force[i]) * scale[i]


def _readonly(x, dtype):
    """``x`` as a C-contiguous read-only array of ``dtype``, not copied where it is one (a `History`'s):
    `linear_strains` then has one compiled variant (numba compiles one per writability)."""
    x = np.ascontiguousarray(x, dtype)
    if x.flags.writeable:
        x = x.view()
        x.flags.writeable = False
    return x


def linear_strains(lengths, index, slope, tau, q0, q):
    """``q[:, 0] = q0``, then eq. (44)'s exact update ``q_{n+1} = a_n q_n + b_n`` into ``q[:, 1:]``, in
    sequence: ``(a_n, b_n)`` of `viscoelastic._linear_update` for the interval ``lengths[index[n]]`` [s],
    the slope ``slope[n]`` [1/s] and each branch's relaxation time ``tau[j]`` [s] (``index`` None:
    ``lengths`` are the intervals themselves). The exponentials are computed once per distinct length
    (``b`` as the slope times that of a unit slope, which `_linear_update` gives to the last bit)."""
    if index is None:
        index = np.arange(np.size(lengths))
    _linear(_readonly(lengths, float), _readonly(index, np.intp), _readonly(slope, float), _arr(tau), _arr(q0), q)
