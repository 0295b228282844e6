"""Campaigns: every protocol of a campaign file on every specimen, one backend."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from ..physics.geometry import geometry_from_card
from ..protocols import load_plan
from ..specs import load_params, load_specimen
from .app import check_outputs, check_seed, execute_setup, prepare_run
from .backend import DEFAULT_PARAMS, DEFAULT_TRUTH, EMULATOR_REPLY_TIMEOUT, Rig, Twin, emulated_rig
from .checked import CheckedPlan, checked_plan
from .engine import RunResult, check_metadata


@dataclass(frozen=True)
class Experiment:
    """One run of a campaign: a plan checked for a specimen, and the dataset it writes.

    Attributes
    ----------
    checked : CheckedPlan
        The plan, the card and the card's geometry, its limits checked (`checked_plan`).
    out : Path
    entry : str
        Where in the campaign file: ``specimens[1] (x.yaml, id ...) with protocols[0] (y.yaml)``.
    """

    checked: CheckedPlan
    out: Path
    entry: str = ""

    card = property(lambda self: self.checked.card, doc="The specimen card.")
    plan = property(lambda self: self.checked.plan, doc="The expanded protocol, its limits checked.")

    @property
    def name(self) -> str:
        return self.entry or f"{self.card.id}/{self.plan.name}"


def experiments(spec, root: Path, out_dir: Path | None = None) -> list[Experiment]:
    """The runs of a campaign, in order (specimen by specimen), every plan checked against its limits.

    Each specimen's card becomes geometry once, here, and each plan is checked once per specimen
    (`checked_plan`); the runs take both from here (`prepare_run` makes neither again). Their datasets go
    under ``out_dir``, by default the campaign's ``out``, relative to the working directory (not to the
    campaign file: a packaged campaign must not write into the package).

    Parameters
    ----------
    spec : CampaignSpec
    root : Path
        The folder the campaign's relative paths start from.
    out_dir : path, optional

    Returns
    -------
    list of Experiment

    Raises
    ------
    LimitError
        The first plan beyond its limits on a specimen.
    """
    out_dir = Path(out_dir if out_dir is not None else spec.out)  # a user's folder, never the campaign's
    plans = [_with_campaign_suspenders(load_plan(root / p), spec) for p in spec.protocols]
    runs = []
    for i, rel in enumerate(spec.specimens):
        card = load_specimen(root / rel)
        geom = geometry_from_card(card)
        for j, plan in enumerate(plans):
            checked = checked_plan(plan, card, geom)
            entry = (f"specimens[{i}] ({Path(rel).name}, id {card.id}) "
                     f"with protocols[{j}] ({Path(spec.protocols[j]).name})")
            runs.append(Experiment(checked, out_dir / card.id / f"{plan.name}.nc", entry))
    return runs


def _with_campaign_suspenders(plan, spec):
    """The plan with the campaign's ``suspend:`` added to its protocol's own (the dataset's ``protocol``
    attribute then says every suspender the run had); the plan itself when the campaign declares none."""
    if not getattr(spec, "suspend", ()):
        return plan
    from ..protocols import as_plan
    from ..specs import merged_suspenders

    plan_spec = plan.spec
    return as_plan(plan_spec.with_suspenders(merged_suspenders(plan_spec, spec)))


def run_campaign(spec, root: Path | None = None, *, out_dir=None, overwrite=False, realtime=False, callbacks=(),
                 on_result=None, metadata=None, command="rdea-lab campaign run", runs=None) -> list[RunResult]:
    """Run every experiment of a campaign (each protocol on each specimen); one result per run.

    Every plan is checked against its limits and every output (two runs on one
    file, a journal in the way, an existing file without ``overwrite``) before
    the first run starts. The emulator backend starts one emulated rig per
    specimen on loopback and stops it after that specimen's runs. Each run gets
    its own noise seed, ``spec.seed + i``. A run ended by Ctrl-C (status
    ``interrupted``) ends the campaign: the results so far are returned.

    Parameters
    ----------
    spec : CampaignSpec or path
        The campaign, or its YAML file (a packaged name such as ``campaigns/paper2021.yaml`` works too).
    root : path, optional
        The folder the campaign's input paths are relative to; default the campaign's own
        (`CampaignSpec.folder`).
    out_dir : path, optional
        Folder of the datasets, one ``<specimen>/<protocol>.nc`` per run; default the campaign's ``out``.
    overwrite : bool
        Replace datasets that exist (the CLI's ``--force``); by default they are refused before any run.
    realtime : bool
        Pace every run at wall-clock speed.
    callbacks : callable or sequence of callables
        Given each block of samples of every run, as in `rdea_lab.run_protocol`.
    on_result : callable, optional
        ``on_result(result)`` after each run.
    metadata : mapping, optional
        Recorded in every dataset (``md_*`` attributes).
    command : str
        The command line recorded in each dataset's ``history``.
    runs : sequence of Experiment, optional
        ``experiments(spec, root, out_dir)`` made already (by a caller that showed them first): their plans
        are not checked again.

    Returns
    -------
    list of RunResult
        One per run that started, in the campaign's order (fewer when a run was interrupted).

    Raises
    ------
    SpecError
        An invalid campaign or input file, a plan beyond its limits, bad metadata or seeds.
    OutputError
        An output that exists (without ``overwrite``), two runs on one file, or a folder that cannot be
        written.
    """
    if isinstance(spec, (str, os.PathLike)):  # a path or a packaged name
        from ..specs.campaign import load_campaign

        spec, folder = load_campaign(spec)
        root = folder if root is None else root
    root = Path(spec.folder if root is None else root)
    runs, seeds, metadata = _checked(spec, root, out_dir, overwrite, metadata, runs)
    catalog = campaign_catalog(runs)
    results = []

    def record(result):
        results.append(result)
        if on_result:
            on_result(result)
        return result.status != "interrupted"  # Ctrl-C ends the campaign, not only the run

    if spec.backend == "twin":
        twin = Twin(load_params(root / spec.params if spec.params else DEFAULT_PARAMS), spec.model, realtime=realtime)
        for run in runs:
            setup = prepare_run(run.checked, run.card, twin, out=run.out, seed=seeds[id(run)])
            if not record(execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command,
                                        catalog=catalog)):
                break
        return results
    truth = campaign_truth(spec, root)
    for card_id in dict.fromkeys(r.card.id for r in runs):
        mine = [r for r in runs if r.card.id == card_id]
        with emulated_rig(mine[0].card, truth, realtime=realtime) as address:  # one rig per specimen
            for run in mine:
                rig = Rig(address, timeout=EMULATOR_REPLY_TIMEOUT)
                setup = prepare_run(run.checked, run.card, rig, out=run.out, seed=seeds[id(run)])
                if not record(execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command,
                                            catalog=catalog)):
                    return results
    return results


def _checked(spec, root, out_dir, overwrite, metadata, runs=None):
    """The experiments, each one's seed (``spec.seed + i``) and the metadata, every check done before any run."""
    runs = experiments(spec, root, out_dir) if runs is None else list(runs)
    metadata = check_metadata(metadata)
    check_seed(spec.seed)
    spec.check_run_seeds([r.name for r in runs])
    check_outputs([r.out for r in runs], overwrite, names=[r.name for r in runs])
    return runs, {id(r): spec.seed + i for i, r in enumerate(runs)}, metadata  # each run its own noise


def campaign_catalog(runs) -> str | None:
    """The catalogue of a campaign's runs: the one at or above the folder holding them all (by default a
    new ``rdea-lab-catalog.sqlite`` there, not one per specimen folder); None for no runs."""
    from ..store.index import resolve_catalog

    outs = [os.path.abspath(Path(r.out).parent.parent) for r in runs]
    return resolve_catalog(os.path.commonpath(outs)) if outs else None


def campaign_truth(spec, root: Path):
    """The truth of an emulated campaign (its ``truth``, or the packaged default)."""
    from ..specs.truth import load_truth

    return load_truth(root / spec.truth if spec.truth else DEFAULT_TRUTH)


def submit_campaign(spec, root: Path, executor, *, out_dir=None, overwrite=False, metadata=None,
                    command="rdea-lab campaign run", first=None, runs=None) -> list[tuple[Experiment, object]]:
    """Submit every experiment of ``spec`` to ``executor`` (a `concurrent.futures` process pool), one task each.

    The checks are `run_campaign`'s, all done here before the first task starts. Each task runs
    `run_experiment`: on the twin, or on an emulated rig of its own (on loopback in the worker), with the
    run's own seed ``spec.seed + i`` as in `run_campaign`, so the datasets hold the same numbers as a
    campaign run in one process. The experiments for which ``first(experiment)`` is true are submitted
    first (a pool starts tasks in order). ``runs`` as in `run_campaign`: experiments listed already, their
    plans not checked again.

    Returns
    -------
    list of (Experiment, Future)
        In the campaign's order; each future gives the run's `RunResult`.
    """
    runs, seeds, metadata = _checked(spec, root, out_dir, overwrite, metadata, runs)
    options = ({"params": load_params(root / spec.params if spec.params else DEFAULT_PARAMS), "model": spec.model}
               if spec.backend == "twin" else {"truth": campaign_truth(spec, root)})
    order = sorted(runs, key=lambda r: not first(r)) if first is not None else runs
    options["catalog"] = campaign_catalog(runs)  # one catalogue for every worker (SQLite's WAL lets them write)
    futures = {id(r): executor.submit(run_experiment, spec.backend, r, seeds[id(r)], metadata=metadata,
                                      command=command, **options) for r in order}
    return [(r, futures[id(r)]) for r in runs]


def run_experiment(backend: str, run: Experiment, seed: int, *, truth=None, params=None, model="auto",
                   metadata=None, command="rdea-lab campaign run", callbacks=(), catalog=None) -> RunResult:
    """One experiment of a campaign by itself: on the twin (``params``, ``model``), or on a built-in emulated
    rig of its own (``truth``), started for this run and stopped after it. What a task of
    `submit_campaign` runs; returns the engine's `RunResult`."""
    if backend == "twin":
        setup = prepare_run(run.checked, run.card, Twin(params, model), out=run.out, seed=seed)
        return execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command, catalog=catalog)
    with emulated_rig(run.card, truth) as address:
        setup = prepare_run(run.checked, run.card, Rig(address, timeout=EMULATOR_REPLY_TIMEOUT), out=run.out, seed=seed)
        return execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command, catalog=catalog)
