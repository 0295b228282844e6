"""Protocols: what the rig (or its twin) does over time, as YAML with units.

A protocol has a stretch channel and a voltage channel, each a list of
waveform segments, a sample rate, what is measured and safety limits::

    name: tensile_ramp_sine_2.6kV
    kind: tensile
    sample_rate: 100 Hz
    measure: [force]
    limits: {max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}
    stretch:
      - {kind: hold, duration: 2 s, value: 1.0}
      - {kind: ramp_sine, duration: 50 s, frequency: 0.1 Hz, base: 1.0, peak_start: 1.1, peak_end: 1.5}
    voltage:
      - {kind: ramp, duration: 2 s, to: 2.6 kV}
      - {kind: hold, duration: 50 s}

or, instead of the two channels, a named preset with its settings
(``preset: tensile_ramp_sine``, ``settings: {voltage: 2.6 kV}``). This module
knows each preset's kind, settings (with defaults and checks) and default
``measure``; `rdea_lab.protocols` expands a preset into segments and samples
the segments into setpoint arrays. Everything is stored in SI: seconds, hertz,
volts, radians, V/m; stretch is dimensionless.
"""

import math
import numbers
import os
from collections.abc import Mapping
from typing import Annotated, Any, Literal, NamedTuple, Union

import yaml
from pydantic import AfterValidator, BaseModel, BeforeValidator, Field, PrivateAttr, field_validator, model_validator

from .errors import DOCUMENT, Identifier, SpecError, SpecModel, parse_yaml_mapping, read_yaml_mapping, show
from .errors import units_required
from .units import _NUMBER, format_quantity, quantity, ureg

KINDS = ("tensile", "blocking", "capacitance", "custom")
MEASURABLE = ("force", "capacitance")
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


# -------------------------------------------------------------- presets
class _StretchSweep(SpecModel):
    """Stretch settings shared by the tensile and capacitance presets."""

    min_stretch: Stretch = 1.0
    max_stretch: Stretch = 1.5
    frequency: Frequency = 0.1
    cycles: Cycles = 5
    settle: Duration = 2.0

    @model_validator(mode="after")
    def _ordered(self):
        if not self.max_stretch > self.min_stretch:
            raise SpecError(
                "", "max_stretch",
                f"max_stretch {self.max_stretch:g} is not above min_stretch {self.min_stretch:g}",
            )
        return self


class TensileRampSineSettings(_StretchSweep):
    """Settings of the ``tensile_ramp_sine`` preset (SI; Section 4.2, Figs. 11-13 of [1])."""

    voltage: Voltage = 0.0


class CapacitanceSweepSettings(_StretchSweep):
    """Settings of the ``capacitance_sweep`` preset: the tensile ramp sine at 0 V (Fig. 16 of [1])."""


class BlockingForceSettings(SpecModel):
    """Settings of the ``blocking_force`` preset (SI; Section 4.2, Fig. 15 of [1])."""

    stretch: Stretch = 1.5
    voltage_min: Voltage = 0.0
    voltage_max: Voltage = 2.6e3
    frequency: Frequency = 1.0
    cycles: Cycles = 10
    approach: Duration = 5.0
    settle: Duration = 5.0

    @model_validator(mode="after")
    def _ordered(self):
        if self.voltage_max < self.voltage_min:
            raise SpecError(
                "", "voltage_max",
                f"voltage_max {format_quantity(self.voltage_max, 'kV')} is below "
                f"voltage_min {format_quantity(self.voltage_min, 'kV')}",
            )
        return self


class PresetSchema(NamedTuple):
    """What the specs layer knows of a preset: its kind, settings model, default measure."""

    kind: str
    settings: type[SpecModel]
    measure: tuple[str, ...]


PRESETS: dict[str, PresetSchema] = {
    "tensile_ramp_sine": PresetSchema("tensile", TensileRampSineSettings, ("force",)),
    "blocking_force": PresetSchema("blocking", BlockingForceSettings, ("force",)),
    "capacitance_sweep": PresetSchema("capacitance", CapacitanceSweepSettings, ("force", "capacitance")),
}
Settings = Union[TensileRampSineSettings, BlockingForceSettings, CapacitanceSweepSettings]


