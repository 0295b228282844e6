"""Compiled passes of the 1R, 3R and CR solves around the certified root kernel (numba, ``cache=True``).

The root of each sample is `kernels.branch_roots`' (a free state's trial: `kernels._one`); what
this module compiles is the rest of a `solve`, with the numpy code as the
reference (the tests check one against the other):

- the result fields at the equilibria: `one_ring.fields`,
  `three_ring.ring_fields` and CR's `continuum.node_mechanics` /
  `continuum.closing` compiled as they are (`kernels._jit`), one parallel
  pass each (`fields1`, `fields3`, `fields_cr`), so equal to the numpy
  functions bit for bit;
- the problems' bounds and loads (`bounds`);
- a slack roll's free state: `kernels.free_stretch` (the bracketing and
  Illinois iteration of `models._common.free_state`, the one compiled form of
  it), each trial the rising-ramp state at the trial stretch from the
  certified `kernels._one` and its stress from the model's compiled fields;
  `_free_lanes` takes the same steps for many samples in lockstep, each
  round's trials in one batched scan (`kernels._scan_block`), bit for bit the
  same. A sample whose search meets a trial that is not certified, or that ends
  without a free state, is reported as not done: the caller hands it to the
  numpy `free_state` (so every status other than ``SLACK`` is the reference's);
- a buffer per thread for the problems' bounds (`scratch`).
"""

from __future__ import annotations

import contextlib
import math
import threading

import numba
import numpy as np
from numba import prange

from . import kernels
from .branch import MAX_ITER, N_SCAN, RTOL
from .kernels import (_arr, _basis, _fields3, _free_start, _free_step, _gradient, _h_start, _jit, _one, _parallel,
                      _put, _scan_block, _slope, _variants, free_check, free_stretch)
from .models import continuum, one_ring, three_ring
from .models._common import FREE_STRETCH_MAX

_stress_from1 = _jit(one_ring.stress_from, inline="always")
_stress1 = _jit(one_ring.stress, inline="always", gradient_terms=_gradient, stress_from=_stress_from1)
_fields1 = _jit(one_ring.fields, inline="always", stress=_stress1,
                fields_from=_jit(one_ring.fields_from, inline="always"))
# inlined: the loop over samples of `bounds` vectorizes
_bounds1 = _jit(one_ring.bounds, inline="always")
_xi_hoop = _jit(three_ring.xi_at_hoop_stretch, inline="always")
_bounds3 = _jit(three_ring.bounds, inline="always", xi_at_hoop_stretch=_xi_hoop)
_bounds_cr = _jit(continuum.bounds, inline="always")
_node_mech = _jit(continuum.node_mechanics, inline="always", slope=_slope)
_closing = _jit(continuum.closing, inline="always")
# `three_ring.ring_fields` with every piece inlined, for the loop of `fields3`
_fields3_inline = _jit(three_ring.ring_fields, inline="always",
                       fields_from=_jit(three_ring.fields_from, inline="always"),
                       ring_state=_jit(three_ring.ring_state, inline="always", gradient_terms=_gradient,
                                       ring_stress=_jit(three_ring.ring_stress, inline="always"),
                                       ring_geometry=_jit(three_ring.ring_geometry, inline="always",
                                                          radii=_jit(three_ring.radii, inline="always"))))

# typed, not Python ints: a literal argument makes numba compile a callee once more (see `step_kernel`)
_N_SCAN = np.int64(N_SCAN)
_RTOL, _MAX_ITER = RTOL, np.int64(MAX_ITER)
_NO, _ZERO = np.bool_(False), np.int64(0)
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


_fcr = _variants(_fields_cr_loop)


def _fields1_loop(l2, l1, v, C10, C20, C30, kap, C0, Ro, Ri, out):
    for i in prange(l2.size):
        out[0, i], out[1, i], out[2, i] = _fields1(l2[i], l1[i], v[i], C10, C20, C30, kap, C0, Ro, Ri)


def _fields3_loop(y, l1, v, R, C10, C20, C30, kap, C0, Ro, out):
    for i in prange(y.size):
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i] = _fields3_inline(
            y[i], l1[i], v[i], R, C10, C20, C30, kap, C0, Ro)


_f1 = _variants(_fields1_loop)
_f3 = _variants(_fields3_loop)


def fields1(l2, l1, v, C, kap, C0, Ro, Ri):
    """`one_ring.fields` of every sample, ``(sigma1, capacitance, r_i)``: the numpy function compiled as it is,
    one pass over the samples (on every core from `kernels.PARALLEL_MIN` samples on); its numbers bit for bit."""
    l2 = _arr(l2)
    out = np.empty((3, l2.size))
    _f1[_parallel(l2.size)](l2, _arr(l1, l2.shape), _arr(v, l2.shape), *map(float, C), float(kap), float(C0),
                            float(Ro), float(Ri), out)
    return tuple(out)


