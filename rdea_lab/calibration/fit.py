"""Calibration with budgets and uncertainty: Nelder-Mead as in Section 4.2 of [1], or bounded least squares."""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._version import __version__
from ..specs import ParameterSet
from .methods import (METHODS, POLISH_STEP, WARM_STARTS, Objective, OutOfBudget, at_yeoh_limit, bounded_least_squares,
                      nelder_mead)
from .objective import goodness, predict_force, residuals
from .parameters import constrain_start, fit_parameters, values_of, with_values


@dataclass(frozen=True)
class Budget:
    """What a calibration may spend, over all its restarts (and branch-growth stages).

    Parameters
    ----------
    evaluations : int
        Objective evaluations [-], >= 0; every residual evaluation counts, a finite-difference
        Jacobian's too.
    seconds : float
        Wall time [s], >= 0.

    Raises
    ------
    SpecError
        A count that is not a whole number >= 0, or a time that is not a number >= 0.
    """

    evaluations: int = 20000
    seconds: float = 300.0

    def __post_init__(self):
        from ..specs import SpecError

        n, t = self.evaluations, self.seconds
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 0:
            raise SpecError("arguments", "budget.evaluations", f"{n!r}; allowed: a whole number >= 0")
        if isinstance(t, bool) or not isinstance(t, numbers.Real) or not t >= 0:
            raise SpecError("arguments", "budget.seconds", f"{t!r}; allowed: a number of seconds >= 0")

    def left(self, evaluations: int, seconds: float) -> "Budget":
        """What remains after ``evaluations`` spent in ``seconds`` [s] (never below zero)."""
        return Budget(max(0, self.evaluations - evaluations), max(0.0, self.seconds - seconds))


class FitMonitor:
    """What a calibration tells while it runs: override any of the methods (no-ops here).

    Any object will do as a monitor: the fit calls those of these methods it has (`calibrate` its
    ``progress``, `calibrate_growing` also ``stage``, `~rdea_lab.calibration.app.calibrate_runs` also
    ``announce``, `~rdea_lab.calibration.crossval.cross_validate` also ``announce_fold`` and ``fold_done``).
    A method that raises stops the calibration there.
    """

    def progress(self, evaluations: int, best: float, elapsed: float) -> None:
        """At most twice a second: evaluations so far, the best objective so far [-], seconds since the fit
        began [s] (over every stage when branches are grown)."""

    def stage(self, index: int, count: int, label: str) -> None:
        """Before each fit when branches are grown one at a time: ``index`` from 1 to ``count``."""

    def announce(self, runs, model: str, reason: str, free, skipped) -> None:
        """Once the inputs are checked, before the fit starts (`~rdea_lab.calibration.app.calibrate_runs`):
        the `RunData`, the model and why ``auto`` chose it (else empty), the free names, the files of input
        folders left out (tuple of dict ``file``, ``reason``)."""

    def announce_fold(self, index: int, count: int, label: str, fitted, predicted) -> None:
        """Before each fold of a cross-validation (``index`` from 1 to ``count``): what it holds out, the
        file names it fits and those it predicts."""

    def fold_done(self, index: int, count: int, fold, rows) -> None:
        """After each fold: the `~rdea_lab.calibration.crossval.Fold` (its fit and envelope) and its rows of
        the result's table (its fitted and predicted runs, as dicts)."""


def hook(monitor, name: str):
    """The monitor's method ``name``, or None when there is no monitor or it has no such method."""
    return None if monitor is None else getattr(monitor, name, None)


class _Relay:
    """A monitor that only relays progress (branch growth's, counted over its stages)."""

    def __init__(self, progress):
        self.progress = progress


