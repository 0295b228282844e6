"""The public application layer: the names of `rdea_lab` (about thirty; see its quick start).

Each is loaded on first use, so ``import rdea_lab`` stays light; a function that returns a dataset brings
``ds.rdea`` with it (`rdea_lab.api.accessor`, registered by the module that defines it). The command line
calls the same functions, and its own plumbing through the private `rdea_lab.api._cli`.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    # runs
    "run_protocol": "rdea_lab.runs.app", "prepare_run": "rdea_lab.runs.app",
    "run_campaign": "rdea_lab.runs.campaign", "Twin": "rdea_lab.runs.backend", "Emulator": "rdea_lab.runs.backend",
    "Rig": "rdea_lab.runs.backend", "LiveTable": "rdea_lab.runs.callbacks", "LivePlot": "rdea_lab.runs.live",
    # data
    "open_run": "rdea_lab.store", "catalog": "rdea_lab.store", "recover": "rdea_lab.store",
    "import_files": "rdea_lab.store.importers",
    # the twin
    "predict": "rdea_lab.twin", "simulate": "rdea_lab.twin", "TwinStep": "rdea_lab.twin",
    # calibration and reports
    "calibrate_runs": "rdea_lab.calibration.app", "cross_validate": "rdea_lab.calibration.crossval",
    "validation_report": "rdea_lab.reports.validation", "reproduce": "rdea_lab.reports.reproduce",
    # planning and design
    "plan_target": "rdea_lab.protocols.target", "run_study": "rdea_lab.design",
    "geometry": "rdea_lab.api.helpers",
    # inputs and errors
    "load_specimen": "rdea_lab.specs", "load_params": "rdea_lab.specs", "load_protocol": "rdea_lab.specs",
    "load_study": "rdea_lab.specs.study", "SpecError": "rdea_lab.specs", "LimitError": "rdea_lab.specs",
    # the rig
    "RigServer": "rdea_lab.emulator",
}

__all__ = sorted(_EXPORTS)


#: The names whose results are (or hold) run datasets: looking one up registers ``ds.rdea``.
_DATASETS = {"run_protocol", "run_campaign", "open_run", "recover", "import_files", "predict", "simulate",
             "Twin", "Emulator", "Rig"}


def __getattr__(name):
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'rdea_lab.api' has no attribute {name!r}") from None
    if name in _DATASETS:
        importlib.import_module("rdea_lab.api.accessor")  # ds.rdea on what it returns
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
