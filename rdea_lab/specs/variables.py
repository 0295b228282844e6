"""The one variable table: CF attributes of every variable and the global attributes rdea-lab writes.

Runs (the store's journal, `rdea_lab.store.schema`), imports and the twin's own datasets (`simulate`,
`predict`) describe each variable in the same words (CF 1.8: ``units`` and ``long_name`` everywhere,
``flag_values`` and ``flag_meanings`` on status codes, a ``time`` coordinate with a reference time). It is
the glossary's netCDF half (the same word for an argument, a YAML key and a variable), so it sits in the
specs, below both the twin and the store that write datasets: each imports it from here.
"""

from __future__ import annotations

import re

import numpy as np

from .._version import __version__
from .status import STATUS_NAMES

#: Variables of every run, in journal column order after ``time``:
#: name -> (units, long_name). SI units, CF ``units`` strings.
RUN_VARIABLES: dict[str, tuple[str, str]] = {
    "stretch": ("1", "axial stretch lambda1 = l1 / L1"),
    "position": ("m", "displacement of the moving end from the unstretched length, l1 - L1"),
    "voltage": ("V", "voltage across the electrodes"),
    "force": ("N", "axial force"),
    "capacitance": ("F", "capacitance (NaN where not measured)"),
    "stretch_setpoint": ("1", "commanded axial stretch"),
    "voltage_setpoint": ("V", "commanded voltage"),
}

#: Variables of the twin's model (a run of the twin backend has ``model_status``;
#: `simulate` writes them all): name -> (units, long_name, netCDF dtype).
MODEL_VARIABLES: dict[str, tuple[str, str, str]] = {
    "sigma1": ("Pa", "axial true stress (reversible + viscoelastic)", "f8"),
    "sigma1_irr": ("Pa", "viscoelastic overstress, eq. (44) or its finite-strain form (attribute viscoelastic_law)",
                   "f8"),
    "lambda2b": ("1", "circumferential stretch of the active ring b", "f8"),
    "converged": ("1", "whether the model has a stable equilibrium", "i1"),
    "model_status": ("1", "status of the twin model's solution", "i1"),
}


#: Run variables recorded only when the protocol measures them (``measure: [force, current]``), so runs
#: without them keep the schema they had: name -> (units, long_name, netCDF dtype).
OPTIONAL_RUN_VARIABLES: dict[str, tuple[str, str, str]] = {
    "current": ("A", "current into the electrodes from the amplifier's current monitor, mean over each sample "
                     "interval (charging d(C v)/dt plus leakage)", "f8"),
}

#: The phases of a sample of a run that can pause (issue 29), the values of its ``paused`` flag: running,
#: ramping the voltage down, held, ramping back up (`rdea_lab.protocols.pause` drives them).
PAUSE_FLAG_VALUES = (0, 1, 2, 3)
#: CF ``flag_meanings`` of ``paused`` (blank-separated, in the order of `PAUSE_FLAG_VALUES`).
PAUSE_FLAG_MEANINGS = "running ramping_down held ramping_up"

#: Variables of a run that can pause: ``paused``, the phase of each sample (along ``time``, a journal column),
#: and the pause table (along ``pause``, one entry per pause, written with the dataset: `rdea_lab.store.pauses`):
#: name -> (units, long_name, netCDF dtype; "S1" text as a CF character array, UTF-8). The times are written in
#: the units of the run's ``time`` (seconds since its start: `pause_attrs`). CF 1.8 as both checkers read it:
#: no 64-bit integers (int32 indices) and no netCDF-4 strings.
PAUSE_VARIABLES: dict[str, tuple[str, str, str]] = {
    "paused": ("1", "phase of the run: running, or paused (ramping down, held, ramping up)", "i1"),
    "pause_start": ("s", "start of a pause: time of its first sample not running", "f8"),
    "pause_end": ("s", "end of a pause: time of the first running sample after it (a run that ended paused: its "
                       "last sample's time plus one sample interval)", "f8"),
    "pause_first": ("1", "index along time of the first sample of a pause", "i4"),
    "pause_samples": ("1", "samples of a pause (ramping down, held and ramping up)", "i4"),
    "pause_reason": ("", "why the run was paused", "S1"),
    "pause_by": ("", "who or what paused the run", "S1"),
}

#: Variables of a self-sensing dataset (`rdea_lab.twin.selfsense`, ``rdea-lab selfsense``):
#: name -> (units, long_name, netCDF dtype).
SELFSENSE_VARIABLES: dict[str, tuple[str, str, str]] = {
    "capacitance_estimate": ("F", "capacitance estimated from voltage and current (self-sensing, recursive "
                                  "least squares with forgetting on the charge balance)", "f8"),
    "stretch_estimate": ("1", "axial stretch lambda1 from the estimated capacitance (inverse of the calibrated "
                              "capacitance model)", "f8"),
    "stretch_error": ("1", "stretch_estimate minus the encoder's stretch", "f8"),
    "stretch_error_percent": ("percent", "stretch_error as a percentage of the run's stretch range (encoder)", "f8"),
    "estimate_valid": ("1", "whether the estimate is used (estimator settled, roll taut, model invertible)", "i1"),
}


