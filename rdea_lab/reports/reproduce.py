"""`rdea-lab reproduce`: the paper campaign end to end, on the built-in emulator.

Steps (each written under ``out``):

1. ``datasets/``: the campaign (default ``campaigns/paper2021.yaml``) on the
   emulated rig, one netCDF file per specimen and protocol;
2. ``params/calibrated.yaml``: Nelder-Mead calibration on specimen 2's tensile
   runs (SU, one Maxwell branch and the parallel damper, eps_r fixed at 2.8);
3. ``validation/``: the Table 4 analogue, the figures and ``index.html``;
4. ``speed/``: time per sample against error for SU, 1R, 3R, CR and auto;
5. ``models/``: Table 2 and Section 3.4 (Figures 5-8);
6. ``index.html``: links to all of it, with the key tables and figures.

Everything comes from the packaged reference inputs (`rdea_lab.paths`), so an
installed wheel runs it from any folder; it writes nowhere but ``out`` (and
``datasets``, when given apart).
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

from ..calibration import calibrate, find_runs, initial_guess, load_run
from ..calibration.record import write_record
from ..paths import data_dir
from ..runs import check_writable, experiments, run_campaign
from ..store.outputs import OutputError
from ..specs.campaign import load_campaign
from ..specs.errors import UserError
from .paper_models import reproduce_models
from .speed import speed_study
from .html import write_reproduce_index
from .validation import COLUMNS, validation_report

CALIBRATION_SPECIMEN = "specimen-2"


class ReproduceInputError(UserError):
    """A campaign that reproduce cannot use (a user mistake: exit status 2)."""


def reproduce(out: Path, *, datasets=None, campaign=None, speed=True, overwrite=False, echo=print,
              progress_factory=None) -> dict:
    """Run the whole campaign and write every result under ``out``.

    Parameters
    ----------
    out : Path
        Output folder. An existing folder with files in it is refused unless ``overwrite``.
    datasets : Path, optional
        Folder for the campaign's datasets (default ``out/datasets``). The committed reference
        report of a source checkout is regenerated with ``out=reports/paper2021`` and
        ``datasets=datasets/paper2021`` (CONTRIBUTING.md).
    campaign : Path, optional
        Campaign file (default: the packaged ``campaigns/paper2021.yaml``); must include specimen 2's
        tensile tests.
    speed : bool
        Run the speed-against-error study.
    overwrite : bool
        Write into an ``out`` that already holds files (its datasets are replaced).
    echo : callable
        Where progress lines go.
    progress_factory : callable, optional
        ``progress_factory(total, label)`` -> context manager with ``update(n)`` (a progress bar).

    Returns
    -------
    dict
        ``campaign``, ``campaign_name``, ``calibration`` (files), ``calibration_result``,
        ``validation``, ``speed`` (unless skipped), ``models``, ``stages`` (stage name, seconds),
        ``seconds``, ``index``.
    """
    out = Path(out)
    data = Path(datasets) if datasets is not None else out / "datasets"
    check_fresh(out, overwrite)
    check_writable(data / "x.nc", "--datasets" if datasets is not None else "--out")  # before twelve runs
    stages: list[tuple[str, float]] = []
    t0 = time.perf_counter()

    @contextlib.contextmanager
    def stage(name):
        start = time.perf_counter()
        yield
        stages.append((name, time.perf_counter() - start))

    root = data_dir()
    with stage("campaign"):
        spec, spec_root = load_campaign(campaign or root / "campaigns" / "paper2021.yaml")
        runs = experiments(spec, spec_root, data)
        if CALIBRATION_SPECIMEN not in {r.card.id for r in runs}:
            raise ReproduceInputError(f"{campaign or 'the campaign'}: it has no {CALIBRATION_SPECIMEN}, "
                                      "the specimen the paper calibrates on")
        total = sum(r.plan.time.size for r in runs)
        echo(f"[1/5] campaign {spec.name} on the {spec.backend}: {len(runs)} runs, {total} samples -> {data}/")
        if progress_factory is not None:
            with progress_factory(total, spec.name) as bar:
                results = run_campaign(spec, spec_root, out_dir=data, overwrite=True,
                                       callbacks=lambda b: bar.update(len(b)))
        else:
            results = run_campaign(spec, spec_root, out_dir=data, overwrite=True)
        failed = [r for r in results if r.status != "complete"]
        if failed:
            raise RuntimeError(f"{len(failed)} campaign runs did not complete: {failed[0].path}: {failed[0].reason}")

    with stage("calibration"):
        echo(f"[2/5] calibration on {CALIBRATION_SPECIMEN}'s tensile runs (SU, Nelder-Mead, viscoelastic law "
             "linear: eq. (44), as the paper)")
        cal_runs = [load_run(p) for p in find_runs([data / CALIBRATION_SPECIMEN], ("tensile",))]
        if not cal_runs:
            raise ValueError(f"no tensile runs of {CALIBRATION_SPECIMEN} in the campaign")
        fit = calibrate(cal_runs, initial_guess(cal_runs, 1, 2.8), model="su")
        files = write_record(fit, cal_runs, out / "params" / "calibrated.yaml", name="calibrated-specimen-2")
        echo(f"      {fit.message}; {fit.nfev} evaluations; C10 {fit.values['C10'] / 1e3:.1f}, "
             f"C20 {fit.values['C20'] / 1e3:.1f}, C30 {fit.values['C30'] / 1e3:.1f} kPa -> {files['params']}")

    with stage("validation"):
        echo("[3/5] validation report: the twin on every run's own stretch and voltage")
        report = validation_report(files["params"], data, out / "validation", model="su")
    result = {"campaign": [str(r.path) for r in results], "campaign_name": spec.name, "calibration": files,
              "calibration_result": fit, "validation": report, "datasets": str(data)}
    if speed:
        with stage("speed study"):
            echo("[4/5] speed against error: SU, 1R, 3R, CR and auto on the paper's scenes and the Section 3.4 cores")
            result["speed"] = speed_study(out / "speed", root)
    else:
        echo("[4/5] speed study skipped")
    with stage("models"):
        echo("[5/5] Table 2 and Section 3.4 (Figures 5-8)")
        result["models"] = reproduce_models(root, out / "models")
    with stage("index"):
        result["seconds"] = time.perf_counter() - t0
        result["index"] = write_reproduce_index(out, result, COLUMNS)
    result["stages"] = stages
    result["seconds"] = time.perf_counter() - t0
    return result


def check_fresh(out: Path, overwrite: bool) -> None:
    """Refuse an output folder that already holds files, unless ``overwrite`` (checked before any work)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(str(out), "--out", "is a file; give a folder")
    if not overwrite and out.is_dir() and any(out.iterdir()):
        raise OutputError(str(out), "--out", "exists and holds files; give another folder, or --force "
                          "(overwrite=True) to write over it")
