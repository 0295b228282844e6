"""`calibrate_runs`: measured runs in, a calibrated parameter set out (its record: ``result.write(out)``).

Run discovery (folders give their complete runs of the chosen protocol kinds),
the start (a parameter file, or estimated from the data), the number of
Maxwell branches (fitted one at a time when they start from the data), the
free parameters, the model (``auto``: the most detailed one any specimen of
the runs needs) and the record. The CLI's ``calibrate``, ``reproduce`` and a
notebook all come here.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr

from ..physics.selection import ORDER, select_model
from ..specs import LAWS, MODEL_CHOICES, SpecError, ViscoBranch, as_params
from ..specs.protocol import KINDS
from .fit import Budget, CalibrationResult, FitMonitor, calibrate, calibrate_growing, hook, initial_guess
from .branches import AUTO_MAX_BRANCHES, calibrate_auto
from .methods import METHODS, WARM_STARTS
from .objective import find_runs, load_run
from .parameters import HYPERELASTIC, check_hyperelastic, names_for, values_of

MODELS = MODEL_CHOICES
DEFAULT_EPS_R = 2.8  # Table 1 of [1]
ARGS = "arguments"


def parameter_names(M: int, law: str = "linear") -> list[str]:
    """The names a calibration with M branches can free: Yeoh, each branch's k (or mu) and eta, the damper."""
    return names_for(M, law)


def gather_runs(inputs, kinds=("tensile",), skipped=None) -> list:
    """`RunData` of every dataset named by ``inputs`` (paths, folders or Datasets in memory).

    ``skipped``, a list, receives the files of a folder left out and why (unreadable, not complete).

    Raises
    ------
    SpecError
        A path that does not exist, an unknown kind, no runs found, or a run that cannot be fitted.
    """
    if isinstance(inputs, (str, os.PathLike, xr.Dataset)):
        inputs = [inputs]
    kinds = tuple(kinds)
    bad = [k for k in kinds if k not in KINDS]
    if bad or not kinds:
        raise SpecError(ARGS, "protocol_kind", f"{', '.join(bad) or 'none given'}; allowed: {', '.join(KINDS)}")
    paths, runs = [], []
    for item in inputs:
        if isinstance(item, xr.Dataset):
            paths.append(item)
        elif not Path(item).exists():
            raise SpecError(str(item), "<document>", "no such dataset or folder")
        else:
            paths += find_runs([item], kinds, skipped)
    if not paths:
        raise SpecError(", ".join(str(p) for p in inputs), "<document>",
                        f"no complete runs of kind {', '.join(kinds)} found")
    for p in paths:
        try:
            runs.append(load_run(p))
        except SpecError:  # already names the file and the field
            raise
        except (KeyError, OSError, ValueError) as exc:
            raise SpecError(str(getattr(p, "encoding", {}).get("source", p)), "<document>",
                            f"cannot fit: {exc}") from None
    return runs


def choose_model(runs, start, model: str, tolerance: float = 0.01) -> tuple[str, str]:
    """The model to fit with, and why: ``auto`` takes the most detailed one any specimen's runs need."""
    if model not in MODELS:
        raise SpecError(ARGS, "model", f"{model!r}; allowed: {', '.join(MODELS)}")
    if model != "auto":
        return model, ""
    choices = []
    for s in dict.fromkeys(r.specimen for r in runs):
        mine = [r for r in runs if r.specimen == s]
        choices.append(select_model(mine[0].geom, start, np.concatenate([r.stretch for r in mine]),
                                    np.concatenate([r.voltage for r in mine]), tolerance))
    chosen = max((c.model for c in choices), key=ORDER.index)
    return chosen, "; ".join(c.reason for c in choices)


