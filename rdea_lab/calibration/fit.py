"""Nelder-Mead calibration with restarts, budgets and uncertainty (Section 4.2 of [1])."""

from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from .. import __version__
from ..specs import ParameterSet, SpecError
from .objective import goodness, predict_force, residuals
from .parameters import fit_parameters, values_of, with_values


class _OutOfBudget(Exception):
    pass


#: Objective values closer than this are equal: the normalized force error has
#: reached the rounding floor of double precision.
_F_FLOOR = 1e-14


@dataclass(frozen=True)
class CalibrationResult:
    """What a calibration found, with the numbers to judge it (fixed fields).

    Attributes
    ----------
    params, start : ParameterSet
        Best and starting parameter sets.
    parameters : tuple of FitParameter
        Names, bounds, transforms, which were free.
    values : dict
        Best values [SI], every parameter.
    stderr : dict
        Standard errors [SI] of the free parameters (NaN where the data cannot
        identify the parameter).
    correlation : numpy.ndarray
        Correlation matrix of the free parameters, in `free_names` order.
    free_names : tuple of str
    at_bound, unmoved, unidentifiable : tuple of str
        Flags: ended within 1e-6 of a bound; never moved from the start
        (relative change < 1e-9); standard error above half the value or
        correlation beyond 0.999 with another parameter.
    model, metric : str
    objective : float
        Best objective (rms or max of the normalized force error).
    chisqr, redchi, aic, bic : float
        Statistics of the normalized residuals (each run counts equally).
    ndata, nfree, nfev, nit, restarts : int
    wall_time : float [s]
    converged : bool
        The last restart did not improve, within the budgets.
    message : str
    runs : tuple of dict
        Per-run goodness of fit (rms error [N], R^2, max relative error).
    history : numpy.ndarray, shape (k, 2)
        (evaluation, best objective so far) at every improvement.
    software : str
        rdea-lab version.
    model_reason : str
        Why ``auto`` chose `model` (empty otherwise).
    run_data : tuple of RunData
        The runs fitted (set by `calibrate_runs`).
    skipped : tuple of dict
        Files of the input folders left out, with why (``file``, ``reason``).
    record_files : dict
        ``params``, ``history``, ``plot`` paths of the record, when one was written.
    """

    params: ParameterSet
    start: ParameterSet
    parameters: tuple
    values: dict
    stderr: dict
    correlation: np.ndarray
    free_names: tuple
    at_bound: tuple
    unmoved: tuple
    unidentifiable: tuple
    model: str
    metric: str
    objective: float
    chisqr: float
    redchi: float
    aic: float
    bic: float
    ndata: int
    nfree: int
    nfev: int
    nit: int
    restarts: int
    wall_time: float
    converged: bool
    message: str
    runs: tuple
    history: np.ndarray
    software: str = __version__
    model_reason: str = ""
    run_data: tuple = ()
    skipped: tuple = ()
    record_files: dict = dataclasses.field(default_factory=dict)


class Objective:
    """Objective over runs; counts evaluations, keeps the best point and its history."""

    def __init__(self, runs, start, parameters, model, metric, max_evals, max_time, progress=None,
                 clock=_time.monotonic):
        self.runs, self.start, self.parameters = runs, start, parameters
        self.model, self.metric = model, metric
        self.free = [p for p in parameters if p.free]
        self.fixed = {p.name: p.start for p in parameters if not p.free}
        self.max_evals, self.max_time = max_evals, max_time
        self.nfev = 0
        self.best = (np.inf, None)
        self.history = []
        self.progress = progress
        self._clock = clock
        self.t0 = clock()
        self._last_report = self.t0

    def values(self, z) -> dict:
        v = dict(self.fixed)
        v.update({p.name: p.to_physical(zi) for p, zi in zip(self.free, z)})
        return v

    def paramset(self, values) -> ParameterSet | None:
        try:
            return with_values(self.start, values, self.start.M)
        except SpecError:
            return None  # the physics refuses it: the objective is infinite there

    def score(self, params) -> float:
        if params is None:
            return np.inf
        r = residuals(self.runs, params, self.model)
        if not np.all(np.isfinite(r)):
            return np.inf
        return float(np.sqrt(np.mean(r * r))) if self.metric == "rms" else float(np.max(np.abs(r)))

    def __call__(self, z) -> float:
        if self.nfev >= self.max_evals or self._clock() - self.t0 > self.max_time:
            raise _OutOfBudget
        self.nfev += 1
        values = self.values(z)
        f = self.score(self.paramset(values))
        if f < self.best[0]:
            self.best = (f, np.array(z, float))
            self.history.append((self.nfev, f))
        now = self._clock()
        if self.progress is not None and now - self._last_report > 0.5:
            self._last_report = now
            self.progress(self.nfev, self.best[0], now - self.t0)
        return f


