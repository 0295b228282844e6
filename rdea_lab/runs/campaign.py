"""Campaigns: every protocol of a campaign file on every specimen, one backend."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..protocols import first_violation, load_plan
from ..specs import load_params, load_specimen
from ..physics.geometry import geometry_from_card
from ..backends.twin import TwinBackend
from .engine import RunResult, execute

DEFAULT_PARAMS = "params/paper2021_table3.yaml"


@dataclass(frozen=True)
class Experiment:
    card: object
    plan: object
    out: Path


def experiments(spec, root: Path, out_dir: Path | None = None) -> list[Experiment]:
    """The runs of a campaign, in order (specimen by specimen), every plan checked."""
    out_dir = Path(out_dir) if out_dir is not None else root / spec.out
    plans = [load_plan(root / p) for p in spec.protocols]
    runs = []
    for rel in spec.specimens:
        card = load_specimen(root / rel)
        L3 = geometry_from_card(card).L3
        for plan in plans:
            first_violation(plan, L3=L3)
            runs.append(Experiment(card, plan, out_dir / card.id / f"{plan.name}.nc"))
    return runs


@contextmanager
def _emulator(card, truth, realtime, faults=()):
    """A built-in emulated rig on a free loopback port, for the duration of the block."""
    from ..emulator import RigServer

    server = RigServer(card, truth, port=0, realtime=realtime, faults=faults)
    host, port = server.start()
    try:
        yield f"tcp://{host}:{port}"
    finally:
        server.shutdown()


def run_campaign(spec, root: Path, *, out_dir=None, realtime=False, progress=None, on_result=None,
                 command="rdea-lab campaign run") -> list[RunResult]:
    """Run every experiment of ``spec``; returns one result per run.

    The emulator backend starts one emulated rig per specimen on loopback and
    stops it after that specimen's runs.
    """
    from ..backends.rig import RigBackend

    runs = experiments(spec, root, out_dir)
    results = []
    if spec.backend == "twin":
        params = load_params(root / (spec.params or DEFAULT_PARAMS))
        for i, run in enumerate(runs):
            backend = TwinBackend(run.card, params, model=spec.model, realtime=realtime, seed=spec.seed + i)
            results.append(execute(run.plan, run.card, backend, run.out, seed=spec.seed + i, command=command,
                                   progress=progress))
            if on_result:
                on_result(results[-1])
        return results
    from ..specs.truth import load_truth

    truth = load_truth(root / (spec.truth or "truth/paper2021.yaml"))
    seeds = {id(r): spec.seed + i for i, r in enumerate(runs)}  # each run its own noise, reproducibly
    for card_id in dict.fromkeys(r.card.id for r in runs):
        mine = [r for r in runs if r.card.id == card_id]
        with _emulator(mine[0].card, truth, realtime) as address:
            for run in mine:
                seed = seeds[id(run)]
                results.append(execute(run.plan, run.card, RigBackend(address, run.card, seed=seed), run.out,
                                       seed=seed, command=command, progress=progress))
                if on_result:
                    on_result(results[-1])
    return results
