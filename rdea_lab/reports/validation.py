"""The Table 4 analogue: the twin against every measured run, with figures and provenance.

``validation_report(params, datasets_folder)`` runs the twin on each
complete run's own measured stretch and voltage history
(:func:`rdea_lab.twin.predict`, viscoelastic branches included),
and for capacitance runs also the capacitance at the samples where the LCR
bridge measured it. Each run gives one row: the maximum relative error
against the largest measured force or capacitance of that run (the metric of
Table 4 in [1]) and the rms error, beside the paper's value, and says what the
run is (:mod:`~rdea_lab.reports.provenance`): its name, protocol, nominal
stretch rate and maximum stretch, where its data come from (import, emulator,
twin, rig), its role against the calibration record (calibration run, held out
(same specimen), other specimen) and where it leaves the calibration envelope.
It returns a :class:`ValidationReport`, whose ``write(out)`` writes ``table4.md``,
``table4.csv``, ``table4.tex``, figures in the manner of Figures 11-16 (PNG and PDF,
with residual panels) and ``index.html``.

[1] Prechtl et al., Smart Mater. Struct. 30 (2021), doi:10.1088/1361-665X/ac34be.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..calibration.bands import UNBOUNDED, Uncertainty, check_level, coverage
from ..calibration.crossval import nominal_rate
from ..calibration.envelope import beyond, run_envelope, stretch_text
from ..calibration.objective import error_measures, load_run
from ..specs import MODEL_CHOICES, UserError, as_params
from ..store import open_run
from ..store.outputs import check_new
from ..twin import predict
from . import tables
from .html import write_validation_index
from .repeats import REPEAT_KEYS, REPEAT_LEGEND, add_repeats, columns_for, repeat_key, repeat_lines
from .provenance import (NONE_RECORDED, NOT_CHECKED, calibration_envelope, calibration_summary, data_origin, role,
                         run_origin)
from .validation_figures import write_figures
from ..store.journal import walk_runs

#: Table 4 of [1]: maximum relative error [-] per (experiment, voltage [V]) and specimen.
PAPER_TABLE4 = {
    ("tensile", 0.0): {"specimen-1": 0.0320, "specimen-2": 0.0519, "specimen-3": 0.0481},
    ("tensile", 2600.0): {"specimen-1": 0.0613, "specimen-2": 0.0541, "specimen-3": 0.0653},
    ("blocking", 2600.0): {"specimen-1": 0.0090, "specimen-2": 0.0099, "specimen-3": 0.0118},
    ("capacitance", 0.0): {"specimen-1": 0.0499, "specimen-2": 0.0078, "specimen-3": 0.0516},
}
#: A run's voltage matches a paper voltage within this [V] (5 % of 2.6 kV).
VOLTAGE_MATCH = 130.0
MODELS = MODEL_CHOICES
KIND_ORDER = ("tensile", "blocking", "capacitance", "custom")

#: The columns shown (Markdown, LaTeX, HTML); the CSV has every key of CSV_KEYS.
COLUMNS = [
    ("experiment", "experiment", tables.text),
    ("voltage", "voltage", tables.text),
    ("specimen", "specimen", tables.text),
    ("name", "run", tables.text),
    ("protocol", "protocol", tables.text),
    ("rate_per_s", "rate [/s]", tables.number(".3g")),
    ("max_stretch", "max. stretch", stretch_text),
    ("origin", "data", tables.text),
    ("role", "role", tables.text),
    ("model", "model", tables.text),
    ("samples", "samples", tables.text),
    ("max_rel_error", "max. rel. error [%]", tables.percent),
    ("paper_max_rel_error", "paper [%]", tables.percent),
    ("rms_rel_error", "rms/peak [%]", tables.percent),
    ("p99_rel_error", "p99/peak [%]", tables.percent),
    ("rms_text", "rms error", tables.text),
    ("beyond_calibration", "beyond the calibration", tables.text),
    ("notes", "notes", tables.text),
]
CSV_KEYS = ["experiment", "kind", "quantity", "voltage", "voltage_V", "specimen", "name", "protocol", "rate_per_s",
            "max_stretch", "file", "sha256", "origin", "origin_detail", "source_file", "source_credit", "role",
            "calibrated_on", "model", "model_reason", "samples", "excluded", "peak", "unit", "max_rel_error",
            "rms_error", "paper_max_rel_error", "rms_rel_error", "p99_rel_error", "beyond_calibration", "window",
            "notes"]
CSV_KEYS += REPEAT_KEYS  # where runs repeat a test (rdea_lab.reports.repeats)
#: The line under every rendering of the table that says which error measure is which.
LEGEND = ("Errors relative to the run's largest measured force or capacitance (peak): max. rel. error = "
          "max |predicted - measured| / peak (Table 4's metric); rms/peak = rms(predicted - measured) / peak; "
          "p99/peak = 99th percentile of |predicted - measured| / peak; rms error in the quantity's unit. "
          "Run: the file's name; rate: the run's nominal stretch rate, the median |d stretch/dt| over its moving "
          "samples; data: where the file says its data come from (import, emulator, twin, rig); role: calibration "
          "run (fitted: its sha256 is in the calibration record), held out (same specimen) or other specimen; "
          "beyond the calibration: where the run leaves the stretch, rate, voltage or hold range of the fitted "
          "runs, or a combination of them that no fitted run covered (the calibration envelope).")


#: With ``bands``: the columns added after the error columns, the CSV keys and the legend's sentence.
BAND_COLUMNS = [
    ("band_coverage", "band coverage", tables.number(".3f")),
    ("band_half_width_rel", "band half-width/peak [%]", tables.percent),
    ("band_status", "band", tables.text),
]
BAND_CSV_KEYS = ["band_level", "band_coverage", "band_half_width_rel", "band_misfit_rel", "band_status",
                 "band_detail"]
BAND_LEGEND = ("Band coverage: the fraction of the run's measured samples inside the {level:g} % prediction band "
               "(rdea_lab.calibration.bands: the fit's covariance propagated by the delta method, combined in "
               "quadrature with the cross-validated misfit of the record's validation.misfit); band half-width: "
               "its median over the samples, of the peak; band: bounded, parameter-only (no cross-validation in "
               "the record), widened (beyond the calibration: the misfit of held-out runs that were themselves "
               "extrapolations) or unbounded (beyond the calibration, and no such held-out run: coverage —); "
               "in-sample: the run's own held-out error is in the misfit, so its coverage does not test the band.")


def report_columns(band_level):
    """The shown columns and the CSV keys of a report with (``band_level`` a level) or without bands (None)."""
    if band_level is None:
        return COLUMNS, CSV_KEYS
    i = [k for k, _, _ in COLUMNS].index("rms_text") + 1
    return COLUMNS[:i] + BAND_COLUMNS + COLUMNS[i:], CSV_KEYS + BAND_CSV_KEYS


def add_bands(evaluated, uncertainty: Uncertainty, level: float) -> None:
    """Each evaluated force run's band (its ``flags`` the report's), coverage and half-width, into its row and
    series (``force_lower``, ``force_upper`` [N]); capacitance rows get none."""
    misfit = uncertainty.misfit or {}
    groups = [misfit.get("inside"), misfit.get("beyond"), *misfit.get("beyond_by_axes", ())]
    learnt = {Path(name).name for g in groups if g for name in g["runs"]}  # the runs the misfit was learnt from
    for e in evaluated:
        r, s, run = e["row"], e["series"], e["run"]
        if r["quantity"] != "force":
            r.update(band_level=level, band_coverage=None, band_half_width_rel=None, band_misfit_rel=None,
                     band_status="—", band_detail="no band: the band is of the force")
            continue
        b = uncertainty.band(run, level, r["model"], point=s["force_pred"], flags=r["flags"])
        sel = s.get("window", np.ones(run.n, bool))
        half = 0.5 * (b["upper"][sel] - b["lower"][sel])
        peak = float(np.max(np.abs(run.force[sel])))
        s.update(force_lower=b["lower"], force_upper=b["upper"], band_level=level, band_status=b["status"])
        own = Path(r["file"]).name in learnt  # its own held-out error is in the misfit: not a test of the band
        r.update(band_level=level, band_coverage=coverage(run.force[sel], b["lower"][sel], b["upper"][sel]),
                 band_half_width_rel=(math.inf if b["status"] == UNBOUNDED else float(np.nanmedian(half) / peak)),
                 band_misfit_rel=b["misfit_rel"], band_status=b["status"] + (" (in-sample)" if own else ""),
                 band_detail=b["detail"] + ("; in-sample: this run's own held-out error is in the misfit, so its "
                                            "coverage does not test the band" if own else ""))


class ReportInputError(UserError):
    """Bad input to a report (no runs, unknown model): one line, exit status 2 at the CLI."""


def kv(volts: float) -> str:
    """A voltage as the paper writes it: ``0 V``, ``2.60 kV``."""
    return "0 V" if abs(volts) < 5.0 else f"{round(volts, -1) / 1e3:.2f} kV"


def scan_runs(folder: Path) -> tuple[list[Path], list[dict]]:
    """The complete runs (``*.nc``, recursively) below ``folder``, and the files skipped, with why."""
    use, skipped = [], []
    for path in map(Path, walk_runs(folder)[0]):  # not inside a journal (its shadow file)
        try:
            with xr.open_dataset(path, engine="netcdf4") as ds:
                status = ds.attrs.get("status", "?")
                missing = [k for k in ("time", "stretch", "voltage", "force", "specimen") if
                           k not in ds.variables and k not in ds.attrs]
        except Exception as exc:  # a foreign or broken file: list it, say why
            skipped.append({"file": str(path), "reason": f"unreadable ({type(exc).__name__})"})
            continue
        if missing:
            skipped.append({"file": str(path), "reason": f"not an rdea-lab run (no {', '.join(missing)})"})
        elif status != "complete":
            skipped.append({"file": str(path), "reason": f"status {status}"})
        else:
            use.append(path)
    return use, skipped


def experiment(kind: str, protocol: str, voltage: np.ndarray, has_capacitance: bool) -> dict:
    """Which row of Table 4 a run is: its label, the voltage label and the paper's key."""
    v = np.asarray(voltage, float)
    plateau = float(np.median(v))
    lo, hi = float(np.min(v)), float(np.max(v))
    if kind == "blocking":
        key = ("blocking", 2600.0) if abs(lo) <= VOLTAGE_MATCH and abs(hi - 2600.0) <= VOLTAGE_MATCH else None
        return {"experiment": "blocking force", "voltage": f"{kv(lo)} to {kv(hi)}", "voltage_V": hi,
                "quantity": "force", "key": key}
    if kind == "capacitance" and has_capacitance:
        key = ("capacitance", 0.0) if abs(plateau) <= VOLTAGE_MATCH else None
        return {"experiment": "capacitance", "voltage": kv(plateau), "voltage_V": plateau,
                "quantity": "capacitance", "key": key}
    if kind == "capacitance":  # a capacitance run without a capacitance sample: its force only
        return {"experiment": "capacitance run (force; no capacitance measured)", "voltage": kv(plateau),
                "voltage_V": plateau, "quantity": "force", "key": None}
    if kind == "tensile":
        near = [p for (k, p) in PAPER_TABLE4 if k == "tensile" and abs(plateau - p) <= VOLTAGE_MATCH]
        return {"experiment": "tensile (force)", "voltage": kv(plateau), "voltage_V": plateau, "quantity": "force",
                "key": ("tensile", near[0]) if near else None}
    return {"experiment": f"custom ({protocol})", "voltage": f"{kv(lo)} to {kv(hi)}", "voltage_V": hi,
            "quantity": "force", "key": None}


