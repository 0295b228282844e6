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
import math
import os
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from ..backends.base import Backend
from ..backends.twin import TwinBackend
from ..paths import resolve
from ..physics.geometry import geometry_from_card
from ..physics.models import three_ring
from ..protocols import as_plan, first_violation
from ..specs import MODEL_CHOICES, SpecError, as_params, as_specimen
from ..store import journal_path, open_run
from ..store.outputs import OutputError, check_dataset_name, check_new, check_writable  # noqa: F401  (this layer's API)
from .engine import check_metadata, execute

DEFAULT_PARAMS = "params/paper2021_table3.yaml"
DEFAULT_TRUTH = "truth/paper2021.yaml"
BACKENDS = ("twin", "emulator", "rig")
MODELS = MODEL_CHOICES
#: Where a user's arguments are named in messages.
ARGS = "arguments"


class OutputInUse(OutputError):
    """A dataset to be written exists (without overwrite), is written twice, or has a journal in the way."""


def project_default(given, default: str, field_name: str):
    """``given``, or the packaged ``default`` file (e.g. the paper's Table 3 parameters)."""
    if given is not None:
        return given
    path = resolve(default, default.partition("/")[0])
    if not path.is_file():
        raise SpecError(ARGS, field_name, f"required here (no {default} to default to)")
    return path


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


def check_tolerance(tolerance) -> float:
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and 0.0 < tolerance < 1.0):
        raise SpecError(ARGS, "tolerance", f"{tolerance!r} is not a relative deviation; allowed: 0 < tolerance < 1")
    return float(tolerance)


@contextlib.contextmanager
def emulated_rig(card, truth, *, realtime=False, faults=()):
    """A built-in emulated rig on a free loopback port for the duration of the block; yields its address."""
    from ..emulator import RigServer

    server = RigServer(card, truth, port=0, realtime=realtime, faults=faults)
    host, port = server.start()
    try:
        yield f"tcp://{host}:{port}"
    finally:
        server.shutdown()


@dataclass
class RunSetup:
    """A run checked and ready: what `run_protocol` will execute (`describe` is the dry run).

    Attributes
    ----------
    plan : Plan
    card : SpecimenCard
    backend : str or Backend
        ``"twin"``, ``"emulator"``, ``"rig"`` or a Backend given by the caller.
    out : Path
    options : dict
        The backend's settings (params, model, address, truth, faults, ...).
    """

    plan: object
    card: object
    backend: object
    out: Path
    options: dict = field(default_factory=dict)

    def make_backend(self, address=None) -> Backend:
        """The executor (for ``"emulator"``, ``address`` is the emulated rig's)."""
        o = self.options
        if not isinstance(self.backend, str):
            return self.backend
        if self.backend == "twin":
            return TwinBackend(self.card, o["params"], model=o["model"], tolerance=o["tolerance"],
                               realtime=o["realtime"], seed=o["seed"])
        from ..backends.rig import RigBackend

        return RigBackend(address or o["address"], self.card, token=o.get("token"),
                          stall_timeout=o["stall_timeout"], seed=o["seed"], trust_card=o.get("trust_card", False))

    def describe(self) -> str:
        """The dry run: the expanded plan, its limits checked, and what would run it."""
        geom = geometry_from_card(self.card)
        lines = [self.plan.describe(), f"limits: ok for {self.card.id} (L3 = {geom.L3 * 1e6:g} um)"]
        o = self.options
        if self.backend == "twin":
            twin = self.make_backend()
            twin.start(self.plan)
            sel = twin.choice
            lines.append(f"twin: model {twin.model}" + (f" ({sel.reason})" if sel is not None else "")
                         + f", parameters {o['params'].name}")
        elif self.backend == "rig":
            lines.append(f"rig {o['address']}: not contacted (dry run)")
        elif self.backend == "emulator":
            faults = ", ".join(f"{k}-at={a:g}" for k, a in o["faults"])
            lines.append(f"emulator: truth {o['truth'].name}" + (f", faults {faults}" if faults else ""))
        else:
            lines.append(f"backend {getattr(self.backend, 'name', type(self.backend).__name__)} (given)")
        exists = " (it exists: the run would need --force)" if Path(self.out).exists() else ""
        lines.append(f"dataset: none written (dry run); the run would write {self.out}{exists}")
        return "\n".join(lines)


