"""Suspenders: conditions on rig channels that pause a run, and resume it when they recover.

A protocol (or a campaign, for every one of its runs) may list them::

    suspend:
      - {name: door, when: interlock == open}
      - {name: hot, when: amplifier_temperature > 60 degC, resume: amplifier_temperature < 50 degC, wait: 30 min}
      - {when: "|force_offset_drift| > 5 mN"}

A condition is ``<channel> <op> <value>``, one comparison (no ``and``/``or``), read by a small
tokenizer (never evaluated as code). The channels (`SUSPEND_CHANNELS`):

- ``interlock``: ``open`` or ``closed``; only ``==`` and ``!=``.
- ``amplifier_temperature``: a temperature (``60 degC``, ``333 K``, ``140 degF``), kept in kelvin (degC is
  an offset unit: 60 degC is 333.15 K).
- ``force_offset_drift``: a force (``5 mN``), kept in newtons; compared signed as written, or by its
  magnitude when written between bars: ``|force_offset_drift| > 5 mN``.

The operators are ``>``, ``>=``, ``<``, ``<=``, ``==``, ``!=``. ``resume`` is a condition too (by default:
``when`` no longer holds); ``wait`` is the longest a run waits for it (default 10 min, at most 24 h) before it
is aborted. The state machine that acts on them is `rdea_lab.protocols.suspend`.
"""

from __future__ import annotations

import math
import numbers
import operator
import re
from collections.abc import Mapping
from typing import Annotated, Any, Iterator

from pydantic import AfterValidator, ValidationError, model_validator

from .base import Identifier, SpecModel, spec_error_from_validation, units_required
from .errors import DOCUMENT, SpecError, show
from .units import format_quantity, parse_quantity

#: The channels a condition may name: channel -> (dimension, display unit) for a quantity, or the values it
#: takes (``interlock``). Readings are SI: kelvin, newtons.
SUSPEND_CHANNELS: dict[str, tuple[str, str] | tuple[str, ...]] = {
    "interlock": ("open", "closed"),
    "amplifier_temperature": ("temperature", "degC"),
    "force_offset_drift": ("force", "mN"),
}
#: The comparisons, two-character ones first (the tokenizer's order).
OPERATORS = (">=", "<=", "==", "!=", ">", "<")
_COMPARE = {">": operator.gt, ">=": operator.ge, "<": operator.lt, "<=": operator.le, "==": operator.eq,
            "!=": operator.ne}
#: Channels whose values are words, compared only for (in)equality.
_STATES = {"interlock"}
#: The longest condition text (a condition is one comparison).
MAX_CONDITION = 200
#: Default and longest wait for a suspender's resume condition [s].
DEFAULT_WAIT, MAX_WAIT = 600.0, 86400.0

_TOKEN = re.compile(r"""
    (?P<space>\s+)
  | (?P<op>>=|<=|==|!=|>|<)
  | (?P<bar>\|)
  | (?P<number>[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<word>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<other>.)
""", re.VERBOSE | re.DOTALL)


def _tokens(text: str) -> Iterator[tuple[str, str, int]]:
    """``(kind, text, column)`` of each token of `text` (columns from 1), spaces left out."""
    for match in _TOKEN.finditer(text):
        if match.lastgroup != "space":
            yield match.lastgroup, match.group(), match.start() + 1


def _quantity_channels() -> str:
    return ", ".join(c for c in SUSPEND_CHANNELS if c not in _STATES)


class _Reader:
    """The parser of one condition text: its tokens, consumed left to right."""

    def __init__(self, text: str):
        self.text = text
        self.tokens = list(_tokens(text))
        self.i = 0

    def fail(self, column: int, message: str) -> SpecError:
        return SpecError("", "", f"at column {column} of {show(self.text)}: {message}")

    def peek(self) -> tuple[str, str, int]:
        return self.tokens[self.i] if self.i < len(self.tokens) else ("end", "", len(self.text) + 1)

    def take(self, kind: str, what: str) -> tuple[str, str, int]:
        token = self.peek()
        if token[0] != kind:
            got = "the end of the condition" if token[0] == "end" else show(token[1])
            raise self.fail(token[2], f"expected {what}, got {got}")
        self.i += 1
        return token


