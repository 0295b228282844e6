"""`rdea-lab reproduce`: the paper campaign end to end, on the built-in emulator.

Steps (each written under ``out``):

1. ``datasets/``: the campaign (default ``campaigns/paper2021.yaml``) on the
   emulated rig, one netCDF file per specimen and protocol;
2. ``params/calibrated.yaml``: Nelder-Mead calibration on specimen 2's tensile
   runs (SU, the parallel damper and the Maxwell branches the data choose, 0 to
   `REPRODUCE_MAX_BRANCHES`, by :func:`~rdea_lab.calibration.branches.calibrate_auto`; eps_r fixed at 2.8);
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
import multiprocessing
import os
import sys
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

from ..calibration import find_runs, initial_guess, load_run
from ..calibration.branches import calibrate_auto
from ..calibration.record import write_record
from ..paths import data_dir
from ..runs import check_writable, experiments, run_campaign, submit_campaign
from ..store.outputs import check_new
from ..specs.campaign import load_campaign
from ..specs.errors import UserError
from .paper_models import reproduce_models
from .speed import speed_study
from .html import write_reproduce_index
from .validation import COLUMNS, ValidationReport, validation_report

CALIBRATION_SPECIMEN = "specimen-2"
#: The most Maxwell branches reproduce's calibration tries: the emulated truth has two; the growth stops at
#: the first count that does not lower the criterion, and a third costs twice the evaluations of a second.
REPRODUCE_MAX_BRANCHES = 3


class ReproduceInputError(UserError):
    """A campaign that reproduce cannot use (a user mistake: exit status 2)."""


@dataclass(frozen=True, eq=False)
class ReproduceResult:
    """What :func:`reproduce` made, and where it wrote it.

    Attributes
    ----------
    out : Path
        The output folder.
    campaign : tuple of str
        The campaign's datasets (one netCDF file per specimen and protocol).
    campaign_name : str
        The campaign's name.
    calibration : dict
        The calibration's files (``params``: the record, ``history``, ``plot``).
    calibration_result : CalibrationResult
        The calibration on specimen 2's tensile runs.
    validation : ValidationReport
        The Table 4 analogue.
    validation_files : dict of str to Path
        What the validation report wrote (``markdown``, ``csv``, ``latex``, the figures, ``html``).
    models : dict
        Table 2 and Section 3.4 (:func:`~rdea_lab.reports.paper_models.reproduce_models`).
    speed : dict or None
        The speed-against-error study (None when skipped).
    datasets : str
        The folder of the datasets.
    workers : int
        Processes used.
    stages : tuple of (str, float)
        Each stage's name and its time [s] from its start to its end (with ``workers`` > 1 the campaign,
        the calibration and the models overlap, so they add up to more than ``seconds``).
    seconds : float
        Wall time of the whole [s].
    index : Path or None
        The top-level ``index.html`` (None only while it is being written).
    """

    out: Path
    campaign: tuple
    campaign_name: str
    calibration: dict
    calibration_result: object
    validation: ValidationReport
    validation_files: dict
    models: dict
    speed: dict | None
    datasets: str
    workers: int
    stages: tuple = ()
    seconds: float = 0.0
    index: Path | None = None

    def lines(self) -> list[str]:
        """The text ``rdea-lab reproduce`` prints after the run: the Table 4 analogue, the outputs and the
        time by stage.

        Returns
        -------
        list of str
            The lines, without their line ends (the table's own lines included): printed one after the
            other, each with a line end.
        """
        v = self.validation
        lines = ["", f"Table 4 analogue ({v.origin})", *(v.markdown + v.legend).split("\n"), "", "outputs:",
                 f"  index           {self.index} (links to everything below)",
                 f"  datasets        {self.datasets}/<specimen>/<protocol>.nc",
                 f"  parameters      {self.calibration['params']} (+ .history.csv, .history.png)",
                 f"  validation      {self.validation_files['html']} (table4.md/.csv/.tex, figures)"]
        if self.speed is not None:
            lines.append(f"  speed vs error  {self.out / 'speed'}/speed.md, pareto.png, figure8_sweep.png")
        lines.append(f"  models          {self.out / 'models'}/models.md, figure5-8*.png")
        lines.append("time by stage:" + (f" ({self.workers} processes: the campaign, calibration and models "
                                         "overlap)" if self.workers > 1 else ""))
        lines += [f"  {name:<15} {seconds:6.1f} s" for name, seconds in self.stages]
        lines.append(f"  {'total':<15} {self.seconds:6.1f} s")
        return lines


def reproduce(out: Path, *, datasets=None, campaign=None, speed=True, overwrite=False, echo=print,
              progress_factory=None, pdf=False, workers=None) -> ReproduceResult:
    """Run the whole campaign and write every result under ``out``.

    Parameters
    ----------
    out : Path
        Output folder. An existing folder with files in it is refused unless ``overwrite``.
    datasets : Path, optional
        Folder for the campaign's datasets (default ``out/datasets``); one that holds files is refused unless
        ``overwrite``. The committed reference
        report of a source checkout is regenerated with ``out=reports/paper2021`` and
        ``datasets=datasets/paper2021`` (CONTRIBUTING.md; PNG figures only, as committed).
    campaign : Path, optional
        Campaign file (default: the packaged ``campaigns/paper2021.yaml``); must include specimen 2's
        tensile tests.
    speed : bool
        Run the speed-against-error study.
    overwrite : bool
        Write over an ``out`` (and a ``datasets`` folder) that already holds files (its datasets are replaced).
    echo : callable
        Where progress lines go.
    progress_factory : callable, optional
        ``progress_factory(total, label)`` -> context manager with ``update(n)`` (a progress bar; with
        ``workers`` > 1 it advances by a run's samples as each run ends).
    pdf : bool
        A PDF beside every PNG figure (vector, for a paper); PNG only by default.
    workers : int, optional
        Processes (default: the cores this process may use, at most `WORKERS`). With more than one,
        a process pool runs the campaign's runs (each on an emulated rig of its own, with its own seed
        as in one process: the same datasets), the models section beside them, the calibration as
        soon as specimen 2's tensile runs are in, and the validation's runs and figures; the speed
        study runs last and alone, so that nothing else runs while it times the models. 1: every
        stage in this process, one after the other.

    Returns
    -------
    ReproduceResult
        The campaign's files, the calibration's files and result, the validation report and its files,
        the speed (unless skipped) and models results, the time by stage, the total, ``workers`` and
        the top-level ``index.html``; its ``lines()`` are what the CLI prints after the run.

    Raises
    ------
    OutputError
        ``out`` (or ``datasets``) holds files and not ``overwrite``, or cannot be written.
    ReproduceInputError
        The campaign has no specimen 2.
    """
    out = Path(out)
    data = Path(datasets) if datasets is not None else out / "datasets"
    check_fresh(out, overwrite)
    if datasets is not None:  # a folder of its own (the committed datasets/paper2021: only with --force)
        check_new(data, overwrite, "--datasets", folder=True)
    check_writable(data / "x.nc", "--datasets" if datasets is not None else "--out")  # before twelve runs
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    t0 = time.perf_counter()  # the campaign's stage and the total start here, the pool's start-up included
    root = data_dir()
    spec, spec_root = load_campaign(campaign or root / "campaigns" / "paper2021.yaml")
    with contextlib.ExitStack() as stack:
        if workers > 1 and start_method() == "fork":
            preload(spec, spec_root)
        pool = stack.enter_context(process_pool(workers)) if workers > 1 else None
        return _reproduce(out, data, root, spec, spec_root, campaign, speed, echo, progress_factory, pdf, pool,
                          workers, t0)


def _reproduce(out, data, root, spec, spec_root, campaign, speed, echo, progress_factory, pdf, pool, workers, t0):
    stages: dict[str, float] = {}

    @contextlib.contextmanager
    def stage(name):
        start = time.perf_counter()
        yield
        stages[name] = time.perf_counter() - start

    runs = experiments(spec, spec_root, data)
    if CALIBRATION_SPECIMEN not in {r.card.id for r in runs}:
        raise ReproduceInputError(f"{campaign or 'the campaign'}: it has no {CALIBRATION_SPECIMEN}, "
                                  "the specimen the paper calibrates on")
    total = sum(r.plan.samples for r in runs)
    echo(f"[1/5] campaign {spec.name} on the {spec.backend}: {len(runs)} runs, {total} samples -> {data}/"
         + (f" ({workers} processes)" if pool is not None else ""))
    models = None
    if pool is None:
        results = _campaign_here(spec, spec_root, data, progress_factory, total, runs)
    else:
        submitted = submit_campaign(spec, spec_root, pool, out_dir=data, overwrite=True, first=_calibration_run,
                                    runs=runs)
        models = pool.submit(_timed, reproduce_models, root, out / "models", pdf)  # needs nothing of the campaign
        progress = _CampaignProgress(submitted, progress_factory, total, spec.name, t0)
        with contextlib.ExitStack() as bar:
            progress.start(bar)
            fitted = progress.wait(_calibration_run)  # the calibration's runs are submitted first
            fit, files = _calibrate(out, [r.path for r in fitted], echo, stage)  # while the pool runs the others
            results = progress.wait(lambda r: True)
        stages["campaign"] = progress.seconds
    failed = [r for r in results if r.status != "complete"]
    if failed:
        raise RuntimeError(f"{len(failed)} campaign runs did not complete: {failed[0].path}: {failed[0].reason}")
    if pool is None:
        stages["campaign"] = time.perf_counter() - t0
        fit, files = _calibrate(out, [res.path for run, res in zip(runs, results) if _calibration_run(run)], echo,
                                stage)

    with stage("validation"):
        echo("[3/5] validation report: the twin on every run's own stretch and voltage")
        report = validation_report(files["params"], data, model="su", executor=pool)
        written = report.write(out / "validation", pdf=pdf, executor=pool, overwrite=True)  # out: by check_fresh
    if models is None:
        with stage("models"):
            made = reproduce_models(root, out / "models", pdf)
    else:
        made, stages["models"] = models.result()
    studied = None
    if speed:
        with stage("speed study"):  # last, and alone: it times the models
            echo("[4/5] speed against error: SU, 1R, 3R, CR and auto on the paper's scenes and the Section 3.4 cores")
            studied = speed_study(out / "speed", root, pdf=pdf, overwrite=True,
                                  sweep=(made["figure8"], out / "models" / "figure8_sweep.png"))
    else:
        echo("[4/5] speed study skipped")
    echo("[5/5] Table 2 and Section 3.4 (Figures 5-8)" + (" (made beside the campaign)" if pool is not None else ""))
    result = ReproduceResult(out=out, campaign=tuple(str(r.path) for r in results), campaign_name=spec.name,
                             calibration=files, calibration_result=fit, validation=report, validation_files=written,
                             models=made, speed=studied, datasets=str(data), workers=workers)
    with stage("index"):
        index = write_reproduce_index(out, replace(result, seconds=time.perf_counter() - t0), COLUMNS)
    return replace(result, index=index, stages=tuple((name, stages[name]) for name in STAGES if name in stages),
                   seconds=time.perf_counter() - t0)


#: The stages, in the order of the time table.
STAGES = ("campaign", "calibration", "validation", "speed study", "models", "index")
#: Most processes `reproduce` starts by default (the campaign has twelve runs; the figures a few more).
WORKERS = 4


def default_workers() -> int:
    """The cores this process may use, at most `WORKERS`."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(WORKERS, cores))


def start_method() -> str:
    """How the pool starts its processes: ``fork`` on Linux in a process with one thread and no numba
    thread pool running (safe there, and the workers need no start-up of their own); else ``forkserver``
    (a clean process forks them) where there is one, or ``spawn``."""
    numba_threads = getattr(sys.modules.get("numba.np.ufunc.parallel"), "_is_initialized", False)
    if sys.platform.startswith("linux") and threading.active_count() == 1 and not numba_threads:
        return "fork"
    return "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"


@contextlib.contextmanager
def process_pool(workers: int):
    """A process pool of ``workers``: forked where that is safe (Linux, this process with one thread: the
    workers start with its imports, no second start-up), else the platform's own start method."""
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context(start_method()))
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def preload(spec, spec_root) -> None:
    """Import what the pool's tasks use (the emulator, the rig client, matplotlib's Agg; for an emulated
    campaign the truth's compiled viscoelastic kernel) here, once: forked workers start with it, instead
    of each importing it again."""
    import importlib

    for name in ("rdea_lab.emulator", "rdea_lab.backends.rig", "pyvisa", "pyvisa_py", "matplotlib.backends.backend_agg",
                 "PIL.Image", "netCDF4"):
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    if spec.backend != "twin":
        from ..physics import viscoelastic
        from ..runs.campaign import campaign_truth

        viscoelastic.prepare(campaign_truth(spec, spec_root).material.law)


