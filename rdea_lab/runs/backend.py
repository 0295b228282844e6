"""What runs a protocol, as objects: `Twin`, `Emulator`, `Rig`.

Each is validated where it is built (a bad model, fault, address or timeout is a `SpecError` naming the
argument) and knows three things: what it checks once the run's geometry is known (`check`), how the dry
run describes it (`describe`), and the executor it opens for one run (`opened`, a context manager: the
emulator starts its loopback server there). The executor takes the run's card and geometry from the
`~rdea_lab.runs.app.RunSetup` (the geometry made once, in `prepare_run`). `rdea_lab.run_protocol` takes one of them::

    rdea_lab.run_protocol("protocols/blocking_force.yaml", "specimens/specimen2.yaml",
                          rdea_lab.Twin(model="su"), out="demo.nc")
    rdea_lab.run_protocol(..., rdea_lab.Emulator(faults=["stall-at=3"]), ...)
    rdea_lab.run_protocol(..., rdea_lab.Rig("tcp://127.0.0.1:5025", token="..."), ...)

A `~rdea_lab.backends.Backend` of one's own (the executor protocol) is taken as it is.
"""

from __future__ import annotations

import contextlib
import math
import os
from dataclasses import dataclass

from ..paths import resolve
from ..specs import MODEL_CHOICES, SpecError

#: Where a user's arguments are named in messages.
ARGS = "arguments"
DEFAULT_PARAMS = "params/paper2021_table3.yaml"
DEFAULT_TRUTH = "truth/paper2021.yaml"
#: Longest the driver waits for one reply of the built-in emulator [s]. A ``FETC?`` computes at most one
#: block of the truth's physics (2048 samples, bit-identical whatever the chunking): milliseconds with numba,
#: seconds without it, more on a busy machine (a 5 s timeout then cut a healthy run off as a lost connection).
EMULATOR_REPLY_TIMEOUT = 120.0


def project_default(given, default: str, field_name: str):
    """``given``, or the packaged ``default`` file (e.g. the paper's Table 3 parameters)."""
    if given is not None:
        return given
    path = resolve(default, default.partition("/")[0])
    if not path.is_file():
        raise SpecError(ARGS, field_name, f"required here (no {default} to default to)")
    return path


def _stall_timeout(value, field="stall_timeout") -> float:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and 0.1 <= value <= 3600):
        raise SpecError(ARGS, field, f"{value!r}; allowed: 0.1 to 3600 s")
    return float(value)


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


class _Backend:
    """What every backend object does for `rdea_lab.run_protocol` (the documentation of its methods)."""

    def check(self, geom) -> None:
        """Refuse a geometry this backend cannot run; by default none (a rig checks the run on its side).

        Parameters
        ----------
        geom : RollGeometry or StripGeometry
            The run's geometry, made once from the card in `~rdea_lab.runs.app.prepare_run`.
        """
        return None

    def opened(self, setup):
        """The executor of one run, as a context manager (the emulator starts its rig here, a rig connects).

        Parameters
        ----------
        setup : RunSetup
            The prepared run (`~rdea_lab.runs.app.prepare_run`): its checked plan, card, geometry and seed.

        Yields
        ------
        Backend
            The executor of the one run (`rdea_lab.backends.Backend`).
        """
        raise NotImplementedError

    def describe(self, setup) -> str:
        """What the dry run says of this backend, in one line (a rig is not contacted).

        Parameters
        ----------
        setup : RunSetup
            The prepared run.

        Returns
        -------
        str
            One line, e.g. ``twin: model su, parameters paper2021_table3``.
        """
        raise NotImplementedError


