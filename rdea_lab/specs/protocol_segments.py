"""Protocol building blocks: units-aware field types, safety limits and waveform segments.

See `rdea_lab.specs.protocol` for the protocol file as a whole.
"""

import math
import numbers
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Union

from pydantic import AfterValidator, BaseModel, BeforeValidator, Field

from .errors import DOCUMENT, SpecError, SpecModel, show
from .errors import units_required
from .units import _NUMBER, format_quantity, quantity, ureg


KINDS = ("tensile", "blocking", "capacitance", "custom")
MEASURABLE = ("force", "capacitance", "current")
SEGMENT_KINDS = ("hold", "step", "ramp", "sine", "ramp_sine", "chirp")
CHANNELS = ("stretch", "voltage")
#: value of each channel before its first segment
REST = {"stretch": 1.0, "voltage": 0.0}
MAX_SAMPLE_RATE = 100e3  # [Hz]
MAX_SAMPLES = 50_000_000
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


def _whole_positive(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise SpecError("", "", f"must be a whole number >= 1, got {show(value)}")
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


class Limits(SpecModel):
    """Safety limits of a protocol (SI).

    Attributes
    ----------
    max_voltage : float
        Largest allowed ``|voltage|`` [V]; 3 kV by default.
    max_stretch : float
        Largest allowed stretch [-]; 2.0 by default.
    max_force : float
        Largest allowed ``|force|`` [N], enforced while running; 50 N by default.
    max_field : float
        Largest allowed field estimate ``|v| sqrt(stretch) / L3`` [V/m]; 80 V/um by default.
    """

    max_voltage: quantity("voltage", "kV", gt=0.0) = 3e3
    max_stretch: quantity("dimensionless", "", ge=1.0) = 2.0
    max_force: quantity("force", "N", gt=0.0) = 50.0
    max_field: quantity("electric_field", "V/um", gt=0.0) = 80e6

    @classmethod
    def from_options(cls, values: dict, source: str = "command line") -> "Limits":
        """Limits from option texts (``{"max_voltage": "3 kV", ...}``); a bad one is a `SpecError` naming
        the option (``--max-voltage``)."""
        from .errors import SpecError

        try:
            return cls(**values)
        except SpecError as err:
            raise SpecError(source, "--" + err.field.replace("_", "-"), err.message) from None


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

    classes = dict(zip(SEGMENT_KINDS, (Hold, Step, Ramp, Sine, RampSine, Chirp)))
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
StretchHold, StretchStep, StretchRamp, StretchSine, StretchRampSine, StretchChirp = STRETCH_SEGMENTS.values()
VoltageHold, VoltageStep, VoltageRamp, VoltageSine, VoltageRampSine, VoltageChirp = VOLTAGE_SEGMENTS.values()
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
            raise SpecError("", f"{where}.kind", f"unknown segment kind {show(kind)}; allowed: {', '.join(SEGMENT_KINDS)}")
        try:
            out.append(classes[kind](**{str(k): v for k, v in item.items()}))
        except SpecError as err:
            raise SpecError("", _join(where, err.field), err.message) from None
    return tuple(out)


def channel_duration(segments: tuple) -> float:
    """Sum of the segment durations [s]."""
    return math.fsum(s.duration for s in segments)


def check_sample_count(duration: float, sample_rate: float) -> int:
    """Number of samples ``round(duration * rate) + 1``; `SpecError` (field
    ``sample_rate``, no source) if above `MAX_SAMPLES`."""
    n = round(duration * sample_rate) + 1
    if n > MAX_SAMPLES:
        raise SpecError(
            "", "sample_rate",
            f"{format_quantity(duration, 's', digits=6)} at {rate_text(sample_rate, 6)} "
            f"gives {n} samples; at most {MAX_SAMPLES} (50 million) are allowed; "
            "lower the sample rate or shorten the protocol",
        )
    return n