def compare(measured: np.ndarray, predicted: np.ndarray) -> dict:
    """Table 4's metric: ``max |pred - meas| / max |meas|``, the rms error, and the rms and 99th
    percentile of the error over the same peak (:func:`rdea_lab.calibration.error_measures`), over the
    finite predictions.

    The same numbers as :func:`rdea_lab.calibration.goodness` when every
    prediction is finite; samples without an equilibrium are counted in
    ``excluded`` instead of turning the row into NaN.
    """
    ok = np.isfinite(predicted)
    r = predicted[ok] - measured[ok]
    peak = float(np.max(np.abs(measured)))
    if not ok.any() or peak == 0.0:
        return {"max_rel_error": math.nan, "rms_rel_error": math.nan, "p99_rel_error": math.nan,
                "rms_error": math.nan, "peak": peak, "excluded": int((~ok).sum())}
    return {**error_measures(r, peak), "rms_error": float(np.sqrt(np.mean(r**2))), "peak": peak,
            "excluded": int((~ok).sum())}


def _voltage_window(voltage: np.ndarray) -> np.ndarray:
    """Blocking runs: the samples from the first to the last where |v| exceeds 1 % of its maximum
    (every sample if the voltage never leaves 0)."""
    on = np.flatnonzero(np.abs(voltage) > 0.01 * np.max(np.abs(voltage)))
    if not on.size:
        return np.ones(voltage.size, bool)
    mask = np.zeros(voltage.size, bool)
    mask[on[0]:on[-1] + 1] = True
    return mask


