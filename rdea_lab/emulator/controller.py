"""The interpreter of the rig's command set (``docs/rig-protocol.md``), over `RigState`.

`RigController` executes one command at a time for a numbered session (a
connection) and returns the reply; it knows nothing of sockets. It looks the
header up in the protocol's table (`rdea_lab.specs.rigwire.COMMANDS`),
checks who sent it (only the controlling connection may send the commands
declared ``CONTROLLER``; the first such command makes a connection the
controlling one), refuses a setting while a run is armed, parses the
argument as declared, and calls the rig state (`rdea_lab.emulator.rigstate`)
under its lock; errors become ``ERR`` replies and are queued per session
for ``SYST:ERR?``. One run at a time: from ``ARM`` until the run ends, only
the session that armed it may send commands that change or consume
anything; the others may ask ``*IDN?``, ``STAT?``, ``LIM?``,
``CONF:RATE?``, ``CONF:MEAS?``, ``TRAJ:POIN?``, ``SYST:ERR?``,
``SYST:TRUTH?``, ``PAUS?`` and ``COND?``.

``ABOR`` never takes the lock (`RigState.emergency_stop`); ``STAT?`` waits
for it `STAT_WAIT` s at most, then answers from what it can read without it.
"""

from __future__ import annotations

import collections
import math
import re
import time

from .._version import __version__
from ..specs.rigwire import (CHANNEL_CODES, COMMAND_ERROR, COMMANDS, CONTROLLER, LIMITS, NOT_IN_CONTROL,
                             SYNTAX_ERROR, UNDEFINED_HEADER, PARAMETER_NOT_ALLOWED, QUEUE_OVERFLOW, Block,
                             FramingError, RigError, armed_checksum, clean, conditions_reply, encode_block,
                             error_reply, new_nonce, status_reply)
from ..specs.truth import truth_json
from .conditions import WINDOWED, Fault
from .rigstate import FAULTS, CloseConnection, RigState, check_faults

#: Most rows one ``FETC?`` returns.
MAX_FETCH = 1_000_000
#: Longest ``STAT?`` waits for the lock before it answers from what it can read without it [s].
STAT_WAIT = 0.02
_ERRORS_KEPT = 20


