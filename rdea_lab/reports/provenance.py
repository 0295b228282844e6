"""What a validation report's rows are: the role of each run, where its data come from, and the
calibration envelope it is judged against.

- Role, per run (not per specimen), from the calibration record's ``runs`` (their ``sha256``):
  `CALIBRATION_RUN` (fitted), `HELD_OUT` (a run of a fitted specimen that was not fitted),
  `OTHER_SPECIMEN`; `NONE_RECORDED` without a record.
- Origin, from what each file says (its attributes): ``import`` (``backend: import``, with
  ``source_file`` and ``source_credit``), ``emulator`` (:func:`~rdea_lab.store.schema.is_emulated`,
  with the truth's name), ``twin`` (``backend: twin``), ``rig`` (a physical rig: ``backend: rig``,
  not emulated); anything else is ``unknown``.
- Envelope (:mod:`rdea_lab.calibration.envelope`): the record's ``calibration.validation.envelope``
  (written by ``rdea-lab calibrate --holdout``) if it has one; otherwise the envelope of the fitted
  runs, found among the report's runs by their sha256 or at the record's paths (checked by hash).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..backends.rig import truth_name
from ..calibration.envelope import Envelope, envelope
from ..calibration.objective import file_hash, load_run
from ..specs import SpecError
from ..specs.record import CalibrationRecord
from ..store.schema import origin_kind

CALIBRATION_RUN = "calibration run"
HELD_OUT = "held out (same specimen)"
OTHER_SPECIMEN = "other specimen"
NONE_RECORDED = "none recorded"
#: What a row's flags cell says when there is no envelope to judge it against.
NOT_CHECKED = "not checked (no envelope)"


def calibration_summary(params_path) -> dict:
    """Provenance of a parameter file: its hash and, if present, its calibration record in brief.

    A parameter set given as an object (not a file) has neither: it says so.

    Raises
    ------
    SpecError
        The record is there but a field is not what a record holds (`rdea_lab.specs.CalibrationRecord`).
    """
    if not isinstance(params_path, (str, os.PathLike)):
        name = getattr(params_path, "name", "?")
        return {"file": f"<ParameterSet {name}>", "sha256": "", "record": False, "specimens": [], "runs": [],
                "envelope": None, "summary": "parameters given as an object: no file, no calibration record"}
    record = CalibrationRecord.of_file(params_path)
    out = {"file": str(params_path), "sha256": file_hash(params_path), "record": record is not None,
           "envelope": None}
    if record is None:
        return {**out, "specimens": [], "runs": [], "summary": "no calibration record in the file"}
    runs = record.runs
    out.update({k: getattr(record, k) for k in ("model", "metric", "objective", "converged", "message", "software")})
    out["runs"] = [{k: getattr(r, k) for k in ("specimen", "protocol", "file", "sha256", "max_rel_error")}
                   for r in runs]
    out["specimens"] = sorted({str(r.specimen) for r in runs if r.specimen})
    if record.validation is not None and record.validation.envelope is not None:
        out["envelope"] = record.validation.envelope
    out["nfev"] = record.statistics.nfev if record.statistics is not None else None
    out["summary"] = (f"model {out['model']}, {out['metric']} objective {out['objective']}, "
                      f"{len(runs)} run(s): " + ", ".join(f"{r.specimen}/{Path(str(r.file)).stem}" for r in runs))
    return out


def role(sha256: str, specimen: str, cal: dict) -> str:
    """A run's role against the record ``cal`` (:func:`calibration_summary`): fitted, held out, other specimen."""
    if not cal["record"]:
        return NONE_RECORDED
    if sha256 in {r.get("sha256") for r in cal["runs"]}:
        return CALIBRATION_RUN
    return HELD_OUT if specimen in cal["specimens"] else OTHER_SPECIMEN


