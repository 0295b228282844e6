"""Compiled passes of the 1R, 3R and CR solves around the certified root kernel (numba, ``cache=True``).

The root of each sample is `kernels.branch_roots`' (a free state's trial: `kernels._one`); what
this module compiles is the rest of a `solve`, with the numpy code as the
reference (the tests check one against the other):

- the result fields at the equilibria, one parallel pass writing every field:
  `three_ring.ring_fields` and `continuum.node_mechanics` / `continuum.closing`,
  compiled as they are (`kernels._jit`); 1R's `one_ring.fields` stays numpy,
  by blocks (`one_ring.BLOCK` says why);
- the problems' bounds and loads (`bounds`);
- a slack roll's free state: `kernels.free_stretch` (the bracketing and
  Illinois iteration of `models._common.free_state`, the one compiled form of
  it), each trial the rising-ramp state at the trial stretch from the
  certified `kernels._one` and its stress from the model's compiled fields.
  A sample whose search meets a trial that is not certified, or that ends
  without a free state, is reported as not done: the caller hands it to the
  numpy `free_state` (so every status other than ``SLACK`` is the reference's).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

from . import kernels
from .branch import N_SCAN
from .kernels import (_arr, _basis, _fields3, _gradient, _h_start, _jit, _one, _parallel, _slope, _variants,
                      free_stretch)
from .models import continuum, one_ring, three_ring
from .models._common import FREE_STRETCH_MAX

_stress1 = _jit(one_ring.stress, gradient_terms=_gradient)
# inlined: the loop over samples of `bounds` vectorizes
_bounds1 = _jit(one_ring.bounds, inline="always")
_xi_hoop = _jit(three_ring.xi_at_hoop_stretch, inline="always")
_bounds3 = _jit(three_ring.bounds, inline="always", xi_at_hoop_stretch=_xi_hoop)
_bounds_cr = _jit(continuum.bounds, inline="always")
_node_mech = _jit(continuum.node_mechanics, inline="always", slope=_slope)
_closing = _jit(continuum.closing, inline="always")

_N_SCAN = N_SCAN
_FREE_MAX = FREE_STRETCH_MAX


@numba.njit(cache=True, error_model="numpy", inline="always")
def _cr_mechanics(xi, l1, xi0, x0, lx0p, Q, W, C10, C20, C30):
    """``lambda1 dpsi/dlambda1`` at fixed ``xi`` and the region-averaged hoop stretches of one CR sample:
    `continuum.node_mechanics` summed over the quadrature nodes as `continuum._mechanics` sums it in numpy
    (`cr_tables`: ``Q`` the nodes and weights, ``W`` the region averages' weights)."""
    A = (xi - xi0) * (xi + xi0)
    B = l1 * A
    mech = 0.0
    h0 = 0.0
    h1 = 0.0
    h2 = 0.0
    for j in range(Q.shape[1]):
        m, h = _node_mech(A, B, x0, lx0p, l1, Q[0, j], Q[4, j], C10, C20, C30)
        mech += m * Q[3, j]
        h0 += h * W[0, j]
        h1 += h * W[1, j]
        h2 += h * W[2, j]
    return mech, h0, h1, h2


def _fields3_loop(y, l1, v, R, C10, C20, C30, kap, C0, Ro, out):
    for i in prange(y.size):
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i] = _fields3(
            y[i], l1[i], v[i], R, C10, C20, C30, kap, C0, Ro)


#: Samples per block of the CR field pass: each node is applied to a block of samples in a loop the compiler
#: vectorizes (divisions and square roots four or eight at a time), as the per-sample loop over nodes is not.
CR_BLOCK = 256


