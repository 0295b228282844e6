"""The minimizers of a calibration: Nelder-Mead with restarts, and bounded least squares.

Both work on one `Objective`, which counts every evaluation against the
budgets, keeps the best point and its history, and builds each trial
parameter set without revalidating it (the physics' own check of the set is
kept; pydantic's parsing of fields that are already floats is not).
"""

from __future__ import annotations

import dataclasses
import math
import re
import time as _time

import numpy as np
from scipy.optimize import least_squares, minimize

from ..specs import ParameterSet, SpecError
from ..specs.params import material_problems, yeoh_slope_nonpositive_at
from ..twin import viscous
from .objective import FusedRuns, residual_scale, residuals
from .parameters import values_of, with_values

#: The methods `calibrate` offers.
METHODS = ("nelder-mead", "least-squares")

#: How Nelder-Mead may get its start (`calibrate`'s ``warm_start``): ``auto`` is ``least-squares`` under
#: metric rms and ``none`` under max.
WARM_STARTS = ("auto", "least-squares", "none")

#: Initial simplex step [internal variables] of a Nelder-Mead polish of a least-squares optimum: about
#: 0.1 % of a log parameter between its bounds, where least squares' answer is trusted (it stopped on a
#: relative step of 1e-9); the adaptive simplex expands from there where it finds a descent, and a
#: restart that still improves goes on. On the five VHB files (finite strain, M = 2) the polish takes
#: 1004, 838 and 708 evaluations from steps 1e-3, 1e-4 and 1e-5 to the same optimum.
POLISH_STEP = 1e-4

#: Objective values closer than this are equal: the normalized force error has
#: reached the rounding floor of double precision.
_F_FLOOR = 1e-14


class OutOfBudget(Exception):
    """The evaluation or time budget is spent (raised by `Objective` before an evaluation)."""


def _yeoh_admissible(C10, C20, C30) -> bool:
    """False where `~rdea_lab.specs.params.material_problems` certainly finds a Yeoh problem (cheap test).

    True does not mean physical: the set's own check decides then.
    """
    if not (math.isfinite(C10) and math.isfinite(C20) and math.isfinite(C30)) or C10 <= 0.0 or C30 < 0.0:
        return False
    return yeoh_slope_nonpositive_at(C10, C20, C30) is None


def at_yeoh_limit(values, rtol=1e-6) -> bool:
    """Whether the Yeoh coefficients of ``values`` [Pa] lie within ``rtol`` (of C20) of the admissibility
    limit ``C20 = -sqrt(3 C10 C30)`` (False without all three)."""
    if not all(n in values for n in ("C10", "C20", "C30")) or values["C20"] >= 0:
        return False
    return not _yeoh_admissible(values["C10"], values["C20"] * (1 + rtol), values["C30"])


def _fast_builder(start: ParameterSet, M: int):
    """``build(values)``: the set `with_values` would give, without pydantic revalidation, or None.

    Names follow `values_of`: ``<field>_v<j>`` (j >= 1) is field ``<field>`` of
    branch j, any other name a field of the set. The result is the start's
    frozen copy with those fields changed, checked by the set's own physical
    check (``_physical``, the model validator that calls
    :func:`~rdea_lab.specs.params.material_problems`) and each changed
    branch's, which raise SpecError as validation would. None when ``start``
    does not follow that pattern (another law's layout): the caller then keeps
    the validated path.
    """
    names = values_of(start)
    slots = {}
    for name in names:
        m = re.fullmatch(r"(.+)_v([1-9][0-9]*)", name)
        slots[name] = (int(m.group(2)) - 1, m.group(1)) if m else (None, name)
    try:
        ok = (M == start.M and all(
            float(getattr(start if j is None else start.branches[j], f)) == names[n] for n, (j, f) in slots.items()))
    except (AttributeError, IndexError, TypeError, ValueError):
        ok = False
    check_set = getattr(type(start), "_physical", None)
    if not ok or not callable(check_set):
        return None
    yeoh = all(n in names for n in ("C10", "C20", "C30"))

    def build(values):
        if yeoh and not _yeoh_admissible(values["C10"], values["C20"], values["C30"]):
            raise SpecError("", "yeoh", "not physical")  # what _physical would say, without formatting it
        top, per_branch = {}, {}
        for name, (j, f) in slots.items():
            if j is None:
                top[f] = float(values[name])
            else:
                per_branch.setdefault(j, {})[f] = float(values[name])
        branches = tuple(b.model_copy(update=per_branch[j]) if j in per_branch else b
                         for j, b in enumerate(start.branches))
        for j in per_branch:
            check = getattr(branches[j], "_physical", None)
            if callable(check):
                check()
        ps = start.model_copy(update={**top, "branches": branches})
        ps._physical()
        return ps

    return build