def _parse(text: str) -> dict:
    """The fields of a `Condition` from its text (see the module); `SpecError` naming the column."""
    if len(text) > MAX_CONDITION:
        raise SpecError("", "", f"a condition of {len(text)} characters; allowed: one comparison such as "
                        f"'interlock == open', at most {MAX_CONDITION} characters")
    r = _Reader(text)
    for kind, word, column in r.tokens:
        if kind == "word" and word.lower() in ("and", "or", "not"):
            raise r.fail(column, f"{show(word)} is not supported: a condition is one comparison; give one "
                         "suspender per condition")
    magnitude = r.peek()[0] == "bar"
    if magnitude:
        r.take("bar", "'|'")
    _, channel, column = r.take("word", f"a channel ({', '.join(SUSPEND_CHANNELS)})")
    if channel not in SUSPEND_CHANNELS:
        raise r.fail(column, f"unknown channel {show(channel)}; allowed: {', '.join(SUSPEND_CHANNELS)}")
    if magnitude:
        if channel in _STATES:
            raise r.fail(column, f"{channel} is {' or '.join(SUSPEND_CHANNELS[channel])}: it has no magnitude; "
                         f"|...| is for {_quantity_channels()}")
        r.take("bar", f"'|' closing |{channel}|")
    allowed_ops = ("==", "!=") if channel in _STATES else OPERATORS
    kind, op, column = r.peek()
    if kind != "op" or op not in allowed_ops:
        got = "the end of the condition" if kind == "end" else show(op)
        why = f"{channel} is {' or '.join(SUSPEND_CHANNELS[channel])}, compared with == or !=" \
            if channel in _STATES else f"allowed: {', '.join(OPERATORS)}"
        raise r.fail(column, f"expected a comparison after {channel}, got {got}; {why}")
    r.i += 1
    if channel in _STATES:
        states = SUSPEND_CHANNELS[channel]
        _, value, column = r.take("word", f"{' or '.join(states)}")
        if value not in states:
            raise r.fail(column, f"{channel} is {' or '.join(states)}, not {show(value)}")
        kind, extra, column = r.peek()
        if kind != "end":
            raise r.fail(column, f"unexpected {show(extra)} after the value; a condition is one comparison")
        return {"channel": channel, "op": op, "value": value, "magnitude": False}
    dimension = SUSPEND_CHANNELS[channel][0]
    _, number, column = r.take("number", f"a number with a unit, e.g. {_example(channel)}")
    unit_column = r.peek()[2]
    unit_text = text[unit_column - 1:].strip()
    if not unit_text:
        raise r.fail(unit_column, f"{number} has no unit; give e.g. {_example(channel, number)}")
    try:
        value = parse_quantity(f"{number} {unit_text}", dimension, source="", field="")
    except SpecError as err:
        raise r.fail(column, err.message) from None
    return {"channel": channel, "op": op, "value": value, "magnitude": magnitude}


def _example(channel: str, number: str | None = None) -> str:
    return {"amplifier_temperature": f"'{number or 60} degC'", "force_offset_drift": f"'{number or 5} mN'"}[channel]


def _text(channel: str, op: str, value: float | str, magnitude: bool) -> str:
    """The canonical text of a condition (``amplifier_temperature > 60 degC``)."""
    shown = f"|{channel}|" if magnitude else channel
    if channel in _STATES:
        return f"{shown} {op} {value}"
    return f"{shown} {op} {format_quantity(value, SUSPEND_CHANNELS[channel][1])}"


