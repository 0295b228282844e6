"""`run_protocol`: one protocol on one specimen, on any backend, into one dataset.

Everything a run needs between "this protocol on that specimen" and the
engine: the limit checks (voltage, stretch, field estimate; the force limit
while running), the backend wiring (the twin, a built-in emulated rig on a
loopback port, a rig server at an address), the default output path and the
check that nothing already measured is overwritten, the journal (in the
engine) and the dataset it returns. The CLI's ``run``, ``campaign run`` and
``reproduce`` and a notebook all come here.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from ..backends.base import Backend
from ..physics.geometry import geometry_from_card
from ..protocols import as_plan
from ..specs import SpecError, as_specimen
from ..store import journal_path, open_run
from ..store.outputs import OutputError, check_dataset_name, check_new, check_writable  # noqa: F401  (this layer's API)
from .backend import (ARGS, BACKENDS, DEFAULT_PARAMS, DEFAULT_TRUTH, Emulator, Rig, Twin,  # noqa: F401
                      backend_from_choice, emulated_rig, project_default)
from .checked import CheckedPlan, checked_plan
from .engine import check_metadata, execute



class OutputInUse(OutputError):
    """A dataset to be written exists (without overwrite), is written twice, or has a journal in the way."""


def default_out(card_id: str, plan_name: str, folder="datasets") -> Path:
    """``datasets/<specimen>/<protocol>-<UTC time>.nc`` (``-2``, ``-3``, ... after it if that is taken)."""
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    base = Path(folder) / card_id / f"{plan_name}-{stamp}"
    out, k = base.with_name(base.name + ".nc"), 1
    while out.exists() or journal_path(out).exists():
        k += 1
        out = base.with_name(f"{base.name}-{k}.nc")
    return out


def check_outputs(paths, overwrite: bool = False, names=None) -> None:
    """Check every dataset to be written before any run starts.

    Two runs writing one file, an unfinished run's journal in the way, or an
    existing file without ``overwrite`` raise `OutputInUse`; a folder that
    cannot be written raises `OutputError`. With ``overwrite`` an existing
    file is replaced only when its run's new dataset is written (atomically),
    so a run refused or failing before that keeps the old one; journals are
    never replaced (recover them).

    Parameters
    ----------
    paths : sequence of path
    overwrite : bool
    names : sequence of str, optional
        What each path is for (e.g. ``specimen-2/blocking_force``), for messages.
    """
    paths = [Path(p) for p in paths]
    names = list(names) if names is not None else [str(p) for p in paths]
    seen = {}
    for out, name in zip(paths, names):
        key = os.path.abspath(out)
        if key in seen:
            raise OutputInUse(str(out), "out", f"written by both {seen[key]} and {name}; give each run its own "
                              "output (distinct specimen ids and protocol names)")
        seen[key] = name
    for out in paths:
        check_dataset_name(out)
        check_writable(out)  # first: a name the file system refuses cannot even be looked up
        if journal_path(out).exists():
            raise OutputInUse(str(out), "out", f"an unfinished run's journal {journal_path(out)} is in the way; "
                              "rdea-lab recover it, or remove it")
        check_new(out, overwrite, error=OutputInUse)


def check_seed(seed) -> int:
    """A noise seed: an integer from 0 to 2**63 - 1 (what the rig and the dataset attributes hold;
    `rdea_lab.specs.errors.seed_problem`, the rule of truth files and campaigns too)."""
    from ..specs.errors import seed_problem

    problem = seed_problem(seed)
    if problem:
        raise SpecError(ARGS, "seed", problem)
    return int(seed)


@dataclass
class RunSetup:
    """A run checked and ready: what `run_protocol` will execute (`describe` is the dry run).

    Attributes
    ----------
    checked : CheckedPlan
        The expanded protocol with the card and geometry its limits were checked for
        (`~rdea_lab.runs.checked.checked_plan`); the engine runs nothing else.
    backend : Twin, Emulator, Rig or a Backend of one's own
    out : Path
    seed : int
        The run's noise seed (the emulator's; a rig records it).
    plan : Plan
        ``checked.plan`` (read-only, as are `card` and `geometry`).
    card : SpecimenCard
        ``checked.card``.
    geometry : RollGeometry or StripGeometry
        ``checked.geometry``: the card's geometry, made once, where the card came in; the backends take it
        from here.
    """

    checked: CheckedPlan
    backend: object
    out: Path
    seed: int = 0

    plan = property(lambda self: self.checked.plan, doc="The expanded protocol, its limits checked.")
    card = property(lambda self: self.checked.card, doc="The specimen card.")
    geometry = property(lambda self: self.checked.geometry, doc="The card's geometry (made once).")

    def opened(self):
        """The executor for this run, for the duration of the block (the emulator's server with it)."""
        return self.backend.opened(self)

    def describe(self) -> str:
        """The dry run: the expanded plan, its limits checked, and what would run it."""
        lines = [self.plan.describe(), f"limits: ok for {self.card.id} (L3 = {self.geometry.L3 * 1e6:g} um)",
                 self.backend.describe(self)]
        exists = " (it exists: the run would need --force)" if Path(self.out).exists() else ""
        lines.append(f"dataset: none written (dry run); the run would write {self.out}{exists}")
        return "\n".join(lines)


class _Given:
    """A `Backend` executor of the caller's own, as a backend object."""

    name = "given"

    def __init__(self, executor):
        self.executor = executor

    def check(self, geom) -> None:
        pass

    @contextlib.contextmanager
    def opened(self, setup):
        yield self.executor

    def describe(self, setup) -> str:
        return f"backend {getattr(self.executor, 'name', type(self.executor).__name__)} (given)"


def as_backend(backend):
    """A backend object: `Twin`, `Emulator`, `Rig` as given; ``None`` the default `Twin`; a name
    (``"twin"``, ``"emulator"``, ``"rig"``) or ``tcp://HOST:PORT`` that backend with its defaults; a
    `Backend` executor of one's own as it is."""
    if backend is None:
        return Twin()
    if isinstance(backend, (Twin, Emulator, Rig)):
        return backend
    if isinstance(backend, str):
        return backend_from_choice(backend)
    if isinstance(backend, Backend):
        return _Given(backend)
    raise TypeError(f"backend: expected Twin, Emulator, Rig, a name, tcp://HOST:PORT or a Backend, "
                    f"got {type(backend).__name__}")


def prepare_run(protocol, specimen, backend=None, *, out=None, seed=0) -> RunSetup:
    """Check a run completely, before anything moves.

    The card becomes geometry here, once; the plan's limits (stretch, voltage, field) are checked here for
    every backend (`~rdea_lab.runs.checked.checked_plan`), and the engine runs only a plan checked so.

    Parameters
    ----------
    protocol : Plan, ProtocolSpec, path or CheckedPlan
        As in `run_protocol`; a `CheckedPlan` already checked for ``specimen`` (a campaign's, from
        `experiments`) is taken as it is, its geometry with it: neither is made again.
    specimen : SpecimenCard or path
    backend : Twin, Emulator, Rig, str or Backend, optional
        As in `run_protocol` (default the twin with the paper's parameters).
    out : path, optional
        As in `run_protocol`: the dataset's file (default ``datasets/<specimen>/<protocol>-<UTC time>.nc``).
    seed : int, optional
        As in `run_protocol`: the noise seed of an emulated or twin run.

    Returns
    -------
    RunSetup

    Raises
    ------
    SpecError
        As `run_protocol`, before anything moves.
    """
    plan = protocol if isinstance(protocol, CheckedPlan) else as_plan(protocol)
    card = as_specimen(specimen)
    if isinstance(plan, CheckedPlan) and plan.is_for(card):
        checked = plan
    else:  # stretch, voltage and field, refused here for every backend
        checked = checked_plan(plan.plan if isinstance(plan, CheckedPlan) else plan, card, _geometry(card, specimen))
    seed = check_seed(seed)
    backend = as_backend(backend)
    backend.check(checked.geometry)
    out = Path(out) if out is not None else default_out(card.id, checked.plan.name)
    return RunSetup(checked, backend, out, seed)


def _geometry(card, specimen):
    """The card's geometry; a card no roll can be built from is a `SpecError` of the card."""
    try:
        return geometry_from_card(card)
    except ValueError as exc:
        raise SpecError(str(specimen) if isinstance(specimen, (str, os.PathLike)) else card.id, "<document>",
                        str(exc)) from None


def run_protocol(protocol, specimen, backend=None, *, out=None, overwrite=False, seed=0, metadata=None,
                 callbacks=(), command="", control=None):
    """Run a protocol on a specimen and return the run's dataset.

    Parameters
    ----------
    protocol : Plan, ProtocolSpec or path
        What the rig does (a protocol file is read and expanded).
    specimen : SpecimenCard or path
    backend : Twin, Emulator, Rig or Backend, optional
        What runs it (`rdea_lab.runs.backend`): ``Twin(params, model)``, the physics model (the default,
        with the paper's Table 3); ``Emulator(truth, faults)``, a built-in emulated rig on a loopback port
        for this run; ``Rig(address, token)``, a rig server. A name (``"twin"``, ``"emulator"``,
        ``"rig"``) or ``tcp://HOST:PORT`` is that backend with its defaults.
    out : path, optional
        Dataset to write; default ``datasets/<specimen>/<protocol>-<UTC time>.nc``.
    overwrite : bool
        Replace an existing dataset (never a journal).
    seed : int
        Noise seed (the emulator's), recorded; 0 to 2**63 - 1.
    metadata : dict, optional
        Operator, sample batch, notes, ...: str -> str, in the ``metadata`` attribute.
    callbacks : callable or sequence
        Subscribers called with each block (`rdea_lab.runs.callbacks`), e.g.
        `LiveTable`, `LivePlot` or a function of your own.
    command : str
        Recorded in the dataset's history.
    control : RunControl, optional
        To pause, resume or abort the run while it goes, from any thread (`rdea_lab.runs.control`):
        ``ctl = RunControl(); run_protocol(..., control=ctl)`` and ``ctl.pause("look at the specimen")``.
        Another process does the same through the run's journal (``rdea-lab pause RUN``).

    Returns
    -------
    xarray.Dataset
        The run, read back from its file (``ds.encoding["source"]``); its
        ``status`` attribute is ``complete`` or ``aborted`` (by the rig or a
        limit). Ctrl-C ends the run (voltage off, the dataset written with
        status ``interrupted``) and then raises KeyboardInterrupt, whose message
        names the file.

    Raises
    ------
    SpecError
        A bad protocol, card, parameter set or argument; `~rdea_lab.specs.LimitError`
        for a plan beyond its limits; `OutputInUse` for an output in the way.
        Raised before anything moves and before anything is written.
    """
    setup = prepare_run(protocol, specimen, backend, out=out, seed=seed)
    metadata = check_metadata(metadata)
    check_outputs([setup.out], overwrite)
    result = execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command, control=control)
    if result.status == "interrupted":  # Ctrl-C stops the caller too (a notebook loop), once the file is safe
        raise KeyboardInterrupt(f"{result.reason}; {result.samples} samples kept in {result.path}")
    ds = open_run(result.path)
    ds.encoding["source"] = str(result.path)
    return ds


def execute_setup(setup: RunSetup, *, callbacks=(), metadata=None, command="", catalog=None, control=None,
                  on_interrupt=None):
    """Execute a prepared run (`prepare_run`); returns the engine's `RunResult`.

    The dataset written, its row goes into the catalogue (``catalog``, a URL; default
    `~rdea_lab.store.index.resolve_catalog` of its folder); a catalogue that cannot be written leaves the run
    unindexed, says so in one line on stderr (`~rdea_lab.store.index.index_quietly`) and changes nothing else.
    ``control`` and ``on_interrupt`` are the engine's (`~rdea_lab.runs.engine.execute`): pause, resume and
    abort requests, and what a Ctrl-C does.
    """
    with setup.opened() as executor:
        result = execute(setup.checked, setup.card, executor, setup.out, seed=setup.seed, command=command,
                         callbacks=callbacks, metadata=metadata, control=control, on_interrupt=on_interrupt)
    from ..signals import deferred
    from ..store.index import index_quietly

    with deferred():  # the run is closed whole: a Ctrl-C now comes after its row (and its status line)
        index_quietly(result.path, catalog)
    return result