def _fields_cr_loop(y, l1, v, xi0, x0, lx0p, Q, W, present, C10, C20, C30, Lb, kap, C0, Ro, out):
    n = y.size
    for b in prange((n + CR_BLOCK - 1) // CR_BLOCK):
        lo = b * CR_BLOCK
        m = min(CR_BLOCK, n - lo)
        A = np.empty(m)
        B = np.empty(m)
        acc = np.zeros((4, m))
        for i in range(m):
            A[i] = (y[lo + i] - xi0[lo + i]) * (y[lo + i] + xi0[lo + i])
            B[i] = l1[lo + i] * A[i]
        for j in range(Q.shape[1]):  # `_cr_mechanics`, node by node over the block
            s, s_i_s, w, w0, w1, w2 = Q[0, j], Q[4, j], Q[3, j], W[0, j], W[1, j], W[2, j]
            for i in range(m):
                k = lo + i
                mech, h = _node_mech(A[i], B[i], x0[k], lx0p[k], l1[k], s, s_i_s, C10, C20, C30)
                acc[0, i] += mech * w
                acc[1, i] += h * w0
                acc[2, i] += h * w1
                acc[3, i] += h * w2
        for i in range(m):
            k = lo + i
            out[0, k], out[4, k], out[5, k] = _closing(acc[0, i], y[k], xi0[k], l1[k], v[k], Lb, kap, C0, Ro)
            out[1, k] = acc[1, i] if present[0] else math.nan
            out[2, k] = acc[2, i] if present[1] else math.nan
            out[3, k] = acc[3, i] if present[2] else math.nan


_f3 = _variants(_fields3_loop)
_fcr = _variants(_fields_cr_loop)


def fields3(y, l1, v, R, C, kap, C0, Ro):
    """`three_ring.ring_fields` of every sample: the six rows of one block."""
    y = _arr(y)
    out = np.empty((6, y.size))
    _f3[_parallel(y.size)](y, _arr(l1, y.shape), _arr(v, y.shape), tuple(float(r) for r in R), *map(float, C),
                           float(kap), float(C0), float(Ro), out)
    return tuple(out)


def cr_tables(roll):
    """``(Q, W, present)`` of a `continuum._Roll` for `fields_cr` and `free_states`: ``Q`` the rows
    ``(s, w / s, w / s**2, w, s_i / s)`` of the quadrature nodes (the first four `kernels._terms`'), ``W`` the
    weights of each region's average (`_Roll.avg`, transposed) and which regions are present."""
    s = roll.s
    Q = np.empty((5, s.size))
    Q[:4] = np.stack(roll.weights)
    Q[4] = roll.s_i / s
    return Q, np.ascontiguousarray(roll.avg.T, float), np.array(roll.present, np.bool_)


def fields_cr(y, l1, v, roll, C, kap, C0, Ro, tables=None):
    """The CR result fields of every sample (`continuum.evaluate`'s, compiled): six rows ``(sigma1, lambda2a,
    lambda2b, lambda2c, capacitance, r_i)``."""
    y = _arr(y)
    n = y.size
    Q, W, present = cr_tables(roll) if tables is None else tables
    out = np.empty((6, n))
    _fcr[_parallel(n)](y, _arr(l1, y.shape), _arr(v, y.shape), _arr(roll.xi0, y.shape), _arr(roll.x0, y.shape),
                       _arr(roll.lx0p, y.shape), Q, W, present, *map(float, C), float(roll.Lb),
                       float(kap), float(C0), float(Ro), out)
    return tuple(out)


@numba.njit(cache=True, error_model="numpy")
def _bounds_loop(code, l1, v, kap, B, y0, y_max, load, K):
    if code == 1:
        for i in range(l1.size):
            y0[i], y_max[i], load[i] = _bounds1(l1[i], kap)
    elif code == 3:
        for i in range(l1.size):
            y0[i], y_max[i], load[i] = _bounds3(l1[i], kap, B)
    else:
        for i in range(l1.size):
            y0[i], y_max[i], load[i] = _bounds_cr(l1[i], kap, B[0], B[1])
    for i in range(l1.size):
        K[i] = load[i] * v[i] * v[i]


def bounds(code, l1, v, kap, B=(0.0,) * 4):
    """``(y0, y_max, load, K)`` of a model's `~rdea_lab.physics.branch.Problem` in one pass: its ``bounds``
    (`one_ring.bounds`, `three_ring.bounds` with ``B`` its bound constants, `continuum.bounds` with ``B = (s_i,
    s_ie, 0, 0)``) and ``K = load v**2``."""
    l1 = _arr(l1)
    out = np.empty((4, l1.size))
    _bounds_loop(code, l1, _arr(v, l1.shape), float(kap), tuple(float(b) for b in B), *out)
    return tuple(out)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _rising(code, lam, v, R, B, Q, C10, C20, C30, kap, offsets, pitchfork):
    """The rising-ramp state at stretch ``lam``: ``(y, certified, R)`` by `kernels._one` (``R``: CR's
    per-sample constants at ``lam``)."""
    if code == 1:
        y0, y_max, load = _bounds1(lam, kap)
    elif code == 3:
        y0, y_max, load = _bounds3(lam, kap, B)
    else:
        y0, y_max, load = _bounds_cr(lam, kap, B[0], B[1])
        _, x0 = _basis(lam)
        R = (y0, x0, R[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    h0 = _h_start(code, y0, lam, R, Q, C10, C20, C30, pitchfork)
    y, cert = _one(code, lam, y0, y_max, load * v * v, h0, R, Q, C10, C20, C30, offsets, False, 1e-14, 100,
                   _N_SCAN, pitchfork)
    return y, cert == 1, R


@numba.njit(cache=True, error_model="numpy", inline="always")
def _stress(code, y, lam, v, R, B, Q, W, C10, C20, C30, kap):
    """The axial stress [Pa] at the equilibrium ``y`` of stretch ``lam`` (the model's compiled fields)."""
    if code == 1:
        return _stress1(y, lam, v, C10, C20, C30, kap)
    if code == 3:
        s, _, _, _, _, _ = _fields3(y, lam, v, R, C10, C20, C30, kap, 0.0, 0.0)
        return s
    lx0p, x0 = _basis(lam)
    mech, _, _, _ = _cr_mechanics(y, lam, R[0], x0, lx0p, Q, W, C10, C20, C30)
    s, _, _ = _closing(mech, y, R[0], lam, v, R[2], kap, 0.0, 0.0)
    return s


@numba.njit(cache=True, error_model="numpy")
def _trial(lam, args):
    """A trial of `kernels.free_stretch`: ``(stress, certified)`` of the rising-ramp state at ``lam``; a certified
    one is kept in ``memo[i] = (lam, y, stress)`` (the last one is the free state: not solved again)."""
    code, v, R, B, Q, W, C10, C20, C30, kap, offsets, pitchfork, memo, i = args
    y, ok, R = _rising(code, lam, v, R, B, Q, C10, C20, C30, kap, offsets, pitchfork)
    if not ok:
        return math.nan, False
    s = _stress(code, y, lam, v, R, B, Q, W, C10, C20, C30, kap)
    memo[i, 0], memo[i, 1], memo[i, 2] = lam, y, s
    return s, True


def _free_loop(code, l1, v, s1, R, B, Q, W, C10, C20, C30, kap, offsets, pitchfork, free_max, memo, done):
    for i in prange(l1.size):
        done[i] = False
        memo[i, 0] = math.nan
        args = (code, v[i], R, B, Q, W, C10, C20, C30, kap, offsets, pitchfork, memo, i)
        x = free_stretch(_trial, args, l1[i], s1[i], free_max)
        # the reference's final check at the free stretch (its last trial): the stress vanishes (does not jump)
        if x == x and memo[i, 0] == x and kernels.free_check(memo[i, 2], s1[i]):
            done[i] = True
        else:
            memo[i, 0] = memo[i, 1] = math.nan


_free = _variants(_free_loop)
#: A free state costs some 5-10 roots and stresses (its trials): calls of this many slack samples run on all
#: cores.
FREE_PARALLEL_MIN = 256


def free_states(code, l1, v, s1, C, kap, offsets, pitchfork, R=(0.0,) * 9, B=(0.0,) * 4, cr=None):
    """The free states of slack samples (stretch ``l1``, voltage ``v``, stress ``s1 < 0`` there), compiled:
    ``(free stretch, y there, done)``; a sample not done goes to the numpy `free_state`.

    ``code``: `kernels.CODES`; ``offsets``: the scale nodes of the call's problem (`branch.scale_offsets`:
    those of its widest span, so each trial is scanned at least at the nodes the reference scans it at);
    ``R``, ``B``: 3R's ring and bound constants; ``cr``: CR's ``(Q, W, s_i, s_ie, Lb)`` (`cr_tables`).
    """
    n = l1.size
    memo, done = np.empty((n, 3)), np.empty(n, np.bool_)
    if n == 0:
        return memo[:, 0], memo[:, 1], done
    if cr is not None:
        Q, W, s_i, s_ie, Lb = cr
        R, B = (0.0, 0.0, float(Lb), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (float(s_i), float(s_ie), 0.0, 0.0)
    else:
        Q, W = _NO_Q, _NO_W
    par = int(n >= FREE_PARALLEL_MIN and _parallel(kernels.PARALLEL_MIN))
    _free[par](code, _arr(l1), _arr(v, l1.shape), _arr(s1, l1.shape), tuple(float(r) for r in R),
               tuple(float(b) for b in B), Q, W, *map(float, C), float(kap), _arr(offsets),
               bool(pitchfork), _FREE_MAX, memo, done)
    return memo[:, 0].copy(), memo[:, 1].copy(), done


_NO_Q = np.zeros((5, 0))
_NO_W = np.zeros((3, 0))


def free_hook(code, problem, l1, v, C, kap, fields, R=(0.0,) * 9, B=(0.0,) * 4, cr=None):
    """`Evaluation.free` of a model's call: ``free(sel, s1)`` gives ``(free stretch, fields, done)`` of the slack
    samples ``sel`` (stress ``s1`` at their own stretch) by `free_states`; ``fields(y, stretch, voltage)`` is the
    model's fields dict (``lambda2a``, ``lambda2b``, ``lambda2c``, ``capacitance``, ``r_i``) at equilibria ``y``
    (NaN where not done). ``problem``: the call's, whose scale nodes the trials are scanned at."""
    from .branch import scale_offsets

    offsets = scale_offsets(problem)

    def free(sel, s1):
        vs = v[sel]
        lam, y, done = free_states(code, l1[sel], vs, s1, C, kap, offsets, problem.pitchfork, R, B, cr)
        return lam, fields(y, lam, vs), done

    return free
