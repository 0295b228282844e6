"""What the quasi-static models share: load factors, the solve driver, the slack state."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..branch import BranchResult, PathResult, follow_branch, follow_path
from ..constants import EPS0
from .._backend import compiled
from ..result import NOT_CONVERGED, OK, SLACK, SNAPPED, PathEnd, finish, is_valid, prepare_inputs

#: Upper end of the admissible range of the active ring's circumferential
#: stretch, as a multiple of the uniaxial value ``lambda1**-0.5``. States
#: beyond it are reported as outside the solved range (and a fold below it as
#: past the limit point). At 10x the active layer would be thinned a
#: hundredfold; no physical input of the paper's materials gets there.
HOOP_STRETCH_CAP = 10.0

#: Slack: largest axial stretch searched for the free (F = 0) state [-].
FREE_STRETCH_MAX = 100.0


def free_check(stress, sigma_at_l1):
    """`free_state`'s final check: where the stress [Pa] at a free stretch found is small enough to be its
    zero (``|stress| <= 1e-6 |sigma_at_l1| + 1e-6``, ``sigma_at_l1`` the clamped roll's stress); False
    where it jumps there (the free roll would snap) or is NaN. The one statement of the tolerance: the
    compiled kernels compile this function (`rdea_lab.physics.kernels.free_check`)."""
    return np.abs(stress) <= 1e-6 * np.abs(sigma_at_l1) + 1e-6


def yeoh_coefficients(material):
    """``(C10, C20, C30)`` [Pa] of a parameter set: floats, or arrays where a design study varies them
    (`rdea_lab.physics.designs`)."""
    return tuple(_number(getattr(material, key)) for key in ("C10", "C20", "C30"))


def _number(value):
    """A float for a scalar, a float array (broadcast against the samples) otherwise."""
    if type(value) is float:
        return value
    value = np.asarray(value, float)
    return float(value) if value.ndim == 0 else value


def kappa(geom, material):
    """Electrical load factor ``eps0 eps_r alpha_e1 eta_b / (2 L3**2)`` [F/m^3 = Pa/V^2].

    The electrical part of the free enthalpy density is
    ``-C v**2 / (2 Omega) = -kappa v**2 lambda1**2 lambda2b**2``, since
    ``C0 / Omega = eps0 eps_r alpha_e1 eta_b / L3**2`` (ERRATA, "Things the
    paper leaves implicit").
    """
    return EPS0 * _number(material.eps_r) * geom.alpha_e1 * geom.eta_b / (2.0 * geom.L3**2)


@dataclass
class Evaluation:
    """A model's equilibria at the given stretches (one entry per sample), before slack.

    ``fields``: ``sigma1`` (the equilibrium's axial stress at the given
    stretch, signed), ``lambda2a``, ``lambda2b``, ``lambda2c``,
    ``capacitance``, ``r_i``. ``critical_voltage`` / ``range_voltage`` as in
    ModelResult (None: NaN for every sample); ``end`` the path's last coordinate.
    ``free``: the compiled free state of slack samples, where the model has one
    (`rdea_lab.physics.ring_kernels.free_hook`): ``free(sel, sigma1)`` returns
    ``(free stretch, fields, done)`` of the samples ``sel``; those not done are
    `free_state`'s.
    """

    status: np.ndarray
    critical_voltage: np.ndarray | None
    range_voltage: np.ndarray | None
    fields: dict
    end: float | None = None
    y: np.ndarray | None = None
    free: Callable | None = None



def ring_kernels(kernel, n, *coefficients):
    """`rdea_lab.physics.ring_kernels` where `compiled` gives the compiled kernels for ``n`` samples and every
    coefficient is one number (a design study's per-sample materials stay numpy), else None."""
    if not all(np.ndim(c) == 0 for c in coefficients) or compiled(kernel, n) is None:
        return None
    from .. import ring_kernels as module

    return module


def with_bounds_buffer(fast, n, path, origin, solved):
    """``solved(out)``: a model's evaluation with its problem's bounds written into ``out``, the thread's reused
    buffer (`rdea_lab.physics.ring_kernels.scratch`) where the compiled rising-ramp rule runs (``fast``, no path,
    no ``origin``), else ``solved()`` (fresh arrays). The bounds are not read after the solve: the evaluation
    holds none of them."""
    if fast is None or path or origin is not None:
        return solved()
    with fast.scratch(n) as out:
        return solved(out)


def evaluate_free(problem, state, *, path=False, start=None, origin=None, kernel="auto", free=None) -> Evaluation:
    """Solve a one-coordinate problem (rising-ramp rule, the path, or descent from
    ``origin`` per sample) and assemble its fields.

    ``state(y)`` returns the fields dict at the equilibrium coordinates. With a
    compiled ``kernel``, the samples it certifies (one basin, no fold) are its
    and every other sample is the reference's rule (compiled too:
    `_branch_certified`, `follow_path`); ``free(problem)`` then
    gives the compiled free state of its slack samples (`Evaluation.free`).
    """
    fast = compiled(kernel, problem.K.size) if (problem.kernel is not None and origin is None) else None
    if origin is not None:
        found = follow_path(problem, origin=origin)
    elif path:
        y_start, label = start if start is not None else (None, None)
        if fast is not None:
            found = _path_certified(fast, problem, y_start, label)
        else:
            found = follow_path(problem, y_start, start_label=label)
    elif fast is not None:
        found = PathResult(*_branch_certified(fast, problem), None)
    else:
        found = PathResult(*follow_branch(problem), None)
    return Evaluation(found.status, _voltage(problem, found.K_crit), _voltage(problem, found.K_range),
                      state(found.y), found.end, found.y,
                      free(problem) if (free is not None and fast is not None) else None)


def _voltage(problem, K):
    """`Problem.voltage`, None for None (no sample has one)."""
    return None if K is None else problem.voltage(K)


def _branch_certified(fast, problem):
    """`follow_branch` with the compiled kernel's certified samples, the rest by the reference's steps compiled
    (`rdea_lab.physics.scan_kernel.follow_branch_at`); ``K_crit``, ``K_range`` None where every sample is
    certified (no fold, no range end)."""
    y, ok = fast.branch_roots(problem, whole=False)
    n = y.size
    status = np.full(n, OK, dtype=np.int8)
    bad = np.flatnonzero(~ok)
    if not bad.size:
        return BranchResult(y, status, None, None)
    K_crit, K_range = np.full(n, np.nan), np.full(n, np.nan)
    from ..scan_kernel import follow_branch_at  # the reference's rising-ramp rule, compiled

    y[bad], status[bad], K_crit[bad], K_range[bad] = follow_branch_at(problem, bad)
    return BranchResult(y, status, K_crit, K_range)


def _path_certified(fast, problem, y_start, label):
    """`follow_path` with the compiled kernel's certified samples: a single-basin sample's state is its
    one root whatever came before; the other samples take the reference's full scan and path rule compiled
    (`rdea_lab.physics.scan_kernel`), each from the state before it."""
    y, ok = fast.branch_roots(problem, whole=True, start=y_start)
    n = y.size
    status = np.full(n, OK, dtype=np.int8)
    K_crit, K_range = np.full(n, np.nan), np.full(n, np.nan)
    if n == 0:
        return PathResult(y, status, K_crit, K_range, (y_start, label))
    if ok.all():
        return PathResult(y, status, K_crit, K_range, (float(y[-1]), None))
    from ..scan_kernel import follow_runs  # the reference's full scan and path rule, compiled

    end = follow_runs(problem, y, ok, y_start, label, status, K_crit, K_range)
    return PathResult(y, status, K_crit, K_range, end)


def check_start(name, path, start):
    """``(y, label)`` of a path's ``start`` (a `PathEnd` of model ``name``), None without one."""
    if start is None:
        return None
    if not path:
        raise ValueError("start: a path's end continues a path; give path=True (without it every sample "
                         "is solved from the unloaded roll)")
    if not isinstance(start, PathEnd) or start.model != name:
        raise ValueError(f"start: expected the end of a {name} path (ModelResult.end), got {start!r}")
    return (start.y, start.label)


def solve_model(name, evaluate, geom, material, stretch=None, voltage=None, *, path=False, start=None, slack=True,
                kernel="auto", prepared=None):
    """The solve of every model: inputs checked, equilibria, slack, one ModelResult.

    ``evaluate(geom, material, l1, v, path=, start=)`` returns an
    :class:`Evaluation` at 1-D clean inputs. Where the equilibrium's tension
    is negative the roll is slack: force and stress 0, the other fields those
    of the free state (:func:`free_state`), status ``SLACK``. With
    ``slack=False`` the equilibrium at the given stretch is returned as it is,
    a negative stress and force included (the paper's equations with
    Assumption 1 taken as given: for comparing models and checking equations).
    ``prepared``: `prepare_inputs`' result, where the caller has it already (instead of ``stretch``,
    ``voltage``).
    """
    l1, v, bad, shape, raw = prepare_inputs(stretch, voltage) if prepared is None else prepared
    start = check_start(name, path, start)
    if path and bad.any():  # a NaN sample has no state: the path runs on across it
        good = np.flatnonzero(~bad)
        ev = _expand(evaluate(geom, _take(material, good), l1[good], v[good], path=True, start=start, kernel=kernel),
                     good, l1.size, start)
    else:
        ev = evaluate(geom, material, l1, v, path=path, start=start, kernel=kernel)
    fields = dict(ev.fields)
    fields["tension"] = fields["sigma1"]
    status = ev.status  # the evaluation's own: written in place
    free = l1.copy()
    if slack:
        with np.errstate(invalid="ignore"):
            slack = np.flatnonzero(np.asarray(fields["sigma1"]) < 0.0)  # few: the other tests on those alone
        slack = slack[is_valid(status[slack]) & ~bad[slack]]
    else:
        slack = []
    if len(slack):
        # a path's free state continues the branch the clamped state is on
        origin = ev.y[slack] if (path and ev.y is not None) else None
        # the free state's trials are solved as the call's samples were (compiled or not), however few
        sub_kernel = kernel if kernel != "auto" else ("numba" if compiled(kernel, l1.size) is not None else "numpy")
        s1 = fields["sigma1"][slack]
        if origin is None and ev.free is not None:  # compiled, the samples it does not finish by the reference
            lam_f, f_free, done = ev.free(slack, s1)
            st_f = np.full(slack.size, SLACK, np.int8)
            rest = np.flatnonzero(~done)
            if rest.size:
                at = slack[rest]
                lam_r, st_f[rest], f_r = free_state(evaluate, geom, _take(material, at), l1[at], v[at], s1[rest],
                                                    kernel=sub_kernel)
                lam_f[rest] = lam_r
                for key, arr in f_r.items():
                    f_free[key] = np.array(f_free[key], float)  # one array per field from here on
                    f_free[key][rest] = arr
        else:
            lam_f, st_f, f_free = free_state(evaluate, geom, _take(material, slack), l1[slack], v[slack], s1,
                                             origin=origin, kernel=sub_kernel)
        # slack either way (force 0: the clamped state pushes); a snap-through stays the event it is.
        # Where the free state lies beyond what the model solves (outside its range, past a fold, or
        # past FREE_STRETCH_MAX) the stretches and capacitance stay the clamped state's, free_stretch NaN.
        status[slack] = np.where(status[slack] == SNAPPED, SNAPPED, SLACK)
        sig = np.asarray(fields["sigma1"], float).copy()
        sig[slack] = 0.0
        fields["sigma1"] = sig
        found = st_f == SLACK
        at, written = slack[found], {}
        for key in ("lambda2a", "lambda2b", "lambda2c", "capacitance", "r_i"):
            arr = fields[key]
            prev = written.get(id(arr))
            if prev is not None and f_free[key] is f_free[prev[0]]:  # one array for equal fields (SU, 1R)
                fields[key] = prev[1]
                continue
            if (prev is not None or not isinstance(arr, np.ndarray) or arr.shape != l1.shape
                    or arr.dtype != float or not arr.flags.writeable):
                arr = np.array(np.broadcast_to(np.asarray(arr, float), l1.shape))
            written[id(fields[key])] = (key, arr)
            arr[at] = f_free[key][found]  # the evaluation's own arrays: written in place
            fields[key] = arr
        free[slack] = lam_f
    end = None
    if path:
        y_end, label = ev.end if isinstance(ev.end, tuple) else (ev.end, None)
        end = PathEnd(name, y_end, label)
    return finish(name, geom, l1, bad, shape, raw, fields, status, ev.critical_voltage, ev.range_voltage, free,
                  end)


def free_state(evaluate, geom, material, l1, v, sigma_at_l1, *, origin=None, rtol=1e-13, max_iter=200,
               kernel="auto"):
    """The free (F = 0) state of a slack roll: the stretch above ``l1`` where the stress vanishes.

    At fixed voltage the equilibrium stress rises with stretch; the free
    stretch is bracketed by growing ``l1`` by 25 % steps, then found by the
    Illinois variant of regula falsi. Each trial is the model itself: the
    rising-ramp rule at the trial stretch, or with ``origin`` (a path's
    coordinates) descent from it, so the free state stays on the path's branch.
    A free stretch where the stress jumps (the free roll would snap) rather
    than vanishes is ``NOT_CONVERGED``.

    Returns
    -------
    stretch : numpy.ndarray
        Free stretch [-] (NaN where there is none).
    status : numpy.ndarray of int8
        ``SLACK`` where found; the model's status at the stretch where it
        lost its equilibrium (e.g. past a limit point: the free roll would
        pull in), or ``NOT_CONVERGED``.
    fields : dict
        ``lambda2a``, ``lambda2b``, ``lambda2c``, ``capacitance``, ``r_i``
        of the free state.
    """
    n = l1.size
    status = np.full(n, SLACK, dtype=np.int8)
    lo, s_lo = l1.astype(float).copy(), np.asarray(sigma_at_l1, float).copy()
    hi = lo.copy()
    s_hi = np.full(n, -np.inf)
    open_ = np.arange(n)
    while open_.size:
        trial = np.minimum(hi[open_] * 1.25, FREE_STRETCH_MAX)
        ev = _trial(kernel, evaluate, geom, material, trial, v[open_], origin, open_)
        sig = ev.fields["sigma1"]
        ok = is_valid(ev.status) & np.isfinite(sig)
        status[open_[~ok]] = np.where(is_valid(ev.status[~ok]), NOT_CONVERGED, ev.status[~ok])
        got = ok & (sig >= 0.0)
        hi[open_[got]] = trial[got]
        s_hi[open_[got]] = sig[got]
        more = ok & ~got
        lo[open_[more]] = trial[more]
        s_lo[open_[more]] = sig[more]
        stuck = more & (trial >= FREE_STRETCH_MAX)
        status[open_[stuck]] = NOT_CONVERGED
        hi[open_[more]] = trial[more]
        open_ = open_[more & ~stuck]
    work = np.flatnonzero(status == SLACK)
    lam = np.full(n, np.nan)
    side = np.zeros(n, dtype=np.int8)  # Illinois: which end was kept last time
    a, b, fa, fb = lo[work], hi[work], s_lo[work], s_hi[work]
    tol = 1e-10 * np.abs(np.asarray(sigma_at_l1, float)[work])  # the free state's stress, relative to the clamp's
    x = b.copy()
    active = np.arange(work.size)
    for _ in range(max_iter):
        if active.size == 0:
            break
        xa, xb, ya, yb = a[active], b[active], fa[active], fb[active]
        xn = (xa * yb - xb * ya) / (yb - ya)
        xn = np.where((xn > xa) & (xn < xb), xn, 0.5 * (xa + xb))
        ev = _trial(kernel, evaluate, geom, material, xn, v[work[active]], origin, work[active])
        yn = ev.fields["sigma1"]
        bad = ~(is_valid(ev.status) & np.isfinite(yn))
        yn = np.where(bad, 0.0, yn)  # treat as the root: flagged below
        status[work[active[bad]]] = NOT_CONVERGED
        x[active] = xn
        neg = yn < 0.0
        s = side[work[active]]
        # replace the end on the root's side; halve the kept end's value when it is kept twice
        a[active] = np.where(neg, xn, xa)
        fa[active] = np.where(neg, yn, np.where(s == 1, 0.5 * ya, ya))
        b[active] = np.where(neg, xb, xn)
        fb[active] = np.where(neg, np.where(s == -1, 0.5 * yb, yb), yn)
        side[work[active]] = np.where(neg, -1, 1)
        done = bad | (np.abs(yn) <= tol[active]) | (b[active] - a[active] <= rtol * b[active])
        active = active[~done]
    status[work[active]] = NOT_CONVERGED
    lam[work] = x
    keep = status == SLACK
    lam[~keep] = np.nan
    fields = {k: np.full(n, np.nan) for k in ("lambda2a", "lambda2b", "lambda2c", "capacitance", "r_i")}
    w = np.flatnonzero(keep)
    if w.size:
        ev = _trial(kernel, evaluate, geom, material, lam[w], v[w], origin, w)
        jump = ~free_check(ev.fields["sigma1"], np.asarray(sigma_at_l1, float)[w])
        status[w[jump]] = NOT_CONVERGED
        lam[w[jump]] = np.nan
        for key in fields:
            fields[key][w] = np.broadcast_to(np.asarray(ev.fields[key], float), (w.size,))
    return lam, status, fields


def _trial(kernel, evaluate, geom, material, l1, v, origin, idx):
    material = _take(material, idx)
    if origin is None:
        return evaluate(geom, material, l1, v, kernel=kernel)
    return evaluate(geom, material, l1, v, origin=origin[idx], kernel=kernel)


def _take(material, idx):
    """The material of the samples ``idx``: itself, or its entries where it varies per sample
    (`rdea_lab.physics.designs.SampleMaterial`)."""
    take = getattr(material, "take", None)
    return material if take is None else take(idx)


def _expand(ev: Evaluation, good, n, start) -> Evaluation:
    """An evaluation of the samples ``good`` spread back over ``n`` samples (NaN elsewhere)."""
    def spread(a, fill):
        if a is None:
            return None
        out = np.full(n, fill, dtype=np.asarray(a).dtype if fill is not np.nan else float)
        out[good] = a
        return out
    fields = {k: spread(np.broadcast_to(np.asarray(a, float), (good.size,)), np.nan) for k, a in ev.fields.items()}
    return Evaluation(spread(ev.status, NOT_CONVERGED).astype(np.int8), spread(ev.critical_voltage, np.nan),
                      spread(ev.range_voltage, np.nan), fields, ev.end if good.size else (start or (None, None)),
                      None if ev.y is None else spread(ev.y, np.nan))