class RigController:
    """The interpreter of one emulated rig (see the module docstring).

    Parameters
    ----------
    card : SpecimenCard
    truth : TruthSpec
    realtime : bool
        Pace the run at wall-clock speed (a producer thread) instead of
        producing samples when they are fetched.
    faults : sequence
        ``(kind, run time [s])`` of `FAULTS`, or ``(kind, run time [s], duration [s])`` for the
        condition faults (``interlock``, ``overheat``, ``drift``; `rdea_lab.emulator.conditions`).
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
        connection before the rig aborts it (voltage off) [s].
    """

    def __init__(self, card, truth, *, realtime=False, faults=(), truth_source=None, close_session=None,
                 clock=time.monotonic, limits=None, heartbeat=10.0):
        self.rig = rig = RigState(card, truth, realtime=realtime, faults=faults, truth_source=truth_source,
                                  close_session=close_session, clock=clock, limits=limits, heartbeat=heartbeat)
        self.idn = f"rdea-lab,rig-emulator,{card.id},{__version__}"
        self._truth_json = truth_json(truth)
        self._errors: dict[object, collections.deque] = {}
        codes = {name: code for code, name in CHANNEL_CODES.items()}
        actions = {
            "*IDN?": lambda session, _: self.idn,
            "SYST:AUTH?": lambda session, _: new_nonce(),  # the server answers it where a token is set
            "SYST:AUTH": lambda session, _: "OK",  # the token is checked by the server before the first command
            "SYST:CTRL?": lambda session, _: "NONE" if rig.owner is None else (
                "THIS" if rig.owner == session else "OTHER"),
            "SYST:ERR?": lambda session, _: self._next_error(session),
            "SYST:TRUTH?": lambda session, _: self._truth_json,
            "*RST": lambda session, _: _ok(rig.reset(session)),
            "SYST:REL": lambda session, _: _ok(rig.release(session)),
            "SYST:BEAT": lambda session, _: "OK",
            "CONF:RATE?": lambda session, _: repr(rig.rate) if rig.rate is not None else "nan",
            "CONF:MEAS?": lambda session, _: ",".join(codes[m] for m in rig.measure),
            "CONF:SEED?": lambda session, _: str(rig.seed),
            "LIM?": lambda session, _: ",".join(repr(x) for x in rig.limits_in_force()),
            "TRAJ:POIN?": lambda session, _: str(_size(rig.trajectories["TRAJ:STR"])),
            "ARM": lambda session, _: f"OK,{rig.arm(session)}",
            "INIT": lambda session, _: _ok(rig.init()),
            "STAT?": lambda session, _: self._stat(),
            "FETC?": lambda session, rows: encode_block(rig.fetch(session, min(rows, MAX_FETCH))),
            "ABOR": lambda session, _: _ok(rig.emergency_stop("aborted by ABOR")),  # (execute serves ABOR itself)
            "CONF:PAUS?": lambda session, _: "NONE" if rig.pause is None else ",".join(repr(x) for x in rig.pause),
            "PAUS": lambda session, _: _ok(rig.pause_run()),
            "CONT": lambda session, _: _ok(rig.resume_run()),
            "PAUS?": lambda session, _: "{},{}".format(*rig.pause_status()),
            "COND?": lambda session, _: conditions_reply(rig.conditions()),
        }
        for header, name in (("CONF:RATE", "rate"), ("CONF:MEAS", "measure"), ("CONF:LENG", "L1"),
                             ("CONF:THIC", "L3"), ("CONF:SEED", "seed"), ("CONF:PAUS", "pause")):
            actions[header] = lambda session, value, name=name: _ok(rig.configure(name, value))
        for header in LIMITS:
            actions[header] = lambda session, value, header=header: _ok(rig.set_limit(header, value))
        for header in ("TRAJ:STR", "TRAJ:VOLT"):
            actions[header] = lambda session, value, header=header: _ok(rig.set_trajectory(header, value))
        assert actions.keys() == COMMANDS.keys(), set(actions) ^ set(COMMANDS)
        #: header -> (handler(session, arg, block), whether only the controlling connection may send it)
        self._commands = {h: (self._handler(COMMANDS[h], action), COMMANDS[h].access == CONTROLLER)
                          for h, action in actions.items()}
        #: commands any connection may send, whoever controls the rig: queries and the emergency stops
        self._anyone = {h for h, command in COMMANDS.items() if command.access != CONTROLLER}
        self._blocks = {h for h, command in COMMANDS.items() if isinstance(command.arg, Block)}

    def _handler(self, command, action):
        """The command's handler: a setting is refused while armed, the argument parsed as declared."""
        def handler(session, arg, block):
            if command.setting:
                self.rig.check_configurable(command.header)
            return action(session, command.arg.parse(command.header, arg, block))

        return handler

    # ----------------------------------------------- the rig state, read
    state = property(lambda self: self.rig.state, doc="``IDLE``, ``ARMED``, ``RUNNING``, ``DONE``, ``ABORTED``")
    reason = property(lambda self: self.rig.reason, doc="Why the last run ended (empty if it did not abort).")
    owner = property(lambda self: self.rig.owner, doc="The session that controls the rig, or None.")
    acquired = property(lambda self: self.rig.acquired, doc="Samples the run has acquired.")
    fetched = property(lambda self: self.rig.fetched, doc="Samples fetched of the run.")
    voltage_on = property(lambda self: self.rig.voltage_on,
                          doc="True while a run drives the specimen; False from the instant of an emergency stop.")

    def emergency_stop(self, reason: str = "aborted by ABOR") -> None:
        """Voltage off now, without waiting for the lock (`RigState.emergency_stop`)."""
        self.rig.emergency_stop(reason)

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
        rig = self.rig
        try:
            try:
                handler = self._commands[header][0]
            except KeyError:
                if not header:
                    raise RigError(SYNTAX_ERROR, "syntax error: a block without a command") from None
                raise RigError(UNDEFINED_HEADER, f"undefined header {header[:40]!r}; see docs/rig-protocol.md") \
                    from None
            if block is not None and header not in self._blocks:
                raise RigError(PARAMETER_NOT_ALLOWED, f"parameter not allowed: {header} takes no binary block")
            if header == "ABOR":  # the emergency stop: no lock, no wait (see RigState.emergency_stop)
                COMMANDS["ABOR"].arg.parse("ABOR", arg.strip(), None)
                rig.emergency_stop("aborted by ABOR")
                rig.heard(session)
                return "OK"
            if header == "*RST":
                rig.emergency_stop("*RST")  # the voltage off first; the reset under the lock below
            if header == "STAT?":  # a status that never waits long: from what can be read without the lock
                if not rig.lock.acquire(timeout=STAT_WAIT):
                    COMMANDS["STAT?"].arg.parse("STAT?", arg.strip(), None)
                    return status_reply(*rig.status())
                rig.lock.release()
            with rig.lock:
                rig.take_trip()
                if rig.doomed(session):  # the injected disconnect (realtime)
                    raise CloseConnection()
                rig.heard(session)  # any command of the controlling connection is a heartbeat
                if header not in self._anyone:
                    if rig.owner is not None and rig.owner != session:
                        raise RigError(NOT_IN_CONTROL, f"another connection controls the rig ({rig.state}); "
                                                       f"{header} refused (queries, ABOR and *RST are allowed "
                                                       "to anyone)")
                    if rig.owner is None:  # the first configuring command makes this the controlling connection
                        rig.take_control(session)
                with rig.answering(session):
                    return handler(session, arg.strip(), block)
        except (RigError, FramingError) as err:
            return self._error(session, err.code, err.message)
        except CloseConnection:
            raise
        except Exception as exc:  # a bug must not take the server down: report it
            return self._error(session, COMMAND_ERROR, f"{type(exc).__name__}: {exc}")

    def _stat(self) -> str:
        if self.rig.realtime:
            self.rig.advance_realtime()
        return status_reply(*self.rig.status())

    def _error(self, session, code: int, message: str) -> str:
        message = clean(message)
        queue = self._errors.setdefault(session, collections.deque())
        if len(queue) < _ERRORS_KEPT:
            queue.append((code, message))
        else:
            queue[-1] = (QUEUE_OVERFLOW, "Queue overflow")
        return error_reply(code, message)

    def _next_error(self, session) -> str:
        queue = self._errors.get(session)
        if not queue:
            return '0,"No error"'
        code, message = queue.popleft()
        return f'{code},"{message}"'

    def session_closed(self, session) -> None:
        """A connection ended: a run it armed or drives aborts (voltage off), and it controls the rig no more."""
        with self.rig.lock:
            self._errors.pop(session, None)
        self.rig.session_closed(session)

    def shutdown(self) -> None:
        """End of the server: abort anything running (voltage off) and stop the producer."""
        self.rig.shutdown()