class Condition(SpecModel):
    """One comparison of a rig channel's reading with a value: ``interlock == open``.

    Read from its text (`parse_condition`, or a string where a spec expects a condition); made in Python
    from its fields (the value in SI), its `text` then written for it.

    Attributes
    ----------
    channel : str
        A key of `SUSPEND_CHANNELS`.
    op : str
        One of `OPERATORS` (``==`` or ``!=`` for ``interlock``).
    value : float or str
        ``"open"``/``"closed"`` for ``interlock``; else SI: a temperature [K], a force [N].
    magnitude : bool
        Compare the reading's magnitude (``|force_offset_drift| > 5 mN``), not its signed value.
    text : str
        The condition as written (spaces collapsed): what messages show and a dump writes.
    """

    channel: str
    op: str
    value: float | str
    magnitude: bool = False
    text: str = ""

    @model_validator(mode="before")
    @classmethod
    def _from_text(cls, data: Any) -> Any:
        if isinstance(data, str):
            return {**_parse(data), "text": " ".join(data.split())}
        if isinstance(data, Condition):
            return data
        if units_required() or not isinstance(data, Mapping):
            raise SpecError("", "", f"expected a condition such as 'interlock == open' or "
                            f"'amplifier_temperature > 60 degC', got {show(data)}")
        data = dict(data)
        channel, op, value = data.get("channel"), data.get("op"), data.get("value")
        if channel not in SUSPEND_CHANNELS:
            raise SpecError("", "channel", f"unknown channel {show(channel)}; allowed: {', '.join(SUSPEND_CHANNELS)}")
        if op not in (("==", "!=") if channel in _STATES else OPERATORS):
            raise SpecError("", "op", f"{show(op)} does not compare {channel}; allowed: "
                            f"{'==, !=' if channel in _STATES else ', '.join(OPERATORS)}")
        if channel in _STATES:
            if value not in SUSPEND_CHANNELS[channel] or data.get("magnitude"):
                raise SpecError("", "value", f"{channel} is {' or '.join(SUSPEND_CHANNELS[channel])}, not "
                                f"{show(value)} (and has no magnitude)")
        elif isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            raise SpecError("", "value", f"{show(value)} is not a finite number in SI "
                            f"({'K' if channel == 'amplifier_temperature' else 'N'})")
        elif channel == "amplifier_temperature" and value < 0.0:
            raise SpecError("", "value", f"{value!r} K is below absolute zero")
        value = value if channel in _STATES else float(value)
        magnitude = bool(data.get("magnitude", False))
        fields = {"channel": channel, "op": op, "value": value, "magnitude": magnitude}
        text = data.get("text")
        if text:  # a text given with the fields must say the same: a dump writes the text
            if not isinstance(text, str) or _parse(text) != fields:
                raise SpecError("", "text", f"{show(text)} does not say {_text(channel, op, value, magnitude)}; "
                                "leave the text out (it is written from the fields)")
            return {**data, **fields, "text": " ".join(text.split())}
        return {**data, **fields, "text": _text(channel, op, value, magnitude)}

    def holds(self, readings: Mapping) -> bool | None:
        """Whether the condition holds for `readings`; None when it cannot be told.

        Parameters
        ----------
        readings : Mapping
            Channel -> latest reading, in SI (``amplifier_temperature`` [K], ``force_offset_drift`` [N]),
            ``interlock`` as ``"open"`` or ``"closed"``.

        Returns
        -------
        bool or None
            None when the channel is missing from `readings`, its reading is None or NaN.

        Raises
        ------
        ValueError
            A reading of the wrong kind (an interlock that is neither open nor closed, a temperature that is
            not a number): the backend's mistake, not the protocol's.
        """
        reading = readings.get(self.channel)
        if reading is None:
            return None
        if self.channel in _STATES:
            if reading not in SUSPEND_CHANNELS[self.channel]:
                raise ValueError(f"{self.channel} reading {reading!r} is not one of "
                                 f"{', '.join(SUSPEND_CHANNELS[self.channel])}")
        else:
            if isinstance(reading, bool) or not isinstance(reading, numbers.Real):
                raise ValueError(f"{self.channel} reading {reading!r} is not a number")
            reading = float(reading)
            if math.isnan(reading):
                return None
            if self.magnitude:
                reading = abs(reading)
        return bool(_COMPARE[self.op](reading, self.value))

    def __str__(self) -> str:
        return self.text


def parse_condition(text: str, source: str = "<python>", field: str = "") -> Condition:
    """A `Condition` from its text (``"amplifier_temperature > 60 degC"``).

    Raises
    ------
    SpecError
        An unknown channel, operator or unit, a value of the wrong kind, or anything after the value;
        the message names the column and what is allowed.
    """
    try:
        return Condition.model_validate(text)
    except ValidationError as exc:
        err = spec_error_from_validation(exc, source=source, model=Condition)
        where = ".".join(p for p in (field, "" if err.field == DOCUMENT else err.field) if p)
        raise SpecError(source, where or DOCUMENT, err.message) from None


def _wait(value: float) -> float:
    if not 0.0 < value <= MAX_WAIT:
        shown = format_quantity(value, "h" if value > 3600.0 else "s", digits=6)
        raise SpecError("", "", f"{shown} is not a wait; allowed: 0 s < wait <= "
                        "24 h (the longest a run waits for the resume condition before it is aborted)")
    return value


