"""The rig's wire protocol (``docs/rig-protocol.md``), declared once for the driver and the emulator.

Every command is declared once in `COMMANDS`, in the manner of QCoDeS'
``add_parameter(name, unit=..., vals=...)``: its SCPI header (a query ends
in ``?``), the kind of its argument (none, a `Number` with its unit and
validator, an `Integer`, a `Count` of rows, `Channels`, a `Block` of
setpoints, free `Text`), who may send it (`BEFORE_AUTH`: any connection,
before authentication too; `ANYONE`: any authenticated connection;
`CONTROLLER`: the controlling connection only, and the first such command
makes a connection the controlling one) and whether it is a setting
(refused while a run is ``ARMED`` or ``RUNNING``). An argument's ``parse``
raises the `RigError` the rig replies.

Beside the commands: the columns of a ``FETC?`` row (`COLUMNS`), the
measured channels' codes, the definite-length blocks (`encode_block`,
`decode_block`), the CRC-32 of what ``ARM`` armed (`armed_checksum`), the
HMAC-SHA256 answer to a ``SYST:AUTH?`` nonce (`auth_response`), the error
codes and the ``ERR`` and ``STAT?`` replies (`error_reply`, `status_reply`
and their readers). The driver (`rdea_lab.backends.rig`) and the emulator
(`rdea_lab.emulator`) both import them from here; neither imports the other.
"""

from __future__ import annotations

import hashlib
import hmac
import math
import re
import secrets
import zlib
from dataclasses import dataclass
from typing import Callable

import numpy as np

# ------------------------------------------------------------------ error codes
#: Codes of ``ERR <code>,"<message>"`` (SCPI's where there is one).
COMMAND_ERROR = -100  # a command that could not be read or executed (too long, a failing handler)
INVALID_CHARACTER = -101
SYNTAX_ERROR = -102
DATA_TYPE_ERROR = -104
PARAMETER_NOT_ALLOWED = -108
MISSING_PARAMETER = -109
UNDEFINED_HEADER = -113
BLOCK_DATA_ERROR = -161
NOT_IN_CONTROL = -200  # another connection controls the rig
SETTINGS_CONFLICT = -221
DATA_OUT_OF_RANGE = -222
ILLEGAL_PARAMETER_VALUE = -224
TOKEN_REQUIRED = -300
TOO_MANY_CONNECTIONS = -310
QUEUE_OVERFLOW = -350