@dataclass(frozen=True)
class CalibrationResult:
    """What a calibration found, with the numbers to judge it (fixed fields).

    The statistics have lmfit's names and meanings.

    Attributes
    ----------
    params, start : ParameterSet
        Best and starting parameter sets (of the last stage when branches were grown).
    parameters : tuple of FitParameter
        Names, start values (lmfit's ``init_value``), bounds, transforms, which were free.
    values : dict
        Best values [SI], every parameter.
    stderr : dict
        Standard errors [SI] of the free parameters (NaN where the data cannot
        identify the parameter, and for every parameter under ``metric="max"``,
        where they do not apply).
    correlation, covar : numpy.ndarray
        Correlation and covariance matrices [SI^2] of the free parameters, in
        `free_names` order (NaN where not identifiable, all NaN under ``metric="max"``).
    free_names : tuple of str
    at_bound, unmoved, unidentifiable : tuple of str
        Flags: ended within 1e-6 of a bound (C20 also on the Yeoh admissibility limit
        ``C20 = -sqrt(3 C10 C30)``, within 1e-6 of C20); never moved from the start
        (relative change < 1e-9); a Jacobian column that is zero, correlation
        beyond 0.999 with another parameter, or (``metric="rms"``) a standard
        error above half the value.
    model, metric : str
    method : {"nelder-mead", "least-squares"}
    objective : float
        Best objective (rms or max of the normalized force error).
    chisqr, redchi, aic, bic : float
        Sum of squared normalized residuals (each run counts equally),
        ``chisqr / nfree``, and the information criteria (NaN under ``metric="max"``).
    ndata, nvarys, nfree : int
        Residuals (samples of all runs), free parameters, ``ndata - nvarys``.
    nfev, nit, restarts : int
        Evaluations, iterations and restarts of the minimizer, summed over every stage.
    wall_time : float [s]
        Of the whole calibration (every stage and candidate).
    converged : bool
        Nelder-Mead: the last restart did not improve; least squares: a
        tolerance was met; in both cases within the budgets. False when a
        budget stopped any stage (``message`` says which budget and where).
    message : str
    runs : tuple of dict
        Per-run goodness of fit (rms error [N], R^2, relative errors).
    history : numpy.ndarray, shape (k, 3)
        (evaluation, best objective so far in its stage, stage) at every
        improvement; evaluations are counted over all stages.
    stages : tuple of dict
        One per fit (``stage``, ``label``, ``branches``, ``nfev``, ``wall_time_s``,
        ``objective``, ``restarts``, ``converged``, ``kept``, ``message``, and
        ``budget_reached``: ``"time"`` or ``"evaluations"`` if a budget stopped it, else ``""``).
    budgets : dict
        ``max_evals``, ``max_time_s`` (over all stages), ``max_restarts``, ``step`` and ``tolerances``.
    versions : dict
        rdea-lab, numpy, scipy (and numba if installed) versions.
    software : str
        rdea-lab version.
    model_reason : str
        Why ``auto`` chose `model` (empty otherwise).
    run_data : tuple of RunData
        The runs fitted (what `write` records).
    skipped : tuple of dict
        Files of the input folders left out, with why (``file``, ``reason``).
    record_files : dict
        ``params``, ``history``, ``plot`` paths of the record, when one was written and kept here
        (:func:`~rdea_lab.calibration.crossval.cross_validate` does; `write` returns them).
    hyperelastic : {"yeoh", "yeoh-monotone", "neo-hookean"}
        The Yeoh coefficients the fit could reach (:func:`~rdea_lab.calibration.parameters.constrain_start`).
    warm_start : str
        How Nelder-Mead got its start when not from ``start`` directly (empty otherwise): the
        least-squares start and the Nelder-Mead polish, with the evaluations of each.
    branch_choice : dict
        Empty unless the number of branches was chosen from the data
        (:func:`~rdea_lab.calibration.branches.calibrate_auto`): the criterion, what was tried and why
        the count was chosen.
    spectrum : dict
        How a relaxation spectrum was chosen (:func:`~rdea_lab.calibration.spectrum.fit_spectrum`: its
        grid ``tau_s``, every ``modulus_Pa`` on it, the rules, the regularization ``strength``); empty
        for the other fits.
    """

    params: ParameterSet
    start: ParameterSet
    parameters: tuple
    values: dict
    stderr: dict
    correlation: np.ndarray
    covar: np.ndarray
    free_names: tuple
    at_bound: tuple
    unmoved: tuple
    unidentifiable: tuple
    model: str
    metric: str
    method: str
    objective: float
    chisqr: float
    redchi: float
    aic: float
    bic: float
    ndata: int
    nvarys: int
    nfree: int
    nfev: int
    nit: int
    restarts: int
    wall_time: float
    converged: bool
    message: str
    runs: tuple
    history: np.ndarray
    stages: tuple
    budgets: dict
    versions: dict = dataclasses.field(default_factory=lambda: versions())
    software: str = __version__
    model_reason: str = ""
    run_data: tuple = ()
    skipped: tuple = ()
    record_files: dict = dataclasses.field(default_factory=dict)
    hyperelastic: str = "yeoh"
    warm_start: str = ""
    branch_choice: dict = dataclasses.field(default_factory=dict)
    spectrum: dict = dataclasses.field(default_factory=dict)

    def fit_report(self) -> str:
        """The fit report, as ``rdea-lab calibrate`` prints it.

        Returns
        -------
        str
            Method, message, budget; each parameter [kPa or kPa s] with its standard error and flags;
            the per-run fit; how Nelder-Mead got its start and how the branch count was chosen (where
            either applies); AIC/BIC (or why they do not apply); the evaluations of each stage when
            there were several. No trailing newline.
        """
        lines = [f"{self.method}: {self.message}; objective {self.objective:.4e} after {self.nfev} evaluations, "
                 f"{self.restarts} restarts, {self.wall_time:.2f} s"]
        if len(self.stages) > 1:
            lines.append("  stages: " + "; ".join(f"{st['label']}{'' if st['kept'] else ' (dropped)'}: {st['nfev']} "
                                                  f"evaluations, {st['objective']:.4g}" for st in self.stages))
        for p in self.parameters:
            v = self.values[p.name]
            se = self.stderr.get(p.name)
            flags = [f for f, names_ in (("at bound", self.at_bound), ("unmoved", self.unmoved),
                                         ("not identifiable", self.unidentifiable)) if p.name in names_]
            unit = "kPa" if p.unit == "Pa" else "kPa s"
            lines.append(f"  {p.name:<7} {v / 1e3:12.5g} {unit:<6}"
                         + (f" +- {se / 1e3:.3g}" if p.free and se == se else "")
                         + ("" if p.free else "  (fixed)") + (f"  [{', '.join(flags)}]" if flags else ""))
        for g in self.runs:
            lines.append(f"  {g['specimen']}/{g['protocol']}: rms {g['rms_error_N']:.4g} N, R2 {g['r2']:.5f}, "
                         f"max rel. error {100 * g['max_rel_error']:.2f} %, rms/peak "
                         f"{100 * g.get('rms_rel_error', float('nan')):.2f} %, p99/peak "
                         f"{100 * g.get('p99_rel_error', float('nan')):.2f} %")
        if self.warm_start:
            lines.append(f"  start: {self.warm_start}")
        if self.branch_choice:
            lines.append(f"  branches: {self.branch_choice['reason']}")
        lines.append(f"  AIC {self.aic:.1f}, BIC {self.bic:.1f}" if self.metric == "rms"
                     else f"  standard errors, AIC and BIC: not applicable (metric {self.metric})")
        return "\n".join(lines)

    def write(self, out, *, name: str | None = None, overwrite: bool = False) -> dict[str, Path]:
        """Write the calibration record: the parameter file with its ``calibration`` section, and beside it
        ``<out stem>.history.csv`` and ``<out stem>.history.png``.

        Parameters
        ----------
        out : path
            The parameter file (loadable by :func:`~rdea_lab.specs.load_params`); its folder is made.
        name : str, optional
            Name of the calibrated set in the file; default ``out``'s stem (spaces as ``_``).
        overwrite : bool
            Replace existing files (the CLI's ``--force``); otherwise any of the three existing is refused
            before anything is written.

        Returns
        -------
        dict of Path
            ``params``, ``history``, ``plot`` (:func:`~rdea_lab.calibration.record.record_files`).

        Raises
        ------
        OutputError
            A record file exists (and not ``overwrite``) or cannot be written.
        ValueError
            The result does not hold the runs it was fitted to (`run_data`).
        """
        from ..store.outputs import check_new
        from .record import record_files, write_record

        if not self.run_data:
            raise ValueError("this result does not hold the runs it was fitted to (run_data); write the record "
                             "with rdea_lab.calibration.record.write_record(result, runs, out)")
        out = Path(out)
        for path in record_files(out).values():
            check_new(path, overwrite)
        return write_record(self, self.run_data, out, name=name or out.stem.replace(" ", "_"))