@dataclass(frozen=True, init=False)
class Twin(_Backend):
    """The physics model as the backend.

    Parameters
    ----------
    params : ParameterSet or path, optional
        Default: the paper's Table 3 (``params/paper2021_table3.yaml``).
    model : {"auto", "su", "1r", "3r", "cr"}
        ``auto``: the cheapest model within ``tolerance`` of 3R on the run.
    tolerance : float
        For ``auto``: the deviation from 3R allowed, relative to the peak stress [-], 0 < tolerance < 1.
    realtime : bool
        Pace the run at wall-clock speed (as a rig would).

    Raises
    ------
    SpecError
        An unknown model, a tolerance outside (0, 1), or a parameter file that is missing or invalid.
    """

    params: object
    model: str
    tolerance: float
    realtime: bool
    name = "twin"

    def __init__(self, params=None, model="auto", tolerance=0.01, realtime=False):
        from ..specs import as_params

        model = model.lower() if isinstance(model, str) else model
        if model not in MODEL_CHOICES:
            raise SpecError(ARGS, "model", f"{model!r}; allowed: {', '.join(MODEL_CHOICES)}")
        if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and 0.0 < tolerance < 1.0):
            raise SpecError(ARGS, "tolerance", f"{tolerance!r} is not a relative deviation; allowed: 0 < tolerance < 1")
        object.__setattr__(self, "params", as_params(project_default(params, DEFAULT_PARAMS, "params")))
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "tolerance", float(tolerance))
        object.__setattr__(self, "realtime", bool(realtime))

    def check(self, geom) -> None:
        """Refuse a geometry the model does not apply to: 3R and CR need a roll (a core, no strip).

        Parameters
        ----------
        geom : RollGeometry or StripGeometry
            The run's geometry, made once from the card in `~rdea_lab.runs.app.prepare_run`.

        Raises
        ------
        SpecError
            ``model`` is 3R or CR and the specimen is a strip or has no core.
        """
        if self.model in ("3r", "cr"):
            from ..physics.models import three_ring

            three_ring.check_applicable(geom)

    def executor(self, setup):
        """The twin's executor for one run.

        Parameters
        ----------
        setup : RunSetup
            The prepared run: its card, geometry and seed.

        Returns
        -------
        TwinBackend
            The physics model behind the executor protocol (`rdea_lab.backends.twin.TwinBackend`).
        """
        from ..backends.twin import TwinBackend

        return TwinBackend(setup.card, self.params, model=self.model, tolerance=self.tolerance,
                           realtime=self.realtime, seed=setup.seed, geometry=setup.geometry)

    @contextlib.contextmanager
    def opened(self, setup):
        yield self.executor(setup)

    def describe(self, setup) -> str:
        twin = self.executor(setup)
        twin.start(setup.plan)
        sel = twin.choice
        return (f"twin: model {twin.model}" + (f" ({sel.reason})" if sel is not None else "")
                + f", parameters {self.params.name}")


@dataclass(frozen=True, init=False)
class Emulator(_Backend):
    """A built-in emulated rig on a free loopback port, for the one run: the rig protocol end to end, with
    the truth's physics (which no model has) and its instruments.

    Parameters
    ----------
    truth : TruthSpec or path, optional
        Default ``truth/paper2021.yaml``.
    faults : sequence
        ``"stall-at=3"`` or ``("stall", 3.0)``: ``disconnect``, ``breakdown``, ``stall`` at a run time [s];
        ``"interlock-at=5:2"`` or ``("interlock", 5.0, 2.0)``: the door open, the amplifier overheated
        (``overheat``) or the load cell's zero drifted (``drift``) from a run time for a duration [s] (to
        the end without one): the conditions a protocol's suspenders watch.
    realtime : bool
        Pace the emulated rig at wall-clock speed.
    stall_timeout : float
        Seconds without a new sample before the run is aborted [s], 0.1 to 3600.

    Raises
    ------
    SpecError
        A truth file that is missing or invalid, an unknown fault, or a stall timeout outside 0.1 to 3600 s.
    """

    truth: object
    faults: tuple
    realtime: bool
    stall_timeout: float
    name = "emulator"

    def __init__(self, truth=None, faults=(), realtime=False, stall_timeout=5.0):
        from ..emulator.controller import parse_faults
        from ..specs.truth import load_truth

        if truth is None or isinstance(truth, (str, os.PathLike)):
            truth = load_truth(project_default(truth, DEFAULT_TRUTH, "truth"))
        object.__setattr__(self, "truth", truth)
        object.__setattr__(self, "faults", tuple(parse_faults(faults, ARGS, "faults")))
        object.__setattr__(self, "realtime", bool(realtime))
        object.__setattr__(self, "stall_timeout", _stall_timeout(stall_timeout))

    @contextlib.contextmanager
    def opened(self, setup):
        from ..backends.rig import RigBackend

        with emulated_rig(setup.card, self.truth, realtime=self.realtime, faults=self.faults) as address:
            yield RigBackend(address, setup.card, timeout=EMULATOR_REPLY_TIMEOUT, stall_timeout=self.stall_timeout,
                             seed=setup.seed, geometry=setup.geometry)

    def describe(self, setup) -> str:
        faults = ", ".join(str(f) for f in self.faults)  # interlock-at=5:2, stall-at=3
        return f"emulator: truth {self.truth.name}" + (f", faults {faults}" if faults else "")


