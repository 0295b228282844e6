"""The compiled per-sample step of the twin (numba): quasi-static state, branches and force in one call.

`rdea_lab.twin.TwinStep` calls `step` once per sample with its state and
parameter arrays. The equations are the reference's own functions compiled
(`kernels._jit`); the state follows the path rule of
`rdea_lab.physics.branch.follow_path`: ``y0`` where the load is at most
``h(y0)`` and the previous state is not above ``y0`` (no scan needed), the
certified root of `kernels._one` where ``h`` rises everywhere (one basin),
and otherwise the reference's full scan and path rule compiled
(`scan_kernel.path_rule`: folds, snaps, pull-in, the range's end and the
label a run of lost samples keeps). A slack roll's free state is
`models._common.free_state`'s search, each trial the same path rule. So
every 1R and 3R sample with a finite stretch >= 1 and voltage stays
compiled; `step` returns ``NEEDS_REFERENCE`` (state untouched) only for a
CR roll with a core (no compiled CR state) and for bad inputs, which the
caller hands to the reference solver and then to `advance` (branches and
force, compiled).

Cost: bounded by the scan's (see `scan_kernel`) times the free state's
trials (at most ``200 + log(100) / log(1.25) + 2`` of them, in practice
below 15); measured by ``benchmarks/step_worst_case.py``.

State ``S``: ``[started, t, stretch, y, has_state, label_status, label_K_crit, q_1 .. q_M]`` (the label:
status and fold of the last sample where it had no state, ``has_state`` 0); parameters
``P``: ``[C10, C20, C30, kappa, C0, area, eta_v0, law, M, k_1 .. k_M,
tau_1 .. tau_M]`` (law 0 linear, 1 finite strain; ``k`` the branch moduli);
output ``out``: ``[force, capacitance, sigma1, sigma1_irr, lambda2b, status]``.
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np

from . import _branch_kernels as _bk
from .kernels import _fields3, _basis, _one, _slope, _terms, free_check, free_stretch
from .ring_kernels import _bounds1, _bounds3, _stress1
from .models import one_ring, three_ring
from .branch import MAX_ITER, N_SCAN, RTOL, scale_offsets
from .models._common import FREE_STRETCH_MAX, kappa, yeoh_coefficients
from .result import OK, OVERFLOW, SLACK, SNAPPED
from .scan_kernel import path_rule
from .viscoelastic import _FS_GROW, _FS_STEP, _FS_STRETCH_STEP


#: Model codes of `step` (CR is not stepped here: its samples go to the reference).
CODES = {"su": 0, "1r": 1, "3r": 3}
#: `step` results.
DONE, NEEDS_REFERENCE, TIME_NOT_INCREASING = 0, 1, -1
# integers and flags passed to compiled calls as typed values, never as Python constants: numba compiles a
# callee once more for each literal argument it is given (a `0`, a `False`, a global int), and the state's
# chain (`_state`, `_path_state`, `scan_kernel.path_rule`, `kernels._one`) takes seconds to compile
_N_SCAN = np.int64(N_SCAN)
_RTOL, _MAX_ITER = RTOL, np.int64(MAX_ITER)
_NO, _YES, _ZERO = np.bool_(False), np.bool_(True), np.int64(0)
_FREE_MAX = FREE_STRETCH_MAX
_Q = np.zeros((4, 0))
#: Where the branches' strains start in ``S``.
Q_START = 7


def constants(model, geom, material, modulus, tau, eta_v0, law):
    """``(code, P, R, B, offsets, pitchfork)`` of `step` for a model, a roll and a material (see the module
    docstring; ``code`` -1: every sample is the reference's). A solid roll's CR is the SU state exactly
    (``r_i = 0`` pinned), so it steps as SU."""
    code = CODES.get(model, -1)
    if model == "cr" and getattr(geom, "Ri", None) == 0.0:
        code = CODES["su"]
    modulus, tau = np.atleast_1d(np.asarray(modulus, float)), np.atleast_1d(np.asarray(tau, float))
    P = np.array([*yeoh_coefficients(material), kappa(geom, material), geom.C0(material.eps_r), geom.area,
                  float(eta_v0), 0.0 if law == "linear" else 1.0, modulus.size, *modulus, *tau], float)
    R, B, offsets, pitchfork = (0.0,) * 9, (0.0,) * 4, np.zeros(0), False
    if code in (1, 3):
        # the reference's own problem (at one stretch) says whether it is a pitchfork and what scale its scan
        # is graded to: its scale offsets up to any span the hoop-stretch cap allows (< 1e3 Ro), of which
        # `_state` takes those the sample's own span takes (`branch.scan_nodes`)
        module = three_ring if code == 3 else one_ring
        probe = module.problem(geom, material, np.ones(1), np.zeros(1))
        pitchfork = bool(probe.pitchfork)
        offsets = np.ascontiguousarray(scale_offsets(dataclasses.replace(probe, span_max=1e3)), float)
    if code == 3:
        rings = three_ring._Rings(geom, np.ones(1))
        R, B = rings.constants, rings.bound_constants
    return code, P, R, B, offsets, pitchfork


@numba.njit(cache=True, error_model="numpy")
def advance(S, P, t, l1, sigma_rev, capacitance, lambda2b, status, out):
    """Carry the branches to ``(t, l1)``, compose eqs. (43), (44), (16) and write ``out``; advance ``S``."""
    area, eta_v0, law, M = P[5], P[6], P[7], int(P[8])
    started = S[0] != 0.0
    rate = 0.0
    if started:
        dt = t - S[1]
        rate = (l1 - S[2]) / dt
    irr = 0.0
    for j in range(M):
        k, tau = P[9 + j], P[9 + M + j]
        q = S[Q_START + j] if started else 0.0
        if started:
            if law == 0.0:
                r = dt / tau
                q = math.exp(-r) * q + rate * tau * -math.expm1(-r)
            else:
                q = _bk.interval(q, S[1], t, S[2], l1, tau, _FS_STEP, _FS_GROW, _FS_STRETCH_STEP)
        S[Q_START + j] = q
        irr += k * q if law == 0.0 else k * (math.expm1(2.0 * q) - math.expm1(-q))
    if eta_v0 != 0.0:
        irr += eta_v0 * rate
    sigma = sigma_rev + irr
    force = sigma * area / l1
    if force < 0.0:  # NaN stays NaN, as np.maximum keeps it
        force = 0.0
    if force == 0.0:
        sigma = 0.0
    if status == OK and sigma_rev + irr < 0.0:
        status = SLACK
    elif status == SLACK and force > 0.0:
        status = OK
    out[0], out[1], out[2], out[3], out[4], out[5] = force, capacitance, sigma, irr, lambda2b, status
    S[0], S[1], S[2] = 1.0, t, l1


@numba.njit(cache=True, error_model="numpy")
def _state_su(P, l1, v):
    """`_state` of the SU model (no branches: the stress at the stretch), a function of its own: the design
    loop calls it directly (6x faster than through `_state`'s code argument), and so does `_free`'s SU trial,
    whose compiled form then holds none of the ring models' state."""
    C10, C20, C30, kap, C0 = P[0], P[1], P[2], P[3], P[4]
    b, x = _basis(l1)
    W1, _ = _slope(x, (C10, C20, C30))
    return b * W1 - kap * (l1 * v ** 2), C0 * l1, 1.0 / np.sqrt(l1), math.nan, OK, math.nan, False


@numba.njit(cache=True, error_model="numpy")
def _state(code, P, R, B, offsets, pitchfork, l1, v, y_prev, label, label_status, label_K, origin):
    """The path's state at ``(l1, v)`` coming from ``y_prev`` (NaN: the unloaded roll) as
    `branch.follow_path` finds it: ``(sigma_rev, capacitance, lambda2b, y, status, K_crit, lost)``.
    ``label``: the sample before had no state (``label_status``, ``label_K``: its status and fold);
    ``origin``: descent from ``y_prev`` alone (the free state's trials). The certified root of
    `kernels._one` where it applies, else the reference's full scan (`scan_kernel.path_rule`)."""
    if code == 0:
        return _state_su(P, l1, v)
    C10, C20, C30, kap, C0 = P[0], P[1], P[2], P[3], P[4]
    if code == 1:
        y0, y_max, load = _bounds1(l1, kap)
    else:
        y0, y_max, load = _bounds3(l1, kap, B)
    K = load * v * v
    h0 = 0.0
    if pitchfork:
        _, p_yy, _, c_yy = _terms(code, y0, l1, R, _Q, C10, C20, C30)
        h0 = p_yy / c_yy
    if K <= h0 and (y_prev != y_prev or y_prev <= y0):
        # y0 is a minimum of g (g_y >= 0 there, or g_yy >= 0 at a pitchfork) and the state before is not
        # above it: descent stays at y0 and crosses no fold, whatever h does beyond (the reference scans it
        # all and finds the same, unless refining a crossing beyond failed: NOT_CONVERGED there)
        y, status, K_crit, lost = y0, OK, math.nan, False
    else:
        y, status, K_crit, lost = _path_state(code, l1, y0, y_max, K, h0, R, C10, C20, C30, offsets, pitchfork,
                                              y_prev, label, label_status, label_K, origin)
        if not (status == OK or status == SNAPPED):  # no state: the reference's fields are NaN
            return math.nan, math.nan, math.nan, y, status, K_crit, lost
    if code == 1:
        return _stress1(y, l1, v, C10, C20, C30, kap), C0 * (l1 * y) ** 2, y, y, status, K_crit, lost
    sigma, _, l2b, _, cap, _ = _fields3(y, l1, v, R, C10, C20, C30, kap, C0, 0.0)  # (r_i is not needed)
    return sigma, cap, l2b, y, status, K_crit, lost


@numba.njit(cache=True, error_model="numpy")
def _path_state(code, l1, y0, y_max, K, h0, R, C10, C20, C30, offsets, pitchfork, y_prev, label, label_status,
                label_K, origin):
    """``(y, status, K_crit, lost)``: the certified root of `kernels._one` where it applies, else the
    reference's full scan (`scan_kernel.path_rule`)."""
    first = (1.0 / _N_SCAN) ** 2 * (y_max - y0)
    n_off = 0
    while n_off < offsets.size and offsets[n_off] < first:
        n_off += 1
    off = offsets[:n_off]
    if K > h0:  # (at or below h0 `_one` certifies only the state y0 from below it, which `_state` took)
        y, cert = _one(code, l1, y0, y_max, K, h0, R, _Q, C10, C20, C30, off, _YES, _RTOL, _MAX_ITER, _N_SCAN,
                       pitchfork)
        if cert == 1:
            return y, OK, math.nan, False
    start = y0 if y_prev != y_prev else y_prev
    y, status, K_crit, _, lost = path_rule(code, l1, y0, y_max, K, h0, R, _Q, C10, C20, C30, off, _N_SCAN,
                                           pitchfork, start, label, label_status, label_K, origin, _RTOL, _MAX_ITER)
    return y, status, K_crit, lost


@numba.njit(cache=True, error_model="numpy")
def _free_trial(lam, args):
    """A trial of `_free`: the path's state at stretch ``lam`` descending from ``origin``, ``(stress, valid)``;
    the trial's stretch, stress, capacitance, lambda2b and status kept in ``last``."""
    code, P, R, B, offsets, pitchfork, v, origin, last = args
    sig, cap, l2b, _, st, _, _ = _state(code, P, R, B, offsets, pitchfork, lam, v, origin, _NO, _ZERO, 0.0, _YES)
    last[0], last[1], last[2], last[3], last[4] = lam, sig, cap, l2b, st
    return sig, (st == OK or st == SNAPPED)


@numba.njit(cache=True, error_model="numpy")
def _free_trial_su(lam, args):
    """`_free_trial` of the SU model (`_state_su`)."""
    P, v, last = args
    sig, cap, l2b, _, st, _, _ = _state_su(P, lam, v)
    last[0], last[1], last[2], last[3], last[4] = lam, sig, cap, l2b, st
    return sig, (st == OK or st == SNAPPED)


@numba.njit(cache=True, error_model="numpy")
def _free(code, P, R, B, offsets, pitchfork, l1, v, sigma_l1, origin, last):
    """The free (F = 0) state of a slack roll: `kernels.free_stretch` (the steps of
    `models._common.free_state`), each trial the path's state descending from ``origin``, then the
    reference's final check. ``(capacitance, lambda2b, found, free stretch)``. ``last``: scratch of 5
    floats (the caller's: no allocation per sample) for the last trial's state."""
    if code == 0:
        return _free_with(_free_trial_su, (P, v, last), l1, sigma_l1, last)
    return _free_with(_free_trial, (code, P, R, B, offsets, pitchfork, v, origin, last), l1, sigma_l1, last)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _free_with(trial, args, l1, sigma_l1, last):
    """`_free` with its trial function (``trial(stretch, args)``, which keeps its state in ``last``); inlined,
    as `kernels.free_stretch` is (a compiled function passed as an argument could not be cached)."""
    last[0] = math.nan
    x = free_stretch(trial, args, l1, sigma_l1, _FREE_MAX)
    if x != x:
        return math.nan, math.nan, False, math.nan
    if last[0] != x:  # the stretch returned is not the last trial's: its state computed once more
        trial(x, args)
    sig, cap, l2b, st = last[1], last[2], last[3], int(last[4])
    if not ((st == OK or st == SNAPPED) and free_check(sig, sigma_l1)):
        return math.nan, math.nan, False, math.nan
    return cap, l2b, True, x


@numba.njit(cache=True, error_model="numpy")
def step(code, S, P, R, B, offsets, pitchfork, t, l1, v, out):
    """One sample: `DONE` (``out`` written, ``S`` advanced), `NEEDS_REFERENCE` or `TIME_NOT_INCREASING`."""
    started = S[0] != 0.0
    if not (abs(t) < math.inf) or (started and not (t > S[1])):
        return TIME_NOT_INCREASING
    if code < 0:
        return NEEDS_REFERENCE
    if not (l1 >= 1.0 and l1 < math.inf and abs(v) < math.inf):
        return NEEDS_REFERENCE
    label = started and S[4] == 0.0
    sigma, cap, l2b, y, status, K_crit, lost = _state(code, P, R, B, offsets, pitchfork, l1, v,
                                                      S[3] if started else math.nan, label, int(S[5]), S[6],
                                                      _NO)
    if status == OK or status == SNAPPED:
        if not (abs(sigma) < math.inf and abs(sigma * P[5] / l1) < math.inf):
            sigma, cap, l2b, status = math.nan, math.nan, math.nan, OVERFLOW
        elif sigma < 0.0:  # slack: the roll's own state is its free one (the clamped one's where none is found)
            cap_f, l2b_f, found, _ = _free(code, P, R, B, offsets, pitchfork, l1, v, sigma, y, np.empty(5))
            if found:
                cap, l2b = cap_f, l2b_f
            if status != SNAPPED:
                status = SLACK
    advance(S, P, t, l1, sigma, cap, l2b, status, out)
    S[3], S[4] = y, 0.0 if lost else 1.0
    S[5], S[6] = (status, K_crit) if lost else (0.0, math.nan)
    return DONE