def versions() -> dict:
    """Versions of rdea-lab and the numerical libraries a calibration ran on (numba if installed)."""
    import importlib.metadata
    import importlib.util

    import scipy

    out = {"rdea-lab": __version__, "numpy": np.__version__, "scipy": scipy.__version__}
    if importlib.util.find_spec("numba") is not None:  # its version without the cost of importing it
        try:
            out["numba"] = importlib.metadata.version("numba")
        except importlib.metadata.PackageNotFoundError:
            pass
    return out


def check_method(method: str, metric: str, warm_start: str = "auto") -> bool:
    """Raise ValueError unless ``method`` is known and can minimize ``metric`` (with ``warm_start``).

    Returns whether Nelder-Mead starts from a least-squares optimum (``warm_start`` ``auto`` under rms, or
    ``least-squares``).
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r}; allowed: {', '.join(METHODS)}")
    if metric not in ("rms", "max"):
        raise ValueError(f"metric {metric!r}; allowed: rms, max")
    if method == "least-squares" and metric != "rms":
        raise ValueError(f"least-squares minimizes the rms error only, not metric {metric!r}; "
                         "allowed with metric max: nelder-mead")
    if warm_start not in WARM_STARTS:
        raise ValueError(f"warm_start {warm_start!r}; allowed: {', '.join(WARM_STARTS)}")
    if warm_start == "least-squares" and metric != "rms":
        raise ValueError(f"a least-squares start has the rms optimum, not that of metric {metric!r}; "
                         "allowed with metric max: warm_start auto or none")
    return method == "nelder-mead" and metric == "rms" and warm_start != "none"


def calibrate(runs, start: ParameterSet, *, model="su", free=None, metric="rms", method="nelder-mead",
              budget: Budget = Budget(), max_restarts=20, step=0.1, xatol=1e-9, ftol=1e-10,
              monitor=None, hyperelastic: str = "yeoh", warm_start="auto") -> CalibrationResult:
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
    method : {"nelder-mead", "least-squares"}
        Nelder-Mead with restarts (the paper's), or bounded least squares
        (rms only).
    budget : Budget
        Evaluations and seconds of wall time over all restarts; every
        residual evaluation counts, a finite-difference Jacobian's too.
    max_restarts : int
        Nelder-Mead restarts from the best point while they still improve.
    step : float
        Initial simplex step in the internal variables (0.1 is about a factor
        1.8 for log parameters).
    xatol, ftol : float
        Nelder-Mead stops when the simplex spans less than ``xatol`` in the
        internal variables and its objective values less than ``ftol`` times
        the objective at the restart's start. Least squares stops when a step
        changes the variables by less than ``xatol`` (relative) or the sum of
        squares by less than ``ftol`` (relative), or the scaled gradient is
        below ``ftol``.
    monitor : FitMonitor or any object, optional
        Its ``progress(evaluations, best, elapsed)``, if it has one, is called at most twice a second.
    hyperelastic : {"yeoh", "yeoh-monotone", "neo-hookean"}
        The Yeoh coefficients the fit may reach (:func:`~rdea_lab.calibration.parameters.constrain_start`):
        the paper's Yeoh (default), monotone stiffening (C20, C30 >= 0), or neo-Hookean (C20 = C30 = 0,
        held); the start is projected onto that set.
    warm_start : {"auto", "least-squares", "none"}
        Nelder-Mead's start. ``least-squares`` (what ``auto`` is under metric rms): bounded least squares
        from ``start`` first, then Nelder-Mead polishes its optimum (initial simplex step
        :data:`~rdea_lab.calibration.methods.POLISH_STEP` instead of ``step``; restarts and
        tolerances as given). The rms and the sum of squares have the same minimizer, so this is
        Nelder-Mead's own optimum, reached in a tenth of the evaluations (five VHB files, finite
        strain: benchmarks/vhb_fit_speed.py). ``none`` (what ``auto`` is under max, where least squares
        would minimize another objective): Nelder-Mead from ``start`` with ``step``, as in [1].
        Not used by least squares. ``warm_start`` of the result says what was done.

    Returns
    -------
    CalibrationResult
        Frozen; ``run_data`` holds ``runs`` (what `CalibrationResult.write` records).

    Raises
    ------
    ValueError
        An unknown method, metric or parameter; a start without a finite force prediction.
    TypeError
        A ``budget`` that is not a `Budget`.
    SpecError
        An unknown ``hyperelastic``.

    Notes
    -----
    Both methods work in the transformed parameters of
    :mod:`~rdea_lab.calibration.parameters`: Nelder-Mead (scipy, adaptive)
    through their sine map onto the bounds; least squares (scipy's
    trust-region reflective, ``x_scale="jac"``, forward-difference Jacobian)
    on the log/asinh variables scaled onto [0, 1], whose bounds it keeps
    natively. A parameter set the physics refuses scores infinity. Standard
    errors and correlations come from the Jacobian of the residuals at the
    optimum (central differences), ``covar = s^2 (J^T J)^-1`` with
    ``s^2 = redchi``; residuals of a time series are correlated, so they are
    optimistic lower bounds; under ``metric="max"`` they do not apply.
    """
    warm = check_method(method, metric, warm_start)
    if not isinstance(budget, Budget):
        raise TypeError(f"budget {budget!r}; allowed: a rdea_lab.calibration.fit.Budget")
    max_evals, max_time = budget.evaluations, budget.seconds
    names_all = [p for p in values_of(start)]
    free = set(names_all if free is None else free)
    unknown = free - set(names_all)
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(sorted(unknown))}; allowed: {', '.join(names_all)}")
    start = constrain_start(start, hyperelastic)
    parameters = fit_parameters(start, free, hyperelastic)
    obj = Objective(runs, start, parameters, model, metric, max_evals, max_time, hook(monitor, "progress"))
    f0 = obj.score(start)
    if not np.isfinite(f0):
        raise ValueError("the start parameters give no finite force prediction on these runs "
                         "(a model without equilibrium somewhere); choose another start or model")
    z0 = np.array([p.to_internal(p.start) for p in obj.free])
    obj.best_f, obj.best_values, obj.best_x = f0, obj.values(z0), z0
    obj.history = [(0, f0)]
    restarts, nit, converged, message, budget_reached = 0, 0, False, "", ""
    warm_note, n_warm = "", None
    if obj.free:
        try:
            if method == "nelder-mead" and warm:
                _, nit, _, warm_message = bounded_least_squares(obj, xtol=xatol, ftol=ftol, gtol=ftol)
                n_warm = obj.nfev
                obj.best_x = obj.internal_of(obj.best_values)  # least squares kept its own variables
                restarts, nit_nm, converged, message = nelder_mead(obj, obj.best_f, max_restarts=max_restarts,
                                                                   step=POLISH_STEP, xatol=xatol, ftol=ftol)
                nit += nit_nm
            elif method == "nelder-mead":
                restarts, nit, converged, message = nelder_mead(obj, f0, max_restarts=max_restarts, step=step,
                                                                xatol=xatol, ftol=ftol)
            else:
                restarts, nit, converged, message = bounded_least_squares(obj, xtol=xatol, ftol=ftol, gtol=ftol)
        except OutOfBudget:
            budget_reached = "evaluations" if obj.nfev >= max_evals else "time"
            message = budget_message(budget_reached, max_evals, max_time, obj.nfev)
        if method == "nelder-mead" and warm:
            warm_note = polish_note(n_warm, obj.nfev, warm_message if n_warm is not None else "")
    else:
        converged, message = True, "no free parameters"
    if method == "nelder-mead":
        tolerances = {"xatol": xatol, "fatol": f"{ftol:g} x the objective at each restart's start"}
        if warm:
            tolerances.update({"least-squares start": {"xtol": xatol, "ftol": ftol, "gtol": ftol}})
        restart_budget = max_restarts
    else:
        tolerances = {"xtol": xatol, "ftol": ftol, "gtol": ftol}
        restart_budget = "not used by least-squares"
    budgets = {"max_evals": int(max_evals), "max_time_s": float(max_time), "max_restarts": restart_budget,
               "step": (f"{POLISH_STEP:g} (the polish of a least-squares start)" if warm else step)
               if method == "nelder-mead" else "not used by least-squares", "tolerances": tolerances}
    values = obj.best_values
    best = with_values(start, values, start.M)
    result = _finish(obj, parameters, best, values, model, metric, method, restarts, nit, converged, message,
                     budgets, budget_reached)
    result = dataclasses.replace(result, hyperelastic=hyperelastic)
    if not warm_note:
        return result
    return dataclasses.replace(result, warm_start=warm_note, stages=({**result.stages[0], "warm_start": warm_note},))