class _Trial:
    """What the compiled residual pass and :func:`~rdea_lab.twin.viscous` read of a parameter set (law linear),
    without pydantic: a trial point's values, already checked physical."""

    __slots__ = ("C10", "C20", "C30", "eps_r", "branches", "eta_v0", "law")

    def __init__(self, C10, C20, C30, eps_r, branches, eta_v0):
        self.C10, self.C20, self.C30, self.eps_r, self.branches, self.eta_v0 = C10, C20, C30, eps_r, branches, eta_v0
        self.law = "linear"


class _TrialBranch:
    __slots__ = ("modulus", "eta")

    def __init__(self, modulus, eta):
        self.modulus, self.eta = modulus, eta


#: What `_lean_residuals`' function returns for a point the physics refuses.
REFUSED = object()


def _lean_residuals(start: ParameterSet, runs, model, scale):
    """``residuals_of(values)``: the residuals `residuals` gives for the set `_fast_builder` builds of
    ``values``, `REFUSED` where it refuses the set, None where the compiled pass does not apply to it
    (then the full path); or None (no such function) where the pass does not apply to these runs
    (`FusedRuns.of`) or the set is not of the layout `_fast_builder` builds (law linear).

    The check of a point is the set's own (`~rdea_lab.specs.params.material_problems`, once; the layout's
    other rules, one spring kind per branch and of the set's law, hold for every point as they hold for
    ``start``), the physics inputs are read from ``values`` (`_Trial`), and the runs' data and the pass's
    scratch are prepared once (`FusedRuns`): no parameter set is built, the pass and its inputs are the same.
    """
    if _fast_builder(start, start.M) is None or start.law != "linear":
        return None
    fused = FusedRuns.of(runs, scale, model, start.M)
    if fused is None:
        return None
    eps_r = float(start.eps_r)
    keys = [(f"k_v{j}", f"eta_v{j}") for j in range(1, start.M + 1)]

    def residuals_of(values):
        C10, C20, C30 = float(values["C10"]), float(values["C20"]), float(values["C30"])
        if not _yeoh_admissible(C10, C20, C30):
            return REFUSED
        ks = [float(values[k]) for k, _ in keys]
        etas = [float(values[e]) for _, e in keys]
        eta_v0 = float(values["eta_v0"])
        if material_problems(C10, C20, C30, eps_r, ks, etas, eta_v0):
            return REFUSED
        trial = _Trial(C10, C20, C30, eps_r, tuple(map(_TrialBranch, ks, etas)), eta_v0)
        return fused(trial, viscous(trial))

    return residuals_of


#: Seconds between two calls of an objective's ``progress`` (twice a second: a live line, not a log).
REPORT_EVERY = 0.5


