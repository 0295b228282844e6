"""Calibration: fit the material of the twin to measured runs (Nelder-Mead, as in [1]).

- `calibrate_runs` (paths or datasets, model=, free=, branches=, out=): run
  discovery, start values, branch growth, model choice; returns the frozen
  `CalibrationResult` and writes the record if ``out`` is given.
- `calibrate`: the Nelder-Mead fit itself on `RunData`; `load_run`, `find_runs`.
- The objective predicts the force through the twin's one composition
  (:func:`rdea_lab.twin.compose`), with a cached SU stress basis.

Quick start::

    import rdea_lab
    fit = rdea_lab.calibrate_runs("datasets/paper2021/specimen-2", model="su", out="calibrated.yaml")
    print(rdea_lab.calibration.format_result(fit))
"""

from .app import calibrate_runs, format_result, gather_runs
from .fit import CalibrationResult, calibrate, initial_guess
from .objective import RunData, find_runs, goodness, load_run, predict_force

__all__ = ["CalibrationResult", "RunData", "calibrate", "calibrate_runs", "find_runs", "format_result",
           "gather_runs", "goodness", "initial_guess", "load_run", "predict_force"]
