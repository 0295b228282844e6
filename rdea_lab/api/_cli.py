"""What the command line needs of the application layer beyond the public names: its plumbing (output
checks, defaults, formatting of results, option parsing). Private: the CLI imports it as ``api``; a user
imports `rdea_lab` (whose names are here too, so that a command and a notebook call the same functions).
Each name is loaded on first use, so ``rdea-lab --help`` imports none of them."""

from __future__ import annotations

import importlib

from . import _EXPORTS as _PUBLIC

_EXPORTS = {
    **_PUBLIC,
    "check_figure": "rdea_lab.store.outputs",
    "check_outputs": "rdea_lab.runs.app", "record_files": "rdea_lab.calibration.record",
    "Budget": "rdea_lab.calibration.fit",
    "write_protocol": "rdea_lab.protocols.target",
    "tracking_error": "rdea_lab.reports.tracking", "track_target": "rdea_lab.reports.tracking",
    "speed_study": "rdea_lab.reports.speed", "selfsense_run": "rdea_lab.reports.selfsense",
    "figure_files": "rdea_lab.reports.validation", "check_validation_inputs": "rdea_lab.reports.validation",
    "run_card": "rdea_lab.design.outputs", "quasi_static_curves": "rdea_lab.twin",
    "project_default": "rdea_lab.runs.backend", "plot_selfsense": "rdea_lab.reports.selfsense",
    "plot_run": "rdea_lab.reports.plots", "plot_plan": "rdea_lab.reports.plots",
    "parse_units": "rdea_lab.store.importers", "parse_map": "rdea_lab.store.importers",
    "parse_faults": "rdea_lab.emulator.controller", "load_truth": "rdea_lab.specs.truth",
    "load_target": "rdea_lab.specs.target", "load_plan": "rdea_lab.protocols",
    "load_campaign": "rdea_lab.specs.campaign", "is_loopback": "rdea_lab.emulator",
    "dedicate_process": "rdea_lab.emulator.server",
    "format_cv": "rdea_lab.calibration.crossval", "suggest": "rdea_lab.calibration.suggest",
    "write_suggestion": "rdea_lab.calibration.suggest", "load_scene": "rdea_lab.calibration.suggest",
    "experiments": "rdea_lab.runs.campaign",
    "execute_setup": "rdea_lab.runs.app", "describe_run": "rdea_lab.store",
    "check_study_out": "rdea_lab.design.outputs", "check_plan": "rdea_lab.api.helpers",
    "check_new": "rdea_lab.store.outputs", "check_metadata": "rdea_lab.runs.engine",
    "check_format": "rdea_lab.store.importers", "check_card_run": "rdea_lab.design.outputs",
    "benchmarks_dir": "rdea_lab.paths", "backend_from_choice": "rdea_lab.runs.backend",
    "StudyAborted": "rdea_lab.design", "RunInProgress": "rdea_lab.store",
    "ImportOptions": "rdea_lab.store.importers", "EmptyJournal": "rdea_lab.store",
    "DEFAULT_TRUTH": "rdea_lab.runs.backend", "CURVE_MAX_FIELD": "rdea_lab.twin.curves",
    "CURVE_FIELDS": "rdea_lab.twin.curves",
    "monitor": "rdea_lab.monitor", "Monitor": "rdea_lab.monitor",
    "rebuild_catalog": "rdea_lab.store.index", "check_catalog": "rdea_lab.store.index",
    "RunControl": "rdea_lab.runs.control", "request": "rdea_lab.runs.control",
    "ControlError": "rdea_lab.runs.control",
}


def __getattr__(name):
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'rdea_lab.api._cli' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value