def fields3(y, l1, v, R, C, kap, C0, Ro):
    """`three_ring.ring_fields` of every sample: the six rows of one block. The numpy function compiled as it
    is, one pass over the samples (on every core from `kernels.PARALLEL_MIN` samples on); its numbers bit for
    bit."""
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
    Q.setflags(write=False)  # read-only, as `_NO_Q` and a compiled global are: one signature of the kernels
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


def _bounds_loop(code, l1, v, kap, B, y0, y_max, load, K):
    if code == 1:
        for i in prange(l1.size):
            y0[i], y_max[i], load[i] = _bounds1(l1[i], kap)
            K[i] = load[i] * v[i] * v[i]
    elif code == 3:
        for i in prange(l1.size):
            y0[i], y_max[i], load[i] = _bounds3(l1[i], kap, B)
            K[i] = load[i] * v[i] * v[i]
    else:
        for i in prange(l1.size):
            y0[i], y_max[i], load[i] = _bounds_cr(l1[i], kap, B[0], B[1])
            K[i] = load[i] * v[i] * v[i]


_bounds_pass = _variants(_bounds_loop)


def bounds(code, l1, v, kap, B=(0.0,) * 4, out=None):
    """``(y0, y_max, load, K)`` of a model's `~rdea_lab.physics.branch.Problem` in one pass: its ``bounds``
    (`one_ring.bounds`, `three_ring.bounds` with ``B`` its bound constants, `continuum.bounds` with ``B = (s_i,
    s_ie, 0, 0)``) and ``K = load v**2``; ``out``: four rows to write them to (`scratch`)."""
    l1 = _arr(l1)
    out = np.empty((4, l1.size)) if out is None else out
    _bounds_pass[_parallel(l1.size)](code, l1, _arr(v, l1.shape), float(kap), tuple(float(b) for b in B), *out)
    return tuple(out)


#: Calls of up to this many samples take their problem's bounds from `scratch` (a buffer of 8 MiB at most per
#: thread).
SCRATCH_MAX = 1 << 18
_SCRATCH = threading.local()