def polish_note(n_start, n_total, start_message: str = "") -> str:
    """What `CalibrationResult.warm_start` says: ``"least-squares start, 655 evaluations (ftol termination
    condition is satisfied); Nelder-Mead polish, 1004 evaluations"`` (``n_start`` None: least squares
    did not finish)."""
    if n_start is None:
        return f"least-squares start, stopped after {n_total} evaluations; no Nelder-Mead polish"
    why = f" ({start_message})" if start_message else ""
    return f"least-squares start, {n_start} evaluations{why}; Nelder-Mead polish, {n_total - n_start} evaluations"


def budget_message(budget_reached: str, max_evals: int, max_time: float, nfev: int) -> str:
    """Why a fit stopped short: ``"stopped at the evaluation budget of 20 evaluations"`` or ``"stopped at the
    300 s time budget after 1234 evaluations"``."""
    if budget_reached == "evaluations":
        return f"stopped at the evaluation budget of {max_evals} evaluations"
    return f"stopped at the {max_time:g} s time budget after {nfev} evaluations"


def _finish(obj, parameters, best, values, model, metric, method, restarts, nit, converged, message, budgets,
            budget_reached):
    free = [p for p in parameters if p.free]
    r = residuals(obj.runs, best, model)
    n, k = r.size, len(free)
    chisqr = float(np.sum(r * r))
    stderr, corr, covar, unident = _uncertainty(obj, best, values, free, chisqr, n, model, metric)
    wall = obj._clock() - obj.t0
    start_values = values_of(obj.start)
    if metric == "max":  # an information criterion needs a likelihood: Gaussian residuals, least squares
        aic = bic = float("nan")
    else:
        aic = float(n * np.log(chisqr / n) + 2 * k) if chisqr > 0 else -np.inf
        bic = float(n * np.log(chisqr / n) + k * np.log(n)) if chisqr > 0 else -np.inf
    stage = {"stage": 0, "label": f"M = {start_branches(obj.start)}", "branches": start_branches(obj.start),
             "nfev": obj.nfev, "wall_time_s": float(wall), "objective": float(obj.best_f), "restarts": restarts,
             "converged": bool(converged), "kept": True, "message": message, "budget_reached": budget_reached}
    history = np.array([(e, f, 0) for e, f in obj.history], float).reshape(-1, 3)
    return CalibrationResult(
        params=best, start=obj.start, parameters=tuple(parameters), values=values, stderr=stderr,
        correlation=corr, covar=covar, free_names=tuple(p.name for p in free),
        at_bound=tuple(p.name for p in free if p.at_bound(values[p.name])
                       or (p.name == "C20" and at_yeoh_limit(values))),
        unmoved=tuple(p.name for p in free
                      if abs(values[p.name] - start_values[p.name]) <= 1e-9 * max(abs(start_values[p.name]), 1e-300)),
        unidentifiable=tuple(unident), model=model, metric=metric, method=method, objective=float(obj.best_f),
        chisqr=chisqr, redchi=chisqr / max(n - k, 1), aic=aic, bic=bic, ndata=int(n), nvarys=k, nfree=int(n - k),
        nfev=obj.nfev, nit=nit, restarts=restarts, wall_time=float(wall), converged=bool(converged),
        message=message, runs=tuple(goodness(run, predict_force(run, best, model)) for run in obj.runs),
        history=history, stages=(stage,), budgets=budgets, run_data=tuple(obj.runs),
    )


