"""The compiled quasi-static states of many rolls at once (numba), each roll with its own radii: 3R designs.

`rdea_lab.physics.designs.solve_designs` runs the 3R model of every design
of a study through `rolls`: one compiled loop over designs x samples whose
per-sample state is the twin's (`rdea_lab.physics.step_kernel._state`: the
certified root of `kernels._one` with the roll's own ring constants, and
`step_kernel._free`, the free state of a slack roll descending from the
clamped state). No equation is written here. A sample the compiled state does
not certify is marked, and the caller solves it with the model's own `solve`
(the reference), as `rdea_lab.physics.models._common._path_certified` does
for one roll.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import prange

from . import step_kernel
from .kernels import _parallel, _readonly, _variants
from .result import OK, SLACK


def _rolls_loop(code, P, R, B, offsets, n_off, pitchfork, l1, v, path, slack, sigma, tension, cap, l2b, y, free,
                status, ok):
    for d in prange(l1.shape[0]):
        Rd = (R[d, 0], R[d, 1], R[d, 2], R[d, 3], R[d, 4], R[d, 5], R[d, 6], R[d, 7], R[d, 8])
        Bd = (B[d, 0], B[d, 1], B[d, 2], B[d, 3])
        off = offsets[d, :n_off[d]]
        Pd = P[d]
        fork = pitchfork[d]
        y_prev = math.nan
        last = np.empty(5)  # the free state's scratch (`step_kernel._free`), one per design
        handed = False  # on a path: a sample went to the reference, so do the ones after it (from its state)
        for i in range(l1.shape[1]):
            lam, u = l1[d, i], v[d, i]
            good = not handed and lam >= 1.0 and lam < math.inf and abs(u) < math.inf
            s, c, l2, yy = math.nan, math.nan, math.nan, math.nan
            if good:
                yp = y_prev if path else math.nan
                # SU's state by its own small function, not through `_state`'s code argument (6x faster)
                if code == 0:
                    s, c, l2, yy, st, _, _ = step_kernel._state_su(Pd, lam, u)
                else:
                    s, c, l2, yy, st, _, _ = step_kernel._state(code, Pd, Rd, Bd, off, fork, lam, u, yp,
                                                                step_kernel._NO, step_kernel._ZERO, math.nan,
                                                                step_kernel._NO)
                # a fold, a snap, the range's end: the reference says which, with its voltage
                good = st == OK and s == s and abs(s) < math.inf
            st, f, t = OK, lam, s
            if good and slack and s < 0.0:
                c, l2, good, f = step_kernel._free(code, Pd, Rd, Bd, off, fork, lam, u, s, yy, last)
                st, s = SLACK, 0.0
            sigma[d, i], tension[d, i], cap[d, i], l2b[d, i], y[d, i], free[d, i] = s, t, c, l2, yy, f
            status[d, i] = st
            ok[d, i] = good
            y_prev = yy
            handed = handed or (path and not good)


_rolls = _variants(_rolls_loop)


@functools.lru_cache(maxsize=1 << 16)
def _constants(model, Ri, Rie, Roe, Ro, L1, L1e, L3, C10, C20, C30, eps_r):
    """`step_kernel.constants` of one roll and material (cached: a study solves each design many times)."""
    from .designs import Material
    from .geometry import RollGeometry

    geom = RollGeometry(Ri=Ri, Rie=Rie, Roe=Roe, Ro=Ro, L1=L1, L1e=L1e, L3=L3)
    return step_kernel.constants(model, geom, Material(C10, C20, C30, eps_r), (), (), 0.0, "linear")


def rolls(model, rows, l1, v, *, path, slack):
    """The certified states of ``n`` rolls over their samples ``(n, samples)``.

    ``rows``: ``n`` tuples ``(Ri, Rie, Roe, Ro, L1, L1e, L3, C10, C20, C30, eps_r)``. Returns a dict of
    ``(n, samples)`` arrays: ``sigma1`` (0 where slack), ``tension``, ``capacitance``, ``lambda2b``, ``y``
    (the free coordinate), ``free_stretch``, ``status`` (OK or SLACK) and ``ok`` (False: not certified,
    the reference must solve the sample; on a path, every sample after it too, continued from the state
    before the first).
    """
    consts = [_constants(model, *r) for r in rows]
    n = len(consts)
    code = consts[0][0] if n else 0  # no design: nothing runs
    P = np.ascontiguousarray([c[1][:6] for c in consts], float).reshape(n, 6)
    R = np.ascontiguousarray([c[2] for c in consts], float).reshape(n, 9)
    B = np.ascontiguousarray([c[3] for c in consts], float).reshape(n, 4)
    n_off = np.array([c[4].size for c in consts], np.int64)
    offsets = np.zeros((n, max(int(n_off.max(initial=0)), 1)))
    for j, c in enumerate(consts):
        offsets[j, :c[4].size] = c[4]
    pitchfork = np.array([c[5] for c in consts], np.bool_)
    # read-only, whatever the caller's are: one compiled variant of the loop (numba compiles one per writability)
    l1 = _readonly(l1, float)
    v = _readonly(np.broadcast_to(v, l1.shape), float)
    out = {k: np.empty(l1.shape) for k in ("sigma1", "tension", "capacitance", "lambda2b", "y", "free_stretch")}
    out["status"] = np.empty(l1.shape, np.int8)
    out["ok"] = np.empty(l1.shape, np.bool_)
    _rolls[_parallel(l1.size)](code, P, R, B, offsets, n_off, pitchfork, l1, v, bool(path), bool(slack),
                               out["sigma1"], out["tension"], out["capacitance"], out["lambda2b"], out["y"],
                               out["free_stretch"], out["status"], out["ok"])
    return out


__all__ = ["rolls"]
