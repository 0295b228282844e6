"""The rig driver: a plan over the SCPI-style command set of docs/rig-protocol.md.

Built on PyVISA with its pure-Python backend (``TCPIP::HOST::PORT::SOCKET``),
so any server that speaks the command set (the built-in emulator, or a lab's
own front end to its DAQ) can be driven. Limits are sent and the trajectories
checked by the server (``ARM``) before anything moves; every abort path sends
``ABOR`` (voltage to zero, actuator back to its start) and keeps every sample
fetched so far.

Every run is armed pausable (``CONF:PAUS`` from the protocol's ``pause:``, else
the defaults of `rdea_lab.protocols.pause`): `RigBackend.pause` and
`RigBackend.resume` ask the rig (``PAUS``, ``CONT``), the rows carry each
sample's phase (the block key ``paused``), and `RigBackend.conditions` reads
the rig's condition channels (``COND?``). A server of an older protocol (no
``CONF:PAUS``) runs as before, without pauses.
"""

from __future__ import annotations

import json
import math
import re
import threading
import time as _time

import numpy as np

from ..specs import rigwire as wire
from ..specs.errors import UserError
from ..specs.rigwire import COLUMNS
from .base import BackendFailure, PauseRefused

#: Least wall time between two ``COND?`` queries; `RigBackend.conditions` answers from its cache meanwhile [s].
CONDITIONS_EVERY = 0.1

_ADDRESS = re.compile(r"^tcp://(?P<host>[A-Za-z0-9.\-]+|\[[0-9a-fA-F:]+\]):(?P<port>\d{1,5})$")


class RigRefused(UserError):
    """The rig refused the run before anything moved (a limit, a bad configuration, a token)."""


class ConnectionLost(BackendFailure):
    """The connection to the rig broke (reset, closed, timed out)."""


def parse_address(address: str) -> tuple[str, int]:
    """``tcp://HOST:PORT`` -> (host, port); ValueError saying what is allowed."""
    m = _ADDRESS.match(address or "")
    if not m or not 0 < int(m["port"]) < 65536:
        raise ValueError(f"rig address {address!r} is not tcp://HOST:PORT (e.g. tcp://127.0.0.1:5025)")
    return m["host"].strip("[]"), int(m["port"])


