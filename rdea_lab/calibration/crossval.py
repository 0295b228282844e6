"""Cross-validation: fit on some runs, predict the others, and say how far the prediction reached.

``cross_validate(inputs, cv=...)`` or ``cross_validate(inputs, holdout=[...])``
splits the runs into folds, calls :func:`~rdea_lab.calibration.app.calibrate_runs`
on each fold's fitted runs only, predicts its held-out runs with
:func:`~rdea_lab.calibration.objective.predict_force` and the fold's parameters,
and returns one row per (fold, run) with the error measures of
:func:`~rdea_lab.calibration.objective.error_measures` and the flags of
:func:`~rdea_lab.calibration.envelope.beyond` against the fold's calibration envelope.

Folds (``cv``):

- ``leave-one-out``: one run held out per fold;
- ``by-rate``: runs grouped by their nominal stretch rate, the median
  |d stretch/dt| over their moving loading and unloading samples
  (:func:`~rdea_lab.calibration.envelope.moving_rates`)
  rounded to 2 significant figures (0.0100625 -> 0.01 /s); one group held out per fold;
- ``by-stretch``: grouped by the maximum stretch rounded to 0.01 (3.00025 -> 3.0).

Groups are ordered by their value (runs by input order for leave-one-out).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..store.outputs import check_new
from ..specs import SpecError
from ..specs.record import add_record_section
from .app import ARGS, calibrate_runs, gather_runs
from .bands import misfit_mapping
from .fit import hook
from .record import record_files
from .envelope import Envelope, beyond, envelope, moving_rates, run_envelope, stretch_text
from .objective import ERROR_LEGEND, find_runs, goodness, predict_force
from .parameters import values_of

CV_CHOICES = ("leave-one-out", "by-rate", "by-stretch")
HOLDOUT = "holdout"
#: Significant figures of the nominal stretch rate, decimals of the maximum stretch (the groups' keys).
RATE_DIGITS, STRETCH_DECIMALS = 2, 2


@dataclass(frozen=True)
class Fold:
    """One split: what was held out, what was fitted, the fit and its envelope.

    Attributes
    ----------
    index : int
        1-based.
    label : str
        What the fold holds out: a run's name (the held-out names for a holdout), ``rate 0.01 /s``
        or ``stretch 3.0``.
    fitted, predicted : tuple of str
        File names of the runs fitted and of those predicted.
    result : CalibrationResult
        The fold's calibration (``result.params``, ``.nfev``, ``.wall_time``, ``.record_files``).
    envelope : Envelope
        Of the fitted runs.
    residuals : dict
        Held-out run name -> (predicted - measured force) / its peak [-] per sample (what a band's misfit
        term learns from: `rdea_lab.calibration.bands.misfit_mapping`).
    """

    index: int
    label: str
    fitted: tuple
    predicted: tuple
    result: object
    envelope: Envelope
    residuals: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def params(self):
        return self.result.params

    @property
    def nfev(self) -> int:
        return self.result.nfev

    @property
    def wall_time(self) -> float:
        return self.result.wall_time


@dataclass(frozen=True)
class CrossValidation:
    """What a cross-validation found: its tables, one per (fold, run) and one per fold, and the folds.

    Attributes
    ----------
    cv : str
        ``leave-one-out``, ``by-rate``, ``by-stretch`` or ``holdout``.
    model : str
        Of the first fold's fit (every fold fits the same model unless ``auto`` chose otherwise).
    grouping : str
        How the folds were made, in words.
    table : pandas.DataFrame
        One row per (fold, run), in fold order, the fitted runs first; the columns :data:`CSV_KEYS`
        (those of ``cv.csv`` before the parameters): ``rate_per_s`` [1/s], ``max_stretch`` [-],
        ``rms_error_N`` [N], the relative errors [-] (of the peak measured force), ``flags`` a tuple
        of str (empty inside the fold's envelope), ``fold_wall_time_s`` [s].
    fold_table : pandas.DataFrame
        One row per fold: ``fold``, ``held_out``, ``fitted`` and ``predicted`` (file names, comma
        separated), ``nfev``, ``converged``, ``wall_time_s`` [s], ``record`` (its parameter file, or
        empty), and the fitted parameters [SI] as ``cv.csv`` names them (``C10_Pa``, ``eta_v1_Pa_s``, ...).
    folds : tuple of Fold
        Each with its `CalibrationResult` and envelope.
    skipped : tuple of dict
        Files of input folders left out (``file``, ``reason``).
    files : dict
        Paths written: ``csv``, ``markdown`` and ``fold-<k>`` (each fold's record) for ``cv``;
        ``params``, ``history``, ``plot`` (the record) and ``holdout`` (the csv) for a holdout.
    """

    cv: str
    model: str
    grouping: str
    table: pd.DataFrame
    fold_table: pd.DataFrame
    folds: tuple
    skipped: tuple = ()
    files: dict = field(default_factory=dict)

    def rows(self, **where) -> list[dict]:
        """The rows of `table` as dicts of Python values, those whose columns equal ``where``
        (e.g. ``rows(role="predicted")``)."""
        return [r for r in _records(self.table) if all(r[k] == v for k, v in where.items())]


CSV_KEYS = ["fold", "held_out", "role", "file", "specimen", "protocol", "samples", "rate_per_s", "max_stretch",
            "rms_error_N", "max_rel_error", "rms_rel_error", "p99_rel_error", "flags", "fold_nfev",
            "fold_converged", "fold_wall_time_s", "model", "path", "sha256"]


def _records(table: pd.DataFrame) -> list[dict]:
    """The rows of a table as dicts of Python values (numpy scalars unboxed: the same numbers)."""
    return [{k: (v.item() if isinstance(v, np.generic) else v) for k, v in r.items()}
            for r in table.to_dict("records")]


def _param_column(name: str) -> str:
    return f"{name}_Pa" + ("_s" if name.startswith("eta") else "")


def _table(rows, columns=CSV_KEYS) -> pd.DataFrame:
    """A DataFrame of dict rows: numeric columns typed, every other column Python objects as given (a
    missing ``sha256`` stays None, not NaN)."""
    data = {}
    for k in columns:
        values = [r[k] for r in rows]
        numeric = all(isinstance(v, (int, float)) for v in values)
        data[k] = pd.Series(values, dtype=None if numeric else object)
    return pd.DataFrame(data, columns=columns)


def _fold_table(folds) -> pd.DataFrame:
    names = list(values_of(folds[0].params)) if folds else []
    rows = [{"fold": f.index, "held_out": f.label, "fitted": ", ".join(f.fitted), "predicted": ", ".join(f.predicted),
             "nfev": f.nfev, "converged": f.result.converged, "wall_time_s": f.wall_time,
             "record": str(f.result.record_files.get("params", "")),
             **{_param_column(n): float(values_of(f.params).get(n, math.nan)) for n in names}} for f in folds]
    return _table(rows, ["fold", "held_out", "fitted", "predicted", "nfev", "converged", "wall_time_s", "record",
                         *(_param_column(n) for n in names)])


def _sig(x: float, digits: int) -> float:
    if not math.isfinite(x) or x == 0:
        return x
    return round(x, digits - 1 - int(math.floor(math.log10(abs(x)))))


def nominal_rate(run) -> float:
    """The run's nominal stretch rate [1/s]: median |d stretch/dt| of its moving samples, 2 significant
    figures (0 when nothing moves)."""
    moving = moving_rates(run)
    return _sig(float(np.median(moving)), RATE_DIGITS) if moving.size else 0.0


def nominal_stretch(run) -> float:
    """The run's maximum stretch rounded to 0.01 [-]."""
    return round(float(np.max(run.stretch)), STRETCH_DECIMALS)


def _name(run) -> str:
    return run.path.name


def make_folds(runs, cv: str | None = None, holdout_index=()) -> list[tuple[str, list[int], list[int]]]:
    """The folds as ``(label, fitted indices, predicted indices)`` of ``runs``.

    Raises
    ------
    SpecError
        Fewer than 2 groups, or nothing left to fit.
    """
    n = len(runs)
    if cv is None:
        held = sorted(set(holdout_index))
        if len(held) == n:
            raise SpecError(ARGS, "holdout", "every input is held out; allowed: hold out some of the inputs, "
                            "leaving at least one to fit")
        return [(", ".join(_name(runs[i]) for i in held), [i for i in range(n) if i not in held], held)]
    if cv == "leave-one-out":
        groups = {i: (_name(r), [i]) for i, r in enumerate(runs)}
    else:
        key = nominal_rate if cv == "by-rate" else nominal_stretch
        groups = {}
        for i, r in enumerate(runs):
            k = key(r)
            label = f"rate {k:g} /s" if cv == "by-rate" else f"stretch {stretch_text(k)}"
            groups.setdefault(k, (label, []))[1].append(i)
        groups = dict(sorted(groups.items()))
    if len(groups) < 2:
        what = "; ".join(f"{label}: {', '.join(_name(runs[i]) for i in idx)}" for label, idx in groups.values())
        raise SpecError(ARGS, "cv", f"{cv} gives {len(groups)} group ({what}); allowed: inputs that make at "
                        "least 2 groups")
    return [(label, [i for i in range(n) if i not in idx], list(idx)) for label, idx in groups.values()]


def _expand(inputs, kinds, skipped) -> list:
    """The inputs as one item per run: a dataset file or a Dataset in memory (folders expanded)."""
    if isinstance(inputs, (str, os.PathLike, xr.Dataset)):
        inputs = [inputs]
    items = []
    for item in inputs:
        if not isinstance(item, xr.Dataset) and Path(item).is_dir():
            items += find_runs([item], kinds, skipped)
        else:
            items.append(item)
    return items


def _holdout_index(items, holdout) -> list[int]:
    if isinstance(holdout, (str, os.PathLike, xr.Dataset)):
        holdout = [holdout]
    holdout = list(holdout)
    if not holdout:
        raise SpecError(ARGS, "holdout", "no file given; allowed: one or more of the input runs")
    resolved = [None if isinstance(it, xr.Dataset) else Path(it).resolve() for it in items]
    out = []
    for h in holdout:
        if isinstance(h, xr.Dataset):
            hit = [i for i, it in enumerate(items) if it is h]
        else:
            hit = [i for i, p in enumerate(resolved) if p is not None and p == Path(h).resolve()]
        if not hit:
            names = ", ".join(str(getattr(it, "encoding", {}).get("source", it)) for it in items)
            raise SpecError(ARGS, "holdout", f"{h} is not among the inputs; allowed: one of {names}")
        out += hit
    return out


def cross_validate(inputs, *, cv: str | None = None, holdout=None, out=None, name=None, overwrite=False,
                   monitor=None, **calibrate_kwargs) -> CrossValidation:
    """Fit on some runs, predict the others: k-fold (``cv``) or one split (``holdout``).

    Parameters
    ----------
    inputs : path, Dataset or sequence of them
        Datasets, or folders of datasets (their complete runs of ``kinds``), as for `calibrate_runs`.
    cv : {"leave-one-out", "by-rate", "by-stretch"}, optional
        How to make the folds (see the module's docstring); not together with ``holdout``.
    holdout : path or sequence of paths, optional
        Runs (among the inputs) to predict; the rest are fitted. One fold.
    out : path, optional
        With ``cv``: a folder for ``cv.csv``, ``cv.md`` and each fold's record ``fold-<k>.yaml``.
        With ``holdout``: the record of the fit (as `calibrate_runs` writes it); the held-out rows go
        beside it to ``<stem>.holdout.csv`` and into its ``calibration`` section as ``validation``.
        An existing output (a folder that holds files, with ``cv``) is refused before any fit unless
        ``overwrite``.
    name : str, optional
        Name of the calibrated set in each record (default: the record's stem).
    overwrite : bool
        Write over existing outputs (the CLI's ``--force``).
    monitor : FitMonitor or any object, optional
        Passed to `calibrate_runs` for every fold (its ``announce``, ``progress``, ``stage``); here its
        ``announce_fold(index, count, label, fitted_names, predicted_names)`` is called before each fold's
        fit and its ``fold_done(index, count, fold, rows)`` after it: the `Fold` (its fit and envelope)
        and its rows of the result's table (its fitted and predicted runs). Those it has.
    **calibrate_kwargs
        Passed to `calibrate_runs` for every fold (``model``, ``free``, ``branches``, ``budget``, ...;
        ``kinds`` also selects the runs of folders here).

    Returns
    -------
    CrossValidation
        Frozen: ``table`` (a DataFrame, one row per fold and run), ``fold_table`` (one per fold),
        ``folds`` (each with its `CalibrationResult`), ``files``.

    Raises
    ------
    SpecError
        Both or neither of ``cv`` and ``holdout``; an unknown ``cv``; fewer than 2 groups; a held-out run
        that is not among the inputs; every input held out; ``out`` of the wrong kind; whatever
        `calibrate_runs` refuses.
    """
    if cv is not None and holdout is not None:
        raise SpecError(ARGS, "cv", "not together with --holdout; allowed: one of them (--cv "
                        f"{'|'.join(CV_CHOICES)}, or --holdout FILE)")
    if cv is None and holdout is None:
        raise SpecError(ARGS, "cv", f"none given; allowed: {', '.join(CV_CHOICES)} (or a holdout)")
    if cv is not None and cv not in CV_CHOICES:
        raise SpecError(ARGS, "cv", f"{cv!r}; allowed: {', '.join(CV_CHOICES)}")
    out = Path(out) if out is not None else None
    if out is not None and cv is not None and out.exists() and not out.is_dir():
        raise SpecError(str(out), "out", "is a file; with --cv, --out names a folder")
    if out is not None and cv is None and out.is_dir():
        raise SpecError(str(out), "out", "is a folder; with --holdout, --out names the record file")
    if out is not None and cv is not None:  # before any fit
        check_new(out, overwrite, "out", folder=True)
    if out is not None and cv is None:
        for path in (*record_files(out).values(), _holdout_csv(out)):
            check_new(path, overwrite)
    kinds = tuple(calibrate_kwargs.get("kinds", ("tensile",)))
    skipped = []
    items = _expand(inputs, kinds, skipped)
    runs = gather_runs(items, kinds)
    held = _holdout_index(items, holdout) if cv is None else ()
    plan = make_folds(runs, cv, held)
    grouping = _grouping(cv)
    announce_fold, fold_done = hook(monitor, "announce_fold"), hook(monitor, "fold_done")
    folds, rows = [], []
    for k, (label, fit_idx, pred_idx) in enumerate(plan, start=1):
        fitted, predicted = [_name(runs[i]) for i in fit_idx], [_name(runs[i]) for i in pred_idx]
        if announce_fold is not None:
            announce_fold(k, len(plan), label, fitted, predicted)
        record = (out / f"fold-{k}.yaml" if cv is not None else out) if out is not None else None
        result = calibrate_runs([items[i] for i in fit_idx], monitor=monitor, **calibrate_kwargs)
        if record is not None:  # new: checked above, before any fit
            result = replace(result, record_files=result.write(record, name=name, overwrite=overwrite))
        fit_runs = list(result.run_data) or [runs[i] for i in fit_idx]
        env = envelope(fit_runs)
        held_res = {_name(runs[i]): (predict_force(runs[i], result.params, result.model) - runs[i].force)
                    / runs[i].peak for i in pred_idx}
        fold = Fold(k, label, tuple(fitted), tuple(predicted), result, env, held_res)
        folds.append(fold)
        mine = [_row(fold, "fitted", r, env) for r in fit_runs] + [_row(fold, "predicted", runs[i], env)
                                                                   for i in pred_idx]
        rows += mine
        if fold_done is not None:
            fold_done(k, len(plan), fold, tuple(mine))
    cv_name = cv or HOLDOUT
    result = CrossValidation(cv_name, folds[0].result.model, grouping, _table(rows), _fold_table(folds),
                             tuple(folds), tuple(skipped))
    if out is not None:
        files = write_cv(result, out) if cv is not None else write_holdout(result, out)
        result = replace(result, files=files)
    return result


def _grouping(cv) -> str:
    if cv is None:
        return "the held-out runs against a fit on the rest"
    if cv == "leave-one-out":
        return "one run held out per fold"
    if cv == "by-rate":
        return ("runs grouped by nominal stretch rate (median |d stretch/dt| of the moving samples, "
                "2 significant figures); one group held out per fold")
    return "runs grouped by maximum stretch (rounded to 0.01); one group held out per fold"


def _row(fold: Fold, role: str, run, env: Envelope) -> dict:
    res = fold.result
    g = goodness(run, predict_force(run, res.params, res.model))
    own = run_envelope(run)
    return {"fold": fold.index, "held_out": fold.label, "role": role, "file": _name(run), "specimen": run.specimen,
            "protocol": run.protocol, "samples": run.n, "rate_per_s": nominal_rate(run),
            "max_stretch": own.stretch[1], "rms_error_N": g["rms_error_N"], "max_rel_error": g["max_rel_error"],
            "rms_rel_error": g["rms_rel_error"], "p99_rel_error": g["p99_rel_error"], "flags": beyond(env, own),
            "fold_nfev": res.nfev, "fold_converged": res.converged, "fold_wall_time_s": round(res.wall_time, 3),
            "model": res.model, "path": str(run.path), "sha256": run.sha256}


# ------------------------------------------------------------------ output
def _pct(x) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{100 * x:.2f}"


#: The columns of the printed and Markdown table: (key, header, format).
COLUMNS = [("fold", "fold", str), ("held_out", "held out", str), ("role", "role", str), ("file", "run", str),
           ("rate_per_s", "rate [/s]", lambda v: f"{v:.3g}"), ("max_stretch", "max. stretch", stretch_text),
           ("max_rel_error", "max/peak [%]", _pct), ("rms_rel_error", "rms/peak [%]", _pct),
           ("p99_rel_error", "p99/peak [%]", _pct),
           ("flags", "beyond the calibration", lambda f: "; ".join(f) or "—")]


def table(rows, columns=COLUMNS) -> str:
    """A Markdown table, padded so that it also reads as plain text."""
    cells = [[h for _, h, _ in columns]] + [[str(f(r[k])).replace("|", r"\|") for k, _, f in columns] for r in rows]
    width = [max(len(c[j]) for c in cells) for j in range(len(columns))]
    line = lambda c: "| " + " | ".join(s.ljust(w) for s, w in zip(c, width)) + " |"  # noqa: E731
    return "\n".join([line(cells[0]), "|" + "|".join("-" * (w + 2) for w in width) + "|"]
                     + [line(c) for c in cells[1:]]) + "\n"


def _fold_line(f: Fold) -> str:
    values = ", ".join(f"{n} {v / 1e3:.5g} kPa" + (" s" if n.startswith("eta") else "")
                       for n, v in values_of(f.params).items())
    rec = f.result.record_files.get("params")
    state = "" if f.result.converged else f", not converged ({f.result.message})"
    return (f"fold {f.index} (held out: {f.label}): fitted on {', '.join(f.fitted)}; {f.nfev} evaluations, "
            f"{f.wall_time:.2f} s{state}; {values}" + (f"; record {Path(rec).name}" if rec else ""))


def format_cv(result: CrossValidation) -> str:
    """The table, its legend and one line per fold (evaluations, wall time, parameters, record)."""
    legend = ("Legend: " + ERROR_LEGEND + ". Rate: the run's nominal stretch rate; beyond the calibration: "
              "where the run leaves the stretch, rate, voltage or hold range of its fold's fitted runs, or a "
              "combination of them that no fitted run covered.")
    return "\n".join([table(result.rows()), legend, "", *(_fold_line(f) for f in result.folds)]) + "\n"


def _csv_value(key, value):
    if key == "flags":
        return "; ".join(value)
    return repr(value) if isinstance(value, float) else value


def _write_csv(path: Path, rows, folds) -> Path:
    names = list(values_of(folds[0].params)) if folds else []
    by_index = {f.index: values_of(f.params) for f in folds}
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_KEYS + [_param_column(n) for n in names])
        for r in rows:
            params = by_index[r["fold"]]
            w.writerow([_csv_value(k, r[k]) for k in CSV_KEYS] + [repr(float(params.get(n, math.nan))) for n in names])
    return path


def write_cv(result: CrossValidation, out: Path) -> dict:
    """``cv.csv`` (one line per fold and run, with the fold's parameters [SI]) and ``cv.md`` in ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    md = out / "cv.md"
    md.write_text(f"# Cross-validation ({result.cv}, model {result.model})\n\nFolds: {result.grouping}.\n\n"
                  + format_cv(result))
    files = {"csv": _write_csv(out / "cv.csv", result.rows(), result.folds), "markdown": md}
    files.update({f"fold-{f.index}": f.result.record_files["params"] for f in result.folds})
    return files


def validation_mapping(result: CrossValidation) -> dict:
    """The ``validation`` section a holdout adds to its record (YAML-ready): the held-out rows, the envelope,
    the legend and the misfit of the held-out samples (`rdea_lab.calibration.bands.misfit_mapping`)."""
    fold = result.folds[0]
    keep = ("file", "specimen", "protocol", "samples", "rate_per_s", "max_stretch", "rms_error_N", "max_rel_error",
            "rms_rel_error", "p99_rel_error", "sha256")
    return {"held_out": [{**{k: r[k] for k in keep}, "beyond_calibration": list(r["flags"])}
                         for r in result.rows(role="predicted")],
            "envelope": fold.envelope.mapping(), "measures": ERROR_LEGEND, "misfit": misfit_mapping(result)}


def _holdout_csv(record) -> Path:
    return Path(record).with_name(Path(record).stem + ".holdout.csv")


def write_holdout(result: CrossValidation, record: Path) -> dict:
    """``<stem>.holdout.csv`` beside the record, and the record's ``calibration.validation`` section.

    The section is nested in ``calibration`` (a parameter file takes no other top-level key).
    """
    record = Path(record)
    files = dict(result.folds[0].result.record_files)
    rows = result.rows(role="predicted")
    files["holdout"] = _write_csv(_holdout_csv(record), rows, result.folds)
    add_to_record(record, validation_mapping(result))
    return files


def add_to_record(record: Path, section: dict, key: str = "validation") -> None:
    """`rdea_lab.specs.record.add_record_section`: add ``key: section`` to the record's ``calibration``."""
    add_record_section(record, section, key)


__all__ = ["CSV_KEYS", "CV_CHOICES", "CrossValidation", "Fold", "add_to_record", "cross_validate", "format_cv",
           "make_folds", "nominal_rate", "nominal_stretch", "validation_mapping", "write_cv", "write_holdout"]