def calibrate(runs, start: ParameterSet, *, model="su", free=None, metric="rms", max_evals=20000,
              max_time=300.0, max_restarts=20, step=0.1, xatol=1e-9, ftol=1e-10,
              progress=None) -> CalibrationResult:
    """Fit the Yeoh and viscoelastic parameters of ``start`` to measured forces.

    Parameters
    ----------
    runs : list of RunData
        Measured runs (:func:`~rdea_lab.calibration.objective.load_run`).
    start : ParameterSet
        Start values, the number of branches, and the fixed eps_r.
    model : {"su", "1r", "3r", "cr"}
    free : iterable of str, optional
        Parameters to fit (default: every Yeoh and viscoelastic parameter).
    metric : {"rms", "max"}
        rms or max of the force error, each run normalized by its peak measured
        force and counted equally.
    max_evals, max_time : int, float
        Budgets (evaluations, seconds of wall time) over all restarts.
    max_restarts : int
        Nelder-Mead restarts from the best point while they still improve.
    step : float
        Initial simplex step in the internal variables (0.1 is about a factor
        1.8 for log parameters).
    xatol, ftol : float
        Nelder-Mead stops when the simplex spans less than ``xatol`` in the
        internal variables and its objective values less than ``ftol`` times
        the objective at the restart's start.
    progress : callable, optional
        ``progress(evaluations, best, elapsed)``, called at most twice a second.

    Notes
    -----
    Nelder-Mead (scipy, adaptive) on the transformed parameters of
    :mod:`~rdea_lab.calibration.parameters`; a parameter set the physics
    refuses scores infinity. Standard errors and correlations come from the
    Jacobian of the residuals at the optimum (central differences),
    ``cov = s^2 (J^T J)^-1``; residuals of a time series are correlated, so
    they are optimistic lower bounds.
    """
    if metric not in ("rms", "max"):
        raise ValueError(f"metric {metric!r}; allowed: rms, max")
    names_all = [p for p in values_of(start)]
    free = set(names_all if free is None else free)
    unknown = free - set(names_all)
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(sorted(unknown))}; allowed: {', '.join(names_all)}")
    parameters = fit_parameters(start, free)
    obj = Objective(runs, start, parameters, model, metric, max_evals, max_time, progress)
    f0 = obj.score(start)
    if not np.isfinite(f0):
        raise ValueError("the start parameters give no finite force prediction on these runs "
                         "(a model without equilibrium somewhere); choose another start or model")
    z = np.array([p.to_internal(p.start) for p in obj.free])
    obj.best, obj.history = (f0, z.copy()), [(0, f0)]
    restarts, nit, converged, message = 0, 0, False, ""
    if obj.free:
        try:
            f_prev = f0
            while True:
                simplex = np.vstack([z] + [z + step * np.eye(z.size)[i] for i in range(z.size)])
                res = minimize(obj, z, method="Nelder-Mead",
                               options={"adaptive": True, "initial_simplex": simplex, "xatol": xatol,
                                        "fatol": max(ftol * f_prev, _F_FLOOR),
                                        "maxfev": max(1, max_evals - obj.nfev), "maxiter": 10**9})
                nit += int(res.nit)
                z = obj.best[1]
                f_new = obj.best[0]
                if obj.nfev >= max_evals:
                    raise _OutOfBudget
                improved = f_new < f_prev * (1 - 1e-9) - _F_FLOOR
                if not improved or restarts >= max_restarts:
                    converged = not improved
                    message = ("no further improvement from a restart" if converged
                               else f"stopped after {max_restarts} restarts, still improving")
                    break
                f_prev = f_new
                restarts += 1
        except _OutOfBudget:
            message = (f"evaluation budget {max_evals} reached" if obj.nfev >= max_evals
                       else f"time budget {max_time:g} s reached")
            z = obj.best[1]
    else:
        converged, message = True, "no free parameters"
    values = obj.values(obj.best[1])
    best = with_values(start, values, start.M)
    return _finish(obj, parameters, best, values, model, metric, restarts, nit, converged, message)