class Objective:
    """Objective over runs; counts evaluations, keeps the best point and its history.

    Parameters
    ----------
    runs : list of RunData
    start : ParameterSet
    parameters : list of FitParameter
    model, metric : str
    max_evals : int
        Evaluations before `OutOfBudget` (every residual evaluation counts,
        those of a finite-difference Jacobian too).
    max_time : float
        Seconds of wall time before `OutOfBudget`.
    progress : callable, optional
        ``progress(evaluations, best, elapsed)``, at most once every `REPORT_EVERY` seconds.
    """

    def __init__(self, runs, start, parameters, model, metric, max_evals, max_time, progress=None,
                 clock=_time.monotonic):
        self.runs, self.start, self.parameters = runs, start, parameters
        self.model, self.metric = model, metric
        self.free = [p for p in parameters if p.free]
        self.fixed = {p.name: p.start for p in parameters if not p.free}
        self.max_evals, self.max_time = max_evals, max_time
        self.nfev = 0
        self.best_f, self.best_values, self.best_x = np.inf, None, None
        self.history = []
        self.progress = progress
        self._clock = clock
        self.t0 = clock()
        self._last_report = self.t0
        self._build = _fast_builder(start, start.M)
        self.ndata = int(sum(r.n for r in runs))
        self.scale = residual_scale(runs) if runs else []  # of the data alone: once, not per evaluation
        self._lean = _lean_residuals(start, runs, model, self.scale)
        self._last = None

    # ---- variables
    def values(self, z) -> dict:
        """Values [SI] of every parameter from the sine-mapped internal variables (Nelder-Mead's)."""
        v = dict(self.fixed)
        v.update({p.name: p.to_physical(zi) for p, zi in zip(self.free, z)})
        return v

    def _margin_slot(self):
        """Index of C20 among the free parameters when least squares fits it as the Yeoh margin, else None."""
        if not hasattr(self, "_slot"):  # the parameters do not change: once per objective
            self._slot = self._find_margin_slot()
            self._margin = None if self._slot is None else self._margin_parameter()
        return self._slot

    def _find_margin_slot(self):
        names = [p.name for p in self.free]
        if "C20" not in names or not all(n in {p.name for p in self.parameters} for n in ("C10", "C30")):
            return None
        if self.free[names.index("C20")].lo >= 0.0:  # C20 >= 0 (monotone Yeoh): always admissible, a plain box
            return None
        return names.index("C20")

    def _margin_parameter(self):
        p = next(q for q in self.free if q.name == "C20")
        return dataclasses.replace(p, name="C20 + sqrt(3 C10 C30)", lo=1e-9 * max(p.scale, 1.0), hi=2 * p.hi)

    def values_unit(self, u) -> dict:
        """Values [SI] from the free parameters' log/asinh variables scaled onto [0, 1] (no sine map).

        ``u = (g(x) - g(lo)) / (g(hi) - g(lo))`` with ``g`` the parameter's log or
        asinh map: an affine image of that variable, so [0, 1] are its bounds. C20
        enters as the Yeoh margin ``m = C20 + sqrt(3 C10 C30) > 0`` (asinh, positive
        bounds): the admissibility limit of :func:`~rdea_lab.specs.params.material_problems`,
        which no box on C20 can express, is then a box bound that trf follows.
        """
        u = np.asarray(u, float)
        return self._with_margin(self.values(np.arcsin(np.clip(2.0 * u - 1.0, -1.0, 1.0))), u)

    def values_unit_moved(self, u, values, i) -> dict:
        """`values_unit` of ``u``, given ``values``, those of a point that differs from ``u`` in variable
        ``i`` alone (a Jacobian's probe): that parameter's value is computed again, and C20 where it is the
        Yeoh margin, by the same operations; the others are taken from ``values`` (the same numbers)."""
        z = np.arcsin(np.clip(2.0 * u - 1.0, -1.0, 1.0))
        v = dict(values)
        p = self.free[i]
        v[p.name] = p.to_physical(z[i])
        return self._with_margin(v, u)

    def _with_margin(self, v, u) -> dict:
        """``v`` with C20 from the Yeoh margin's [0, 1] variable in ``u``, where least squares fits C20 so."""
        i = self._margin_slot()
        if i is not None:
            m = self._margin.to_physical(float(np.arcsin(np.clip(2.0 * u[i] - 1.0, -1.0, 1.0))))
            v["C20"] = m - math.sqrt(3.0 * v["C10"] * v["C30"])
        return v

    def internal_of(self, values) -> np.ndarray:
        """Nelder-Mead's sine-mapped internal variables of the free parameters' ``values`` [SI]."""
        return np.array([p.to_internal(values[p.name]) for p in self.free])

    def unit_of(self, values) -> np.ndarray:
        """Inverse of `values_unit` for the free parameters."""
        u = np.array([(np.sin(p.to_internal(values[p.name])) + 1.0) * 0.5 for p in self.free])
        i = self._margin_slot()
        if i is not None:
            m = values["C20"] + math.sqrt(3.0 * values["C10"] * values["C30"])
            u[i] = (np.sin(self._margin_parameter().to_internal(m)) + 1.0) * 0.5
        return u

    # ---- evaluation
    def paramset(self, values) -> ParameterSet | None:
        """The parameter set of ``values``, or None where the physics refuses it."""
        try:
            if self._build is not None:
                return self._build(values)
            return with_values(self.start, values, self.start.M)
        except SpecError:
            return None  # the physics refuses it: the objective is infinite there

    def score_residuals(self, r) -> float:
        """The objective of residuals ``r`` (None: refused), infinite where one is not finite."""
        if r is None:
            return np.inf
        # a residual inf or NaN makes the mean square (and the largest |r|) inf or NaN: no separate test
        f = float(np.sqrt(np.mean(r * r))) if self.metric == "rms" else float(np.max(np.abs(r)))
        return f if f < np.inf else np.inf

    def score(self, params) -> float:
        """The objective of a parameter set (not counted)."""
        return self.score_residuals(None if params is None
                                    else residuals(self.runs, params, self.model, self.scale))

    def evaluate(self, values, x=None):
        """One counted evaluation: ``(objective, residuals or None)``; raises OutOfBudget first if spent.

        ``x``, the minimizer's own variables, is kept with the best point (``best_x``).
        """
        if self.nfev >= self.max_evals or self._clock() - self.t0 > self.max_time:
            raise OutOfBudget
        self.nfev += 1
        r = self._lean(values) if self._lean is not None else None
        if r is REFUSED:
            r = None
        elif r is None:  # the full path: the set built and checked, `residuals`
            params = self.paramset(values)
            r = None if params is None else residuals(self.runs, params, self.model, self.scale)
        f = self.score_residuals(r)
        if f < self.best_f:
            self.best_f, self.best_values, self.best_x = f, values, np.array(x, float) if x is not None else None
            self.history.append((self.nfev, f))
        now = self._clock()
        if self.progress is not None and now - self._last_report >= REPORT_EVERY:
            self._last_report = now
            self.progress(self.nfev, self.best_f, now - self.t0)
        return f, r

    def __call__(self, z) -> float:
        """Nelder-Mead's objective of the sine-mapped internal variables."""
        return self.evaluate(self.values(z), z)[0]

    def residual_vector(self, u) -> np.ndarray:
        """Least squares' residuals of `values_unit` variables (infinite where the physics refuses)."""
        return self.residuals_at(u, self.values_unit(u))[1]

    def residuals_at(self, u, values):
        """`residual_vector` at ``u`` whose `values_unit` are ``values``, with the objective: ``(f, r)``."""
        f, r = self.evaluate(values, u)
        r = np.full(self.ndata, np.inf) if r is None else r
        self._last = (np.array(u, float), r)
        return f, r

    def last_residuals(self, u) -> np.ndarray:
        """`residual_vector` at ``u``, reusing the last evaluation when it was there."""
        if self._last is not None and np.array_equal(self._last[0], u):
            return self._last[1]
        return self.residual_vector(u)