class RigBackend:
    """Run a plan on a rig server.

    Parameters
    ----------
    address : str
        ``tcp://HOST:PORT``.
    card : SpecimenCard or path
        The specimen on the rig (its L1 and L3 configure position and field limit).
    token : str, optional
        Presented with ``SYST:AUTH`` before anything else.
    timeout : float
        Seconds to wait for any reply before calling the connection lost.
    stall_timeout : float
        Seconds of wall time without a new sample, while the rig says it is
        running, before the run is aborted as stalled.
    poll : float
        Seconds between polls when no sample is ready.
    seed : int
        Sent as ``CONF:SEED`` (the emulator draws its noise from it; recorded).
    trust_card : bool
        Run although the rig's ``*IDN?`` names another specimen than the card.
    geometry : RollGeometry or StripGeometry, optional
        The card's geometry, as the run's preparation made it (`rdea_lab.runs.app.RunSetup.geometry`): its
        ``L1`` [m] and ``L3`` [m] configure the rig (``CONF:LENG``, ``CONF:THIC``); made from ``card`` at
        the start when not given (a driver built by hand).
    """

    name = "rig"
    extra_variables = ()

    def __init__(self, address, card, *, token=None, timeout=5.0, stall_timeout=5.0, poll=0.02, seed=0,
                 trust_card=False, clock=_time.monotonic, sleep=_time.sleep, geometry=None):
        self.address = address
        self.host, self.port = parse_address(address)
        from ..specs import as_specimen

        self.card = as_specimen(card)
        self.geom = geometry
        self.token = token
        self.trust_card = bool(trust_card)
        #: what the identity check found (recorded as the dataset's ``rig_identity``)
        self.identity = ""
        self.timeout = timeout
        self.stall_timeout = stall_timeout
        self.poll = poll
        self.seed = int(seed)
        self._clock, self._sleep = clock, sleep
        self._inst = None
        self._rm = None
        self.idn = ""
        self.truth = ""
        self._rows = 1000
        self._columns = COLUMNS
        self._done = False
        self._lost = None
        self.aborted = None
        #: whether a command that changes the rig (``*RST`` onward) has been sent: until then a failure
        #: sends nothing, not even ``ABOR`` (which any connection may send: it would stop another's run)
        self._touched = False
        #: whether the rig armed the run pausable (it took ``CONF:PAUS``)
        self.pausable = False
        #: why the run was last paused (`pause`'s reason), "" when it never was
        self.pause_reason = ""
        self._conditions: dict | None = None
        self._conditions_at = -math.inf
        # one command and its reply at a time, from whichever thread (the engine may ask to pause or read the
        # conditions from another thread than the one reading blocks); ABOR takes no lock (abort)
        self._io = threading.RLock()

    # -- plumbing ---------------------------------------------------------
    def _open(self):
        import pyvisa

        self._rm = pyvisa.ResourceManager("@py")
        try:
            self._inst = self._rm.open_resource(f"TCPIP::{self.host}::{self.port}::SOCKET", read_termination="\n",
                                                write_termination="\n", timeout=int(self.timeout * 1000))
        except Exception as exc:
            raise RigRefused(f"rig {self.address}: cannot connect ({type(exc).__name__}: {exc})") from None

    def _query(self, command: str) -> str:
        try:
            with self._io:
                return self._inst.query(command).strip()
        except Exception as exc:
            raise ConnectionLost(f"connection to the rig {self.address} lost during {command.split()[0]} "
                                 f"({type(exc).__name__})") from None

    def _command(self, command: str, refuse=True) -> None:
        reply = self._query(command)
        if reply != "OK":
            message = _error_text(reply)
            if refuse:
                raise RigRefused(f"rig {self.address} refused {command.split()[0]}: {message}")
            raise BackendFailure(f"rig {self.address}: {command.split()[0]} failed: {message}")

    def _upload(self, command: str, windows, n: int, crc: int) -> int:
        """Send a trajectory of `n` setpoints as one binary block, window by window (the plan is never held
        whole: the block's bytes go out as they are computed); returns `crc` continued over them."""
        size = 8 * n
        with self._io:
            try:
                self._inst.write_raw(f"{command} #{len(str(size))}{size}".encode("ascii"))
                for values in windows:
                    values = np.ascontiguousarray(values, "<f8")
                    crc = wire.checksum_more(crc, values)
                    self._inst.write_raw(values.tobytes())
                self._inst.write_raw(b"\n")
                reply = self._inst.read().strip()
            except Exception as exc:
                raise ConnectionLost(f"connection to the rig {self.address} lost during upload "
                                     f"({type(exc).__name__})") from None
        if reply != "OK":
            raise RigRefused(f"rig {self.address} refused {command}: {_error_text(reply)}")
        return crc

    def _authenticate(self) -> None:
        """With a token: the challenge-response of docs/rig-protocol.md (``SYST:AUTH?`` gives a nonce, the
        reply is its HMAC-SHA256 keyed with the token): the token never travels, and an answer overheard
        does not open another connection."""
        if self.token is None:
            return
        nonce = self._query("SYST:AUTH?")
        if nonce.startswith("ERR") or not wire.is_nonce(nonce):
            raise RigRefused(f"rig {self.address}: no nonce for SYST:AUTH (it replied {nonce[:80]!r}); "
                             "a server of an older protocol, or not a rig")
        self._command(wire.line("SYST:AUTH", wire.auth_response(self.token, nonce)))

    def _check_identity(self) -> None:
        """The rig's ``*IDN?`` serial names the specimen it holds (``-`` or empty: it does not know); one
        that names another than the card is refused before anything moves, unless `trust_card`."""
        parts = [p.strip() for p in self.idn.split(",")]
        serial = parts[2] if len(parts) >= 3 else ""
        if serial in ("", "-"):
            self.identity = "not checked: the rig does not name its specimen"
        elif serial == self.card.id:
            self.identity = f"checked: the rig holds {serial}"
        elif self.trust_card:
            self.identity = (f"overridden: the rig says it holds {serial[:80]!r}, the card {self.card.id!r} was "
                             "taken as right (--trust-card)")
        else:
            raise RigRefused(f"rig {self.address} holds specimen {serial[:80]!r} (*IDN?), the card is "
                             f"{self.card.id[:80]!r}: nothing sent to the rig; mount the card's specimen, give its "
                             "card, or --trust-card if the card is right")

    def _check_free(self) -> None:
        """Refuse a rig that another connection controls or runs, before the reset that would end its run:
        ``SYST:CTRL?`` says who controls it (an older server answers ERR: then ``STAT?`` alone)."""
        ctrl = self._query("SYST:CTRL?").upper()
        stat = self._query("STAT?")
        state = stat.split(",", 1)[0].strip().upper()
        if ctrl == "OTHER" or state in ("ARMED", "RUNNING"):
            found = f"{state} ({stat.split(',')[1] if stat.count(',') else '?'} samples acquired)" \
                if state in ("ARMED", "RUNNING") else f"{state}, controlled by another connection"
            raise RigRefused(f"rig {self.address} is busy: {found}; nothing sent to it, the other experiment "
                             "goes on. Wait for it to end (STAT?) or stop it with ABOR.")

    # -- Backend interface -------------------------------------------------
    def attrs(self) -> dict:
        """``rig_idn``, ``emulated`` (1 for the rdea-lab emulator, else 0; the sentence in ``comment``),
        CF's ``source`` and, for a remote rig only, ``rig_address``: a loopback address is the port
        of a rig started for one run (the built-in emulator), meaningless once it has gone."""
        out = {"rig_idn": self.idn}
        if self.identity:
            out["rig_identity"] = self.identity
        if not _loopback(self.host):
            out["rig_address"] = self.address
        if self.truth or wire.idn_model(self.idn) == wire.EMULATOR_MODEL:
            name = truth_name(self.truth) or "not given"
            out.update({"emulated": 1, "comment": "data from the rdea-lab rig emulator, not a physical rig",
                        "source": f"rdea-lab rig emulator (truth {name})"})
            if self.truth:
                out["emulator_truth"] = self.truth
        else:
            out.update({"emulated": 0, "source": f"physical rig {self.idn or self.address}"})
        return out

    def start(self, plan) -> None:
        try:
            self._start(plan)
        except BaseException as exc:
            if self._touched:
                self.abort(f"start failed: {type(exc).__name__}")  # ABOR, in case INIT reached the rig
            else:
                self.aborted = f"start failed: {type(exc).__name__}"  # nothing sent: the rig is as it was
            if isinstance(exc, ConnectionLost):  # a rig that does not answer is refused (exit 2)
                raise RigRefused(f"rig {self.address}: no answer before the run started ({exc})") from None
            raise

    def _start(self, plan) -> None:
        if plan.samples > wire.MAX_POINTS:  # refused before the rig is touched, not a broken pipe mid-upload
            raise RigRefused(f"rig {self.address}: the protocol '{plan.name}' has {plan.samples} samples; the rig "
                             f"protocol takes at most {wire.MAX_POINTS} setpoints per trajectory (shorten the "
                             "protocol or lower its sample_rate)")
        if self.geom is None:  # a driver built by hand: its card comes in here
            from ..physics.geometry import geometry_from_card

            self.geom = geometry_from_card(self.card)
        geom = self.geom
        self._open()
        self._authenticate()
        self.idn = self._query("*IDN?")
        if self.idn.startswith("ERR"):
            raise RigRefused(f"rig {self.address}: {_error_text(self.idn)}")
        self._check_identity()
        self._check_free()
        if wire.idn_model(self.idn) == wire.EMULATOR_MODEL:
            truth = self._query("SYST:TRUTH?")
            self.truth = "" if truth.startswith("ERR") else truth
        lim = plan.limits
        self._touched = True  # from here on the rig is ours: a failure sends ABOR
        limits = (lim.max_voltage, lim.max_stretch, lim.max_force, lim.max_field)  # in the order of wire.LIMITS
        for header, value in (("*RST", None), ("CONF:RATE", plan.sample_rate), ("CONF:MEAS", plan.measure),
                              ("CONF:LENG", geom.L1), ("CONF:THIC", geom.L3), ("CONF:SEED", self.seed),
                              *zip(wire.LIMITS, limits)):
            self._command(wire.line(header, value))
        pause = self._arm_pausable(plan)
        # rows gain a column, the amplifier current, when it is measured, and a last one, each sample's phase,
        # when the run is pausable (docs/rig-protocol.md)
        self._columns = wire.row_columns(plan.measure, paused=self.pausable)
        crc = wire.checksum_head(plan.sample_rate, limits, geom.L3, pause)
        for name in ("stretch", "voltage"):  # streamed window by window; the rig holds both (one block each)
            crc = self._upload(_TRAJECTORY[name], _setpoints(plan, name), plan.samples, crc)
        reply = self._query("ARM")
        if reply != "OK" and not reply.startswith("OK,"):
            raise RigRefused(f"rig {self.address} refused ARM: {_error_text(reply)}")
        if reply.startswith("OK,"):  # the rig says what it armed: it must be what was sent
            ours = f"{crc:08x}"
            if reply[3:].strip().lower() != ours:
                self._query("ABOR")
                raise RigRefused(f"rig {self.address} armed something else than was sent (checksum "
                                 f"{reply[3:].strip()}, ours {ours}): refused, ABOR sent")
        self._command("INIT", refuse=False)
        self._rows = max(1, int(plan.sample_rate))  # at most a second of samples per block
        self._last_new = self._clock()

    def _arm_pausable(self, plan) -> tuple | None:
        """Send ``CONF:PAUS`` (the plan's `PauseSpec`); the values sent, or None when the rig does not know the
        command (``ERR -113``: a server of an older protocol; the run goes on without pauses)."""
        from ..protocols.pause import pause_spec_of

        spec = pause_spec_of(plan)
        pause = (float(spec.ramp_rate), float(spec.hold_stretch or 0.0), float(spec.stretch_rate))
        reply = self._query(wire.line("CONF:PAUS", pause))
        if reply == "OK":
            self.pausable = True
            return pause
        if wire.error_code(reply) == wire.UNDEFINED_HEADER:
            self.pausable = False
            return None
        raise RigRefused(f"rig {self.address} refused CONF:PAUS: {_error_text(reply)}")

    def _fetch(self) -> np.ndarray:
        with self._io:
            try:
                data = self._inst.query_binary_values(f"FETC? {self._rows}", datatype="d", is_big_endian=False,
                                                      container=np.array)
            except Exception as exc:
                raise ConnectionLost(f"connection to the rig {self.address} lost while fetching samples "
                                     f"({type(exc).__name__})") from None
        width = len(self._columns)
        if data.size % width:
            raise BackendFailure(f"rig {self.address} sent {data.size} values, not whole rows of {width}")
        return data.reshape(-1, width)

    def read_block(self):
        if self._done or self.aborted is not None:
            return None
        while True:
            try:
                return self._next_block()
            except ConnectionLost as exc:
                if self._lost is not None or not self._reconnect():
                    raise BackendFailure(f"{exc}; could not reconnect, so samples the rig acquired after the "
                                         "last fetch are not in this dataset") from None
                self._lost = str(exc)  # reconnected: drain what the rig kept

    def _next_block(self):
        while True:
            rows = self._fetch()
            if rows.shape[0]:
                self._last_new = self._clock()
                self._conditions_at = -math.inf  # new samples: the next conditions() reads the rig again
                return {name: rows[:, j].copy() for j, name in enumerate(self._columns)}
            state, acquired, fetched, reason = _status(self._query("STAT?"))
            if state == "DONE" and fetched >= acquired:
                self._done = True
                if self._lost is not None:
                    raise BackendFailure(f"{self._lost}; reconnected and fetched all {acquired} samples")
                return None
            if state == "ABORTED" and fetched >= acquired:
                why = f"the rig aborted the run: {reason or 'no reason given'}"
                if self._lost is not None:
                    why = f"{self._lost}; reconnected and fetched all {acquired} samples the rig acquired; {why}"
                raise BackendFailure(why)
            if state not in ("RUNNING", "DONE", "ABORTED"):
                raise BackendFailure(f"rig {self.address} is {state} in the middle of a run")
            if self._clock() - self._last_new > self.stall_timeout:
                raise BackendFailure(f"the rig stalled: no new sample for {self.stall_timeout:g} s "
                                     f"({acquired} acquired, state {state})")
            self._sleep(self.poll)

    # -- pause, resume, conditions -------------------------------------------
    def pause(self, reason: str) -> None:
        """Ask the rig to pause the run (``PAUS``): from its next sample the voltage ramps to 0 at the protocol's
        rate and the stretch is held (or taken to its ``hold_stretch``); the run stays ``RUNNING`` and blocks go
        on coming (held samples, their ``paused`` flag set). Already pausing or held: nothing changes.

        Raises
        ------
        PauseRefused
            The rig refused (no run going, every plan sample driven) or cannot pause (an older server).
        """
        if not self.pausable:
            raise PauseRefused(f"rig {self.address} cannot pause this run: "
                               + ("it does not know CONF:PAUS (a server of an older protocol); the run goes on "
                                  "(ABOR stops it)" if self._inst is not None else "no run started"))
        reply = self._query("PAUS")
        if reply != "OK":
            raise PauseRefused(f"rig {self.address} refused PAUS: {_error_text(reply)}")
        self.pause_reason = str(reason)

    def resume(self) -> None:
        """Ask the rig to resume the paused run (``CONT``): back to the plan's setpoints at the pause (the
        stretch first, then the voltage), and on from the plan sample it would have driven next.

        Raises
        ------
        PauseRefused
            The rig refused: the run is not paused, or the door interlock is open.
        """
        if not self.pausable:
            raise PauseRefused(f"rig {self.address} cannot resume: this run cannot pause")
        reply = self._query("CONT")
        if reply != "OK":
            raise PauseRefused(f"rig {self.address} refused CONT: {_error_text(reply)}")

    def conditions(self) -> dict:
        """The rig's condition channels at its latest sample (``COND?``): ``interlock`` (``"open"`` or
        ``"closed"``), ``amplifier_temperature`` [K], ``force_offset_drift`` (the load cell's zero now minus at
        the run's start) [N]. Asked again once new samples came (a rig in virtual time runs faster than the
        wall clock) or `CONDITIONS_EVERY` s passed; meanwhile the last reading. An empty dict from a server of
        an older protocol (no ``COND?``).

        Raises
        ------
        BackendFailure
            A reply that is not a reading, or no connection (before `start`, after `close`).
        """
        if self._inst is None:
            raise BackendFailure(f"rig {self.address}: not connected (conditions are read during a run)")
        now = self._clock()
        if self._conditions is None or now - self._conditions_at >= CONDITIONS_EVERY:
            reply = self._query("COND?")
            reading = wire.read_conditions(reply)
            if reading is None:
                if wire.error_code(reply) != wire.UNDEFINED_HEADER:
                    raise BackendFailure(f"rig {self.address}: unreadable COND? reply {reply[:80]!r}")
                reading = {}
            self._conditions, self._conditions_at = reading, now
        return dict(self._conditions)

    def _reconnect(self, attempts=3, wait=0.5) -> bool:
        """Open a new connection to the same rig (no reset); True on success."""
        self.close()
        for _ in range(attempts):
            try:
                self._open()
                self._authenticate()
                self._query("*IDN?")
                return True
            except (RigRefused, BackendFailure):
                self.close()
                self._sleep(wait)
        return False

    def abort(self, reason: str) -> None:
        self.aborted = reason
        if self._inst is None:
            return
        try:
            self._inst.query("ABOR")
        except Exception:
            pass  # the connection is gone; the server aborts a run whose client is lost

    def close(self) -> None:
        """Close this driver's connection. Not the resource manager: pyvisa keeps one per process, shared by
        every driver in it, and closing it closes all their sessions (another run's connection included)."""
        try:
            if self._inst is not None:
                self._inst.close()
        except Exception:
            pass
        self._inst = self._rm = None


_TRAJECTORY = {"stretch": "TRAJ:STR", "voltage": "TRAJ:VOLT"}


def _setpoints(plan, name: str):
    """One channel of a plan, window by window (a plan-like object without windows: its whole array)."""
    held = plan.held() if hasattr(plan, "held") else {name: getattr(plan, name)}
    return (held[name],) if name in held else plan.rendered(name)


def _loopback(host: str) -> bool:
    """Whether ``host`` names this machine (``localhost``, 127.0.0.0/8, ``::1``)."""
    import ipaddress

    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


_error_text = wire.error_message


def _status(reply: str):
    status = wire.read_status(reply)
    if status is None:
        raise BackendFailure(f"unreadable rig status {reply!r}")
    return status


def truth_name(truth_json: str) -> str:
    try:
        return json.loads(truth_json).get("name", "")
    except (ValueError, AttributeError):
        return ""