def start_branches(params) -> int:
    return len(getattr(params, "branches", ()) or ())


def _uncertainty(obj, best, values, free, chisqr, n, model, metric):
    """Standard errors, correlations and covariance from the Jacobian at the optimum."""
    k = len(free)
    if k == 0:
        return {}, np.zeros((0, 0)), np.zeros((0, 0)), []
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
    covar = np.full((k, k), np.nan)
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
        covar[np.ix_(idx, idx)] = cov
        for a, i in enumerate(idx):
            others = np.abs(np.delete(c[a], a))
            if (metric == "rms" and sd[a] > 0.5 * abs(values[names[i]])) or (others.size and np.nanmax(others) > 0.999):
                unident.append(names[i])
    if metric == "max":  # s^2 (J^T J)^-1 is the covariance of a least-squares estimate, not of a minimax one
        stderr = {name: float("nan") for name in names}
        corr = np.full((k, k), np.nan)
        covar = np.full((k, k), np.nan)
    return stderr, corr, covar, sorted(set(unident), key=names.index)


def initial_guess(runs, M: int, eps_r: float, name="start-from-data", law="linear") -> ParameterSet:
    """A start from the data alone, for any material.

    C10 from the small-strain slope: near lambda1 = 1 an incompressible solid
    under uniaxial tension has true stress 3 mu (lambda1 - 1) with mu = 2 C10, so
    C10 = slope / 6, fitted by least squares on samples with lambda1 - 1 < 5 %
    (of the 0 V runs when there are any). C20 = 0, C30 = C10 / 20. The M relaxation
    times are spread log-evenly from ten sample intervals to a third of the
    longest run; each branch starts with k = C10 (law linear) or mu = C10 / 3
    (finite strain: the same branch at small strain).
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
    modulus = C10 if law == "linear" else C10 / 3  # the same small-strain branch under either law (k = 3 mu)
    return ParameterSet(name=name, C10=C10, C20=0.0, C30=C10 / 20, eps_r=eps_r, law=law,
                        branches=tuple(ViscoBranch.of(law, modulus, modulus * tau) for tau in taus), eta_v0=0.0,
                        description="start values estimated from the data by rdea-lab calibrate")


from .growth import calibrate_growing  # noqa: E402,F401  (the growth calls calibrate: defined above)