def _finish(obj, parameters, best, values, model, metric, restarts, nit, converged, message):
    free = [p for p in parameters if p.free]
    r = residuals(obj.runs, best, model)
    n, k = r.size, len(free)
    chisqr = float(np.sum(r * r))
    stderr, corr, unident = _uncertainty(obj, best, values, free, chisqr, n, model)
    wall = obj._clock() - obj.t0
    start_values = values_of(obj.start)
    return CalibrationResult(
        params=best, start=obj.start, parameters=tuple(parameters), values=values, stderr=stderr,
        correlation=corr, free_names=tuple(p.name for p in free),
        at_bound=tuple(p.name for p in free if p.at_bound(values[p.name])),
        unmoved=tuple(p.name for p in free
                      if abs(values[p.name] - start_values[p.name]) <= 1e-9 * max(abs(start_values[p.name]), 1e-300)),
        unidentifiable=tuple(unident), model=model, metric=metric, objective=float(obj.best[0]), chisqr=chisqr,
        redchi=chisqr / max(n - k, 1), aic=float(n * np.log(chisqr / n) + 2 * k) if chisqr > 0 else -np.inf,
        bic=float(n * np.log(chisqr / n) + k * np.log(n)) if chisqr > 0 else -np.inf, ndata=int(n), nfree=k,
        nfev=obj.nfev, nit=nit, restarts=restarts, wall_time=float(wall), converged=bool(converged),
        message=message, runs=tuple(goodness(run, predict_force(run, best, model)) for run in obj.runs),
        history=np.array(obj.history, float).reshape(-1, 2),
    )


def _uncertainty(obj, best, values, free, chisqr, n, model):
    """Standard errors and correlations from the Jacobian at the optimum."""
    k = len(free)
    if k == 0:
        return {}, np.zeros((0, 0)), []
    J = np.empty((n, k))
    for i, p in enumerate(free):
        x = values[p.name]
        h = 1e-5 * max(abs(x), p.scale if p.kind == "asinh" else 1e-12 * p.hi)
        cols = []
        for sign in (1, -1):
            v = dict(values)
            v[p.name] = x + sign * h
            ps = obj.paramset(v)
            cols.append(None if ps is None else residuals(obj.runs, ps, model))
        if cols[0] is None or cols[1] is None:  # one side refused: one-sided difference
            good = cols[0] if cols[0] is not None else cols[1]
            sign = 1 if cols[0] is not None else -1
            J[:, i] = np.nan if good is None else (good - residuals(obj.runs, best, model)) / (sign * h)
        else:
            J[:, i] = (cols[0] - cols[1]) / (2 * h)
    names = [p.name for p in free]
    s2 = chisqr / max(n - k, 1)
    ok = np.all(np.isfinite(J), axis=0) & (np.linalg.norm(J, axis=0) > 0)
    stderr = {name: float("nan") for name in names}
    corr = np.full((k, k), np.nan)
    unident = [names[i] for i in range(k) if not ok[i]]
    if np.any(ok):
        Jo = J[:, ok]
        cov = s2 * np.linalg.pinv(Jo.T @ Jo)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        idx = np.flatnonzero(ok)
        for a, i in enumerate(idx):
            stderr[names[i]] = float(sd[a])
        with np.errstate(invalid="ignore", divide="ignore"):
            c = cov / np.outer(sd, sd)
        corr[np.ix_(idx, idx)] = c
        for a, i in enumerate(idx):
            others = np.abs(np.delete(c[a], a))
            if sd[a] > 0.5 * abs(values[names[i]]) or (others.size and np.nanmax(others) > 0.999):
                unident.append(names[i])
    return stderr, corr, sorted(set(unident), key=names.index)