def _timed(fn, *args):
    start = time.perf_counter()
    return fn(*args), time.perf_counter() - start


def _calibration_run(run) -> bool:
    """Whether the calibration uses this experiment (specimen 2's tensile runs)."""
    return run.card.id == CALIBRATION_SPECIMEN and run.plan.kind == "tensile"


def _campaign_here(spec, spec_root, data, progress_factory, total, runs):
    """The campaign in this process; ``runs``: its experiments as listed (and checked) already."""
    if progress_factory is None:
        return run_campaign(spec, spec_root, out_dir=data, overwrite=True, runs=runs)
    with progress_factory(total, spec.name) as bar:
        return run_campaign(spec, spec_root, out_dir=data, overwrite=True, runs=runs,
                            callbacks=lambda b: bar.update(len(b)))


class _CampaignProgress:
    """The submitted runs: wait for some of them, advancing the progress bar as each ends."""

    def __init__(self, submitted, progress_factory, total, label, started):
        self.submitted, self.factory, self.total, self.label = submitted, progress_factory, total, label
        self.done, self.bar, self.started = set(), None, started
        self.seconds = 0.0

    def start(self, stack):
        if self.factory is not None:
            self.bar = stack.enter_context(self.factory(self.total, self.label))

    def wait(self, which):
        from concurrent.futures import FIRST_COMPLETED, wait

        pending = {f for r, f in self.submitted if which(r) and id(f) not in self.done}
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in finished:
                self.done.add(id(f))
                if self.bar is not None:
                    self.bar.update(next(r.plan.samples for r, g in self.submitted if g is f))
        self.seconds = time.perf_counter() - self.started
        return [f.result() for r, f in self.submitted if which(r)]


