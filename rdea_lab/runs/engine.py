"""The run engine: plan -> backend -> blocks -> journal -> dataset.

It sits above both the backends and the store (it drives one and feeds the
other), so it is a layer of its own.

One loop for every backend. Every abort path (a force above the limit, Ctrl-C,
SIGTERM, a lost connection, an error) calls ``backend.abort`` first, which
turns the voltage off, and then closes the dataset with the right status,
keeping every sample received.
"""

from __future__ import annotations

import signal
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..backends.base import BackendFailure, RunInterrupted
from ..specs import dump_specimen
from ..store.journal import JournalWriter, utc_now


@dataclass(frozen=True)
class RunResult:
    path: Path
    status: str
    reason: str
    samples: int


def run_attrs(plan, card, backend, seed, command="") -> dict:
    """The dataset attributes known before the first sample."""
    created = utc_now()
    attrs = {
        "Conventions": "CF-1.8",
        "title": f"{plan.name} on {card.id} ({backend.name})",
        "rdea_lab_version": __version__,
        "run_id": uuid.uuid4().hex,
        "backend": backend.name,
        "specimen_id": card.id,
        "specimen": dump_specimen(card),
        "protocol_name": plan.name,
        "protocol_kind": plan.kind,
        "protocol": plan.yaml,
        "protocol_source": str(plan.source),
        "sample_rate": float(plan.sample_rate),
        "measured": ",".join(plan.measure),
        "seed": int(seed),
        "created": created,
        "status": "running",
        "status_reason": "",
        "history": f"{created}: {command or 'rdea-lab run'}",
    }
    attrs.update(backend.attrs())
    return attrs


def _raise_interrupted(signum, frame):
    raise RunInterrupted(f"signal {signal.Signals(signum).name}")


def execute(plan, card, backend, out: Path, *, seed=0, command="", progress=None) -> RunResult:
    """Run ``plan`` on ``backend`` into the dataset ``out``.

    Parameters
    ----------
    plan : Plan
    card : SpecimenCard
    backend : Backend
    out : Path
        Dataset to write; its journal ``<out>.part`` must not exist.
    seed : int
        Recorded in the attributes.
    command : str
        The command line, for ``history``.
    progress : callable, optional
        Called with the number of samples of each block.

    Returns
    -------
    RunResult
        ``status`` is ``complete``, ``aborted`` (a limit or the backend
        stopped the run) or ``interrupted`` (Ctrl-C, SIGTERM).
    """
    try:
        backend.start(plan)  # may refuse (limits, configuration) before anything moves
    except BaseException:
        backend.close()
        raise
    writer = JournalWriter(out, run_attrs(plan, card, backend, seed, command), extra=backend.extra_variables)
    status, reason = "complete", ""
    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, _raise_interrupted)
    except ValueError:  # not the main thread
        previous = None
    try:
        max_force = plan.limits.max_force
        while True:
            block = backend.read_block()
            if block is None:
                break
            writer.append(block)
            if progress is not None:
                progress(len(block["time"]))
            over = np.flatnonzero(np.abs(block["force"]) > max_force)
            if over.size:
                i = int(over[0])
                status = "aborted"
                reason = (f"force {block['force'][i]:.4g} N at t = {block['time'][i]:.4g} s is above the limit "
                          f"max_force = {max_force:g} N")
                backend.abort(reason)
                break
    except (KeyboardInterrupt, RunInterrupted) as exc:
        status, reason = "interrupted", f"interrupted by the user ({exc or 'Ctrl-C'})"
        backend.abort(reason)
    except BackendFailure as exc:
        status, reason = "aborted", str(exc)
        backend.abort(reason)
    except BaseException as exc:
        status, reason = "aborted", f"internal error: {type(exc).__name__}: {exc}"
        backend.abort(reason)
        writer.finish(status, reason)
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        backend.close()
    path = writer.finish(status, reason)
    return RunResult(path, status, reason, writer.samples)
