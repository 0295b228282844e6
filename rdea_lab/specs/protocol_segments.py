"""Protocol building blocks: units-aware field types and waveform segments (the limits: `rdea_lab.specs.limits`).

See `rdea_lab.specs.protocol` for the protocol file as a whole.
"""

import math
import numbers
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import AfterValidator, BaseModel, BeforeValidator, Field, model_validator

from .base import SpecModel, units_required
from .errors import DOCUMENT, SpecError, show
from .limits import LIMIT_CEILINGS, Limits  # noqa: F401  (re-exported: a protocol's limits)
from .names import KINDS, MAX_STRETCH  # noqa: F401  (re-exported: a protocol's kinds)
from .units import _NUMBER, format_quantity, parse_quantity, quantity, ureg


MEASURABLE = ("force", "capacitance", "current")
SEGMENT_KINDS = ("hold", "step", "ramp", "sine", "ramp_sine", "chirp", "table")
#: most values a ``table`` segment may hold (a sampled setpoint history, e.g. a planned voltage)
MAX_TABLE_VALUES = 1_000_000
CHANNELS = ("stretch", "voltage")
#: value of each channel before its first segment
REST = {"stretch": 1.0, "voltage": 0.0}
MAX_SAMPLE_RATE = 100e3  # [Hz]
#: most samples a protocol may hold: 1e9 is 11.6 days at 1 kHz (a plan is rendered in windows, never whole)
MAX_SAMPLES = 1_000_000_000
#: relative slack when comparing the durations of the two channels (sums of decimals)
_ROUNDING = 1e-9


# ------------------------------------------------------------ field types
def _in_tension(value: float) -> float:
    if not value >= 1.0:
        raise SpecError("", "", f"stretch {value:g} is below 1; the roll must stay in tension (stretch >= 1)")
    return value


def rate_text(value: float, digits: int | None = None) -> str:
    """A sample rate [Hz] in Hz below 1 kHz, else in kHz (``"100 Hz"``, ``"1 kHz"``)."""
    return format_quantity(value, "kHz" if value >= 1e3 else "Hz", digits)


def _at_most_max_rate(value: float) -> float:
    if value > MAX_SAMPLE_RATE:
        raise SpecError(
            "", "", f"must be <= {rate_text(MAX_SAMPLE_RATE)}, got {rate_text(value)}"
        )
    return value


def _angle(value: Any) -> float:
    """An angle [rad] from ``"-90 deg"`` or ``"1.5 rad"``; from Python a number is radians."""
    example = "give an angle with a unit, e.g. '-90 deg' or '0.5 rad'"
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        if units_required():
            raise SpecError("", "", f"'{value}' has no unit; {example}")
        if not math.isfinite(value):
            raise SpecError("", "", f"{value} is not a finite number; {example}")
        return float(value)
    match = _NUMBER.match(value) if isinstance(value, str) else None
    if match is None:
        raise SpecError("", "", f"{show(value)} is not a number followed by a unit; {example}")
    number, unit_text = match.groups()
    if not math.isfinite(float(number)):
        raise SpecError("", "", f"{show(value)} is not a finite number; {example}")
    if not unit_text:
        raise SpecError("", "", f"{show(value)} has no unit; {example}")
    try:
        units = ureg.parse_units(unit_text)
    except Exception:
        raise SpecError("", "", f"{show(value)} has an unknown unit {show(unit_text)}; {example}") from None
    q = ureg.Quantity(float(number), units)
    if not (q.dimensionless and "radian" in str(q.to_root_units().units)):
        raise SpecError("", "", f"{show(value)} is not an angle; {example}")
    return float(q.to("rad").magnitude)


def format_angle(value: float) -> str:
    """An angle [rad] as ``"-90 deg"`` (or in rad if no short degree text round-trips)."""
    deg = math.degrees(value)
    for n in (6, 9, 12, 15, 17):
        text = f"{deg:.{n}g} deg"
        if _angle(text) == value:
            return text
    return f"{value!r} rad"


