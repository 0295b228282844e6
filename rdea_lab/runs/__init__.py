"""Runs: the application layer that executes protocols.

- `run_protocol` (protocol, specimen, backend): every limit check, the backend
  wiring (twin, built-in emulator, rig server), the default output path, the
  journal, callbacks and user metadata; returns the run's Dataset.
- `run_campaign`: every protocol on every specimen of a campaign file; `submit_campaign`
  the same, one process-pool task per run (`run_experiment`).
- `execute`: the engine (plan -> backend -> blocks -> journal -> dataset).
- `callbacks`: `LiveTable`, `RunBlock`; `live.LivePlot`.

Quick start::

    import rdea_lab
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", "specimens/specimen2.yaml", "twin",
                               out="demo.nc", metadata={"operator": "ana"})
    ds.rdea.plot()
"""

from .app import (
    BACKENDS, OutputError, OutputInUse, RunSetup, check_writable, check_outputs, default_out, emulated_rig,
    execute_setup, prepare_run, run_protocol,
)
from .callbacks import LiveTable, RunBlock
from .campaign import Experiment, experiments, run_campaign, run_experiment, submit_campaign
from .engine import EXIT_CODES, RunResult, check_metadata, execute, run_attrs

__all__ = ["BACKENDS", "EXIT_CODES", "Experiment", "LiveTable", "OutputError", "OutputInUse", "check_writable",
           "RunBlock", "RunResult", "RunSetup", "check_metadata", "check_outputs", "default_out", "emulated_rig",
           "execute", "execute_setup", "experiments", "prepare_run", "run_attrs", "run_campaign", "run_experiment",
           "run_protocol", "submit_campaign"]