def _evaluated(path, params, model, tolerance):
    """`evaluate_run`'s second part, or why the run cannot be evaluated (one line)."""
    try:
        return evaluate_run(path, params, model, tolerance)[1]
    except (KeyError, OSError, ValueError) as exc:
        return " ".join(str(exc).split())


def evaluate_run(path: Path, params, model: str, tolerance: float) -> tuple[dict, dict]:
    """One run against the twin: its Table 4 row, its provenance and the series for the figures."""
    run = load_run(path)
    ds = open_run(path)
    a = ds.attrs
    ok = run.index  # the samples load_run kept: align position and capacitance with them
    position = (np.asarray(ds["position"].values, float)[ok] if "position" in ds
                else (run.stretch - 1.0) * run.geom.L1)
    cap = np.asarray(ds["capacitance"].values, float)[ok] if "capacitance" in ds else np.full(run.n, np.nan)
    cap_mask = np.isfinite(cap)
    exp = experiment(run.kind, run.protocol, run.voltage, bool(cap_mask.any()))
    # the twin on the samples load_run kept (the ones the calibration compares too)
    twin = predict({"time": run.t, "stretch": run.stretch, "voltage": run.voltage}, params, model,
                   specimen=run.geom, tolerance=tolerance)
    used = twin.attrs["model"]
    reason = json.loads(twin.attrs["model_selection"])["reason"] if "model_selection" in twin.attrs else ""
    force_pred = twin["force"].values
    series = {"t": run.t, "stretch": run.stretch, "position": position, "voltage": run.voltage,
              "force": run.force, "force_pred": force_pred, "cap_mask": cap_mask, "capacitance": cap[cap_mask]}
    window = ""
    if exp["quantity"] == "capacitance":
        pred = twin["capacitance"].values[cap_mask]
        series["capacitance_pred"] = pred
        err, unit, scale, shown = compare(cap[cap_mask], pred), "F", 1e12, "pF"
        samples = int(cap_mask.sum())
    else:
        sel = _voltage_window(run.voltage) if run.kind == "blocking" else np.ones(run.n, bool)
        if not sel.all():
            window = f"t = {run.t[sel][0]:.3g} to {run.t[sel][-1]:.3g} s (voltage cycles)"
        series["window"] = sel
        err, unit, scale, shown = compare(run.force[sel], force_pred[sel]), "N", 1.0, "N"
        samples = int(sel.sum())
    own = run_envelope(run)
    origin = run_origin(a)
    row = {k: exp[k] for k in ("experiment", "voltage", "voltage_V", "quantity")}
    row.update({"kind": run.kind, "specimen": run.specimen, "name": Path(path).stem, "protocol": run.protocol,
                "rate_per_s": nominal_rate(run), "max_stretch": own.stretch[1], "file": str(path),
                "sha256": run.sha256, **{k: origin[k] for k in ("origin", "origin_detail", "source_file",
                                                                  "source_credit")},
                "model": used, "model_reason": reason, "samples": samples, "unit": unit,
                **err, "window": window,
                "paper_max_rel_error": PAPER_TABLE4.get(exp["key"], {}).get(run.specimen) if exp["key"] else None,
                "rms_text": f"{err['rms_error'] * scale:.4g} {shown}" if math.isfinite(err["rms_error"]) else "—"})
    notes = [window, f"{err['excluded']} samples without equilibrium left out" if err["excluded"] else "",
             f"auto: {reason}" if reason else ""]
    row["notes"] = "; ".join(n for n in notes if n)
    row["test"] = repeat_key(a, run, exp["voltage"], exp["quantity"])
    prov = {"file": str(path), "name": row["name"], "sha256": run.sha256, "run_id": a.get("run_id", "?"),
            "backend": a.get("backend", "?"), "created": a.get("created", "?"), "protocol": run.protocol,
            "kind": run.kind, "specimen": run.specimen, **origin}
    return row, {"row": row, "provenance": prov, "series": series, "run": run, "envelope": own}