def nelder_mead(obj: Objective, f0: float, *, max_restarts, step, xatol, ftol):
    """Nelder-Mead (scipy, adaptive) from ``obj.best_x`` (sine-mapped variables), restarted from the best
    while it improves.

    Returns ``(restarts, nit, converged, message)``; OutOfBudget propagates.
    """
    z = obj.best_x
    restarts, nit = 0, 0
    f_prev = f0
    while True:
        simplex = np.vstack([z] + [z + step * np.eye(z.size)[i] for i in range(z.size)])
        res = minimize(obj, z, method="Nelder-Mead",
                       options={"adaptive": True, "initial_simplex": simplex, "xatol": xatol,
                                "fatol": max(ftol * f_prev, _F_FLOOR),
                                "maxfev": max(1, obj.max_evals - obj.nfev), "maxiter": 10**9})
        nit += int(res.nit)
        z = obj.best_x
        f_new = obj.best_f
        if obj.nfev >= obj.max_evals:
            raise OutOfBudget
        improved = f_new < f_prev * (1 - 1e-9) - _F_FLOOR
        if not improved or restarts >= max_restarts:
            converged = not improved
            message = ("no further improvement from a restart" if converged
                       else f"stopped after {max_restarts} restarts, still improving")
            return restarts, nit, converged, message
        f_prev = f_new
        restarts += 1