def run_origin(attrs) -> dict:
    """Where a run's data come from, as its attributes say.

    Returns
    -------
    dict
        ``origin`` (``import``, ``emulator``, ``twin``, ``rig`` or ``unknown``), ``origin_detail`` (one
        phrase: the source file and credit, the truth, the model, or the rig), ``source_file``,
        ``source_credit`` and ``truth`` (``""`` where the file gives none).
    """
    kind = origin_kind(attrs)
    out = {"source_credit": str(attrs.get("source_credit", "") or ""),
           "source_file": str(attrs.get("source_file", "") or ""), "truth": ""}
    if kind == "import":
        sha, credit = str(attrs.get("source_sha256", "")), out["source_credit"]
        detail = (f"imported from {out['source_file'] or '?'} ({attrs.get('source_format', '?')}"
                  + (f", sha256 {sha[:12]}" if sha else "") + "); "
                  + (f"credit: {credit}" if credit else "no credit in the file"))
        return {**out, "origin": "import", "origin_detail": detail}
    if kind == "emulator":
        out["truth"] = truth_name(str(attrs.get("emulator_truth", ""))) or "unnamed truth"
        return {**out, "origin": "emulator", "origin_detail": f"rdea-lab rig emulator, truth {out['truth']}"}
    if kind == "twin":
        return {**out, "origin": "twin", "origin_detail": f"twin simulation, model {attrs.get('model', '?')}, "
                                                          f"parameters {attrs.get('parameters_name', '?')}"}
    if kind == "rig":
        idn = str(attrs.get("rig_idn", "") or "")
        return {**out, "origin": "rig",
                "origin_detail": "physical rig" + (f" ({idn})" if idn else " (not marked as emulated)")}
    return {**out, "origin": "unknown", "origin_detail": f"backend {attrs.get('backend', '') or 'not given'}"}


def data_origin(provenance: list[dict]) -> str:
    """One plain sentence on where the runs come from (imported files and their credit, emulator, twin, rig)."""
    n = len(provenance)
    groups: dict[str, list[dict]] = {}
    for p in provenance:
        groups.setdefault(p["origin"], []).append(p)
    parts = []
    if "import" in groups:
        g = groups["import"]
        files = sorted({p["source_file"] for p in g if p["source_file"]})
        credits = sorted({p["source_credit"] for p in g if p["source_credit"]})
        uncredited = sum(not p["source_credit"] for p in g)
        shown = ", ".join(files[:6]) + (f" and {len(files) - 6} more" if len(files) > 6 else "")
        parts.append(f"{len(g)} of {n} runs are measurements imported from other files ({shown}); "
                     + (f"data credit: {'; '.join(credits)}" if credits else "the files name no credit")
                     + (f" ({uncredited} file(s) without a credit)" if credits and uncredited else ""))
    if "emulator" in groups:
        g = groups["emulator"]
        names = sorted({p["truth"] for p in g})
        parts.append(f"{len(g)} of {n} runs come from the rdea-lab rig EMULATOR (truth: {', '.join(names)}), "
                     "not from a physical rig")
    if "twin" in groups:
        parts.append(f"{len(groups['twin'])} of {n} runs are twin simulations (a model, not measurements)")
    if "rig" in groups:
        parts.append(f"{len(groups['rig'])} of {n} runs come from a physical rig (backend rig, not marked as "
                     "emulated)")
    if "unknown" in groups:
        backends = sorted({p["origin_detail"] for p in groups["unknown"]})
        parts.append(f"{len(groups['unknown'])} of {n} runs do not say where they come from ({', '.join(backends)})")
    return "; ".join(parts) + "."


def calibration_envelope(cal: dict, runs) -> tuple[Envelope | None, str]:
    """The envelope the report's rows are judged against, and where it comes from (in words).

    Parameters
    ----------
    cal : dict
        :func:`calibration_summary` of the parameter file.
    runs : sequence of RunData
        The report's runs (the fitted ones are looked up among them by sha256 first).

    Raises
    ------
    SpecError
        The record's envelope is there but not readable.
    """
    if not cal["record"]:
        return None, "no calibration record: no envelope, extrapolation not checked"
    if cal["envelope"] is not None:
        try:
            return Envelope.from_mapping(cal["envelope"]), "the record's calibration.validation.envelope"
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise SpecError(cal["file"], "calibration.validation.envelope",
                            f"unreadable ({type(exc).__name__}: {exc}); allowed: the mapping 'rdea-lab calibrate "
                            "--holdout' writes (stretch, rate_per_s, voltage_V: two numbers each; hold_s)") from None
    by_hash = {r.sha256: r for r in runs}
    fitted, missing = [], []
    for r in cal["runs"]:
        if r.get("sha256") in by_hash:
            fitted.append(by_hash[r["sha256"]])
        elif r.get("file") and Path(r["file"]).is_file() and file_hash(r["file"]) == r.get("sha256"):
            fitted.append(load_run(r["file"]))
        else:
            missing.append(Path(str(r.get("file"))).name)
    if missing or not fitted:
        return None, (f"fitted run(s) {', '.join(missing) or '(none listed)'} not found (by sha256 among the "
                      "datasets or at the record's path): no envelope, extrapolation not checked")
    return envelope(fitted), f"computed from the {len(fitted)} fitted run(s)"


__all__ = ["CALIBRATION_RUN", "HELD_OUT", "NONE_RECORDED", "NOT_CHECKED", "OTHER_SPECIMEN", "calibration_envelope",
           "calibration_summary", "data_origin", "role", "run_origin"]
