"""The number of Maxwell branches chosen by the data: grown one at a time while an information
criterion improves.

The criterion is the Bayesian information criterion with an effective sample count,

    BIC_eff(M) = n_eff ln(chisqr_M / ndata) + k_M ln(n_eff),

with ``chisqr_M`` the fit's sum of squared normalized residuals over its ``ndata`` samples (each run
counted equally, as the objective does), ``k_M`` its free parameters and

    n_eff = sum over runs of n_r / tau_r,

``tau_r`` the integrated autocorrelation time of run r's residuals (`autocorrelation_time`): the number
of independent samples that a correlated series of n_r samples is worth, for the variance of its mean.
For an AR(1) series with lag-1 correlation rho, ``tau = (1 + rho) / (1 - rho)``; a misfit correlated
over seconds is no AR(1) series, and its lag-1 correlation alone would count it several times over
(the five VHB files: n_eff 1192 of 31695 from lag 1, and four branches still "improving").
Why not the plain BIC: the residuals of a time series sampled at 50-1000 Hz are strongly
correlated (a misfit is a smooth curve, not noise), so with n = 10^4 the raw BIC rewards any reduction
of chisqr and always picks the most branches tried. Where the residuals are white (the model
is right and only measurement noise remains) n_eff is n and this is the plain BIC.

One n_eff serves every count compared: that of the residuals of the largest count tried, the fit
nearest to white residuals (a smaller model's misfit would make its own n_eff smaller and its criterion
incomparable). The growth stops at the first count whose criterion is not below the best so far;
the count chosen is the one with the lowest criterion, all of them evaluated with that n_eff.
Chosen by BIC rather than cross-validation by run: cross-validation costs a fit per run and count,
and with two or three runs (specimen 2's) a fold leaves too little to fit.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..specs import ParameterSet
from .fit import Budget, CalibrationResult, check_method
from .growth import Growth
from .objective import residuals

#: The most branches ``branches="auto"`` tries (the growth usually stops sooner).
AUTO_MAX_BRANCHES = 4

#: What the record says the criterion is.
CRITERION = ("BIC with an effective sample count: n_eff ln(chisqr / ndata) + nvarys ln(n_eff), n_eff = sum over "
             "runs of n / tau, tau the integrated autocorrelation time (Geyer's initial positive sequence) of the "
             "run's residuals in the fit with the most branches tried")


def autocorrelation_time(r) -> float:
    """The integrated autocorrelation time of a series [samples]: ``1 + 2 sum_k rho_k``.

    Summed by Geyer's initial positive sequence (pairs ``rho_2m + rho_2m+1``, lag 0 included, while
    positive; the estimator of MCMC effective sample sizes): it stops where the estimate turns to
    noise. For an AR(1) series with lag-1 correlation rho it is ``(1 + rho) / (1 - rho)``; for white
    noise 1. At least 1.

    Parameters
    ----------
    r : array_like
        The series, in time order [any unit].

    Returns
    -------
    float
        The autocorrelation time [samples], >= 1.
    """
    d = np.asarray(r, float) - np.mean(r)
    n = d.size
    if n < 3 or not np.any(d):
        return 1.0
    f = np.fft.rfft(d, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n]
    rho = acf / acf[0]
    pairs = rho[:n - n % 2].reshape(-1, 2).sum(axis=1)
    stop = int(np.argmax(pairs <= 0)) if np.any(pairs <= 0) else pairs.size
    return float(max(2.0 * pairs[:stop].sum() - 1.0, 1.0))


def effective_samples(residual_runs) -> float:
    """The effective sample count of residual series (one per run).

    Parameters
    ----------
    residual_runs : sequence of array_like
        Each run's residuals [any unit], in time order.

    Returns
    -------
    float
        ``sum n_r / tau_r`` [-], ``tau_r`` the integrated autocorrelation time of run r
        (`autocorrelation_time`; ``(1 + rho) / (1 - rho)`` for an AR(1) series); at least 1 per run.
    """
    return float(sum(max(np.size(r) / autocorrelation_time(r), 1.0) for r in residual_runs))


def run_residuals(result: CalibrationResult, runs) -> list[np.ndarray]:
    """The normalized residuals of each run at a fit's optimum (what its objective is made of)."""
    r = residuals(runs, result.params, result.model)
    return np.split(r, np.cumsum([run.n for run in runs])[:-1])


def criterion(chisqr: float, ndata: int, nvarys: int, n_eff: float) -> float:
    """``n_eff ln(chisqr / ndata) + nvarys ln(n_eff)`` [-] (module docstring); -inf for a perfect fit."""
    if chisqr <= 0:
        return -np.inf
    return float(n_eff * np.log(chisqr / ndata) + nvarys * np.log(n_eff))


