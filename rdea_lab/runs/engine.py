"""The run engine: plan -> backend -> blocks -> journal -> dataset.

It sits above both the backends and the store (it drives one and feeds the
other), so it is a layer of its own.

One loop for every backend. Every abort path (a force above the limit, Ctrl-C,
SIGTERM, a lost connection, an error) calls ``backend.abort`` first, which
turns the voltage off, and then closes the dataset with the right status,
keeping every sample received.
"""

from __future__ import annotations

import json
import re
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._version import __version__
from ..backends.base import BackendFailure, RunInterrupted
from ..specs import SpecError, dump_specimen
from ..store.journal import DiskFull, JournalWriter, utc_now
from ..store.schema import OPTIONAL_RUN_VARIABLES, global_attrs, portable_command, portable_path
from .callbacks import RunBlock, subscriber_name
from .checked import require_checked
from .control import RunControl
from .operate import Operator
from ..signals import Signals, deferred

#: Exit status of a run by its dataset status (the CLI's, and `RunResult.exit_code`).
EXIT_CODES = {"complete": 0, "aborted": 3, "interrupted": 130}
_MD_KEY = re.compile(r"^[A-Za-z][A-Za-z0-9_.\-]{0,63}$")


@dataclass(frozen=True)
class RunResult:
    """How a run ended: its dataset, status (``complete``, ``aborted``, ``interrupted``), why, and samples kept."""

    path: Path
    status: str
    reason: str
    samples: int

    @property
    def exit_code(self) -> int:
        """0 complete, 3 ended by the rig or a limit (aborted), 130 interrupted."""
        return EXIT_CODES.get(self.status, 1)


def check_metadata(metadata, source="metadata") -> dict:
    """User metadata (operator, sample batch, notes) as a dict of str -> str.

    Keys start with a letter and hold letters, digits, ``_``, ``.``, ``-`` (at most
    64); values are text (numbers are written as text), at most 4096 characters.

    Raises
    ------
    SpecError
        Naming the key and what is allowed.
    """
    if metadata is None:
        return {}
    if not isinstance(metadata, dict):
        raise SpecError(source, "<document>", f"expected a mapping of key to value, got {type(metadata).__name__}")
    out = {}
    for key, value in metadata.items():
        if not isinstance(key, str) or not _MD_KEY.match(key):
            raise SpecError(source, str(key), "not a metadata key; allowed: a letter, then letters, digits, "
                            "'_', '.' or '-' (at most 64)")
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise SpecError(source, key, f"value {value!r:.40} is not text or a number")
        text = str(value)
        if len(text) > 4096 or "\x00" in text:
            raise SpecError(source, key, "value longer than 4096 characters or holding a NUL")
        out[key] = text
    return out


def run_attrs(plan, card, backend, seed, command="", metadata=None) -> dict:
    """The dataset attributes known before the first sample.

    CF's ``institution`` is the metadata's ``institution`` (else "not stated"),
    ``source`` the backend's (how the data were produced); paths are relative to
    the project root (`~rdea_lab.store.schema.portable_path`), never a machine's.
    """
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
        "protocol_source": portable_path(plan.source),
        "sample_rate": float(plan.sample_rate),
        "measured": ",".join(plan.measure),
        "seed": int(seed),
        "created": created,
        "status": "running",
        "status_reason": "",
        "history": f"{created}: {portable_command(command) or 'rdea-lab run'}",
        "metadata": json.dumps(metadata or {}, sort_keys=True),
        **global_attrs(f"rdea-lab {__version__}, backend {backend.name}", metadata),  # a backend says more
    }
    attrs.update(backend.attrs())
    return attrs


def _differing(magnitude: float, limit: float, value: float) -> str:
    """``value`` with enough digits that its magnitude reads differently from ``limit``."""
    for digits in (4, 6, 9, 12, 17):
        if f"{magnitude:.{digits}g}" != f"{limit:.{digits}g}":
            break
    return f"{value:.{digits}g}"


def _raise_pending(signals: Signals, result) -> None:
    """A signal that came while a run that was not interrupted closed: raised now, the dataset whole."""
    if signals.pending and result.status != "interrupted":
        raise RunInterrupted(f"{signals.pending} as the run ended; its dataset {result.path} is closed "
                             f"({result.status}, {result.samples} samples)")