def _ok(_) -> str:
    return "OK"


def _size(values) -> int:
    return 0 if values is None else values.size


__all__ = ["FAULTS", "CloseConnection", "Fault", "RigController", "RigError", "armed_checksum", "check_faults"]


_FAULT_TEXT = re.compile(r"^(?P<kind>[a-z]+)-at=(?P<at>[^:]+)(?::(?P<duration>.*))?$")


def parse_fault(text, source: str = "command line", field: str = "--fault") -> Fault:
    """``"stall-at=3"`` -> ``Fault("stall", 3.0)``, ``"interlock-at=5:2"`` -> ``Fault("interlock", 5.0, 2.0)``
    (the door open from run time 5 s for 2 s; without ``:2``, to the end of the run); a ``(kind, seconds)``
    pair or ``(kind, seconds, duration)`` triple passes through checked. A `Fault` unpacks as the pair
    ``(kind, seconds)``.

    Raises
    ------
    SpecError
        Saying what is allowed.
    """
    from ..specs import SpecError

    allowed = ", ".join(f"{k}-at=SECONDS" + ("[:DURATION]" if k in WINDOWED else "") for k in FAULTS)
    if not isinstance(text, str):
        try:
            return next(iter(check_faults([text]).values()))
        except ValueError as exc:
            raise SpecError(source, field, str(exc)) from None
    m = _FAULT_TEXT.match(text.strip())
    if not m or m["kind"] not in FAULTS:
        raise SpecError(source, field, f"{text!r} is not one of {allowed} (e.g. stall-at=3.0, interlock-at=5:2)")
    try:
        at = float(m["at"])
    except ValueError:
        raise SpecError(source, field, f"{text!r}: {m['at']!r} is not a number of seconds") from None
    if not (math.isfinite(at) and at >= 0.0):
        raise SpecError(source, field, f"{text!r}: the time must be a finite number of seconds >= 0")
    duration = None
    if m["duration"] is not None:
        if m["kind"] not in WINDOWED:
            raise SpecError(source, field, f"{text!r}: {m['kind']} takes no duration (only "
                                           f"{', '.join(WINDOWED)} do)")
        try:
            duration = float(m["duration"])
        except ValueError:
            raise SpecError(source, field, f"{text!r}: {m['duration']!r} is not a number of seconds") from None
        if not (math.isfinite(duration) and duration > 0.0):
            raise SpecError(source, field, f"{text!r}: the duration must be a finite number of seconds > 0")
    return Fault(m["kind"], at, duration)


def parse_faults(items, source: str = "command line", field: str = "--fault") -> list[Fault]:
    """Several faults (texts, pairs or triples), each kind at most once."""
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