# ------------------------------------------------------------- protocol
class ProtocolSpec(SpecModel):
    """A protocol, in SI: either explicit channels or a preset with settings.

    Attributes
    ----------
    name : str
        Letters, digits, ``-``, ``_``, ``.``.
    kind : str
        One of `KINDS`; for a preset, the preset's kind (the default).
    sample_rate : float
        Samples per second [Hz], ``0 < rate <= 100 kHz``.
    measure : tuple of str
        Non-empty subset of `MEASURABLE`, in the given order.
    limits : Limits
    stretch, voltage : tuple of segment models or None
        Explicit channels (None for a preset).
    preset : str or None
        A key of `PRESETS`.
    settings : settings model or None
        The preset's settings; ``model_fields_set`` holds the ones given.
    description, source : str or None
        Free text; `source` says where the settings come from.
    origin : str
        Where the spec was read from (file path, ``"<string>"``, ...), for
        messages about it; not part of equality.
    """

    name: Identifier
    kind: str
    description: str | None = None
    source: str | None = None
    sample_rate: SampleRate
    measure: tuple[str, ...] = ("force",)
    limits: Limits = Limits()
    stretch: tuple[StretchSegment, ...] | None = None
    voltage: tuple[VoltageSegment, ...] | None = None
    preset: str | None = None
    settings: Settings | None = None
    _origin: str = PrivateAttr("<python>")

    def __eq__(self, other: object) -> bool:
        # the same protocol read from two files is the same protocol
        if not isinstance(other, ProtocolSpec):
            return NotImplemented
        return type(self) is type(other) and self.__dict__ == other.__dict__

    @property
    def origin(self) -> str:
        """Where the spec was read from: a file path, ``"<string>"``, ``"<mapping>"`` or ``"<python>"``."""
        return self._origin

    def with_origin(self, origin: str) -> "ProtocolSpec":
        """The same spec, attributed to `origin` (e.g. a preset's expansion)."""
        spec = self.model_copy()
        spec._origin = origin
        return spec

    @model_validator(mode="before")
    @classmethod
    def _waveform(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        if units_required():
            for key, value in data.items():
                if value is None:
                    raise SpecError("", str(key), "no value given")
        data = {k: v for k, v in data.items() if v is not None}
        has_preset, channels = "preset" in data, [c for c in CHANNELS if c in data]
        if has_preset and channels:
            raise SpecError(
                "", "preset", f"give either a preset (with settings) or explicit stretch and voltage channels, "
                f"not both (found preset and {' and '.join(channels)})",
            )
        if not has_preset:
            if "settings" in data:
                raise SpecError("", "settings", "settings belong to a preset; give 'preset' too")
            if not channels:
                raise SpecError(
                    "", "stretch", "missing waveform; give explicit 'stretch' and 'voltage' segment lists, "
                    f"or a 'preset' ({', '.join(PRESETS)}) with its 'settings'",
                )
            for channel in CHANNELS:
                if channel not in data:
                    raise SpecError("", channel, f"missing required key '{channel}' (a list of segments)")
                data[channel] = _segments(channel, data[channel])
            return data
        preset = data["preset"]
        if not isinstance(preset, str) or preset not in PRESETS:
            raise SpecError("", "preset", f"unknown preset {show(preset)}; known presets: {', '.join(PRESETS)}")
        schema = PRESETS[preset]
        settings = data.get("settings", {})
        if not isinstance(settings, schema.settings):
            if not isinstance(settings, Mapping):
                raise SpecError("", "settings", f"expected a mapping of settings, got {show(settings)}")
            try:
                settings = schema.settings(**{str(k): v for k, v in settings.items()})
            except SpecError as err:
                raise SpecError("", _join("settings", err.field), err.message) from None
        data["settings"] = settings
        data.setdefault("kind", schema.kind)
        data.setdefault("measure", schema.measure)
        if data["kind"] != schema.kind:
            raise SpecError(
                "", "kind", f"kind {show(data['kind'])} does not match preset '{preset}' (kind {schema.kind}); "
                "leave kind out or give it as the preset's",
            )
        return data

    @field_validator("kind", mode="before")
    @classmethod
    def _known_kind(cls, value: Any) -> Any:
        if not isinstance(value, str) or value not in KINDS:
            raise SpecError("", "", f"kind {show(value)} is not allowed; allowed: {', '.join(KINDS)}")
        return value

    @field_validator("measure", mode="before")
    @classmethod
    def _known_quantities(cls, value: Any) -> Any:
        allowed = ", ".join(MEASURABLE)
        if not isinstance(value, (list, tuple)):
            raise SpecError("", "", f"expected a list of quantities ({allowed}), got {show(value)}")
        if not value:
            raise SpecError("", "", f"measure is empty; give at least one of {allowed}")
        for item in value:
            if not isinstance(item, str) or item not in MEASURABLE:
                raise SpecError("", "", f"cannot measure {show(item)}; allowed: {allowed}")
        if len(set(value)) != len(value):
            raise SpecError("", "", f"a quantity is listed twice in {show(list(value))}")
        return tuple(value)

    @model_validator(mode="after")
    def _same_duration(self) -> "ProtocolSpec":
        if self.preset is not None:
            return self
        d_stretch, d_voltage = channel_duration(self.stretch), channel_duration(self.voltage)
        if not math.isclose(d_stretch, d_voltage, rel_tol=_ROUNDING):
            raise SpecError(
                "", "voltage",
                f"stretch lasts {format_quantity(d_stretch, 's', digits=9)} but voltage lasts "
                f"{format_quantity(d_voltage, 's', digits=9)}; both channels must last equally long",
            )
        check_sample_count(d_stretch, self.sample_rate)
        return self

    @property
    def duration(self) -> float | None:
        """Duration of the explicit channels [s] (the stretch channel's sum); None for a preset."""
        return None if self.stretch is None else channel_duration(self.stretch)


def protocol_from_mapping(mapping: Any, source: str = "<mapping>") -> ProtocolSpec:
    """Validate a protocol given as a mapping (as read from YAML).

    Raises
    ------
    SpecError
    """
    if not isinstance(mapping, Mapping):
        raise SpecError(source, DOCUMENT, f"expected a mapping of keys, got {show(mapping)}")
    return ProtocolSpec.from_yaml_mapping(dict(mapping), source).with_origin(source)


def protocol_from_yaml(text: str, source: str = "<string>") -> ProtocolSpec:
    """Validate a protocol given as YAML text (e.g. a dataset attr)."""
    return protocol_from_mapping(parse_yaml_mapping(text, source), source)


def load_protocol(path: str | os.PathLike) -> ProtocolSpec:
    """Read and validate a protocol YAML file.

    Raises
    ------
    SpecError
        The file is missing, not YAML, not a mapping, or the protocol is
        invalid; the message names the file and the field.
    """
    mapping, source = read_yaml_mapping(path)
    return protocol_from_mapping(mapping, source)


# ---------------------------------------------------------------- dump
class _Flow(dict):
    """A mapping written on one line (``{kind: hold, duration: 2 s}``)."""


class _FlowList(list):
    """A list written on one line (``[force, capacitance]``)."""


class _Dumper(yaml.SafeDumper):
    pass


_Dumper.add_representer(
    _Flow, lambda dumper, data: dumper.represent_mapping("tag:yaml.org,2002:map", list(data.items()), flow_style=True)
)

_Dumper.add_representer(
    _FlowList, lambda dumper, data: dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True)
)