def _subscribers(callbacks):
    callbacks = () if callbacks is None else (callbacks,) if callable(callbacks) else tuple(callbacks)
    for cb in callbacks:
        if not callable(cb):
            raise TypeError(f"callbacks: {cb!r} is not callable; a subscriber is cb(block), with optional "
                            "start(attrs) and stop(result)")
    return callbacks


class _SubscriberFailed(Exception):
    pass


def execute(plan, card, backend, out: Path, *, seed=0, command="", callbacks=(), metadata=None, control=None,
            suspenders=None, on_interrupt=None) -> RunResult:
    """Run a checked plan on ``backend`` into the dataset ``out``.

    The engine runs only a plan whose limits were checked for this specimen, in
    preparation (`~rdea_lab.runs.checked.checked_plan`, which `prepare_run` calls):
    it checks no limit itself, it asserts that this one was checked and is
    unchanged since. Anything else is refused before the backend is started:
    nothing moves, nothing is written.

    Parameters
    ----------
    plan : CheckedPlan
        `~rdea_lab.runs.checked.checked_plan` (plan, card, geometry).
    card : SpecimenCard
        The specimen the plan was checked for.
    backend : Backend
    out : Path
        Dataset to write; its journal ``<out>.part`` must not exist.
    seed : int
        Recorded in the attributes.
    command : str
        The command line, for ``history``.
    callbacks : callable or sequence of callables
        Subscribers called with each `RunBlock` (see `rdea_lab.runs.callbacks`).
    metadata : dict, optional
        User metadata (str -> str), stored as JSON in the ``metadata`` attribute.
    control : RunControl, optional
        Pause, resume and abort requests to the run (`rdea_lab.runs.control`); one is made when not given.
        Requests from other processes come through the run's journal folder either way.
    suspenders : sequence of Suspender, optional
        Conditions on the backend's channels that pause the run and resume it (`rdea_lab.runs.operate`);
        default: the protocol's ``suspend:``.
    on_interrupt : callable, optional
        Called (in the main thread, from the signal handler) for a Ctrl-C while the run goes; when it returns
        True the Ctrl-C was taken (e.g. as a pause and a question to the user) and the run goes on; otherwise,
        and for SIGTERM always, the run is interrupted at once, voltage off.

    Returns
    -------
    RunResult
        ``status`` is ``complete``, ``aborted`` (a limit or the backend
        stopped the run) or ``interrupted`` (Ctrl-C, SIGTERM).

    Raises
    ------
    UncheckedPlan
        ``plan`` is not a `CheckedPlan` for ``card``, or changed after its check.
    """
    subscribers = _subscribers(callbacks)
    # while the run starts and acquires, the first signal raises RunInterrupted; from then on, and from the
    # moment the loop is left however it ends, the run is closing: a signal waits until the dataset is closed
    control = control if control is not None else RunControl()

    def first() -> bool:  # a Ctrl-C is taken as a pause only while acquiring, by a backend that can pause
        return (guard.acquiring and callable(getattr(backend, "pause", None))
                and bool(getattr(backend, "pausable", True)) and bool(on_interrupt()))

    guard = Signals(RunInterrupted, once=True, first=first if on_interrupt is not None else None)
    guard.acquiring = False  # set once the loop runs: a Ctrl-C while the run starts interrupts it
    with guard as signals:
        result = _execute(plan, card, backend, out, seed, command, subscribers, metadata, signals, control,
                          suspenders)
        _raise_pending(signals, result)
    return result