def _calibrate(out, paths, echo, stage):
    """Calibrate on the datasets ``paths`` of specimen 2's tensile runs: the runs themselves, not a scan of
    their folder (which on a pool also holds the files other processes are still writing)."""
    with stage("calibration"):
        echo(f"[2/5] calibration on {CALIBRATION_SPECIMEN}'s tensile runs (SU, Nelder-Mead, viscoelastic law "
             f"linear: eq. (44), as the paper; branches auto, 0 to {REPRODUCE_MAX_BRANCHES})")
        cal_runs = [load_run(p) for p in find_runs(sorted(paths), ("tensile",))]
        if not cal_runs:
            raise ValueError(f"no tensile runs of {CALIBRATION_SPECIMEN} in the campaign")
        fit = calibrate_auto(cal_runs, initial_guess(cal_runs, 1, 2.8), REPRODUCE_MAX_BRANCHES, model="su")
        echo(f"      branches auto: {fit.branch_choice['reason']}")
        files = write_record(fit, cal_runs, out / "params" / "calibrated.yaml", name="calibrated-specimen-2")
        echo(f"      {fit.message}; {fit.nfev} evaluations; C10 {fit.values['C10'] / 1e3:.1f}, "
             f"C20 {fit.values['C20'] / 1e3:.1f}, C30 {fit.values['C30'] / 1e3:.1f} kPa -> {files['params']}")
    return fit, files


def check_fresh(out: Path, overwrite: bool) -> None:
    """Refuse an output folder that already holds files, unless ``overwrite`` (checked before any work)."""
    check_new(out, overwrite, "--out", folder=True)