@dataclass(frozen=True, init=False)
class Rig(_Backend):
    """A rig server at ``address`` (the physical rig, or `rdea-lab rig serve`), through the rig protocol.

    Parameters
    ----------
    address : str
        ``tcp://HOST:PORT``.
    token : str, optional
        The token the server wants (for the HMAC handshake; never sent itself).
    trust_card : bool
        Run although the rig's ``*IDN?`` names another specimen than the card (recorded in the dataset's
        ``rig_identity``); by default such a run is refused before anything moves.
    stall_timeout : float
        Seconds without a new sample before the run is aborted [s], 0.1 to 3600.
    timeout : float
        Longest wait for one reply [s], 0.1 to 3600; past it the connection counts as lost.

    Raises
    ------
    SpecError
        No address, an address that is not ``tcp://HOST:PORT``, or a timeout outside 0.1 to 3600 s.
    """

    address: str
    token: object
    trust_card: bool
    stall_timeout: float
    timeout: float
    name = "rig"

    def __init__(self, address, token=None, trust_card=False, stall_timeout=5.0, timeout=5.0):
        from ..backends.rig import parse_address

        if not address:
            raise SpecError(ARGS, "address", "required with the rig backend (e.g. tcp://127.0.0.1:5025)")
        try:
            parse_address(address)
        except ValueError as exc:
            raise SpecError(ARGS, "address", str(exc)) from None
        object.__setattr__(self, "address", str(address))
        object.__setattr__(self, "token", token)
        object.__setattr__(self, "trust_card", bool(trust_card))
        object.__setattr__(self, "stall_timeout", _stall_timeout(stall_timeout))
        object.__setattr__(self, "timeout", _stall_timeout(timeout, "timeout"))

    def __repr__(self):  # never the token
        return (f"Rig({self.address!r}, token={'...' if self.token else None}, trust_card={self.trust_card}, "
                f"stall_timeout={self.stall_timeout}, timeout={self.timeout})")

    @contextlib.contextmanager
    def opened(self, setup):
        from ..backends.rig import RigBackend

        yield RigBackend(self.address, setup.card, token=self.token, timeout=self.timeout,
                         stall_timeout=self.stall_timeout, seed=setup.seed, trust_card=self.trust_card,
                         geometry=setup.geometry)

    def describe(self, setup) -> str:
        return f"rig {self.address}: not contacted (dry run)"


#: The backends by the names the CLI and campaign files use.
BACKENDS = {"twin": Twin, "emulator": Emulator, "rig": Rig}


def backend_from_choice(name, *, params=None, model="auto", tolerance=0.01, realtime=False, address=None,
                        token=None, truth=None, faults=(), stall_timeout=5.0, trust_card=False):
    """The backend object for a name and the options the CLI gathers (each option only where it applies:
    the one place that says which, in the CLI's words through `rdea_lab.cli.errors.OPTIONS`)."""
    if isinstance(name, str) and name.startswith("tcp://"):
        name, address = "rig", name
    if name not in BACKENDS:
        raise SpecError(ARGS, "backend", f"{name!r}; allowed: {', '.join(BACKENDS)}, tcp://HOST:PORT "
                        "or a backend object (Twin, Emulator, Rig)")
    if name != "emulator" and (faults or truth is not None):
        raise SpecError(ARGS, "faults/truth", "only with the emulator backend")
    if name != "rig" and (address or token or trust_card):
        raise SpecError(ARGS, "address/token/trust_card", "only with the rig backend")
    if name != "twin" and params is not None:
        raise SpecError(ARGS, "params", "the twin's parameters; a rig measures, it takes none")
    if name == "twin":
        return Twin(params, model, tolerance, realtime)
    if name == "emulator":
        return Emulator(truth, faults, realtime, stall_timeout)
    return Rig(address, token, trust_card, stall_timeout)