def _jacobian(obj: Objective):
    """Forward-difference Jacobian of `Objective.residual_vector` in [0, 1] variables, every probe counted.

    Step ``sqrt(eps)`` (the variables are of order 1), backward at the upper bound or
    where the forward probe is refused by the physics; a column both sides refuse is 0
    (the trust region then leaves that variable alone).
    """
    h = np.sqrt(np.finfo(float).eps)

    def jac(u):
        u = np.asarray(u, float)
        r0 = obj.last_residuals(u)
        values = obj.values_unit(u)  # a probe moves one variable: its values are these but one (not counted)
        J = np.zeros((r0.size, u.size), order="F")  # filled by columns; handed on in C order, as before
        for i in range(u.size):
            for sign in ((1.0, -1.0) if u[i] + h <= 1.0 else (-1.0, 1.0)):
                ui = u.copy()
                ui[i] = min(max(u[i] + sign * h, 0.0), 1.0)  # np.clip's number, without its overhead
                if ui[i] == u[i]:
                    continue
                f, r = obj.residuals_at(ui, obj.values_unit_moved(ui, values, i))
                if f < np.inf or np.all(np.isfinite(r)):  # f finite: every residual is
                    J[:, i] = (r - r0) / (ui[i] - u[i])
                    break
        return np.ascontiguousarray(J)

    return jac


def bounded_least_squares(obj: Objective, *, xtol, ftol, gtol):
    """scipy's trust-region reflective least squares on the residual vector, bounds native.

    The variables are the free parameters' log/asinh variables scaled onto
    [0, 1] (`Objective.values_unit`), bounds [0, 1]; ``x_scale="jac"``; the
    Jacobian by forward differences (`_jacobian`), each of whose evaluations
    counts. With C20 free, the Yeoh admissibility limit (``C20 > -sqrt(3 C10 C30)``)
    is the lower bound of the margin variable: an optimum there is a constrained
    optimum, reported converged, with the message saying that it lies on the limit.
    Returns ``(restarts, nit, converged, message)``; OutOfBudget propagates.
    """
    u0 = np.clip(obj.unit_of(obj.best_values), 0.0, 1.0)
    res = least_squares(obj.residual_vector, u0, jac=_jacobian(obj), bounds=(0.0, 1.0), method="trf",
                        x_scale="jac", xtol=xtol, ftol=ftol, gtol=gtol, max_nfev=max(1, obj.max_evals))
    converged = res.status > 0
    message = res.message.rstrip(".").replace("`", "")
    if converged and at_yeoh_limit(obj.best_values):
        if obj._margin_slot() is not None:
            message += ("; on the Yeoh admissibility limit C20 = -sqrt(3 C10 C30) (a bound of the fit): the runs "
                        "ask for a softer elastic part than an admissible Yeoh law has")
        else:
            converged = False
            message += ("; but it stopped at the Yeoh admissibility limit C20 = -sqrt(3 C10 C30), which is no "
                        "bound of this fit: not a converged optimum")
    return 0, int(res.nfev), converged, message


__all__ = ["METHODS", "Objective", "OutOfBudget", "POLISH_STEP", "WARM_STARTS", "bounded_least_squares",
           "nelder_mead"]