def calibrate_auto(runs, start: ParameterSet, max_branches: int = AUTO_MAX_BRANCHES, *, free=None,
                   budget: Budget = Budget(), monitor=None, **kwargs) -> CalibrationResult:
    """Fit 0, 1, 2, ... Maxwell branches, grown one at a time, until the criterion stops improving.

    The criterion and why it is this one: the module docstring (`CRITERION`). M = 0 is the Yeoh
    material with the parallel damper; M = 1 starts from ``start``'s first branch and each further
    branch is grown as in `~rdea_lab.calibration.growth.calibrate_growing`. Under Nelder-Mead with a
    least-squares warm start, the stages are least squares and only the chosen set is polished.

    Parameters
    ----------
    runs : list of RunData
    start : ParameterSet
        Yeoh start values, eps_r (fixed), law, and the first branch's start (branches beyond it unused).
    max_branches : int
        The largest M tried [-], 0 to 6.
    free : iterable of str, optional
        Parameters to fit, among those of any M (default: all).
    budget : Budget
        For every fit together.
    monitor : FitMonitor or any object, optional
        As `~rdea_lab.calibration.growth.calibrate_growing` (``count`` of ``stage`` is the number of
        fits if every M up to ``max_branches`` is tried).
    **kwargs
        Passed to `~rdea_lab.calibration.fit.calibrate` (``model``, ``metric`` (rms only),
        ``method``, ``warm_start``, ...).

    Returns
    -------
    CalibrationResult
        The fit with the chosen M; ``branch_choice`` has ``criterion`` (text), ``n_eff``, ``ndata``,
        ``tried`` (per M: ``M``, ``objective``, ``chisqr``, ``nvarys``, ``criterion``), ``chosen`` and
        ``reason``; ``stages`` every fit made.

    Raises
    ------
    ValueError
        ``metric`` max (an information criterion needs the rms fit's likelihood), ``max_branches``
        outside 0-6, or as `~rdea_lab.calibration.fit.calibrate`.
    """
    metric = kwargs.get("metric", "rms")
    if metric != "rms":
        raise ValueError(f"branches auto chooses by an information criterion of the rms fit, not metric {metric!r}; "
                         "allowed with metric max: a number of branches")
    if isinstance(max_branches, bool) or not isinstance(max_branches, int) or not 0 <= max_branches <= 6:
        raise ValueError(f"max_branches {max_branches!r}; allowed: an integer from 0 to 6")
    warm = check_method(kwargs.get("method", "nelder-mead"), metric, kwargs.get("warm_start", "auto"))
    two = start.law == "finite_strain"
    count = 1 + (max_branches >= 1) * (2 if two else 1) + 2 * max(max_branches - 1, 0) + int(warm)
    growth = Growth(runs, free=free, budget=budget, monitor=monitor, count=count, **kwargs)
    kept = [growth.fit(start.replace(branches=()), "M = 0")]
    crit, n_eff = [], None
    while True:
        m = len(kept) - 1
        n_eff = effective_samples(run_residuals(growth.done[kept[-1]], runs))
        crit = [criterion(growth.done[i].chisqr, growth.done[i].ndata, growth.done[i].nvarys, n_eff) for i in kept]
        worse = m > 0 and crit[-1] >= min(crit[:-1])
        spent = any(st["budget_reached"] for st in growth.stages)
        if worse or m >= max_branches or spent:
            break
        kept.append(growth.first(start) if m == 0 else growth.add_branch(kept[-1]))
    chosen = int(np.argmin(crit))
    tried = [{"M": M, "objective": float(growth.done[i].objective), "chisqr": float(growth.done[i].chisqr),
              "nvarys": int(growth.done[i].nvarys), "criterion": float(crit[M])} for M, i in enumerate(kept)]
    if worse:
        why = (f"M = {chosen}: the lowest criterion ({crit[chosen]:.1f}); M = {len(kept) - 1} did not lower it "
               f"({crit[-1]:.1f})")
    elif spent:
        why = f"M = {chosen}: the lowest criterion of those tried before the budget ran out ({crit[chosen]:.1f})"
    else:
        why = (f"M = {chosen}: the lowest criterion ({crit[chosen]:.1f}) up to M = {max_branches}, the most "
               "tried (still improving: allow more)" if chosen == max_branches else
               f"M = {chosen}: the lowest criterion ({crit[chosen]:.1f}) up to M = {max_branches}, the most tried")
    why += f"; BIC with n_eff {n_eff:.0f} of {growth.done[kept[-1]].ndata} samples (correlated residuals)"
    growth.polish(kept[chosen])
    path = "; ".join(f"M = {t['M']}: {t['objective']:.4g} (criterion {t['criterion']:.1f})" for t in tried)
    result = growth.result(kept[:chosen + 1], f"branches chosen by the data: {path}")
    choice = {"criterion": CRITERION, "n_eff": float(n_eff), "ndata": int(result.ndata), "max_branches": max_branches,
              "tried": tried, "chosen": chosen, "reason": why}
    return dataclasses.replace(result, branch_choice=choice)


__all__ = ["AUTO_MAX_BRANCHES", "CRITERION", "autocorrelation_time", "calibrate_auto", "criterion",
           "effective_samples", "run_residuals"]