def initial_guess(runs, M: int, eps_r: float, name="start-from-data") -> ParameterSet:
    """A start from the data alone, for any material.

    C10 from the small-strain slope: near lambda1 = 1 an incompressible solid
    under uniaxial tension has true stress 3 mu (lambda1 - 1) with mu = 2 C10, so
    C10 = slope / 6, fitted by least squares on samples with lambda1 - 1 < 5 %
    (of the 0 V runs when there are any). C20 = 0, C30 = C10 / 20. The M relaxation
    times are spread log-evenly from ten sample intervals to a third of the
    longest run; each branch starts with k = C10.
    """
    zero = [r for r in runs if r.zero_voltage] or list(runs)
    x, y = [], []
    for r in zero:
        small = (r.stretch - 1.0) < 0.05
        x.append(r.stretch[small] - 1.0)
        y.append(r.force[small] * r.stretch[small] / r.geom.area)
    x, y = np.concatenate(x), np.concatenate(y)
    A = np.column_stack([x, np.ones_like(x)])  # an intercept soaks up a load-cell offset
    slope = float(np.linalg.lstsq(A, y, rcond=None)[0][0]) if x.size >= 3 else 0.0
    C10 = slope / 6.0 if slope > 0 else 1e5
    dt = min(float(np.median(np.diff(r.t))) for r in runs)
    T = max(float(r.t[-1] - r.t[0]) for r in runs)
    if M > 1:
        taus = np.geomspace(10 * dt, max(T / 3, 20 * dt), M)
    else:  # one branch in the geometric middle of the range; none for M = 0
        taus = np.array([np.sqrt(10 * dt * max(T / 3, 20 * dt))])[:M]
    from ..specs import ViscoBranch
    return ParameterSet(name=name, C10=C10, C20=0.0, C30=C10 / 20, eps_r=eps_r,
                        branches=tuple(ViscoBranch(k=C10, eta=C10 * tau) for tau in taus), eta_v0=0.0,
                        description="start values estimated from the data by rdea-lab calibrate")


def calibrate_growing(runs, start: ParameterSet, M: int, *, free=None, progress=None, **kwargs) -> CalibrationResult:
    """Fit M Maxwell branches one at a time, each from the previous optimum.

    Nelder-Mead started with M branches at once tends to merge them into one time
    scale. Here the fit with m - 1 branches is extended by a branch 10 times slower
    than the slowest and, separately, 10 times faster than the fastest (its
    stiffness a tenth of C10), both fitted, and the better kept; ``start`` supplies
    the first branch. ``free`` names parameters of the final set (default: all).

    Returns
    -------
    CalibrationResult
        Of the final fit with M branches; its ``message`` says how it grew.
    """
    from ..specs import ViscoBranch

    def fit(params):
        names = [n for n in values_of(params)]
        return calibrate(runs, params, free=[n for n in names if free is None or n in free],
                         progress=progress, **kwargs)

    first = start.replace(branches=start.branches[:1])
    best = fit(first)
    path = [f"M = 1: {best.objective:.4g}"]
    for m in range(2, M + 1):
        taus = [b.tau for b in best.params.branches]
        k_new = 0.1 * best.params.C10
        candidates = []
        for tau in (10 * max(taus), 0.1 * min(taus)):
            candidates.append(fit(best.params.replace(branches=best.params.branches + (ViscoBranch(k=k_new, eta=k_new * tau),))))
        best = min(candidates, key=lambda r: r.objective)
        path.append(f"M = {m}: {best.objective:.4g}")
    return dataclasses.replace(best, message=f"{best.message} (grown branch by branch: {'; '.join(path)})")