class Suspender(SpecModel):
    """Pause a run while `when` holds; resume it once `resume` holds; abort it after `wait` without.

    Attributes
    ----------
    name : str or None
        Names it in messages (``suspender 'door'``); letters, digits, ``-``, ``_``, ``.``.
    when : Condition
        Pauses the run when it holds (a reading that cannot be told does not pause).
    resume : Condition or None
        The run may go on once it holds; None: once `when` no longer holds (a reading that cannot be told
        never resumes).
    wait : float
        The longest wait for the resume condition [s], ``0 < wait <= 24 h`` (default 10 min); then the
        run is aborted.
    """

    name: Identifier | None = None
    when: Condition
    resume: Condition | None = None
    wait: Annotated[float, AfterValidator(_wait)] = DEFAULT_WAIT

    @model_validator(mode="before")
    @classmethod
    def _wait_with_unit(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and "wait" in data and data["wait"] is not None:
            wait = data["wait"]
            if isinstance(wait, str) or units_required():
                try:
                    wait = parse_quantity(wait, "time", source="", field="")
                except SpecError as err:
                    raise SpecError("", "wait", err.message) from None
            data = {**data, "wait": wait}
        return data

    @property
    def label(self) -> str:
        """``suspender 'door'``, or the `when` text of one without a name."""
        return f"suspender '{self.name}'" if self.name else f"suspender '{self.when.text}'"

    @property
    def resume_text(self) -> str:
        """The resume condition as words: its text, or ``"<when> no longer holds"``."""
        return self.resume.text if self.resume is not None else f"{self.when.text} no longer holds"

    def _form(self) -> dict:
        """The YAML form (an item of ``suspend:``)."""
        out: dict[str, Any] = {}
        if self.name is not None:
            out["name"] = self.name
        out["when"] = self.when.text
        if self.resume is not None:
            out["resume"] = self.resume.text
        out["wait"] = format_quantity(self.wait, "min" if self.wait >= 60.0 else "s")
        return out


def suspenders_problem(suspenders: tuple[Suspender, ...]) -> SpecError | None:
    """A `SpecError` (no source) for two suspenders of one list with the same name, else None."""
    seen: dict[str, int] = {}
    for i, s in enumerate(suspenders):
        if s.name is None:
            continue
        if s.name in seen:
            return SpecError("", f"suspend[{i}].name", f"{show(s.name)} also names suspend[{seen[s.name]}]; "
                             "give each suspender its own name (messages name them)")
        seen[s.name] = i
    return None


def merged_suspenders(protocol_spec, campaign_spec=None) -> tuple[Suspender, ...]:
    """The suspenders of a campaign's run: its protocol's own, then the campaign's.

    A campaign suspender equal to one of the protocol's is given once.

    Parameters
    ----------
    protocol_spec : ProtocolSpec
        (Or anything with a ``suspend`` tuple, e.g. a plan's ``spec``.)
    campaign_spec : CampaignSpec or None

    Returns
    -------
    tuple of Suspender

    Raises
    ------
    SpecError
        A campaign suspender with the name of a different suspender of the protocol (a message naming
        ``suspender 'door'`` would not say which); names the campaign file and its ``suspend[i].name``.
    """
    own = tuple(getattr(protocol_spec, "suspend", ()) or ())
    extra = tuple(getattr(campaign_spec, "suspend", ()) or ())
    out = list(own)
    named = {s.name: s for s in own if s.name is not None}
    for i, s in enumerate(extra):
        if s in out:
            continue
        if s.name is not None and s.name in named:
            origin = getattr(campaign_spec, "origin", "<campaign>")
            raise SpecError(origin, f"suspend[{i}].name", f"{show(s.name)} also names a different suspender of "
                            f"protocol {getattr(protocol_spec, 'name', '?')!r} (when {named[s.name].when.text}); "
                            "give the campaign's another name")
        out.append(s)
    return tuple(out)


__all__ = ["Condition", "DEFAULT_WAIT", "MAX_CONDITION", "MAX_WAIT", "OPERATORS", "SUSPEND_CHANNELS", "Suspender",
           "merged_suspenders", "parse_condition", "suspenders_problem"]
