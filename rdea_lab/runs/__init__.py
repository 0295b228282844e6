"""Runs: the application layer that executes protocols.

- `run_protocol` (protocol, specimen, backend): every limit check, the backend
  wiring (twin, built-in emulator, rig server), the default output path, the
  journal, callbacks and user metadata; returns the run's Dataset.
- `run_campaign`: every protocol on every specimen of a campaign file; `submit_campaign`
  the same, one process-pool task per run (`run_experiment`).
- `execute`: the engine (checked plan -> backend -> blocks -> journal -> dataset); it runs only a
  `CheckedPlan`, which `checked_plan` makes in preparation (`prepare_run`, `experiments`).
- `callbacks`: `LiveTable`, `RunBlock`; `live.LivePlot`.
- `RunControl`: pause, resume and abort a run while it goes (`control`; `operate` acts on them between
  blocks, with the protocol's suspenders).

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

from .app import (
    OutputError, OutputInUse, RunSetup, check_writable, check_outputs, default_out, execute_setup, prepare_run,
    run_protocol,
)
from .backend import BACKENDS, Emulator, Rig, Twin, backend_from_choice, emulated_rig
from .callbacks import LiveTable, RunBlock
from .checked import CheckedPlan, UncheckedPlan, checked_plan
from .control import RunControl
from .campaign import Experiment, experiments, run_campaign, run_experiment, submit_campaign
from .engine import EXIT_CODES, RunResult, check_metadata, execute, run_attrs

__all__ = ["backend_from_choice", "BACKENDS", "check_metadata", "CheckedPlan", "checked_plan", "check_outputs",
           "check_writable", "default_out", "emulated_rig", "Emulator", "execute", "execute_setup", "EXIT_CODES",
           "Experiment", "experiments", "LiveTable", "OutputError", "OutputInUse", "prepare_run", "Rig", "run_attrs",
           "run_campaign", "run_experiment", "run_protocol", "RunBlock", "RunControl", "RunResult", "RunSetup",
           "submit_campaign",
           "Twin", "UncheckedPlan"]