class RigError(Exception):
    """A command failed: replied as ``ERR <code>,"<message>"`` and queued."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code, self.message = code, message


class FramingError(Exception):
    """Malformed input; ``code`` and ``message`` make the ``ERR`` reply.

    ``fatal`` means the reader cannot find the next command again (a block
    header announcing more bytes than accepted): the connection is closed.
    """

    def __init__(self, code: int, message: str, fatal: bool = False):
        super().__init__(message)
        self.code, self.message, self.fatal = code, message, fatal


def clean(text: str) -> str:
    """One line without double quotes (they delimit the message in replies)."""
    return " ".join(str(text).replace('"', "'").split())


def error_reply(code: int, message: str) -> str:
    """``ERR <code>,"<message>"`` (the message as given: `clean` it first where it may hold quotes)."""
    return f'ERR {code},"{message}"'


def error_code(reply: str) -> int | None:
    """The code of an ``ERR`` reply; None when it is none."""
    m = re.match(r"^ERR\s*(-?\d+)", reply)
    return int(m[1]) if m else None


def error_message(reply: str) -> str:
    """The message of an ``ERR`` reply; the reply itself when it is none (``"no reply"`` when empty)."""
    m = re.match(r'^ERR\s*(-?\d+)\s*,\s*"(.*)"\s*$', reply)
    return m[2] if m else (reply or "no reply")


# ------------------------------------------------------------------ states and rows
STATES = ("IDLE", "ARMED", "RUNNING", "DONE", "ABORTED")

#: Columns of a sample row, in order (the rows of ``FETC?``).
COLUMNS = ("time", "stretch", "position", "voltage", "force", "capacitance", "stretch_setpoint",
           "voltage_setpoint")
#: The column a row gains when ``current`` is measured (after `COLUMNS`).
CURRENT_COLUMN = "current"
#: The last column of a row when the run was armed with ``CONF:PAUS``: the sample's phase (0 running,
#: 1 ramping down, 2 held, 3 ramping up; `rdea_lab.protocols.pause`), as a float.
PAUSED_COLUMN = "paused"
#: ``CONF:MEAS`` codes of the channels that can be measured.
CHANNEL_CODES = {"FORC": "force", "CAP": "capacitance", "CUR": "current"}
#: Channels that can be measured.
CHANNELS = tuple(CHANNEL_CODES.values())


def row_columns(measure, paused: bool = False) -> tuple:
    """The columns of a run's rows: `COLUMNS`, ``current`` when it is measured, ``paused`` last when the run
    was armed with ``CONF:PAUS`` (`paused`)."""
    return COLUMNS + ((CURRENT_COLUMN,) if "current" in measure else ()) + ((PAUSED_COLUMN,) if paused else ())


#: The replies of ``PAUS?`` (``<state>,<pauses so far>``), in the order of the phases they follow.
PAUSE_STATES = ("RUNNING", "PAUSING", "PAUSED", "RESUMING")


def read_pause(reply: str) -> tuple[str, int] | None:
    """``(state, pauses)`` of a ``PAUS?`` reply; None if it is not one."""
    m = re.match(r"^(RUNNING|PAUSING|PAUSED|RESUMING),(\d+)$", reply)
    return (m[1], int(m[2])) if m else None


#: The rig's condition channels (``COND?``) and their units: the door interlock (``open`` or ``closed``),
#: the high-voltage amplifier's temperature [K], the load cell's zero offset now minus at the run's start [N].
CONDITIONS = {"interlock": "", "amplifier_temperature": "K", "force_offset_drift": "N"}


def conditions_reply(reading: dict) -> str:
    """The ``COND?`` reply ``interlock=closed,amplifier_temperature=308.15,force_offset_drift=0.0``."""
    return ",".join(f"{k}={reading[k]}" if k == "interlock" else f"{k}={float(reading[k])!r}" for k in CONDITIONS)


def read_conditions(reply: str) -> dict | None:
    """The channels of a ``COND?`` reply (``interlock`` a str, the others floats in SI); None if it is not one."""
    out = {}
    for part in reply.split(","):
        key, eq, value = part.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or key not in CONDITIONS or key in out:
            return None
        if key == "interlock":
            if value not in ("open", "closed"):
                return None
            out[key] = value
        else:
            try:
                out[key] = float(value)
            except ValueError:
                return None
    return out if out.keys() == CONDITIONS.keys() else None


def status_reply(state: str, acquired: int, fetched: int, reason: str) -> str:
    """The ``STAT?`` reply ``<state>,<acquired>,<fetched>,"<reason>"``."""
    return f'{state},{acquired},{fetched},"{clean(reason)}"'


def read_status(reply: str) -> tuple[str, int, int, str] | None:
    """``(state, acquired, fetched, reason)`` of a ``STAT?`` reply; None if it is not one."""
    m = re.match(r'^([A-Z]+),(\d+),(\d+),"(.*)"$', reply)
    return (m[1], int(m[2]), int(m[3]), m[4]) if m else None


#: The ``*IDN?`` model of the rdea-lab emulator (``rdea-lab,<model>,<serial>,<version>``).
EMULATOR_MODEL = "rig-emulator"


def idn_model(idn: str) -> str:
    """The model field of an ``*IDN?`` reply (empty when there is none)."""
    return (idn.split(",")[1:2] or [""])[0]


# ------------------------------------------------------------------ blocks, checksum, authentication
def encode_block(values) -> bytes:
    """Values as a definite-length block of little-endian float64 (``#10`` if empty)."""
    data = np.ascontiguousarray(values, dtype="<f8").tobytes()
    size = str(len(data))
    return f"#{len(size)}{size}".encode("ascii") + data


def decode_block(payload: bytes) -> np.ndarray:
    """The float64 values of a block's payload; FramingError if not whole values."""
    if len(payload) % 8:
        raise FramingError(BLOCK_DATA_ERROR, f"block of {len(payload)} bytes is not a whole number of float64 "
                                             "values (8 bytes each)")
    return np.frombuffer(payload, dtype="<f8").astype(float)


def armed_checksum(rate, limits, thickness, stretch, voltage, pause=None) -> str:
    """CRC-32 (8 hex digits) of what the client configured and ARM armed: ``CONF:RATE``, the four
    ``LIM:*`` values (VOLT, STR, FORC, FIEL), ``CONF:THIC``, the three ``CONF:PAUS`` values when it was
    given (`pause`: ramp rate, hold stretch or 0, stretch rate) and both trajectories, each as
    little-endian float64, in that order. The driver computes the same from what it sent."""
    crc = checksum_more(checksum_head(rate, limits, thickness, pause), stretch)
    return f"{checksum_more(crc, voltage):08x}"


def checksum_head(rate, limits, thickness, pause=None) -> int:
    """The CRC-32 of `armed_checksum` after ``CONF:RATE``, the four ``LIM:*`` values, ``CONF:THIC`` and
    the ``CONF:PAUS`` values (when `pause` is given)."""
    return zlib.crc32(np.array([rate, *limits, thickness, *(pause or ())], "<f8").tobytes())


def checksum_more(crc: int, values) -> int:
    """`crc` continued over `values` as little-endian float64 (a trajectory, or one window of it after
    the previous ones: the CRC of the whole is the same)."""
    return zlib.crc32(np.ascontiguousarray(values, "<f8"), crc)


def new_nonce() -> str:
    """A fresh ``SYST:AUTH?`` nonce: 32 lowercase hex digits."""
    return secrets.token_hex(16)


def is_nonce(text: str) -> bool:
    """Whether `text` is a nonce as `new_nonce` makes them."""
    return len(text) == 32 and all(c in "0123456789abcdef" for c in text)


def auth_response(token: str, nonce: str) -> str:
    """The answer to the nonce of ``SYST:AUTH?``: HMAC-SHA256 of the nonce (ASCII) keyed with the token
    (ASCII), in lowercase hex. The token itself never travels."""
    return hmac.new(token.encode("ascii"), nonce.encode("ascii"), hashlib.sha256).hexdigest()


# ------------------------------------------------------------------ validators
@dataclass(frozen=True)
class Range:
    """``low <= x <= high`` (and finite); `rule` reads ``1 Hz to 100000 Hz``."""

    low: float
    high: float

    def __call__(self, x) -> bool:
        return self.low <= x <= self.high

    def rule(self, unit: str) -> str:
        return f"{self.low:g} {unit} to {self.high:g} {unit}".replace("  ", " ").strip()


@dataclass(frozen=True)
class Above:
    """``x > low`` (and finite); `rule` reads ``> 0 m``."""

    low: float

    def __call__(self, x) -> bool:
        return x > self.low

    def rule(self, unit: str) -> str:
        return f"> {self.low:g} {unit}".strip()


@dataclass(frozen=True)
class AtLeast:
    """``x >= low`` (and finite); `rule` reads ``>= 1``."""

    low: float

    def __call__(self, x) -> bool:
        return x >= self.low

    def rule(self, unit: str) -> str:
        return f">= {self.low:g} {unit}".strip()


# ------------------------------------------------------------------ argument kinds
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


@dataclass(frozen=True)
class NoArg:
    """A command without an argument."""

    placeholder = ""

    def parse(self, header: str, text: str, block: bytes | None) -> None:
        if text:
            raise RigError(PARAMETER_NOT_ALLOWED, f"parameter not allowed: {header} takes none, got {text[:40]!r}")


@dataclass(frozen=True)
class Text:
    """Free text, passed on as it is (``SYST:AUTH <mac>``: the server checks it)."""

    placeholder: str

    def parse(self, header: str, text: str, block: bytes | None) -> str:
        return text


@dataclass(frozen=True)
class Number:
    """A plain decimal in SI `unit`, accepted when finite and ``vals(x)``.

    `what` names it in the parse errors (``missing parameter: <what>``); `refusal` is the out-of-range
    message, formatted with ``value`` and ``rule`` (the validator's bound in words).
    """

    what: str
    unit: str
    vals: Callable[[float], bool]
    refusal: str
    placeholder: str = ""

    def __post_init__(self):
        if not self.placeholder:
            object.__setattr__(self, "placeholder", self.unit)

    def parse(self, header: str, text: str, block: bytes | None) -> float:
        text = text.strip()
        if not text:
            raise RigError(MISSING_PARAMETER, f"missing parameter: {self.what}")
        if not _NUMBER.fullmatch(text):
            raise RigError(DATA_TYPE_ERROR, f"{text!r} is not a plain decimal number ({self.what})")
        value = float(text)
        if not (self.vals(value) and math.isfinite(value)):
            raise RigError(DATA_OUT_OF_RANGE, self.refusal.format(value=value, rule=self.vals.rule(self.unit)))
        return value


@dataclass(frozen=True)
class Integer:
    """A Python integer literal (``int(text)``), accepted when ``vals(n)``."""

    what: str
    vals: Callable[[int], bool]
    refusal: str
    placeholder: str = "n"

    def parse(self, header: str, text: str, block: bytes | None) -> int:
        try:
            value = int(text)
        except ValueError:
            raise RigError(DATA_TYPE_ERROR, f"data type error: {self.what} {text[:40]!r} is not an integer") from None
        if not self.vals(value):
            raise RigError(DATA_OUT_OF_RANGE, self.refusal.format(value=value))
        return value


@dataclass(frozen=True)
class Count:
    """A number of rows: decimal digits only."""

    placeholder: str

    def parse(self, header: str, text: str, block: bytes | None) -> int:
        text = text.strip()
        if not text:
            raise RigError(MISSING_PARAMETER, f"missing parameter: {header} <{self.placeholder}>")
        if not text.isdigit():
            raise RigError(DATA_TYPE_ERROR, f"{text[:40]!r} is not a number of rows (an integer >= 0)")
        return int(text)


@dataclass(frozen=True)
class Channels:
    """A comma-separated list of `CHANNEL_CODES` (case-insensitive, each at most once; empty: none)."""

    placeholder = "list"

    def parse(self, header: str, text: str, block: bytes | None) -> tuple:
        names = [a.strip().upper() for a in text.split(",")] if text else []
        bad = [n for n in names if n not in CHANNEL_CODES]
        if bad:
            raise RigError(ILLEGAL_PARAMETER_VALUE,
                           f"unknown channel {bad[0][:20]!r}; allowed: FORC, CAP (comma-separated)")
        if len(set(names)) != len(names):
            raise RigError(ILLEGAL_PARAMETER_VALUE, f"channel listed twice in {text!r}")
        return tuple(CHANNEL_CODES[n] for n in names)


@dataclass(frozen=True)
class PauseArgs:
    """``CONF:PAUS <ramp_rate>,<hold_stretch>,<stretch_rate>``: three plain decimals, the voltage ramp rate
    [V/s] > 0, the stretch held while paused (0: where it is; else >= 1) and the stretch rate to and from
    it [1/s] > 0. Parsed as a tuple of three floats."""

    placeholder = "V/s>,<hold_stretch or 0>,<1/s"

    def parse(self, header: str, text: str, block: bytes | None) -> tuple:
        parts = [p.strip() for p in text.split(",")] if text.strip() else []
        if len(parts) != 3:
            raise RigError(MISSING_PARAMETER, f"{header} takes three numbers <ramp_rate V/s>,<hold_stretch or 0>,"
                                              f"<stretch_rate 1/s>; got {len(parts)}")
        bad = [p for p in parts if not _NUMBER.fullmatch(p)]
        if bad:
            raise RigError(DATA_TYPE_ERROR, f"{bad[0][:40]!r} is not a plain decimal number ({header})")
        ramp_rate, hold, stretch_rate = (float(p) for p in parts)
        for name, value, unit in (("ramp_rate", ramp_rate, "V/s"), ("stretch_rate", stretch_rate, "1/s")):
            if not (math.isfinite(value) and value > 0.0):
                raise RigError(DATA_OUT_OF_RANGE, f"{header} {name} {value:g} {unit} must be > 0")
        if not (math.isfinite(hold) and (hold == 0.0 or hold >= 1.0)):
            raise RigError(DATA_OUT_OF_RANGE, f"{header} hold_stretch {hold:g} must be 0 (hold where it is) or >= 1")
        return ramp_rate, hold, stretch_rate


#: Most setpoints one trajectory holds.
MAX_POINTS = 10_000_000


@dataclass(frozen=True)
class Block:
    """A definite-length block of finite float64 setpoints in `unit`, at most `MAX_POINTS`."""

    unit: str
    placeholder = "block"

    def parse(self, header: str, text: str, block: bytes | None) -> np.ndarray:
        if block is None:
            raise RigError(DATA_TYPE_ERROR, f"{header} takes a definite-length binary block #<d><n><bytes> "
                                            "of little-endian float64")
        if text:
            raise RigError(SYNTAX_ERROR, f"syntax error: {text[:40]!r} between {header} and its block")
        values = decode_block(block)
        if values.size > MAX_POINTS:
            raise RigError(DATA_OUT_OF_RANGE, f"{values.size} setpoints; at most {MAX_POINTS}")
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise RigError(ILLEGAL_PARAMETER_VALUE,
                           f"{header} setpoint {int(bad[0])} is {values[bad[0]]!r}, not a finite number")
        return values


# ------------------------------------------------------------------ the commands
BEFORE_AUTH = "before authentication"
ANYONE = "any connection"
CONTROLLER = "controller only"


@dataclass(frozen=True)
class Command:
    """One command of the rig protocol."""

    header: str
    arg: object
    access: str
    setting: bool = False
    doc: str = ""

    @property
    def query(self) -> bool:
        return self.header.endswith("?")

    @property
    def usage(self) -> str:
        """``CONF:RATE <Hz>``: the header and its argument's placeholder."""
        return f"{self.header} <{self.arg.placeholder}>" if self.arg.placeholder else self.header

    def line(self, value=None) -> str:
        """The command line that sends `value` (numbers as ``repr``, channels as their codes)."""
        if value is None:
            return self.header
        if isinstance(self.arg, Channels):
            codes = {name: code for code, name in CHANNEL_CODES.items()}
            return f"{self.header} {','.join(codes[m] for m in value)}"
        if isinstance(self.arg, Number):
            return f"{self.header} {value!r}"
        if isinstance(self.arg, PauseArgs):
            return f"{self.header} {','.join(repr(float(x)) for x in value)}"
        return f"{self.header} {value}"


MIN_RATE, MAX_RATE = 1.0, 100e3
_NONE = NoArg()


def _limit(header, unit, vals, placeholder=""):
    return Command(header, Number(f"{header} limit", unit, vals, f"{header} {{value:g}} must be {{rule}}",
                                  placeholder), CONTROLLER, setting=True)


COMMANDS: dict[str, Command] = {c.header: c for c in (
    Command("*IDN?", _NONE, ANYONE, doc="identify: rdea-lab,<model>,<serial>,<version>"),
    Command("SYST:AUTH?", _NONE, BEFORE_AUTH, doc="a fresh nonce, good for one answer"),
    Command("SYST:AUTH", Text("mac"), BEFORE_AUTH, doc="the HMAC-SHA256 of the nonce keyed with the token"),
    Command("SYST:CTRL?", _NONE, ANYONE, doc="who controls the rig: NONE, THIS or OTHER"),
    Command("SYST:ERR?", _NONE, ANYONE, doc="the oldest queued error"),
    Command("SYST:TRUTH?", _NONE, ANYONE, doc="the emulator's truth as one line of JSON"),
    Command("*RST", _NONE, ANYONE, doc="abort anything running and clear the rig"),
    Command("SYST:REL", _NONE, CONTROLLER, doc="give up control (not while ARMED or RUNNING)"),
    Command("SYST:BEAT", _NONE, ANYONE, doc="a heartbeat"),
    Command("CONF:RATE", Number("sample rate [Hz]", "Hz", Range(MIN_RATE, MAX_RATE),
                                "sample rate {value:g} Hz is outside {rule}"), CONTROLLER, setting=True),
    Command("CONF:RATE?", _NONE, ANYONE),
    Command("CONF:MEAS", Channels(), CONTROLLER, setting=True),
    Command("CONF:MEAS?", _NONE, ANYONE),
    Command("CONF:LENG", Number("specimen length L1 [m]", "m", Above(0.0), "length {value:g} m must be {rule}"),
            CONTROLLER, setting=True, doc="unstretched specimen length L1"),
    Command("CONF:THIC", Number("membrane thickness L3 [m]", "m", Above(0.0),
                                "thickness {value:g} m must be {rule}"),
            CONTROLLER, setting=True, doc="the single-membrane thickness L3 the client assumes"),
    Command("CONF:SEED", Integer("seed", lambda n: 0 <= n < 2**63, "seed {value} is outside 0 to 2**63 - 1"),
            CONTROLLER, setting=True, doc="the run's random seed"),
    Command("CONF:SEED?", _NONE, ANYONE),
    _limit("LIM:VOLT", "V", Above(0.0)),
    _limit("LIM:STR", "", AtLeast(1.0), placeholder="max"),
    _limit("LIM:FORC", "N", Above(0.0)),
    _limit("LIM:FIEL", "V/m", Above(0.0)),
    Command("LIM?", _NONE, ANYONE, doc="the limits in force: <volt>,<str>,<forc>,<fiel>"),
    Command("TRAJ:STR", Block(""), CONTROLLER, setting=True, doc="stretch setpoints"),
    Command("TRAJ:VOLT", Block("V"), CONTROLLER, setting=True, doc="voltage setpoints [V]"),
    Command("TRAJ:POIN?", _NONE, ANYONE, doc="setpoints loaded"),
    Command("ARM", _NONE, CONTROLLER, doc="check the trajectories against every limit; OK,<crc32>"),
    Command("INIT", _NONE, CONTROLLER, doc="start the armed run"),
    Command("STAT?", _NONE, ANYONE, doc='<state>,<acquired>,<fetched>,"<reason>"'),
    Command("FETC?", Count("max rows"), CONTROLLER, doc="up to <max> unfetched rows as a block"),
    Command("ABOR", _NONE, BEFORE_AUTH, doc="emergency stop: voltage to 0 first"),
    Command("CONF:PAUS", PauseArgs(), CONTROLLER, setting=True,
            doc="how this run pauses: <ramp_rate V/s>,<hold_stretch or 0>,<stretch_rate 1/s>"),
    Command("CONF:PAUS?", _NONE, ANYONE, doc="<ramp_rate>,<hold_stretch>,<stretch_rate>, or NONE"),
    Command("PAUS", _NONE, CONTROLLER, doc="pause the run: voltage to 0 at the CONF:PAUS rate, stretch held"),
    Command("CONT", _NONE, CONTROLLER, doc="resume a paused run (not while the door interlock is open)"),
    Command("PAUS?", _NONE, ANYONE, doc="RUNNING|PAUSING|PAUSED|RESUMING,<pauses so far>"),
    Command("COND?", _NONE, ANYONE, doc="interlock=open|closed,amplifier_temperature=<K>,force_offset_drift=<N>"),
)}

#: The ``LIM:*`` commands in the order of ``LIM?`` and of `armed_checksum`.
LIMITS = ("LIM:VOLT", "LIM:STR", "LIM:FORC", "LIM:FIEL")


def line(header: str, value=None) -> str:
    """The command line of `COMMANDS` ``[header]`` with `value` (KeyError for a header not declared)."""
    return COMMANDS[header].line(value)


__all__ = ["ANYONE", "BEFORE_AUTH", "CHANNELS", "CHANNEL_CODES", "COLUMNS", "COMMANDS", "CONDITIONS", "CONTROLLER",
           "CURRENT_COLUMN", "PAUSED_COLUMN", "PAUSE_STATES", "PauseArgs", "conditions_reply", "error_code",
           "read_conditions", "read_pause", "Command", "FramingError", "LIMITS", "RigError", "STATES", "armed_checksum",
           "auth_response", "clean", "decode_block", "encode_block", "error_message", "error_reply", "line",
           "read_status", "status_reply"]
