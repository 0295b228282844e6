"""The rig's state machine behind the command set of ``docs/rig-protocol.md``.

`RigController` executes one command at a time for a numbered session (a
connection) and returns the reply; it knows nothing of sockets. One run at a
time: from ``ARM`` until the run ends, only the session that armed it may
send commands that change or consume anything; the others may ask
``*IDN?``, ``STAT?``, ``LIM?``, ``CONF:RATE?``, ``CONF:MEAS?``,
``TRAJ:POIN?``, ``SYST:ERR?`` and ``SYST:TRUTH?``.

Time is virtual by default: samples are produced when ``FETC?`` asks for them.
With ``realtime=True`` only samples with ``t <=`` the wall time since ``INIT``
exist, and a thread produces them (so limits abort a run even when nobody
fetches).
"""

from __future__ import annotations

import collections
import math
import re
import secrets
import threading
import time

import numpy as np

from .._version import __version__
from ..physics import viscoelastic
from ..specs.truth import truth_json
from ..specs.rigwire import FramingError, RigError, armed_checksum, decode_block, encode_block
from .rig import BLOCK, EmulatedRig, RunConfig, limit_violation

#: Faults that can be injected, each at a run time [s].
FAULTS = ("disconnect", "breakdown", "stall")
STATES = ("IDLE", "ARMED", "RUNNING", "DONE", "ABORTED")
MIN_RATE, MAX_RATE = 1.0, 100e3
#: Most rows one ``FETC?`` returns.
MAX_FETCH = 1_000_000
#: Longest the rig computes samples while holding its lock [s]: a ``FETC?`` returns the rows made by then
#: (fewer than asked; the client asks again), the realtime producer goes on at its next turn. So no
#: command, heartbeat or status waits longer than this (and a block) for the lock; ``ABOR`` waits for none.
PRODUCE_SLICE = 0.1
#: Longest ``STAT?`` waits for the lock before it answers from what it can read without it [s].
STAT_WAIT = 0.02
MAX_POINTS = 10_000_000
_ERRORS_KEPT = 20
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_CHANNELS = {"FORC": "force", "CAP": "capacitance", "CUR": "current"}
_LIMITS = (("volt", "LIM:VOLT <V>"), ("str", "LIM:STR <max>"), ("forc", "LIM:FORC <N>"),
           ("fiel", "LIM:FIEL <V/m>"))


class CloseConnection(Exception):
    """The session's connection is to be closed without a reply (injected disconnect)."""


def check_faults(faults) -> dict[str, float]:
    """``[("stall", 3.0), ...]`` -> ``{"stall": 3.0}``; ValueError naming the bad item."""
    out: dict[str, float] = {}
    for item in faults:
        try:
            kind, at = item
            at = float(at)
        except (TypeError, ValueError):
            raise ValueError(f"fault {item!r} is not (kind, seconds); kinds: {', '.join(FAULTS)}") from None
        if kind not in FAULTS:
            raise ValueError(f"unknown fault {kind!r}; allowed: {', '.join(FAULTS)}")
        if not (math.isfinite(at) and at >= 0.0):
            raise ValueError(f"fault {kind} at {at!r} s: the time must be a finite number of seconds >= 0")
        if kind in out:
            raise ValueError(f"fault {kind} given twice")
        out[kind] = at
    return out


def _clean(text: str) -> str:
    """One line without double quotes (they delimit the message in replies)."""
    return " ".join(str(text).replace('"', "'").split())


def _number(arg: str, what: str) -> float:
    text = arg.strip()
    if not text:
        raise RigError(-109, f"missing parameter: {what}")
    if not _NUMBER.fullmatch(text):
        raise RigError(-104, f"{text!r} is not a plain decimal number ({what})")
    return float(text)


def _in_range(value: float, ok: bool, message: str) -> float:
    if not (ok and math.isfinite(value)):
        raise RigError(-222, message)
    return value