def _sort_key(row):
    return (KIND_ORDER.index(row["kind"]) if row["kind"] in KIND_ORDER else len(KIND_ORDER),
            row["quantity"], round(row["voltage_V"], -1), row["specimen"], row["protocol"], row["file"])


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """The Table 4 analogue for a parameter set and a folder of runs: computed, not yet written.

    Made by :func:`validation_report`; :meth:`write` writes it (``table4.md``, ``.csv``, ``.tex``, the
    figures, ``index.html``).

    Attributes
    ----------
    table : pandas.DataFrame
        One row per run (the keys of :data:`CSV_KEYS`, ``rms_text`` and ``flags``), in the table's order.
    rows : tuple of dict
        The same rows as dicts (what the renderers take).
    markdown : str
        The table as Markdown.
    caption : str
        The line above the table (model, parameters, calibration, data origin, envelope).
    legend : str
        The line under it: which error measure is which (:data:`LEGEND`).
    model : str
        The twin model asked for.
    params : dict
        The calibration summary of the parameter file (:func:`~rdea_lab.reports.provenance.calibration_summary`),
        with ``envelope_source`` and ``envelope_text``.
    params_name : str
        The parameter set's name.
    runs : tuple of dict
        Provenance of every run evaluated (file, hash, run id, backend, origin, ...).
    skipped : tuple of dict
        The files left out, each with ``file`` and ``reason``.
    origin : str
        Where the data come from, in one sentence.
    envelope : dict or None
        The calibration envelope (None when none could be found).
    repeats : tuple of dict
        One per test that runs repeat (:func:`~rdea_lab.reports.repeats.add_repeats`): ``test``, ``runs``,
        ``spread`` and ``ratio`` per run [-], ``within``; empty when no run repeats another.
    band_level : float or None
        The prediction bands' nominal level (None: no bands; else the rows have :data:`BAND_CSV_KEYS`).
    """

    table: pd.DataFrame
    rows: tuple
    markdown: str
    caption: str
    legend: str
    model: str
    params: dict
    params_name: str
    runs: tuple
    skipped: tuple
    origin: str
    envelope: dict | None
    repeats: tuple = ()
    _evaluated: tuple = field(repr=False, default=())  # rows with their series: what the figures draw
    band_level: float | None = None

    @property
    def repeat_lines(self) -> list[str]:
        """One sentence per repeated test (:func:`~rdea_lab.reports.repeats.repeat_lines`)."""
        return repeat_lines(self.repeats)

    def write(self, out, *, figures: bool = True, pdf: bool = True, overwrite: bool = False,
              executor=None) -> dict[str, Path]:
        """Write ``table4.md``, ``table4.csv``, ``table4.tex``, the figures and ``index.html`` into ``out``.

        Parameters
        ----------
        out : path
            Output folder (created); one that holds files is refused unless ``overwrite``.
        figures : bool
            Write the PNG figures (the tables and ``index.html`` are always written).
        pdf : bool
            With the figures, a PDF beside each PNG (vector, for a paper; linked from ``index.html``).
        overwrite : bool
            Write into an ``out`` that holds files (the CLI's ``--force``).
        executor : concurrent.futures.Executor, optional
            Draw the figures as its tasks (the same files as drawn here).

        Returns
        -------
        dict of str to Path
            ``markdown``, ``csv``, ``latex``, each figure under its file name (PNG, and its PDF when
            written) and ``html``, in the order written.

        Raises
        ------
        OutputError
            ``out`` holds files (and not ``overwrite``), is a file, or cannot be written.
        """
        check_new(out, overwrite, "out", folder=True)
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        rows = list(self.rows)
        files = {"markdown": out / "table4.md", "csv": out / "table4.csv", "latex": out / "table4.tex"}
        left_out = "".join(f"- `{sk['file']}`: {sk['reason']}\n" for sk in self.skipped)
        repeated = "".join(f"- {line}\n" for line in self.repeat_lines)
        files["markdown"].write_text(f"# Table 4 analogue\n\n{self.caption}\n\n{self.markdown}\n{self.legend}\n"
                                     + (f"\nRepeats:\n\n{repeated}" if repeated else "")
                                     + (f"\nFiles left out:\n\n{left_out}" if left_out else ""))
        columns, keys = report_columns(self.band_level)
        columns = columns_for(columns, rows)
        tables.write_csv(files["csv"], keys, rows)
        files["latex"].write_text(f"% {tables.latex_escape(self.caption)}\n% {tables.latex_escape(self.legend)}\n"
                                  + tables.latex_tabular(columns, rows))
        figs = write_figures(list(self._evaluated), out, pdf, executor) if figures else {}
        for png in figs:
            files[png.name] = png
            if png.with_suffix(".pdf").is_file() and pdf:
                files[png.with_suffix(".pdf").name] = png.with_suffix(".pdf")
        files["html"] = write_validation_index(out / "index.html", self, columns, figs)
        return files