@contextlib.contextmanager
def scratch(n):
    """Four rows of ``n`` floats for `bounds` that live while the block runs: a buffer of the thread, reused
    from call to call (fresh memory costs a page fault per 4 KiB when first written: some 750 of them on
    1e5 samples, more than the bounds take to compute), fresh memory where the buffer is in use (a solve
    inside the block) or ``n`` is above `SCRATCH_MAX`. Nothing written to it may outlive the block."""
    buf = getattr(_SCRATCH, "buf", None)
    if n > SCRATCH_MAX or getattr(_SCRATCH, "busy", False):
        yield np.empty((4, n))
        return
    if buf is None or buf.shape[1] < n:
        buf = _SCRATCH.buf = np.empty((4, max(n, 4096)))
    _SCRATCH.busy = True
    try:
        yield buf[:, :n]
    finally:
        _SCRATCH.busy = False


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
    y, cert = _one(code, lam, y0, y_max, load * v * v, h0, R, Q, C10, C20, C30, offsets, _NO, _RTOL, _MAX_ITER,
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


#: Lanes of `_free_lanes`: slack samples whose free-state searches run in lockstep, each round's trials in one
#: batched root scan (`kernels._scan_block`).
FREE_LANES = 128
#: Slack samples per task of the threaded `free_states`, at most (`free_chunk`).
FREE_CHUNK = 1024


@numba.njit(cache=True, error_model="numpy")
def _free_lanes(code, l1, v, s1, R, B, Q, W, C10, C20, C30, kap, offsets, pitchfork, free_max, memo, done, i0, i1):
    """`_free_loop` of the samples ``i0 <= i < i1``, `FREE_LANES` at a time in lockstep: each lane takes
    `kernels.free_stretch`'s steps for its sample (`kernels._free_start`, `kernels._free_step`: the one compiled
    form of them), each trial the rising-ramp state of `_rising` (bounds, then `kernels._scan_block`, which
    equals `kernels._one` bit for bit) and `_stress`, so the same result bit for bit; a lane that is done takes
    the next sample. A trial that is not certified (or whose stress is not finite) ends its sample not done,
    as in `_trial`."""
    nl = min(FREE_LANES, i1 - i0)
    idx = np.full(nl, -1)
    state = np.empty((nl, 10))  # each lane's `_free_step` state
    x_try = np.empty(nl)
    vv = np.empty(nl)
    s1v = np.empty(nl)
    act = np.empty(nl, np.int64)
    T = np.empty((8, nl))  # the round's trials, compacted: the scan's arguments and results
    lam, y0, y_max, K, xi0, x0, y, h0 = T[0], T[1], T[2], T[3], T[4], T[5], T[6], T[7]
    ok = np.zeros(nl, np.int8)
    nxt = i0
    busy = 0
    while True:
        for k in range(nl):  # an idle lane takes the next sample
            if idx[k] < 0 and nxt < i1:
                i = nxt
                idx[k] = i
                st = _free_start(l1[i], s1[i], free_max)
                _put(state, k, st)
                x_try[k] = st[10]
                s1v[k] = s1[i]
                vv[k] = v[i]
                memo[i, 0] = memo[i, 1] = math.nan
                done[i] = False
                nxt += 1
                busy += 1
        if busy == 0:
            break
        na = np.int64(0)
        for k in range(nl):  # `_rising`'s bounds
            if idx[k] < 0:
                continue
            act[na] = k
            t = x_try[k]
            lam[na] = t
            if code == 1:
                y0[na], y_max[na], load = _bounds1(t, kap)
            elif code == 3:
                y0[na], y_max[na], load = _bounds3(t, kap, B)
            else:
                y0[na], y_max[na], load = _bounds_cr(t, kap, B[0], B[1])
            K[na] = load * vv[k] * vv[k]
            if code == 4:
                xi0[na] = y0[na]
                _, x0[na] = _basis(t)
            else:
                xi0[na] = x0[na] = t  # (unused)
            na += 1
        # every argument typed as `_roots_loop` passes it: a literal one compiles the scan once more (some 5 s)
        _scan_block(code, lam, y0, y_max, K, xi0, x0, R, Q, C10, C20, C30, offsets, _NO, _RTOL, _MAX_ITER, _N_SCAN,
                    pitchfork, y, ok, h0, _ZERO, na)
        for j in range(na):
            k = act[j]
            i = idx[k]
            trial = x_try[k]
            fin = ok[j] == 1
            ys = math.nan
            if fin:
                Rs = (xi0[j], x0[j], R[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) if code == 4 else R
                ys = _stress(code, y[j], trial, vv[k], Rs, B, Q, W, C10, C20, C30, kap)
            st = state[k]
            p0, p1, p2, p3, p4, p5, p6, p7, p8, p9, x, end, found = _free_step(
                st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7], st[8], st[9], trial, ys, fin, free_max)
            if end:
                # the reference's final check at the free stretch (the last trial): the stress vanishes
                if found == found and free_check(ys, s1v[k]):
                    memo[i, 0], memo[i, 1], memo[i, 2] = trial, y[j], ys
                    done[i] = True
                idx[k] = -1
                busy -= 1
            else:
                _put(state, k, (p0, p1, p2, p3, p4, p5, p6, p7, p8, p9))
                x_try[k] = x


def _free_lanes_loop(code, l1, v, s1, R, B, Q, W, C10, C20, C30, kap, offsets, pitchfork, free_max, memo, done,
                     chunk):
    n = l1.size
    for c in prange((n + chunk - 1) // chunk):
        _free_lanes(code, l1, v, s1, R, B, Q, W, C10, C20, C30, kap, offsets, pitchfork, free_max, memo, done,
                    c * chunk, min(n, (c + 1) * chunk))


def free_chunk(n, threads):
    """Slack samples per task of `_free_lanes_loop` for ``n`` samples on ``threads`` threads: at most `FREE_CHUNK`,
    the tasks a multiple of the threads and of equal size (numba splits a ``prange`` into one contiguous share
    per thread: 3 tasks on 2 threads left one thread a third of the call idle)."""
    if n <= 0:
        return 1
    tasks = threads * -(-n // (threads * FREE_CHUNK))
    return max(1, -(-n // tasks))


_free_batched = _variants(_free_lanes_loop)
#: A free state costs some 5-10 roots and stresses (its trials): calls of this many slack samples run on all
#: cores.
FREE_PARALLEL_MIN = 256


def free_states(code, l1, v, s1, C, kap, offsets, pitchfork, R=(0.0,) * 9, B=(0.0,) * 4, cr=None,
                one_by_one=False, chunk=None):
    """The free states of slack samples (stretch ``l1``, voltage ``v``, stress ``s1 < 0`` there), compiled:
    ``(free stretch, y there, done)``; a sample not done goes to the numpy `free_state`.

    ``code``: `kernels.CODES`; ``offsets``: the scale nodes of the call's problem (`branch.scale_offsets`:
    those of its widest span, so each trial is scanned at least at the nodes the reference scans it at);
    ``R``, ``B``: 3R's ring and bound constants; ``cr``: CR's ``(Q, W, s_i, s_ie, Lb)`` (`cr_tables`).
    The searches run in lockstep lanes (`_free_lanes`); ``one_by_one``: one sample after the other
    (`_free_loop`, each trial `kernels._one`: the same numbers, bit for bit; the tests' reference).
    ``chunk``: the slack samples of one task of lanes (default `free_chunk`; any gives the same numbers).
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
    args = (code, _arr(l1), _arr(v, l1.shape), _arr(s1, l1.shape), tuple(float(r) for r in R),
            tuple(float(b) for b in B), Q, W, *map(float, C), float(kap), _arr(offsets), bool(pitchfork), _FREE_MAX,
            memo, done)
    if one_by_one:
        _free[par](*args)
    else:
        _free_batched[par](*args, free_chunk(n, numba.get_num_threads() if par else 1) if chunk is None else chunk)
    return memo[:, 0].copy(), memo[:, 1].copy(), done


_NO_Q = np.zeros((5, 0))
_NO_Q.setflags(write=False)  # as every Q (`cr_tables`) and the step kernel's: one compiled signature
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