#: The most cycles a preset runs: a million cycles is a fatigue test of days at 10 Hz, and even at 1 kHz
#: the sample count (`MAX_SAMPLES`) refuses more.
MAX_CYCLES = 1_000_000


def _whole_positive(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not 1 <= value <= MAX_CYCLES:
        raise SpecError("", "", f"must be a whole number of cycles, got {show(value)}; allowed: 1 to "
                        f"{MAX_CYCLES} cycles")
    return int(value)


Duration = quantity("time", "s", gt=0.0)
Frequency = quantity("frequency", "Hz", gt=0.0)
SampleRate = Annotated[quantity("frequency", "Hz", gt=0.0), AfterValidator(_at_most_max_rate)]
Stretch = Annotated[quantity("dimensionless", ""), AfterValidator(_in_tension)]
StretchAmplitude = quantity("dimensionless", "", ge=0.0)
Voltage = quantity("voltage", "kV")
VoltageAmplitude = quantity("voltage", "kV", ge=0.0)
Angle = Annotated[float, BeforeValidator(_angle)]
Cycles = Annotated[int, BeforeValidator(_whole_positive)]


#: Largest probe amplitude [V]: a probe is a small signal on the high voltage, not an actuation.
MAX_PROBE_AMPLITUDE = 200.0


def _small_probe(value: float) -> float:
    if value > MAX_PROBE_AMPLITUDE:
        raise SpecError("", "", f"{format_quantity(value, 'V', digits=6)} is above "
                                f"{format_quantity(MAX_PROBE_AMPLITUDE, 'V')}: a probe is a small signal on the "
                                "high voltage, not an actuation; allowed: 0 V < amplitude <= 200 V")
    return value


class Probe(SpecModel):
    """A small sine added to the whole voltage channel, for self-sensing (SI).

    ``v = v_setpoint + amplitude sin(2 pi frequency t)``: the capacitance is
    estimated from the current it drives (`rdea_lab.twin.selfsense`). The
    frequency must lie below the Nyquist frequency of the sample rate, and
    the voltage limits hold with the probe on (`rdea_lab.protocols.check_plan`).

    Attributes
    ----------
    amplitude : float
        Peak of the probe [V], ``0 < amplitude <= 200 V``.
    frequency : float
        [Hz], ``0 < frequency < sample_rate / 2``.
    """

    amplitude: Annotated[quantity("voltage", "V", gt=0.0), AfterValidator(_small_probe)]
    frequency: quantity("frequency", "Hz", gt=0.0)


# ------------------------------------------------------------- segments
def _table_values(channel: str, data: Any) -> Any:
    """A ``table`` segment's mapping with its ``values`` as SI floats (its ``unit`` applied and dropped)."""
    if not isinstance(data, dict):
        return data
    data = dict(data)
    unit = data.pop("unit", None)
    values = data.get("values")
    dimension, example = ("voltage", "V") if channel == "voltage" else ("dimensionless", "")
    factor = 1.0
    if unit is not None:
        if not isinstance(unit, str):
            raise SpecError("", "unit", f"{show(unit)} is not a unit; give e.g. 'unit: {example or 1}'")
        try:
            factor = parse_quantity(f"1 {unit}", dimension, source="", field="unit") if unit.strip() else 1.0
        except SpecError:
            allowed = "a voltage unit such as V or kV" if channel == "voltage" else "none (stretch is a number)"
            raise SpecError("", "unit", f"{show(unit)} is not allowed here; allowed: {allowed}") from None
    elif units_required() and dimension != "dimensionless":
        raise SpecError("", "unit", "missing; a voltage table gives its unit once, e.g. 'unit: V', and plain "
                        "numbers in 'values'")
    if not isinstance(values, (list, tuple)):
        raise SpecError("", "values", f"expected a list of at least 2 numbers, got {show(values)}")
    if not 2 <= len(values) <= MAX_TABLE_VALUES:
        raise SpecError("", "values", f"{len(values)} values; allowed: 2 to {MAX_TABLE_VALUES}")
    if any(isinstance(v, bool) for v in values):
        bad = next(i for i, v in enumerate(values) if isinstance(v, bool))
        raise SpecError("", f"values[{bad}]", f"{show(values[bad])} is not a number")
    try:
        array = np.asarray(values, dtype=float) * factor
    except (TypeError, ValueError):
        bad = next(i for i, v in enumerate(values) if isinstance(v, bool) or not isinstance(v, numbers.Real))
        raise SpecError("", f"values[{bad}]", f"{show(values[bad])} is not a plain number (the unit is "
                        "given once, in 'unit')") from None
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        raise SpecError("", f"values[{bad[0]}]", f"{show(values[bad[0]])} is not a finite number")
    if channel == "stretch":
        low = np.flatnonzero(array < 1.0)
        if low.size:
            raise SpecError("", f"values[{low[0]}]", f"stretch {array[low[0]]:g} is below 1; the roll must stay "
                            "in tension (stretch >= 1)")
    data["values"] = tuple(array.tolist())
    return data


def _segment_classes(channel: str, Value: Any, Amplitude: Any) -> dict[str, type[SpecModel]]:
    """The six segment models of one channel; values typed `Value`."""

    class Hold(SpecModel):
        kind: Literal["hold"] = "hold"
        duration: Duration
        value: Value | None = None

    class Step(SpecModel):
        kind: Literal["step"] = "step"
        duration: Duration
        value: Value

    class Ramp(SpecModel):
        kind: Literal["ramp"] = "ramp"
        duration: Duration
        to: Value
        from_: Value | None = Field(None, alias="from")

    class Sine(SpecModel):
        kind: Literal["sine"] = "sine"
        duration: Duration
        mean: Value
        amplitude: Amplitude
        frequency: Frequency
        phase: Angle = 0.0

    class RampSine(SpecModel):
        kind: Literal["ramp_sine"] = "ramp_sine"
        duration: Duration
        frequency: Frequency
        base: Value
        peak_start: Value
        peak_end: Value

    class Chirp(SpecModel):
        kind: Literal["chirp"] = "chirp"
        duration: Duration
        mean: Value
        amplitude: Amplitude
        f_start: Frequency
        f_end: Frequency

    class Table(SpecModel):
        """Sampled setpoints: ``values`` evenly spaced over the duration, first at its start, last at its
        end, linear in between. From YAML a voltage table needs ``unit`` (e.g. ``unit: V``), and the values
        are plain numbers in it; stretch values are plain numbers."""

        kind: Literal["table"] = "table"
        duration: Duration
        values: tuple[float, ...]

        @model_validator(mode="before")
        @classmethod
        def _in_si(cls, data: Any) -> Any:
            return _table_values(channel, data)

    classes = dict(zip(SEGMENT_KINDS, (Hold, Step, Ramp, Sine, RampSine, Chirp, Table)))
    prefix = channel.capitalize()
    for cls in classes.values():
        cls.__name__ = cls.__qualname__ = prefix + cls.__name__
        cls.__module__ = __name__
        cls.__doc__ = (
            f"A `{cls.model_fields['kind'].default}` segment of the {channel} channel "
            f"(values {'dimensionless' if channel == 'stretch' else 'in V'}, durations in s, frequencies in Hz)."
        )
    return classes


STRETCH_SEGMENTS = _segment_classes("stretch", Stretch, StretchAmplitude)
VOLTAGE_SEGMENTS = _segment_classes("voltage", Voltage, VoltageAmplitude)
SEGMENTS = {"stretch": STRETCH_SEGMENTS, "voltage": VOLTAGE_SEGMENTS}
(StretchHold, StretchStep, StretchRamp, StretchSine, StretchRampSine, StretchChirp,
 StretchTable) = STRETCH_SEGMENTS.values()
(VoltageHold, VoltageStep, VoltageRamp, VoltageSine, VoltageRampSine, VoltageChirp,
 VoltageTable) = VOLTAGE_SEGMENTS.values()
StretchSegment = Union[tuple(STRETCH_SEGMENTS.values())]
VoltageSegment = Union[tuple(VOLTAGE_SEGMENTS.values())]


def _join(where: str, field: str) -> str:
    return where if field in ("", DOCUMENT) else f"{where}.{field}"


def _segments(channel: str, items: Any) -> tuple:
    """Mappings (or segment models) -> a tuple of the channel's segment models."""
    classes = SEGMENTS[channel]
    if not isinstance(items, (list, tuple)):
        raise SpecError("", channel, f"expected a list of segments, got {show(items)}")
    if not items:
        raise SpecError("", channel, "no segments; give at least one, e.g. {kind: hold, duration: 2 s}")
    out = []
    for i, item in enumerate(items):
        where = f"{channel}[{i}]"
        if isinstance(item, tuple(classes.values())):
            out.append(item)
            continue
        if isinstance(item, BaseModel):
            raise SpecError("", where, f"{type(item).__name__} is not a {channel} segment")
        if not isinstance(item, Mapping):
            raise SpecError("", where, f"expected a mapping with keys kind, duration, ..., got {show(item)}")
        if "kind" not in item:
            raise SpecError("", f"{where}.kind", f"missing required key 'kind'; one of {', '.join(SEGMENT_KINDS)}")
        kind = item["kind"]
        if not isinstance(kind, str) or kind not in classes:
            raise SpecError("", f"{where}.kind",
                            f"unknown segment kind {show(kind)}; allowed: {', '.join(SEGMENT_KINDS)}")
        try:
            out.append(classes[kind](**{str(k): v for k, v in item.items()}))
        except SpecError as err:
            raise SpecError("", _join(where, err.field), err.message) from None
    return tuple(out)


def channel_duration(segments: tuple) -> float:
    """Sum of the segment durations [s]."""
    return math.fsum(s.duration for s in segments)


def sample_count(duration: float, sample_rate: float) -> int:
    """The number of samples of a protocol, ``N = round(duration * rate) + 1`` (``t_k = k / rate``, both ends).

    Parameters
    ----------
    duration : float
        The protocol's duration [s].
    sample_rate : float
        [Hz].

    Returns
    -------
    int
        N; not checked against `MAX_SAMPLES` (`check_sample_count` does that).
    """
    return round(duration * sample_rate) + 1


def check_sample_count(duration: float, sample_rate: float) -> int:
    """`sample_count`, or a `SpecError` (field ``sample_rate``, no source) if it is above `MAX_SAMPLES`.

    Parameters
    ----------
    duration : float
        The protocol's duration [s].
    sample_rate : float
        [Hz].

    Returns
    -------
    int
        The number of samples N.

    Raises
    ------
    SpecError
        More than `MAX_SAMPLES` samples (a duration too long to count them, too).
    """
    if not math.isfinite(duration * sample_rate):
        raise SpecError(
            "", "sample_rate",
            f"{format_quantity(duration, 's', digits=6)} at {rate_text(sample_rate, 6)} gives more than "
            f"{MAX_SAMPLES} samples; at most {MAX_SAMPLES} (1 billion) are allowed; "
            "lower the sample rate or shorten the protocol",
        )
    n = sample_count(duration, sample_rate)
    if n > MAX_SAMPLES:
        raise SpecError(
            "", "sample_rate",
            f"{format_quantity(duration, 's', digits=6)} at {rate_text(sample_rate, 6)} "
            f"gives {n} samples; at most {MAX_SAMPLES} (1 billion) are allowed; "
            "lower the sample rate or shorten the protocol",
        )
    return n


