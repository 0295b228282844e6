"""Calibration: fit the material of the twin to measured runs (Nelder-Mead, as in [1])."""

from .fit import CalibrationResult, calibrate, initial_guess
from .objective import RunData, find_runs, goodness, load_run, predict_force

__all__ = ["CalibrationResult", "RunData", "calibrate", "find_runs", "goodness", "initial_guess", "load_run",
           "predict_force"]