def calibrate_runs(inputs, *, model="su", init=None, free=None, branches=None, eps_r=None, kinds=("tensile",),
                   metric="rms", method="nelder-mead", law=None, budget: Budget = Budget(), tolerance=0.01,
                   monitor=None, hyperelastic="yeoh", warm_start="auto") -> CalibrationResult:
    """Fit the Yeoh and viscoelastic parameters (eps_r fixed) to measured runs (Nelder-Mead or least squares).

    Computes only: the record is ``result.write(out)`` (:meth:`CalibrationResult.write`).

    Parameters
    ----------
    inputs : path, Dataset or sequence of them
        Datasets, or folders of datasets (their complete runs of ``kinds``).
    model : {"su", "1r", "3r", "cr", "auto"}
        Quasi-static model; ``auto``: the most detailed that any specimen's
        runs need (:func:`~rdea_lab.physics.selection.select_model` within ``tolerance``).
    init : ParameterSet or path, optional
        Start values; default: estimated from the data (:func:`initial_guess`).
    free : sequence of str or str, optional
        Parameters to fit (e.g. ``"C10,C20,C30"``); default: every Yeoh and viscoelastic one.
    branches : int, "auto" or "spectrum", optional
        Maxwell branches M (0-6); default those of ``init``, or 1. From the
        data, M > 1 are fitted one at a time (they merge otherwise); with
        ``init``, branches beyond its own start 30 times slower than its last.
        ``"auto"``: M from 0 up to :data:`~rdea_lab.calibration.branches.AUTO_MAX_BRANCHES`, grown one
        at a time until the information criterion of
        :func:`~rdea_lab.calibration.branches.calibrate_auto` stops improving (BIC with an effective
        sample count from the residuals' integrated autocorrelation time; metric rms only); ``branch_choice`` of
        the result says what was tried and why M was chosen. ``init`` then supplies the Yeoh start and
        the first branch (else the data).
        ``"spectrum"``: a relaxation spectrum, time scales log-spaced over the
        data's span and moduli by regularized non-negative least squares
        (:func:`~rdea_lab.calibration.spectrum.fit_spectrum`; model su or runs at 0 V, metric rms;
        ``method``, ``free`` and ``budget`` do not apply: it is a linear problem, every parameter is fitted).
    eps_r : float, optional
        Relative permittivity (fixed) [-]; default ``init``'s, or 2.8 (Table 1).
    kinds : sequence of str
        For folders: which protocol kinds.
    metric : {"rms", "max"}
    method : {"nelder-mead", "least-squares"}
        The minimizer (:func:`~rdea_lab.calibration.fit.calibrate`); least squares minimizes the rms only.
    law : {"linear", "finite_strain"}, optional
        Viscoelastic law of the branches; default ``init``'s, or linear (eq. (44) of [1]). An ``init`` of
        the other law starts from the same relaxation times with ``mu = k / 3`` (the small-strain map).
    budget : Budget
        Evaluations and seconds [s], over all restarts and branch-growth stages
        (default 20000 evaluations, 300 s).
    tolerance : float
        Of ``model="auto"`` [-]: the relative force difference a simpler model may make.
    warm_start : {"auto", "least-squares", "none"}
        Nelder-Mead's start (:func:`~rdea_lab.calibration.fit.calibrate`): ``auto`` is a least-squares
        optimum that it polishes under metric rms, the start itself under max.
    monitor : FitMonitor or any object, optional
        Those of its methods it has are called: ``announce(runs, model, reason, free, skipped)`` once
        everything is checked, before the fit starts; ``progress(evaluations, best, elapsed)`` at most
        twice a second (evaluations so far, the best objective so far, seconds since the fit began, over
        every stage when branches are grown); ``stage(index, count, label)`` before each fit when branches
        are grown from the data (:func:`~rdea_lab.calibration.fit.calibrate_growing`).
    hyperelastic : {"yeoh", "yeoh-monotone", "neo-hookean"}
        The Yeoh coefficients the fit may reach: the paper's Yeoh (default), a Yeoh restricted to
        monotone stiffening (C20 >= 0, C30 >= 0: ``d2W/dI1^2 >= 0`` at every stretch), or neo-Hookean
        (C20 = C30 = 0; not free). See :func:`~rdea_lab.calibration.parameters.constrain_start`.

    Returns
    -------
    CalibrationResult
        Frozen; with the runs fitted (``run_data``), the files of input folders left out (``skipped``)
        and why ``auto`` chose its model (``model_reason``).

    Raises
    ------
    SpecError
        Inputs that give no runs or cannot be fitted, an option out of its range, or a fit that cannot
        start (no finite force prediction).

    References
    ----------
    [1] Prechtl et al. 2021 (Section 4.2: the calibration by Nelder-Mead).
    """
    skipped = []
    runs = gather_runs(inputs, kinds, skipped)
    init = as_params(init, "init") if init is not None else None
    eps = eps_r if eps_r is not None else (init.eps_r if init else DEFAULT_EPS_R)
    if not (isinstance(eps, (int, float)) and np.isfinite(eps) and eps >= 1.0):
        raise SpecError(ARGS, "eps_r", f"{eps!r} is not a relative permittivity; allowed: a finite number >= 1")
    auto = branches == "auto"
    spectrum = isinstance(branches, str) and branches.lower() == "spectrum"
    M = AUTO_MAX_BRANCHES if auto else 1 if spectrum else branches if branches is not None else (init.M if init else 1)
    if isinstance(M, bool) or not isinstance(M, int) or not 0 <= M <= 6:
        raise SpecError(ARGS, "branches", f"{M!r}; allowed: an integer from 0 to 6, auto or spectrum")
    if metric not in ("rms", "max"):
        raise SpecError(ARGS, "metric", f"{metric!r}; allowed: rms, max")
    if auto and metric != "rms":
        raise SpecError(ARGS, "branches", f"auto chooses by an information criterion of the rms fit, not metric "
                                          f"{metric}; allowed with metric max: an integer from 0 to 6")
    if method not in METHODS:
        raise SpecError(ARGS, "method", f"{method!r}; allowed: {', '.join(METHODS)}")
    if warm_start not in WARM_STARTS or (warm_start == "least-squares" and metric != "rms"):
        raise SpecError(ARGS, "warm_start", f"{warm_start!r}" + (f" under metric {metric}" if warm_start in WARM_STARTS
                                                                  else "") + "; allowed: "
                        + (", ".join(WARM_STARTS) if metric == "rms" else "auto, none"))
    if method == "least-squares" and metric != "rms":
        raise SpecError(ARGS, "method", f"least-squares minimizes the rms error only, not metric {metric}; "
                                        "allowed with metric max: nelder-mead")
    law = law if law is not None else (init.law if init else "linear")
    if law not in LAWS:
        raise SpecError(ARGS, "law", f"{law!r}; allowed: {', '.join(LAWS)}")
    if init is None:
        start = initial_guess(runs, M, eps, law=law)
    else:
        if init.law != law:  # the same branches at small strain: k = 3 mu, eta(44) = 3 eta
            init = init.replace(law=law, branches=tuple(b.as_law(law) for b in init.branches))
        padded = list(init.branches[:M])
        while len(padded) < M:  # more branches than the start has: slower ones, same stiffness
            last = padded[-1] if padded else ViscoBranch.of(law, init.C10, init.C10)
            padded.append(ViscoBranch.of(law, last.modulus, last.eta * 30))
        start = init.replace(eps_r=eps, branches=tuple(padded))
    check_hyperelastic(hyperelastic)
    names = parameter_names(M, law)
    if hyperelastic == "neo-hookean":  # C20 = C30 = 0, not parameters of the fit
        names = [n for n in names if n not in ("C20", "C30")]
    if isinstance(free, str):
        free = [f.strip() for f in free.split(",") if f.strip()]
    free = list(names if free is None else free)
    unknown = [f for f in free if f not in names]
    if unknown:
        why = " (hyperelastic neo-hookean holds C20 = C30 = 0)" if hyperelastic == "neo-hookean" else ""
        raise SpecError(ARGS, "free", f"{', '.join(unknown)} unknown{why}; allowed: {', '.join(names)}")
    if not isinstance(budget, Budget):
        raise SpecError(ARGS, "budget", f"{budget!r}; allowed: a Budget(evaluations=..., seconds=...)")
    model, why = choose_model(runs, start, model, tolerance)
    if spectrum:  # every parameter of a spectrum is fitted: the Yeoh coefficients and the moduli on its grid
        free = ["C10", "C20", "C30", f"{'k' if law == 'linear' else 'mu'}_v<j> on the spectrum's grid"]
    if spectrum and metric != "rms":
        raise SpecError(ARGS, "metric", f"{metric}: a spectrum is fitted by least squares; allowed: rms")
    if spectrum and hyperelastic != "yeoh":
        raise SpecError(ARGS, "hyperelastic", f"{hyperelastic} with branches spectrum: the spectrum's linear fit "
                                              "keeps the paper's Yeoh only; allowed: yeoh")
    announce = hook(monitor, "announce")
    if announce is not None:  # may refuse, before a long fit (the CLI checks its record files here)
        announce(runs, model, why, free, tuple(skipped))
    try:
        if spectrum:
            from .spectrum import fit_spectrum

            result = fit_spectrum(runs, start, model=model)
        elif auto:
            first = start if init is not None and init.branches else initial_guess(runs, 1, eps, law=law)
            result = calibrate_auto(runs, first.replace(C10=start.C10, C20=start.C20, C30=start.C30,
                                                        eta_v0=start.eta_v0), M, model=model, free=free,
                                    metric=metric, method=method, budget=budget, monitor=monitor,
                                    hyperelastic=hyperelastic, warm_start=warm_start)
        elif init is None and (M > 1 or (M == 1 and law == "finite_strain")):
            # from the data: grow the branches one by one (they merge otherwise); finite strain: two starts
            result = calibrate_growing(runs, initial_guess(runs, 1, eps, law=law), M, model=model, free=free,
                                       metric=metric, method=method, budget=budget, monitor=monitor,
                                       hyperelastic=hyperelastic, warm_start=warm_start)
        else:
            result = calibrate(runs, start, model=model, free=free, metric=metric, method=method, budget=budget,
                               monitor=monitor, hyperelastic=hyperelastic, warm_start=warm_start)
    except ValueError as exc:
        raise SpecError(ARGS, "<calibration>", f"cannot fit: {exc}") from None
    import dataclasses

    extra = {"model_reason": why, "run_data": tuple(runs), "skipped": tuple(skipped)}
    return dataclasses.replace(result, **extra)


__all__ = ["HYPERELASTIC", "KINDS", "MODELS", "Budget", "FitMonitor", "calibrate_runs", "choose_model", "gather_runs",
           "parameter_names", "values_of"]