#: Variables of a prediction band (`rdea_lab.twin.predict` with ``bands``; `rdea_lab.calibration.bands`):
#: name -> (units, long_name, netCDF dtype); LEVEL is replaced by the band's nominal level.
BAND_VARIABLES: dict[str, tuple[str, str, str]] = {
    "force_lower": ("N", "lower bound of the LEVEL prediction band of the axial force (parameter uncertainty and "
                         "cross-validated misfit; -inf where unbounded)", "f8"),
    "force_upper": ("N", "upper bound of the LEVEL prediction band of the axial force (parameter uncertainty and "
                         "cross-validated misfit; +inf where unbounded)", "f8"),
}


def flag_word(name: str) -> str:
    """A status name as one CF ``flag_meanings`` word: ``"past limit point"`` -> ``"past_limit_point"``
    (a parenthesis dropped, anything but letters and digits an underscore)."""
    return re.sub(r"[^a-z0-9]+", "_", name.split(" (")[0].lower()).strip("_")


#: Status variables: name -> (flag_values, flag_meanings); the codes of `rdea_lab.specs.status`.
FLAGS: dict[str, tuple[np.ndarray, str]] = {
    "model_status": (np.array(sorted(STATUS_NAMES), np.int8),
                     " ".join(flag_word(STATUS_NAMES[code]) for code in sorted(STATUS_NAMES))),
    "converged": (np.array([0, 1], np.int8), "no_stable_equilibrium stable_equilibrium"),
    "estimate_valid": (np.array([0, 1], np.int8), "not_used used"),
    "paused": (np.array(PAUSE_FLAG_VALUES, np.int8), PAUSE_FLAG_MEANINGS),
}

TIME_LONG_NAME = "time since the start of the run"

#: The ``references`` attribute of every dataset.
REFERENCES = ("Prechtl et al., Smart Mater. Struct. 30 (2021), doi:10.1088/1361-665X/ac34be; "
              f"rdea-lab {__version__}, experiment management, physics twin and calibration for rolled "
              "dielectric elastomer actuators")

#: ``institution`` when the user's metadata does not name one.
NO_INSTITUTION = "not stated"


def variable_attrs(name: str) -> dict:
    """CF attributes of a variable of the table: ``units``, ``long_name`` and, for a status, its flags."""
    if name in RUN_VARIABLES:
        units, long_name = RUN_VARIABLES[name]
    else:
        units, long_name, _ = {**MODEL_VARIABLES, **OPTIONAL_RUN_VARIABLES, **SELFSENSE_VARIABLES,
                                **BAND_VARIABLES, **PAUSE_VARIABLES}[name]
    attrs = {"units": units, "long_name": long_name} if units else {"long_name": long_name}
    if name in FLAGS:
        values, meanings = FLAGS[name]
        attrs.update({"flag_values": values.copy(), "flag_meanings": meanings})
    return attrs


def time_attrs(start: str) -> dict:
    """CF attributes of the ``time`` coordinate of a run that started at ``start`` (ISO 8601 UTC):
    float seconds since then (a numeric time with its reference, CF 1.8 section 4.4)."""
    return {"units": f"seconds since {start}", "standard_name": "time", "axis": "T", "calendar": "standard",
            "long_name": TIME_LONG_NAME}


def pause_attrs(name: str, time_units: str) -> dict:
    """CF attributes of a variable of the pause table (`PAUSE_VARIABLES`): a time (``pause_start``,
    ``pause_end``) in the run's ``time`` units, ``time_units`` (``seconds since <start>``), so a CF reader
    decodes it as it decodes ``time`` (the calendar is CF's default, ``standard``, as ``time``'s); text has
    no ``units``."""
    attrs = variable_attrs(name)
    if name in ("pause_start", "pause_end"):
        attrs = {**attrs, "units": time_units, "standard_name": "time"}
    return attrs


#: How a ``time`` coordinate is encoded: no ``_FillValue`` (CF 2.5.1: a coordinate has no missing values).
TIME_ENCODING = {"_FillValue": None, "dtype": "f8"}


def global_attrs(source: str, metadata: dict | None = None) -> dict:
    """``institution`` (the user's metadata ``institution``, else "not stated"), ``source`` (how the data
    were produced, CF's meaning) and ``references``."""
    institution = str((metadata or {}).get("institution", "") or "").strip() or NO_INSTITUTION
    return {"institution": institution, "source": source, "references": REFERENCES}


__all__ = ["BAND_VARIABLES", "FLAGS", "MODEL_VARIABLES", "NO_INSTITUTION", "OPTIONAL_RUN_VARIABLES",
           "PAUSE_FLAG_MEANINGS", "PAUSE_FLAG_VALUES", "PAUSE_VARIABLES", "REFERENCES", "RUN_VARIABLES",
           "SELFSENSE_VARIABLES", "TIME_ENCODING", "TIME_LONG_NAME", "flag_word", "global_attrs", "pause_attrs",
           "time_attrs", "variable_attrs"]
