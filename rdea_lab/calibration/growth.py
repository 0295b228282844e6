"""Maxwell branches grown one at a time, each fit starting from the previous optimum.

`calibrate_growing` fits a given number of branches; `~rdea_lab.calibration.branches.calibrate_auto`
grows until an information criterion stops improving. Both go through `Growth`, which keeps every
fit (its stage), counts one budget over all of them and assembles the result.
"""

from __future__ import annotations

import dataclasses
import time as _time

import numpy as np

from ..specs import ParameterSet, ViscoBranch
from .fit import Budget, CalibrationResult, _Relay, budget_message, calibrate, check_method, hook, polish_note
from .methods import POLISH_STEP
from .parameters import values_of


class Growth:
    """The fits of a growth: each stage's result, which were kept, one budget over all of them.

    Under ``method="nelder-mead"`` with a least-squares warm start (metric rms, `calibrate`'s
    ``warm_start``), every stage is fitted by least squares and only the final set is polished by
    Nelder-Mead (`polish`): the polish of each candidate would cost as much again and rank them
    the same (the rms and the sum of squares have one minimizer).
    """

    def __init__(self, runs, *, free=None, budget: Budget = Budget(), monitor=None, count: int = 1, **kwargs):
        if not isinstance(budget, Budget):
            raise TypeError(f"budget {budget!r}; allowed: a rdea_lab.calibration.fit.Budget")
        self.runs, self.free, self.budget, self.count = runs, free, budget, count
        self.method = kwargs.pop("method", "nelder-mead")
        self.warm = check_method(self.method, kwargs.get("metric", "rms"), kwargs.pop("warm_start", "auto"))
        self.kwargs = kwargs
        self.progress, self.stage = hook(monitor, "progress"), hook(monitor, "stage")
        self.t0 = _time.monotonic()
        self.stages, self.done, self.polished = [], [], None

    @property
    def nfev(self) -> int:
        return sum(r.nfev for r in self.done)

    def fit(self, params: ParameterSet, label: str, **options) -> int:
        """Fit ``params`` (a stage called ``label``) with what the budget has left; its index in `done`."""
        spent, best_before = self.nfev, min((r.objective for r in self.done), default=np.inf)
        if self.stage is not None:
            self.stage(len(self.done) + 1, self.count, label)
        report = None if self.progress is None else (
            lambda n, best, elapsed: self.progress(spent + n, min(best, best_before), _time.monotonic() - self.t0))
        method = options.pop("method", "least-squares" if self.warm else self.method)
        if method == "nelder-mead":  # a stage's own Nelder-Mead starts where it is told (the polish, or no warm start)
            options.setdefault("warm_start", "none")
        res = calibrate(self.runs, params, free=[n for n in values_of(params) if self.free is None or n in self.free],
                        monitor=None if report is None else _Relay(report), method=method,
                        budget=self.budget.left(spent, _time.monotonic() - self.t0), **{**self.kwargs, **options})
        self.stages.append({**res.stages[0], "stage": len(self.done), "label": label, "kept": False,
                            "method": method})
        self.done.append(res)
        return len(self.done) - 1

    def first(self, start: ParameterSet) -> int:
        """The one-branch fit from ``start``'s first branch (finite strain: and one a tenth as stiff, the better)."""
        first = start.replace(branches=start.branches[:1])
        if first.law == "finite_strain" and first.branches:
            # a neo-Hookean branch's stress grows like lambda_e**2: started at the small-strain estimate, a
            # local fit on large stretches can switch it off (tau to its bound) instead of softening it; a
            # second start a tenth as stiff (same tau), the better fit of the runs kept
            b0 = first.branches[0]
            soft = first.replace(branches=(ViscoBranch.of(first.law, max(b0.modulus / 10, 1e3), b0.eta / 10),))
            pair = [self.fit(first, "M = 1"), self.fit(soft, "M = 1, spring a tenth as stiff")]
            return min(pair, key=lambda i: self.done[i].objective)
        return self.fit(first, "M = 1")

    def add_branch(self, prev: int) -> int:
        """One branch more than fit ``prev``: 10 times slower than its slowest, or faster than its fastest."""
        params = self.done[prev].params
        m = params.M + 1
        taus = [b.tau for b in params.branches]
        # a tenth of the stiffest spring so far (C10, or a branch that took over the elasticity), in bounds
        k_new = 0.1 * max(params.C10 if params.law == "linear" else params.C10 / 3,
                          *(b.modulus for b in params.branches))
        k_new = min(max(k_new, 1e3), 1e10)
        # the new time scale within what the runs resolve: a tenth of a sample interval to ten run lengths
        dt = min(float(np.median(np.diff(r.t))) for r in self.runs)
        T = max(float(r.t[-1] - r.t[0]) for r in self.runs)
        scales = [(side, min(max(tau, 0.1 * dt), 10 * T)) for side, tau in
                  (("slower", 10 * max(taus)), ("faster", 0.1 * min(taus)))]
        candidates = [self.fit(params.replace(branches=params.branches + (ViscoBranch.of(params.law, k_new,
                                                                                          k_new * tau),)),
                               f"M = {m}, new branch {side} (tau {tau:.3g} s)") for side, tau in scales]
        return min(candidates, key=lambda i: self.done[i].objective)

    def polish(self, kept: int) -> int | None:
        """Nelder-Mead's polish of fit ``kept`` when the stages were least squares' warm start, else None."""
        if not self.warm:
            return None
        self.polished = self.fit(self.done[kept].params, f"M = {self.done[kept].params.M}, Nelder-Mead polish",
                                 method="nelder-mead", warm_start="none", step=POLISH_STEP)
        return self.polished

    def result(self, kept: list[int], what: str) -> CalibrationResult:
        """The result of fit ``kept[-1]`` (polished, if it was), counting every stage; ``what``: how it grew."""
        for i in kept:
            self.stages[i]["kept"] = True
        best = self.done[kept[-1]]
        warm = ""
        if self.polished is not None:
            self.stages[self.polished]["kept"] = True
            polished = self.done[self.polished]
            start_values = values_of(best.start)
            # the polish starts at least squares' optimum: flags and start values are those of the stage before
            unmoved = tuple(n for n in polished.free_names if abs(polished.values[n] - start_values[n])
                            <= 1e-9 * max(abs(start_values[n]), 1e-300))
            warm = polish_note(self.nfev - polished.nfev, self.nfev)
            warm = warm.replace("least-squares start", f"least-squares start (grown: {len(self.done) - 1} fits)")
            best = dataclasses.replace(polished, start=best.start, parameters=best.parameters, unmoved=unmoved)
        offset, history = 0, []
        for i, res in enumerate(self.done):
            h = res.history[:, :2].copy()
            h[:, 0] += offset
            history.append(np.column_stack([h, np.full(len(h), i)]))
            offset += res.nfev
        budgets = {**best.budgets, "max_evals": int(self.budget.evaluations),
                   "max_time_s": float(self.budget.seconds),
                   "scope": "max_evals and max_time cover every stage and candidate together"}
        grown = f"{what}; {len(self.done)} fits"
        # a stage a budget stopped leaves the growth unfinished, even where the fit kept had converged
        stopped = next((st for st in self.stages if st["budget_reached"]), None)
        if stopped is None:
            converged, message = best.converged, f"{best.message} ({grown})"
        else:
            spent = budget_message(stopped["budget_reached"], self.budget.evaluations, self.budget.seconds,
                                   self.nfev)
            converged, message = False, (f"{spent}, in stage {stopped['stage']} '{stopped['label']}'; "
                                         f"the best fit so far kept ({grown})")
        return dataclasses.replace(
            best, method=self.method, nfev=self.nfev, nit=sum(r.nit for r in self.done),
            restarts=sum(r.restarts for r in self.done), wall_time=float(_time.monotonic() - self.t0),
            history=np.vstack(history), stages=tuple(self.stages), budgets=budgets, converged=converged,
            message=message, warm_start=warm)