def _execute(plan, card, backend, out, seed, command, subscribers, metadata, signals, control,
             suspenders) -> RunResult:
    started, writer = False, None
    status, reason = "complete", ""
    failure = None
    failed_cb = [None]

    def notify(method, *args):
        for cb in subscribers:
            fn = cb if method is None else getattr(cb, method, None)
            if fn is None:
                continue
            try:
                fn(*args)
            except KeyboardInterrupt:
                raise
            except Exception as exc:
                failed_cb[0] = cb
                raise _SubscriberFailed(f"subscriber {subscriber_name(cb)} failed: "
                                        f"{type(exc).__name__}: {exc}") from exc

    # from the journal's claim on, every statement is inside a try that closes it: a signal lands between any
    # two calls, and one outside both (the operator's first publish, say) left the journal unclosed
    try:
        metadata = check_metadata(metadata)
        plan = require_checked(plan, card)  # checked in preparation, unchanged since: before anything moves
        attrs = run_attrs(plan, card, backend, seed, command, metadata)
        # the output is claimed (journal folder and lock) before anything moves: a second run on it is refused
        measured = tuple(m for m in plan.measure if m in OPTIONAL_RUN_VARIABLES)  # e.g. current
        extra = tuple(dict.fromkeys((*backend.extra_variables, *measured, "paused")))  # every run: its phases
        with deferred():  # the claim is whole or not made
            writer = JournalWriter(out, None, extra=extra)
        control.attach(writer.dir)
        if suspenders is None:
            suspenders = getattr(getattr(plan, "spec", None), "suspend", None) or ()
        for cb in subscribers:  # a subscriber that cannot start stops the run before anything moves
            start = getattr(cb, "start", None)
            if start is not None:
                start(dict(attrs))
        backend.start(plan)  # may refuse (its own limits, configuration) before anything moves
        started = True
        attrs.update(backend.attrs())  # what the backend knows once started (model choice, rig identity)
        with deferred():
            writer.begin(attrs)
    except BaseException:
        signals.closing = True
        if started:  # the journal could not be written (a full disk, no permission): stop the rig
            backend.abort("the run's journal could not be written")
        if writer is not None:
            writer.abandon()
        backend.close()
        raise
    try:
        try:
            operator = Operator(control, backend, writer, suspenders)
            operator.publish(0, force=True)
            max_force = plan.limits.max_force
            planned = plan.samples
            signals.acquiring = True
            while True:
                block = backend.read_block()
                if block is None:
                    break
                first = writer.samples
                if "paused" not in block:  # a backend that cannot pause: every sample runs the plan
                    block = {**block, "paused": np.zeros(len(block["time"]), np.int8)}
                writer.append(block)
                over = np.flatnonzero(np.abs(block["force"]) > max_force)
                if over.size:
                    i = int(over[0])
                    status = "aborted"
                    reason = (f"force {_differing(abs(block['force'][i]), max_force, block['force'][i])} N at "
                              f"t = {block['time'][i]:.6g} s is above the limit max_force = {max_force:g} N")
                    backend.abort(reason)
                notify(None, RunBlock(block, first, writer.samples, planned, "running"))
                if status != "complete":
                    break
                ended = operator.after_block(block, first, writer.samples)
                if ended is not None:  # an abort asked for, or a suspender that waited too long
                    status, reason = ended
                    backend.abort(reason)
                    break
        finally:  # however the loop is left, the run is closing: a signal from here waits for the dataset
            signals.closing = True
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM (RunInterrupted)
        if status == "complete":  # a limit that already ended the run keeps its reason
            status, reason = "interrupted", f"interrupted by the user ({str(exc) or 'Ctrl-C'})"
        backend.abort(reason)
    except BackendFailure as exc:
        if status == "complete":
            status, reason = "aborted", str(exc)
        backend.abort(reason)
    except DiskFull:  # the journal holds every sample received; finish says so if it cannot write either
        if status == "complete":
            status, reason = "aborted", f"the disk filled up after {writer.samples} samples; the run was stopped"
        backend.abort(reason)
    except _SubscriberFailed as exc:
        if status == "complete":
            status, reason = "aborted", str(exc)
        failure = exc.__cause__
        backend.abort(reason)
    except BaseException as exc:
        if status == "complete":
            status, reason = "aborted", f"internal error: {type(exc).__name__}: {exc}"
        backend.abort(reason)
        writer.finish(status, reason)
        raise
    finally:
        backend.close()
    path = writer.finish(status, reason)
    result = RunResult(path, status, reason, writer.samples)
    for cb in subscribers:  # every subscriber hears how the run ended, but the one that failed
        stop = getattr(cb, "stop", None)
        if stop is not None and not (failure is not None and failed_cb[0] is cb):
            stop(result)
    if failure is not None:
        raise failure
    return result
