"""The public application layer: what the CLI, ``reproduce`` and a notebook call.

Every name here is importable from ``rdea_lab`` itself (loaded on first use,
so ``import rdea_lab`` stays light). The command-line interface imports
nothing from the package but this layer and `rdea_lab.specs`.

Quick start (a notebook cell)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/tensile_ramp_sine_2.6kV.yaml", card, "twin", params=params,
                               out="demo.nc", metadata={"operator": "ana"})
    twin = rdea_lab.predict(ds, params, "su")          # or ds.rdea.predict(params, "su")
    ds.rdea.plot(prediction=twin)

Runs: `run_protocol`, `prepare_run`, `run_campaign`, callbacks `LiveTable`,
`LivePlot`. Data: `open_run`, `catalog` (a DataFrame), `recover`,
`import_files`. Model: `predict`, `simulate`, `TwinStream`, `TwinStep`, `quasi_static_curves`,
`geometry`. Calibration: `calibrate_runs`, `format_result`, `cross_validate`,
`format_cv`, `envelope`, `beyond`. Reports:
`validation_report`, `speed_study`, `reproduce`, `selfsense_run`. Self-sensing: `capacitance_rls`,
`capacitance_secant`, `stretch_from_capacitance`. Rig: `RigServer`. Voltage from a target:
`load_target`, `plan_target`, `write_protocol`, `tracking_error`, `track_target`. Design studies:
`load_study`, `run_study` (on dask.distributed), `write_study`, `study_summary`, `solve_designs` (the
models over arrays of rolls).
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    # runs
    "run_protocol": "rdea_lab.runs.app", "prepare_run": "rdea_lab.runs.app", "execute_setup": "rdea_lab.runs.app",
    "check_outputs": "rdea_lab.runs.app", "default_out": "rdea_lab.runs.app", "emulated_rig": "rdea_lab.runs.app",
    "project_default": "rdea_lab.runs.app", "check_seed": "rdea_lab.runs.app", "OutputInUse": "rdea_lab.runs.app",
    "OutputError": "rdea_lab.store.outputs", "check_writable": "rdea_lab.store.outputs",
    "check_new": "rdea_lab.store.outputs", "check_figure": "rdea_lab.store.outputs",
    "DEFAULT_PARAMS": "rdea_lab.runs.app", "DEFAULT_TRUTH": "rdea_lab.runs.app", "BACKENDS": "rdea_lab.runs.app",
    "run_campaign": "rdea_lab.runs.campaign", "experiments": "rdea_lab.runs.campaign",
    "RunResult": "rdea_lab.runs.engine", "EXIT_CODES": "rdea_lab.runs.engine", "execute": "rdea_lab.runs.engine",
    "check_metadata": "rdea_lab.runs.engine",
    "RunBlock": "rdea_lab.runs.callbacks", "LiveTable": "rdea_lab.runs.callbacks",
    "LivePlot": "rdea_lab.runs.live",
    # specs
    "load_specimen": "rdea_lab.specs", "load_params": "rdea_lab.specs", "load_protocol": "rdea_lab.specs",
    "load_truth": "rdea_lab.specs.truth", "load_campaign": "rdea_lab.specs.campaign",
    "SpecError": "rdea_lab.specs", "LimitError": "rdea_lab.specs", "read_token": "rdea_lab.specs",
    "load_plan": "rdea_lab.protocols", "as_plan": "rdea_lab.protocols", "check_plan": "rdea_lab.api.helpers",
    # physics and twin
    "predict": "rdea_lab.twin", "simulate": "rdea_lab.twin", "TwinStream": "rdea_lab.twin", "TwinStep": "rdea_lab.twin",
    "quasi_static_curves": "rdea_lab.twin", "CURVE_FIELDS": "rdea_lab.twin.curves",
    "CURVE_MAX_FIELD": "rdea_lab.twin.curves",
    "geometry": "rdea_lab.api.helpers", "StretchBelowOneError": "rdea_lab.physics.result",
    "ModelNotApplicable": "rdea_lab.physics.result",
    # store
    "open_run": "rdea_lab.store", "catalog": "rdea_lab.store", "describe_run": "rdea_lab.store",
    "recover": "rdea_lab.store", "journal_path": "rdea_lab.store", "RunInProgress": "rdea_lab.store",
    "EmptyJournal": "rdea_lab.store", "journal_writer": "rdea_lab.store",
    "import_files": "rdea_lab.store.importers", "ImportOptions": "rdea_lab.store.importers",
    "check_format": "rdea_lab.store.importers", "parse_map": "rdea_lab.store.importers",
    "parse_units": "rdea_lab.store.importers", # calibration
    "calibrate_runs": "rdea_lab.calibration.app", "format_result": "rdea_lab.calibration.app",
    "CalibrationResult": "rdea_lab.calibration.fit",
    "cross_validate": "rdea_lab.calibration.crossval", "format_cv": "rdea_lab.calibration.crossval",
    "CrossValidation": "rdea_lab.calibration.crossval", "CV_CHOICES": "rdea_lab.calibration.crossval",
    "envelope": "rdea_lab.calibration.envelope", "beyond": "rdea_lab.calibration.envelope",
    # reports
    "validation_report": "rdea_lab.reports.validation", "ReportInputError": "rdea_lab.reports.validation",
    "speed_study": "rdea_lab.reports.speed", "reproduce": "rdea_lab.reports.reproduce",
    "ReproduceInputError": "rdea_lab.reports.reproduce",
    "plot_run": "rdea_lab.reports.plots", "plot_plan": "rdea_lab.reports.plots",
    "selfsense_run": "rdea_lab.reports.selfsense", "SelfSenseResult": "rdea_lab.reports.selfsense",
    "plot_selfsense": "rdea_lab.reports.selfsense", "SelfSenseStream": "rdea_lab.twin.selfsense",
    "capacitance_rls": "rdea_lab.twin.selfsense", "capacitance_secant": "rdea_lab.twin.selfsense",
    "stretch_from_capacitance": "rdea_lab.twin.selfsense",
    # rig
    "RigServer": "rdea_lab.emulator", "is_loopback": "rdea_lab.emulator", "FAULTS": "rdea_lab.emulator",
    "parse_faults": "rdea_lab.emulator.controller", "RigRefused": "rdea_lab.backends.rig",
    # voltage plans from a target
    "load_target": "rdea_lab.specs.target", "plan_target": "rdea_lab.protocols.target",
    "write_protocol": "rdea_lab.protocols.target", "tracking_error": "rdea_lab.reports.tracking",
    "track_target": "rdea_lab.reports.tracking",
    # design studies
    "load_study": "rdea_lab.specs.study", "run_study": "rdea_lab.design", "StudyResult": "rdea_lab.design",
    "StudyError": "rdea_lab.design", "SchedulerError": "rdea_lab.design",
    "StudyAborted": "rdea_lab.design", "write_study": "rdea_lab.design.outputs",
    "check_study_out": "rdea_lab.design.outputs", "study_summary": "rdea_lab.design.outputs",
    "study_lines": "rdea_lab.design.outputs", "check_card_run": "rdea_lab.design.outputs",
    "run_card": "rdea_lab.design.outputs", "solve_designs": "rdea_lab.physics.designs",
    # misc
    "benchmarks_dir": "rdea_lab.paths",}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'rdea_lab.api' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
