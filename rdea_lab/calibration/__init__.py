"""Calibration: fit the material of the twin to measured runs (Nelder-Mead, as in [1]).

- `calibrate_runs` (paths or datasets, model=, free=, branches=, budget=, monitor=): run
  discovery, start values, branch growth, model choice; returns the frozen
  `CalibrationResult` (``result.fit_report()``; ``result.write(out)`` writes the record).
  `Budget` (evaluations, seconds) bounds a fit; a `FitMonitor` (or any object with some of its
  methods) hears its progress.
- `calibrate`: the Nelder-Mead fit itself on `RunData`; `load_run`, `find_runs`.
- `cross_validate` (inputs, cv= or holdout=): fit some runs, predict the others, with the
  error measures of `error_measures` and the flags of `beyond` against the fitted runs' `envelope`.
- `rdea_lab.calibration.bands`: prediction bands (`Uncertainty.of_record(path)` or `.of_fit(result,
  misfit_mapping(cv))`): the fit's covariance by the delta method, in quadrature with the held-out
  misfit; widened or unbounded beyond the envelope.
- The objective predicts the force through the twin's one composition
  (:func:`rdea_lab.twin.compose`), with a cached SU stress basis.

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

from .app import calibrate_runs, gather_runs
from .fit import Budget, CalibrationResult, FitMonitor, calibrate, initial_guess
from .objective import RunData, error_measures, find_runs, goodness, load_run, predict_force
from .envelope import Envelope, beyond, envelope, run_envelope
from .crossval import CrossValidation, Fold, cross_validate, format_cv

__all__ = ["Budget", "CalibrationResult", "CrossValidation", "Envelope", "FitMonitor", "Fold", "RunData", "beyond",
           "calibrate", "calibrate_runs", "cross_validate", "envelope", "error_measures", "find_runs", "format_cv",
           "gather_runs", "goodness", "initial_guess", "load_run", "predict_force", "run_envelope"]