class RigController:
    """State machine of one emulated rig (see the module docstring).

    Parameters
    ----------
    card : SpecimenCard
    truth : TruthSpec
    realtime : bool
        Pace the run at wall-clock speed (a producer thread) instead of
        producing samples when they are fetched.
    faults : sequence of (str, float)
        ``("disconnect" | "breakdown" | "stall", run time [s])``.
    truth_source : str, optional
        Where the truth came from, for error messages.
    close_session : callable, optional
        ``close_session(session)`` closes a session's connection (used by the
        realtime ``disconnect`` fault).
    clock : callable
        Wall clock [s] for ``realtime`` and the heartbeat.
    limits : Limits, optional
        The rig's own hard limits (``max_voltage``, ``max_stretch``,
        ``max_force``, ``max_field``); no client command can raise them, a
        client's ``LIM:*`` can only lower them. Default: `rdea_lab.specs.Limits()`
        (3 kV, stretch 2, 50 N, 80 V/um). The field is checked with the rig's
        own specimen thickness, whatever ``CONF:THIC`` says.
    heartbeat : float
        Seconds a run may go without a command from its controlling
        connection before the rig aborts it (voltage to zero) [s].
    """

    def __init__(self, card, truth, *, realtime=False, faults=(), truth_source=None, close_session=None,
                 clock=time.monotonic, limits=None, heartbeat=10.0):
        from ..physics.geometry import geometry_from_card
        from ..specs import Limits

        self.card, self.truth, self.truth_source = card, truth, truth_source
        viscoelastic.prepare(truth.material.law)  # before any client waits on a reply
        hard = limits if limits is not None else Limits()
        self.hard_limits = {"volt": float(hard.max_voltage), "str": float(hard.max_stretch),
                            "forc": float(hard.max_force), "fiel": float(hard.max_field)}
        self.thickness = float(geometry_from_card(card).L3)  # the rig's own, for the field limit
        if not (isinstance(heartbeat, (int, float)) and 0.1 <= heartbeat <= 3600):
            raise ValueError(f"heartbeat {heartbeat!r} s; allowed: 0.1 to 3600 s")
        self.heartbeat = float(heartbeat)
        self._last_heard = clock()
        self._watchdog: threading.Thread | None = None
        self.realtime = bool(realtime)
        self.faults = check_faults(faults)
        self.idn = f"rdea-lab,rig-emulator,{card.id},{__version__}"
        self._truth_json = truth_json(truth)
        self._close_session = close_session or (lambda session: None)
        self._doomed = None  # the session an injected realtime disconnect closes at its next command
        self._clock = clock
        self._lock = threading.RLock()
        self._tripped: str | None = None  # an emergency stop not yet booked under the lock (see emergency_stop)
        self._trip_lock = threading.Lock()  # held for a few statements only, never while computing
        self._errors: dict[object, collections.deque] = {}
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._commands = {
            "*IDN?": (self._idn, False), "SYST:AUTH": (self._auth, False), "SYST:ERR?": (self._err, False),
            "SYST:TRUTH?": (self._truth, False), "*RST": (self._rst, True),
            "CONF:RATE": (self._conf_rate, True), "CONF:RATE?": (self._conf_rate_q, False),
            "CONF:MEAS": (self._conf_meas, True), "CONF:MEAS?": (self._conf_meas_q, False),
            "CONF:LENG": (self._conf_leng, True), "CONF:THIC": (self._conf_thic, True),
            "CONF:SEED": (self._conf_seed, True), "CONF:SEED?": (self._conf_seed_q, False),
            "LIM:VOLT": (self._lim("volt"), True), "LIM:STR": (self._lim("str"), True),
            "LIM:FORC": (self._lim("forc"), True), "LIM:FIEL": (self._lim("fiel"), True),
            "LIM?": (self._lim_q, False), "TRAJ:STR": (self._traj("str"), True),
            "TRAJ:VOLT": (self._traj("volt"), True), "TRAJ:POIN?": (self._traj_poin, False),
            "ARM": (self._arm, True), "INIT": (self._init, True), "STAT?": (self._stat, False),
            "FETC?": (self._fetch, True), "ABOR": (self._abor, False), "SYST:REL": (self._release, True),
            "SYST:BEAT": (self._beat, False), "SYST:CTRL?": (self._ctrl, False), "SYST:AUTH?": (self._nonce, False),
        }
        #: commands any connection may send, whoever controls the rig: queries and the emergency stops
        self._anyone = {h for h, (_, controls) in self._commands.items() if not controls} | {"*RST"}
        self._clear()

    # ------------------------------------------------------------- state
    def _clear(self) -> None:
        self.rate: float | None = None
        self.measure: tuple = ("force",)
        self.L1: float | None = None
        self.L3: float | None = None
        self.seed = 0
        self.limits: dict[str, float | None] = {key: None for key, _ in _LIMITS}
        self.trajectories: dict[str, np.ndarray | None] = {"str": None, "volt": None}
        self.state = "IDLE"
        self.reason = ""
        self.owner = None
        self._armed: RunConfig | None = None
        self.run: EmulatedRig | None = None
        self._rows: collections.deque = collections.deque()
        self._buffered = 0
        self.fetched = 0
        self._t0 = 0.0
        self._disconnect_fired = False

    @property
    def acquired(self) -> int:
        return self.run.acquired if self.run is not None else 0

    @property
    def voltage_on(self) -> bool:
        """True while a run drives the specimen (the amplifier may be on); False from the instant of an
        emergency stop, before its bookkeeping."""
        run = self.run
        return run is not None and run.running and not run.interlocked and self._tripped is None

    # -------------------------------------------------- emergency stop
    def emergency_stop(self, reason: str = "aborted by ABOR") -> None:
        """Voltage off now, whatever else the rig is doing: never waits for the lock.

        The amplifier's interlock opens first (`EmulatedRig.interlock`: no sample is made with the voltage
        on after it; a computation under way stops at its next block); the bookkeeping (state ``ABORTED``,
        the reason, the actuator back to its start) follows under the lock, by a thread of its own, and
        every command that takes the lock books it first.
        """
        with self._trip_lock:
            first = self._tripped is None
            if first:
                self._tripped = reason
            run = self.run
        if run is not None:
            run.interlock()
        self._stop.set()
        if first:  # one booking thread per stop, however many ABOR arrive before it is booked
            threading.Thread(target=self._book_trip, daemon=True, name="rig-emulator-estop").start()

    def _book_trip(self) -> None:
        with self._lock:
            self._take_trip()

    def _take_trip(self) -> None:
        """Book an emergency stop (under the lock): the run aborts, state ABORTED."""
        with self._trip_lock:
            reason, self._tripped = self._tripped, None
        if reason is not None:
            self._abort(reason)

    def _abort(self, reason: str) -> None:
        """Voltage to 0, actuator back to start; state ABORTED with `reason`."""
        if self.state == "RUNNING" and self.run is not None:
            self.run.abort(reason)
        if self.state in ("ARMED", "RUNNING"):
            self.state, self.reason = "ABORTED", reason
        self._stop.set()

    def _sync_state(self) -> None:
        if self.state == "RUNNING" and self.run is not None and not self.run.running:
            self.state = "DONE" if self.run.state == "done" else "ABORTED"
            self.reason = self.run.reason
            self._stop.set()  # the controlling connection keeps control for its next run

    # ------------------------------------------------------- production
    def _caps(self) -> int:
        """Samples that may exist at all: before a stall or an injected disconnect."""
        cap = self.run.n
        for kind in ("stall", "disconnect"):
            if kind in self.faults:
                cap = min(cap, self.run.samples_before(self.faults[kind]))
        return cap

    def _produce_to(self, target: int) -> None:
        """Samples up to `target` (within the faults' caps), for at most `PRODUCE_SLICE` s of computing."""
        target = min(target, self._caps())
        end = time.monotonic() + PRODUCE_SLICE
        while self.run.running and self.run.acquired < target and self._tripped is None:
            rows = self.run.produce(min(target - self.run.acquired, BLOCK))
            if rows.shape[0]:
                self._rows.append(rows)
                self._buffered += rows.shape[0]
            if time.monotonic() >= end:
                break
        self._take_trip()
        self._sync_state()

    def _disconnect_due(self, wanted: int) -> bool:
        """Whether the run has reached the injected disconnect (asked for a sample at t >= T)."""
        if "disconnect" not in self.faults or self._disconnect_fired or self.state != "RUNNING":
            return False
        cap = self.run.samples_before(self.faults["disconnect"])
        return cap < self.run.n and wanted > cap and self.run.acquired >= cap  # every sample before it made

    def _fire_disconnect(self) -> object:
        self._disconnect_fired = True
        session = self.owner
        self._abort("client disconnected")
        return session

    def _advance_realtime(self) -> None:
        if self.state != "RUNNING":
            return
        elapsed = self._clock() - self._t0
        wanted = self.run.samples_until(elapsed)
        self._produce_to(wanted)
        if self._disconnect_due(wanted):
            # the line drops between two commands of the controlling connection, never under a reply
            # already taken from the buffer (closing the socket from here raced with the handler sending
            # a FETC? reply: its rows were counted fetched and lost): an idle connection is closed now
            # (close_session leaves a busy one alone), a busy one at its next command
            self._doomed = self._fire_disconnect()
            self._close_session(self._doomed)

    def _producer(self, stop: threading.Event) -> None:
        while not stop.is_set():
            with self._lock:
                if stop.is_set():
                    break
                self._advance_realtime()
                if self.state != "RUNNING":
                    break
            stop.wait(0.02)

    def _stop_producer(self) -> None:
        """Stop and join the producer thread; never call it holding the lock."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join()

    # --------------------------------------------------------- commands
    def execute(self, session, text: str, block: bytes | None = None) -> str | bytes:
        """Execute one command for `session`; the reply without its newline.

        Raises
        ------
        CloseConnection
            The session's connection is to be closed (injected disconnect).
        """
        header, _, arg = text.strip().partition(" ")
        header = header.upper()
        try:
            try:
                handler, controls = self._commands[header]
            except KeyError:
                if not header:
                    raise RigError(-102, "syntax error: a block without a command") from None
                raise RigError(-113, f"undefined header {header[:40]!r}; see docs/rig-protocol.md") from None
            if block is not None and header not in ("TRAJ:STR", "TRAJ:VOLT"):
                raise RigError(-108, f"parameter not allowed: {header} takes no binary block")
            if header == "ABOR":  # the emergency stop: no lock, no wait (see emergency_stop)
                self._no_arg("ABOR", arg.strip())
                self.emergency_stop("aborted by ABOR")
                if session == self.owner:
                    self._last_heard = self._clock()
                return "OK"
            if header == "*RST":
                self.emergency_stop("*RST")  # the voltage off first; the reset under the lock below
            if header == "STAT?":  # a status that never waits long: from what can be read without the lock
                if not self._lock.acquire(timeout=STAT_WAIT):
                    self._no_arg("STAT?", arg.strip())
                    return self._status()
                self._lock.release()
            with self._lock:
                self._take_trip()
                if session is not None and session == self._doomed:  # the injected disconnect (realtime)
                    self._doomed = None
                    raise CloseConnection()
                if session == self.owner:
                    self._last_heard = self._clock()  # any command of the controlling connection is a heartbeat
                if header not in self._anyone:
                    if self.owner is not None and self.owner != session:
                        raise RigError(-200, f"another connection controls the rig ({self.state}); {header} "
                                             "refused (queries, ABOR and *RST are allowed to anyone)")
                    if self.owner is None:  # the first configuring command makes this the controlling connection
                        self.owner, self._last_heard = session, self._clock()
                return handler(session, arg.strip(), block)
        except (RigError, FramingError) as err:
            return self._error(session, err.code, err.message)
        except CloseConnection:
            raise
        except Exception as exc:  # a bug must not take the server down: report it
            return self._error(session, -100, f"{type(exc).__name__}: {exc}")

    def _error(self, session, code: int, message: str) -> str:
        message = _clean(message)
        queue = self._errors.setdefault(session, collections.deque())
        if len(queue) < _ERRORS_KEPT:
            queue.append((code, message))
        else:
            queue[-1] = (-350, "Queue overflow")
        return f'ERR {code},"{message}"'

    def session_closed(self, session) -> None:
        """A connection ended: a run it armed or drives aborts (voltage off), and it controls the rig no more."""
        with self._lock:
            self._errors.pop(session, None)
            if self.owner == session:
                if self.state in ("ARMED", "RUNNING"):
                    self._abort("client disconnected")
                self.owner = None
        self._stop_producer_if_ended()

    def _stop_producer_if_ended(self) -> None:
        if self._stop.is_set():
            self._stop_producer()

    def shutdown(self) -> None:
        """End of the server: abort anything running (voltage off) and stop the producer."""
        with self._lock:
            self._abort("server shut down")
        self._stop_producer()

    @staticmethod
    def _no_arg(header: str, arg: str) -> None:
        if arg:
            raise RigError(-108, f"parameter not allowed: {header} takes none, got {arg[:40]!r}")

    def _idn(self, session, arg, block):
        self._no_arg("*IDN?", arg)
        return self.idn

    def _auth(self, session, arg, block):
        return "OK"  # the token is checked by the server before the first command

    def _err(self, session, arg, block):
        self._no_arg("SYST:ERR?", arg)
        queue = self._errors.get(session)
        if not queue:
            return '0,"No error"'
        code, message = queue.popleft()
        return f'{code},"{message}"'

    def _truth(self, session, arg, block):
        self._no_arg("SYST:TRUTH?", arg)
        return self._truth_json

    def _rst(self, session, arg, block):
        self._no_arg("*RST", arg)
        self._abort("*RST")
        self._stop.set()  # the producer thread ends by itself (joining here, under the lock, would deadlock)
        owner = self.owner
        self._clear()
        if owner is not None and owner != session:  # an emergency stop from elsewhere: control is released
            self.owner = None
        else:
            self.owner = session
        return "OK"

    def _release(self, session, arg, block):
        self._no_arg("SYST:REL", arg)
        if self.state in ("ARMED", "RUNNING"):
            raise RigError(-221, f"settings conflict: SYST:REL while {self.state}; send ABOR first")
        self.owner = None
        return "OK"

    def _beat(self, session, arg, block):
        self._no_arg("SYST:BEAT", arg)
        return "OK"

    def _configurable(self, header: str) -> None:
        if self.state in ("ARMED", "RUNNING"):
            raise RigError(-221, f"settings conflict: {header} while {self.state}; send ABOR or *RST first")

    def _conf_rate(self, session, arg, block):
        self._configurable("CONF:RATE")
        value = _number(arg, "sample rate [Hz]")
        self.rate = _in_range(value, MIN_RATE <= value <= MAX_RATE,
                              f"sample rate {value:g} Hz is outside {MIN_RATE:g} Hz to {MAX_RATE:g} Hz")
        return "OK"

    def _conf_seed(self, session, arg, block):
        """The run's noise seed: the noise comes from (truth seed, run seed), so two runs
        with the same trajectory differ unless they are given the same seed."""
        self._configurable("CONF:SEED")
        try:
            value = int(arg)
        except ValueError:
            raise RigError(-104, f"data type error: seed {arg[:40]!r} is not an integer") from None
        self.seed = _in_range(value, 0 <= value < 2**63, f"seed {value} is outside 0 to 2**63 - 1")
        return "OK"

    def _conf_seed_q(self, session, arg, block):
        self._no_arg("CONF:SEED?", arg)
        return str(self.seed)

    def _conf_rate_q(self, session, arg, block):
        self._no_arg("CONF:RATE?", arg)
        return repr(self.rate) if self.rate is not None else "nan"

    def _conf_meas(self, session, arg, block):
        self._configurable("CONF:MEAS")
        names = [a.strip().upper() for a in arg.split(",")] if arg else []
        bad = [n for n in names if n not in _CHANNELS]
        if bad:
            raise RigError(-224, f"unknown channel {bad[0][:20]!r}; allowed: FORC, CAP (comma-separated)")
        if len(set(names)) != len(names):
            raise RigError(-224, f"channel listed twice in {arg!r}")
        self.measure = tuple(_CHANNELS[n] for n in names)
        return "OK"

    def _conf_meas_q(self, session, arg, block):
        self._no_arg("CONF:MEAS?", arg)
        back = {v: k for k, v in _CHANNELS.items()}
        return ",".join(back[m] for m in self.measure)

    def _conf_leng(self, session, arg, block):
        self._configurable("CONF:LENG")
        value = _number(arg, "specimen length L1 [m]")
        self.L1 = _in_range(value, value > 0, f"length {value:g} m must be > 0 m")
        return "OK"

    def _conf_thic(self, session, arg, block):
        self._configurable("CONF:THIC")
        value = _number(arg, "membrane thickness L3 [m]")
        self.L3 = _in_range(value, value > 0, f"thickness {value:g} m must be > 0 m")
        return "OK"

    def _lim(self, key: str):
        header = {"volt": "LIM:VOLT", "str": "LIM:STR", "forc": "LIM:FORC", "fiel": "LIM:FIEL"}[key]
        rules = {"volt": (lambda x: x > 0, "must be > 0 V"), "str": (lambda x: x >= 1, "must be >= 1"),
                 "forc": (lambda x: x > 0, "must be > 0 N"), "fiel": (lambda x: x > 0, "must be > 0 V/m")}
        ok, rule = rules[key]

        unit = {"volt": "V", "str": "", "forc": "N", "fiel": "V/m"}[key]

        def handler(session, arg, block):
            self._configurable(header)
            value = _number(arg, f"{header} limit")
            value = _in_range(value, ok(value), f"{header} {value:g} {rule}")
            hard = self.hard_limits[key]
            if value > hard * (1.0 + 1e-12):
                raise RigError(-222, f"{header} {value:g} {unit} is above the rig's own limit {hard:g} {unit}; "
                                     "a client can only lower it".replace("  ", " "))
            self.limits[key] = value
            return "OK"

        return handler

    def _lim_q(self, session, arg, block):
        """The limits in force: the client's where it set one, else the rig's own."""
        self._no_arg("LIM?", arg)
        return ",".join(repr(self.limits[k] if self.limits[k] is not None else self.hard_limits[k])
                        for k, _ in _LIMITS)

    def _traj(self, key: str):
        header = {"str": "TRAJ:STR", "volt": "TRAJ:VOLT"}[key]

        def handler(session, arg, block):
            self._configurable(header)
            if block is None:
                raise RigError(-104, f"{header} takes a definite-length binary block #<d><n><bytes> "
                                     "of little-endian float64")
            if arg:
                raise RigError(-102, f"syntax error: {arg[:40]!r} between {header} and its block")
            values = decode_block(block)
            if values.size > MAX_POINTS:
                raise RigError(-222, f"{values.size} setpoints; at most {MAX_POINTS}")
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise RigError(-224, f"{header} setpoint {int(bad[0])} is {values[bad[0]]!r}, not a finite number")
            self.trajectories[key] = values
            return "OK"

        return handler

    def _traj_poin(self, session, arg, block):
        self._no_arg("TRAJ:POIN?", arg)
        x = self.trajectories["str"]
        return str(0 if x is None else x.size)

    def _arm(self, session, arg, block):
        self._no_arg("ARM", arg)
        if self.state == "RUNNING":
            raise RigError(-221, "settings conflict: a run is RUNNING; send ABOR first")
        missing = [cmd for key, cmd in _LIMITS if self.limits[key] is None]
        if missing:
            raise RigError(-221, f"no limit in force for {', '.join(c.split()[0] for c in missing)}: "
                                 f"set {' and '.join(missing)} before ARM")
        lim = {k: min(self.limits[k], self.hard_limits[k]) for k, _ in _LIMITS}  # never above the rig's own
        for value, cmd in ((self.rate, "CONF:RATE <Hz>"), (self.L1, "CONF:LENG <m>"), (self.L3, "CONF:THIC <m>")):
            if value is None:
                raise RigError(-221, f"set {cmd} before ARM")
        x, v = self.trajectories["str"], self.trajectories["volt"]
        if x is None or v is None or x.size == 0:
            raise RigError(-221, "no trajectories: upload TRAJ:STR and TRAJ:VOLT before ARM")
        if x.size != v.size:
            raise RigError(-221, f"TRAJ:STR has {x.size} setpoints but TRAJ:VOLT {v.size}; need as many")
        # the field is checked with the thinner of the rig's own thickness and the client's: CONF:THIC
        # cannot talk the rig out of its field limit
        config = RunConfig(self.rate, x, v, L1=self.L1, L3=min(self.L3, self.thickness), max_voltage=lim["volt"],
                           max_stretch=lim["str"], max_force=lim["forc"], max_field=lim["fiel"],
                           measure=self.measure)
        problem = limit_violation(config)
        if problem:
            raise RigError(-222, problem)
        self._stop.set()
        self._armed, self.run, self.state, self.reason, self.owner = config, None, "ARMED", "", session
        self._rows.clear()
        self._buffered = self.fetched = 0
        self._disconnect_fired = False
        return f"OK,{armed_checksum(self.rate, [self.limits[k] for k, _ in _LIMITS], self.L3, x, v)}"

    def _init(self, session, arg, block):
        self._no_arg("INIT", arg)
        if self.state != "ARMED":
            raise RigError(-221, f"settings conflict: INIT needs an armed run, the rig is {self.state}; send ARM first")
        rng = np.random.default_rng([self.truth.seed, self.seed])
        self.run = EmulatedRig(self.card, self.truth, rng, self._armed, breakdown_at=self.faults.get("breakdown"),
                               truth_source=self.truth_source)
        self.state = "RUNNING"
        self._t0 = self._last_heard = self._clock()
        self._start_watchdog()
        if self.realtime:
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._producer, args=(self._stop,), daemon=True,
                                            name="rig-emulator-daq")
            self._thread.start()
        return "OK"

    def _start_watchdog(self) -> None:
        """A thread that aborts the run (voltage off) when its controlling connection falls silent."""
        if self._watchdog is not None and self._watchdog.is_alive():
            return

        def watch():  # without the lock: it trips the emergency stop, which waits for nothing
            while True:
                time.sleep(min(0.2, self.heartbeat / 4))
                if self.state != "RUNNING" or self._tripped is not None:
                    return
                silent = self._clock() - self._last_heard
                if silent > self.heartbeat:
                    self.emergency_stop(f"no command from the controlling connection for {silent:.3g} s "
                                        f"(heartbeat {self.heartbeat:g} s)")
                    return

        self._watchdog = threading.Thread(target=watch, daemon=True, name="rig-emulator-heartbeat")
        self._watchdog.start()

    def _stat(self, session, arg, block):
        self._no_arg("STAT?", arg)
        if self.realtime:
            self._advance_realtime()
        return self._status()

    def _status(self) -> str:
        """The ``STAT?`` reply; also without the lock (an emergency stop not yet booked reads ABORTED)."""
        state, reason, tripped = self.state, self.reason, self._tripped
        if tripped is not None and state in ("ARMED", "RUNNING"):
            state, reason = "ABORTED", tripped
        return f'{state},{self.acquired},{self.fetched},"{_clean(reason)}"'

    def _ctrl(self, session, arg, block):
        self._no_arg("SYST:CTRL?", arg)
        return "NONE" if self.owner is None else ("THIS" if self.owner == session else "OTHER")

    def _nonce(self, session, arg, block):
        self._no_arg("SYST:AUTH?", arg)  # the server answers it where a token is set; without one, any will do
        return secrets.token_hex(16)

    def _fetch(self, session, arg, block):
        text = arg.strip()
        if not text:
            raise RigError(-109, "missing parameter: FETC? <max rows>")
        if not text.isdigit():
            raise RigError(-104, f"{text[:40]!r} is not a number of rows (an integer >= 0)")
        wanted = min(int(text), MAX_FETCH)
        if self.run is None:
            return encode_block([])
        if self.realtime:
            self._advance_realtime()
            if session is not None and session == self._doomed:  # the disconnect fired: no rows taken
                self._doomed = None
                raise CloseConnection()
        elif self.state == "RUNNING" and self._buffered < wanted:
            target = self.run.acquired + wanted - self._buffered
            self._produce_to(target)
            if self._disconnect_due(target):
                self._fire_disconnect()
                raise CloseConnection()
        rows = self._pop(wanted)
        self.fetched += rows.shape[0]
        return encode_block(rows)

    def _pop(self, n: int) -> np.ndarray:
        out, got = [], 0
        while self._rows and got < n:
            head = self._rows[0]
            take = min(n - got, head.shape[0])
            out.append(head[:take])
            if take == head.shape[0]:
                self._rows.popleft()
            else:
                self._rows[0] = head[take:]
            got += take
        self._buffered -= got
        return np.concatenate(out) if out else np.empty((0, len(self.run.config.columns)))

    def _abor(self, session, arg, block):  # (execute serves ABOR itself, before the lock)
        self._no_arg("ABOR", arg)
        self.emergency_stop("aborted by ABOR")
        return "OK"


__all__ = ["FAULTS", "CloseConnection", "RigController", "RigError", "armed_checksum", "check_faults"]


_FAULT_TEXT = re.compile(r"^(?P<kind>[a-z]+)-at=(?P<at>.+)$")


def parse_fault(text, source: str = "command line", field: str = "--fault") -> tuple[str, float]:
    """``"stall-at=3"`` -> ``("stall", 3.0)``; a ``(kind, seconds)`` pair passes through checked.

    Raises
    ------
    SpecError
        Saying what is allowed.
    """
    from ..specs import SpecError

    allowed = ", ".join(f"{k}-at=SECONDS" for k in FAULTS)
    if not isinstance(text, str):
        try:
            return next(iter(check_faults([text]).items()))
        except ValueError as exc:
            raise SpecError(source, field, str(exc)) from None
    m = _FAULT_TEXT.match(text.strip())
    if not m or m["kind"] not in FAULTS:
        raise SpecError(source, field, f"{text!r} is not one of {allowed} (e.g. stall-at=3.0)")
    try:
        at = float(m["at"])
    except ValueError:
        raise SpecError(source, field, f"{text!r}: {m['at']!r} is not a number of seconds") from None
    if not (math.isfinite(at) and at >= 0.0):
        raise SpecError(source, field, f"{text!r}: the time must be a finite number of seconds >= 0")
    return m["kind"], at


def parse_faults(items, source: str = "command line", field: str = "--fault") -> list[tuple[str, float]]:
    """Several faults (texts or pairs), each kind at most once."""
    from ..specs import SpecError

    parsed = [parse_fault(f, source, field) for f in items]
    kinds = [k for k, _ in parsed]
    for kind in FAULTS:
        if kinds.count(kind) > 1:
            raise SpecError(source, field, f"{kind}-at given {kinds.count(kind)} times; give each kind at most once")
    try:
        check_faults(parsed)
    except ValueError as exc:
        raise SpecError(source, field, str(exc)) from None
    return parsed