def calibrate_growing(runs, start: ParameterSet, M: int, *, free=None, budget: Budget = Budget(), monitor=None,
                      **kwargs) -> CalibrationResult:
    """Fit M Maxwell branches one at a time, each from the previous optimum.

    Nelder-Mead started with M branches at once tends to merge them into one time
    scale. Here the fit with m - 1 branches is extended by a branch 10 times slower
    than the slowest and, separately, 10 times faster than the fastest (its
    stiffness a tenth of the stiffest spring so far), both fitted, and the better kept; ``start`` supplies
    the first branch (finite strain: it and one a tenth as stiff, the better kept). ``free`` names
    parameters of the final set (default: all). Under Nelder-Mead with a least-squares warm start
    (metric rms: `calibrate`'s ``warm_start``), the stages are least squares and Nelder-Mead polishes
    the final set (one stage more; ``warm_start`` of the result says so).

    Parameters
    ----------
    runs : list of RunData
    start : ParameterSet
        Its first branch starts the growth; eps_r fixed.
    M : int
        Maxwell branches of the final set.
    free : iterable of str, optional
        Parameters of the final set to fit (default: all).
    budget : Budget
        For all the fits together: each gets what the ones before it left (a fit left nothing
        stops at its start).
    monitor : FitMonitor or any object, optional
        Its ``progress(evaluations, best, elapsed)`` counts over every fit so far (``best`` the lowest
        objective of any of them, ``elapsed`` [s] since the growth began); its ``stage(index, count,
        label)`` is called before each fit (``index`` from 1 to ``count``, the number of fits the growth
        makes).
    **kwargs
        Passed to `calibrate` (``model``, ``metric``, ``method``, ``warm_start``, ...).

    Returns
    -------
    CalibrationResult
        The final fit with M branches; ``nfev``, ``nit``, ``restarts`` and
        ``wall_time`` count every stage and candidate, ``stages`` has one entry
        each, ``history`` all of theirs (evaluations numbered across stages, a
        stage column); ``message`` says how it grew.

    Raises
    ------
    ValueError, TypeError
        As `calibrate`.
    """
    method = kwargs.get("method", "nelder-mead")
    warm = check_method(method, kwargs.get("metric", "rms"), kwargs.get("warm_start", "auto"))
    two_starts = start.law == "finite_strain" and bool(start.branches)
    count = (2 if two_starts else 1) + 2 * max(M - 1, 0) + int(warm)
    growth = Growth(runs, free=free, budget=budget, monitor=monitor, count=count, **kwargs)
    kept = [growth.first(start)]
    for _ in range(2, M + 1):
        kept.append(growth.add_branch(kept[-1]))
    growth.polish(kept[-1])
    path = "; ".join(f"M = {m}: {growth.done[i].objective:.4g}" for m, i in enumerate(kept, start=1))
    return growth.result(kept, f"grown branch by branch: {path}")


__all__ = ["Growth", "calibrate_growing"]