def figure_files(files: dict[str, Path]) -> list[Path]:
    """The PNG figures among the files :meth:`ValidationReport.write` returned."""
    return [p for p in files.values() if Path(p).suffix == ".png"]


def check_validation_inputs(params, datasets_folder, model: str = "su"):
    """The checks :func:`validation_report` makes before any work, in its order: the model, the folder,
    the parameters (the CLI makes them before it checks ``--out``, as the report did when it wrote).

    Parameters
    ----------
    params : path or ParameterSet
        Parameter file or parameter set.
    datasets_folder : path
        Folder of runs.
    model : str
        Quasi-static model of the twin.

    Returns
    -------
    ParameterSet
        The parameters read.

    Raises
    ------
    ReportInputError
        Unknown model or no folder.
    SpecError
        The parameter file is missing or invalid.
    """
    if model not in MODELS:
        raise ReportInputError(f"--model: {model!r} is not a model; allowed: {', '.join(MODELS)}")
    folder = Path(datasets_folder)
    if not folder.is_dir():
        raise ReportInputError(f"{folder}: no such folder of datasets")
    return as_params(params)


def validation_report(params, datasets_folder, *, model: str = "su", tolerance: float = 0.01,
                      executor=None, bands: float | None = None) -> ValidationReport:
    """The Table 4 analogue for a parameter set and a folder of runs, computed (write it with
    :meth:`ValidationReport.write`).

    Parameters
    ----------
    params : path or ParameterSet
        Parameter file (a calibration record is one; its ``calibration`` section gives the provenance),
        or a parameter set (then without provenance).
    datasets_folder : path
        Folder searched recursively for complete runs (``*.nc``).
    model : {"su", "1r", "3r", "cr", "auto"}
        Quasi-static model of the twin; ``auto`` picks per run with :func:`select_model`.
    tolerance : float
        For ``auto``: allowed deviation from 3R relative to the peak stress [-].
    executor : concurrent.futures.Executor, optional
        Evaluate the runs as its tasks (a process pool: on every core), with the numbers of the serial report.
    bands : float, optional
        Nominal level of a prediction band of each force run [-] (0.9), from ``params``' calibration record
        (:class:`rdea_lab.calibration.bands.Uncertainty`): the rows get its coverage of the measured samples,
        its median half-width and its status (:data:`BAND_COLUMNS`), the figures shade it.

    Returns
    -------
    ValidationReport
        The rows, the table, caption and legend, the provenance of the runs and parameters, the files
        skipped and the series the figures draw.

    Raises
    ------
    SpecError
        The parameter file is missing or invalid.
    ReportInputError
        Unknown model, no folder, or no complete runs in it; ``bands`` with parameters that are no file.
    SpecError
        With ``bands``: a level outside 0.05-0.99, or a parameter file without a calibration record or
        covariance.

    References
    ----------
    [1] Prechtl et al., Smart Mater. Struct. 30 (2021), Table 4.
    """
    params_path, params = params, check_validation_inputs(params, datasets_folder, model)
    uncertainty = None
    if bands is not None:
        bands = check_level(bands)
        if not isinstance(params_path, (str, os.PathLike)):
            raise ReportInputError("--bands: needs --params to be a calibration record (a parameter file "
                                   "'rdea-lab calibrate' wrote): its covariance and cross-validation make the band")
        uncertainty = Uncertainty.of_record(params_path)
    folder = Path(datasets_folder)
    paths, skipped = scan_runs(folder)
    evaluated = []
    n = len(paths)
    for path, got in zip(paths, (executor.map if executor is not None else map)(
            _evaluated, paths, [params] * n, [model] * n, [tolerance] * n)):
        if isinstance(got, str):
            skipped.append({"file": str(path), "reason": f"cannot evaluate: {got}"})
        else:
            evaluated.append(got)
    if not evaluated:
        raise ReportInputError(f"{folder}: no complete runs found" + (
            f" ({len(skipped)} skipped: {skipped[0]['file']}: {skipped[0]['reason']})" if skipped else ""))
    evaluated.sort(key=lambda e: _sort_key(e["row"]))
    cal = calibration_summary(params_path)
    env, env_source = calibration_envelope(cal, [e["run"] for e in evaluated])
    cal["envelope_source"] = env_source
    cal["envelope_text"] = env.describe() if env is not None else ""
    for e in evaluated:
        r = e["row"]
        r["role"] = role(r["sha256"], r["specimen"], cal)
        r["calibrated_on"] = ", ".join(cal["specimens"]) or NONE_RECORDED
        r["flags"] = beyond(env, e["envelope"]) if env is not None else ()
        r["beyond_calibration"] = "; ".join(r["flags"]) or ("—" if env is not None else NOT_CHECKED)
    repeats = add_repeats(evaluated)
    if uncertainty is not None:
        add_bands(evaluated, uncertainty, bands)
    rows = [e["row"] for e in evaluated]
    columns, _ = report_columns(bands)
    origin = data_origin([e["provenance"] for e in evaluated])
    caption = (f"Maximum relative error against the largest measured force or capacitance of each run "
               f"(Table 4 of Prechtl et al. 2021), twin model {model}, parameters {params.name}; "
               f"calibrated on: {', '.join(cal['specimens']) or NONE_RECORDED}. {origin} "
               + (f"Calibration envelope ({env_source}): {cal['envelope_text']}; "
                  f"{sum(bool(r['flags']) for r in rows)} of {len(rows)} runs beyond it."
                  if env is not None else f"Calibration envelope: {env_source}."))
    return ValidationReport(
        table=pd.DataFrame(rows), rows=tuple(rows), markdown=tables.markdown(columns_for(columns, rows), rows),
        caption=caption,
        legend=LEGEND + ("" if bands is None else " " + BAND_LEGEND.format(level=100 * bands))
        + (" " + REPEAT_LEGEND if repeats else ""), model=model, params=cal, params_name=params.name,
        runs=tuple(e["provenance"] for e in evaluated), skipped=tuple(skipped), origin=origin,
        envelope=env.mapping() if env is not None else None, repeats=repeats,
        _evaluated=tuple({"row": e["row"], "series": e["series"]} for e in evaluated), band_level=bands)