def prepare_run(protocol, specimen, backend="twin", *, params=None, model="auto", tolerance=0.01, out=None,
                seed=0, realtime=False, address=None, token=None, truth=None, faults=(), stall_timeout=5.0,
                trust_card=False) -> RunSetup:
    """Check a run completely, before anything moves; see `run_protocol` for the arguments."""
    plan = as_plan(protocol)
    card = as_specimen(specimen)
    try:
        geom = geometry_from_card(card)
    except ValueError as exc:
        raise SpecError(str(specimen) if isinstance(specimen, (str, os.PathLike)) else card.id, "<document>",
                        str(exc)) from None
    first_violation(plan, L3=geom.L3)  # stretch, voltage and field: refused here for every backend
    seed = check_seed(seed)
    options = {"seed": seed, "realtime": bool(realtime), "stall_timeout": float(stall_timeout)}
    if isinstance(backend, str) and backend.startswith("tcp://"):
        backend, address = "rig", backend
    if isinstance(backend, str):
        if backend not in BACKENDS:
            raise SpecError(ARGS, "backend", f"{backend!r}; allowed: {', '.join(BACKENDS)}, tcp://HOST:PORT "
                            "or a Backend object")
        if backend != "emulator" and (faults or truth is not None):
            raise SpecError(ARGS, "faults/truth", "only with the emulator backend")
        if backend != "rig" and (address or token or trust_card):
            raise SpecError(ARGS, "address/token/trust_card", "only with the rig backend")
        if backend != "twin" and params is not None:
            raise SpecError(ARGS, "params", "the twin's parameters; a rig measures, it takes none")
        if not (isinstance(stall_timeout, (int, float)) and 0.1 <= stall_timeout <= 3600):
            raise SpecError(ARGS, "stall_timeout", f"{stall_timeout!r}; allowed: 0.1 to 3600 s")
    elif not isinstance(backend, Backend):
        raise TypeError(f"backend: expected 'twin', 'emulator', 'rig', tcp://HOST:PORT or a Backend, "
                        f"got {type(backend).__name__}")
    if backend == "twin":
        if model not in MODELS:
            raise SpecError(ARGS, "model", f"{model!r}; allowed: {', '.join(MODELS)}")
        if model in ("3r", "cr"):
            three_ring.check_applicable(geom)
        options.update(params=as_params(project_default(params, DEFAULT_PARAMS, "params")), model=model,
                       tolerance=check_tolerance(tolerance))
    elif backend == "rig":
        from ..backends.rig import parse_address

        if not address:
            raise SpecError(ARGS, "address", "required with the rig backend (e.g. tcp://127.0.0.1:5025)")
        try:
            parse_address(address)
        except ValueError as exc:
            raise SpecError(ARGS, "address", str(exc)) from None
        options.update(address=address, token=token, trust_card=bool(trust_card))
    elif backend == "emulator":
        from ..emulator.controller import parse_faults
        from ..specs.truth import load_truth

        options["faults"] = parse_faults(faults, ARGS, "faults")
        if truth is None or isinstance(truth, (str, os.PathLike)):
            truth = load_truth(project_default(truth, DEFAULT_TRUTH, "truth"))
        options["truth"] = truth
    out = Path(out) if out is not None else default_out(card.id, plan.name)
    return RunSetup(plan, card, backend, out, options)


def run_protocol(protocol, specimen, backend="twin", *, params=None, model="auto", tolerance=0.01, out=None,
                 overwrite=False, seed=0, metadata=None, callbacks=(), realtime=False, address=None, token=None,
                 truth=None, faults=(), stall_timeout=5.0, trust_card=False, command=""):
    """Run a protocol on a specimen and return the run's dataset.

    Parameters
    ----------
    protocol : Plan, ProtocolSpec or path
        What the rig does (a protocol file is read and expanded).
    specimen : SpecimenCard or path
    backend : {"twin", "emulator", "rig"}, "tcp://HOST:PORT" or Backend
        ``twin``: the physics model; ``emulator``: a built-in emulated rig on a
        loopback port, for this run; ``rig``: a rig server at ``address``.
    params : ParameterSet or path, optional
        For the twin; default the paper's Table 3 (``params/paper2021_table3.yaml``).
    model : {"su", "1r", "3r", "cr", "auto"}
        For the twin; ``auto`` is the cheapest within ``tolerance`` of 3R on this run.
    tolerance : float
        For ``auto``: allowed deviation from 3R relative to the peak stress [-].
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
    realtime : bool
        Pace the twin or the emulator at wall-clock speed.
    address, token : str, optional
        For ``rig``: ``tcp://HOST:PORT`` and the token the server wants.
    truth : TruthSpec or path, optional
        For ``emulator``; default ``truth/paper2021.yaml``.
    faults : sequence
        For ``emulator``: ``"stall-at=3"`` or ``("stall", 3.0)``, ...
    stall_timeout : float
        Seconds without a new sample before a rig run is aborted [s].
    trust_card : bool
        For ``rig``: run although the rig's ``*IDN?`` names another specimen than the card (recorded in
        the dataset's ``rig_identity``); by default such a run is refused before anything moves.
    command : str
        Recorded in the dataset's history.

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
    setup = prepare_run(protocol, specimen, backend, params=params, model=model, tolerance=tolerance, out=out,
                        seed=seed, realtime=realtime, address=address, token=token, truth=truth, faults=faults,
                        stall_timeout=stall_timeout, trust_card=trust_card)
    metadata = check_metadata(metadata)
    check_outputs([setup.out], overwrite)
    result = execute_setup(setup, callbacks=callbacks, metadata=metadata, command=command)
    if result.status == "interrupted":  # Ctrl-C stops the caller too (a notebook loop), once the file is safe
        raise KeyboardInterrupt(f"{result.reason}; {result.samples} samples kept in {result.path}")
    ds = open_run(result.path)
    ds.encoding["source"] = str(result.path)
    return ds


def execute_setup(setup: RunSetup, *, callbacks=(), metadata=None, command=""):
    """Execute a prepared run (`prepare_run`); returns the engine's `RunResult`."""
    o = setup.options
    with contextlib.ExitStack() as stack:
        address = None
        if setup.backend == "emulator":
            address = stack.enter_context(emulated_rig(setup.card, o["truth"], realtime=o["realtime"],
                                                       faults=o["faults"]))
        executor = setup.make_backend(address)
        return execute(setup.plan, setup.card, executor, setup.out, seed=o.get("seed", 0), command=command,
                       callbacks=callbacks, metadata=metadata)
