"""Campaigns: every protocol of a campaign file on every specimen, one backend."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..physics.geometry import geometry_from_card
from ..protocols import first_violation, load_plan
from ..specs import load_params, load_specimen
from .app import DEFAULT_PARAMS, DEFAULT_TRUTH, check_outputs, check_seed, emulated_rig, execute_setup, prepare_run
from .engine import RunResult, check_metadata


@dataclass(frozen=True)
class Experiment:
    card: object
    plan: object
    out: Path
    entry: str = ""  # where in the campaign file: "specimens[1] (x.yaml) with protocols[0] (y.yaml)"

    @property
    def name(self) -> str:
        return self.entry or f"{self.card.id}/{self.plan.name}"


def experiments(spec, root: Path, out_dir: Path | None = None) -> list[Experiment]:
    """The runs of a campaign, in order (specimen by specimen), every plan checked against its limits.

    Their datasets go under ``out_dir``, by default the campaign's ``out``, relative to the working
    directory (not to the campaign file: a packaged campaign must not write into the package)."""
    out_dir = Path(out_dir if out_dir is not None else spec.out)  # a user's folder, never the campaign's
    plans = [load_plan(root / p) for p in spec.protocols]
    runs = []
    for i, rel in enumerate(spec.specimens):
        card = load_specimen(root / rel)
        L3 = geometry_from_card(card).L3
        for j, plan in enumerate(plans):
            first_violation(plan, L3=L3)
            entry = f"specimens[{i}] ({Path(rel).name}, id {card.id}) with protocols[{j}] ({Path(spec.protocols[j]).name})"
            runs.append(Experiment(card, plan, out_dir / card.id / f"{plan.name}.nc", entry))
    return runs


def run_campaign(spec, root: Path, *, out_dir=None, overwrite=False, realtime=False, callbacks=(),
                 on_result=None, metadata=None, command="rdea-lab campaign run") -> list[RunResult]:
    """Run every experiment of ``spec``; returns one result per run.

    Every plan is checked against its limits and every output (two runs on one
    file, a journal in the way, an existing file without ``overwrite``) before
    the first run starts. The emulator backend starts one emulated rig per
    specimen on loopback and stops it after that specimen's runs. Each run gets
    its own noise seed, ``spec.seed + i``. A run ended by Ctrl-C (status
    ``interrupted``) ends the campaign: the results so far are returned.
    """
    runs = experiments(spec, root, out_dir)
    metadata = check_metadata(metadata)
    check_seed(spec.seed + max(len(runs) - 1, 0))
    check_outputs([r.out for r in runs], overwrite, names=[r.name for r in runs])
    seeds = {id(r): spec.seed + i for i, r in enumerate(runs)}  # each run its own noise, reproducibly
    results = []

    def record(result):
        results.append(result)
        if on_result:
            on_result(result)
        return result.status != "interrupted"  # Ctrl-C ends the campaign, not only the run

    if spec.backend == "twin":
        params = load_params(root / spec.params if spec.params else DEFAULT_PARAMS)
        for run in runs:
            setup = prepare_run(run.plan, run.card, "twin", params=params, model=spec.model, out=run.out,
                                seed=seeds[id(run)], realtime=realtime)
            if not record(execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command)):
                break
        return results
    from ..specs.truth import load_truth

    truth = load_truth(root / spec.truth if spec.truth else DEFAULT_TRUTH)
    for card_id in dict.fromkeys(r.card.id for r in runs):
        mine = [r for r in runs if r.card.id == card_id]
        with emulated_rig(mine[0].card, truth, realtime=realtime) as address:  # one rig per specimen
            for run in mine:
                setup = prepare_run(run.plan, run.card, "rig", address=address, out=run.out, seed=seeds[id(run)])
                if not record(execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command)):
                    return results
    return results