_TIME_KEYS, _FREQUENCY_KEYS = ("duration", "settle", "approach"), ("frequency", "f_start", "f_end")


def _write(key: str, value: Any, channel: str) -> Any:
    if key in _TIME_KEYS:
        return format_quantity(value, "s")
    if key in _FREQUENCY_KEYS:
        return format_quantity(value, "Hz")
    if key == "phase":
        return format_angle(value)
    if isinstance(value, int):
        return value
    return format_quantity(value, "kV") if channel == "voltage" or key.startswith("voltage") else float(value)


def _dump_fields(model: SpecModel, channel: str, only_set: bool = False) -> dict:
    out = {}
    for name, field in type(model).model_fields.items():
        if only_set and name not in model.model_fields_set:
            continue
        value = getattr(model, name)
        if value is not None:
            out[field.alias or name] = value if name == "kind" else _write(name, value, channel)
    return out


def dump_protocol(spec: ProtocolSpec) -> str:
    """Write a protocol as YAML with units; `protocol_from_yaml` reads it back equal.

    A preset is written as ``preset`` and the settings that were given.
    """
    data: dict[str, Any] = {"name": spec.name, "kind": spec.kind}
    for key in ("description", "source"):
        if getattr(spec, key) is not None:
            data[key] = getattr(spec, key)
    data["sample_rate"] = rate_text(spec.sample_rate)
    data["measure"] = _FlowList(spec.measure)
    data["limits"] = {
        "max_voltage": format_quantity(spec.limits.max_voltage, "kV"),
        "max_stretch": spec.limits.max_stretch,
        "max_force": format_quantity(spec.limits.max_force, "N"),
        "max_field": format_quantity(spec.limits.max_field, "V/um"),
    }
    if spec.preset is not None:
        data["preset"] = spec.preset
        settings = _dump_fields(spec.settings, "settings", only_set=True)
        if settings:
            data["settings"] = settings
    else:
        for channel in CHANNELS:
            data[channel] = [_Flow(_dump_fields(s, channel)) for s in getattr(spec, channel)]
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=1000)


__all__ = [
    "CHANNELS", "KINDS", "MAX_SAMPLES", "MAX_SAMPLE_RATE", "MEASURABLE", "PRESETS", "REST", "SEGMENTS",
    "SEGMENT_KINDS", "STRETCH_SEGMENTS", "VOLTAGE_SEGMENTS",
    "BlockingForceSettings", "CapacitanceSweepSettings", "Limits", "PresetSchema", "ProtocolSpec",
    "StretchChirp", "StretchHold", "StretchRamp", "StretchRampSine", "StretchSegment", "StretchSine", "StretchStep",
    "TensileRampSineSettings", "VoltageChirp", "VoltageHold", "VoltageRamp", "VoltageRampSine", "VoltageSegment",
    "VoltageSine", "VoltageStep",
    "channel_duration", "check_sample_count", "rate_text", "dump_protocol", "format_angle", "load_protocol",
    "protocol_from_mapping", "protocol_from_yaml",
]
