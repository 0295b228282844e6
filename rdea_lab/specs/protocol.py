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
knows each preset's kind, settings (with defaults and checks), duration and
default ``measure``, and checks a file whole when it is read (the samples of
a preset's expansion too); `rdea_lab.protocols` only expands a valid spec: a
preset into segments, the segments into setpoint arrays (a ``Plan``).
Everything is stored in SI: seconds, hertz, volts, radians, V/m; stretch is
dimensionless.
"""

import math
import os
from collections.abc import Mapping
from typing import Any

import yaml
from pydantic import PrivateAttr, field_validator, model_validator

from .base import Identifier, SpecModel, empty_value_error, units_required
from .errors import SpecError, show
from .protocol_presets import (  # noqa: F401  (re-exported: part of the protocol spec)
    BlockingForceSettings, CapacitanceSweepSettings, PRESETS, PresetSchema, Settings, TensileRampSineSettings,
)
from .protocol_segments import (  # noqa: F401  (re-exported: part of the protocol spec)
    Angle, CHANNELS, Cycles, Duration, Frequency, KINDS, Limits, MAX_PROBE_AMPLITUDE, MAX_SAMPLES, MAX_SAMPLE_RATE,
    MEASURABLE, Probe, REST,
    SEGMENTS, SEGMENT_KINDS, STRETCH_SEGMENTS, SampleRate, Stretch, StretchAmplitude, StretchChirp, StretchHold,
    StretchRamp, StretchRampSine, StretchSegment, StretchSine, StretchStep, StretchTable, VOLTAGE_SEGMENTS, Voltage,
    VoltageAmplitude, VoltageChirp, VoltageHold, VoltageRamp, VoltageRampSine, VoltageSegment, VoltageSine,
    VoltageStep, VoltageTable, MAX_TABLE_VALUES, channel_duration, check_sample_count, format_angle, rate_text,
    sample_count,
    _ROUNDING, _join, _segments,
)
from .protocol_pause import Pause
from .suspenders import Suspender, suspenders_problem
from .units import format_quantity


#: Longest a pause's ramp may take (the voltage from ``max_voltage`` to 0, the stretch to ``hold_stretch``) [s],
#: and in samples (the rig holds a ramp in memory, as a trajectory: `rdea_lab.specs.rigwire.MAX_POINTS`).
MAX_PAUSE_RAMP = 600.0
MAX_PAUSE_RAMP_SAMPLES = 1e7


# ---------------------------------------------------------------- YAML dumper
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
    probe : Probe or None
        A small sine on the voltage for self-sensing (needs ``current`` in
        `measure`; its frequency below ``sample_rate / 2``).
    pause : Pause or None
        How the run pauses (``pause: {ramp_rate: 1 kV/s, hold_stretch: 1.05, stretch_rate: 0.05 /s}``):
        its ``hold_stretch`` at most ``limits.max_stretch``; None (no ``pause:``) for the defaults.
    suspend : tuple of Suspender
        Conditions on rig channels that pause the run and resume it (``suspend:``, a list); empty
        when not given.
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
    probe: Probe | None = None
    pause: Pause | None = None
    suspend: tuple[Suspender, ...] = ()
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

    def with_suspenders(self, suspenders) -> "ProtocolSpec":
        """The same protocol with `suspenders` as its ``suspend:`` list, checked (names distinct), its
        `origin` kept: e.g. a campaign's run with ``merged_suspenders(spec, campaign)``, so that the
        dataset's ``protocol`` attribute (the dump) holds every suspender the run had."""
        fields = {name: getattr(self, name) for name in type(self).model_fields}
        try:
            spec = type(self)(**{**fields, "suspend": tuple(suspenders)})
        except SpecError as err:
            raise err.with_source(self.origin) from None
        return spec.with_origin(self.origin)

    @model_validator(mode="before")
    @classmethod
    def _waveform(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        if units_required():
            for key, value in data.items():
                if value is None:
                    raise empty_value_error(data, key)
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
    def _probe_fits(self) -> "ProtocolSpec":
        if self.probe is None:
            return self
        nyquist = 0.5 * self.sample_rate
        if not self.probe.frequency < nyquist:
            raise SpecError(
                "", "probe.frequency",
                f"{rate_text(self.probe.frequency, 6)} is not below the Nyquist frequency "
                f"{rate_text(nyquist, 6)} of the sample rate {rate_text(self.sample_rate, 6)}; "
                "allowed: 0 < frequency < sample_rate / 2",
            )
        if "current" not in self.measure:
            raise SpecError("", "measure", f"a probe is for self-sensing from the amplifier current: add current "
                                           f"to measure (got {', '.join(self.measure)})")
        return self

    @model_validator(mode="after")
    def _pause_within_limits(self) -> "ProtocolSpec":
        hold = None if self.pause is None else self.pause.hold_stretch
        if hold is not None and not hold <= self.limits.max_stretch:
            raise SpecError("", "pause.hold_stretch", f"stretch {hold:g} is above the limit max_stretch = "
                            f"{self.limits.max_stretch:g}; allowed: 1 <= hold_stretch <= {self.limits.max_stretch:g} "
                            "(limits.max_stretch)")
        if self.pause is not None:  # a ramp the run (and the rig, which holds it in memory) can drive
            ramps = [("ramp_rate", self.limits.max_voltage / self.pause.ramp_rate, "V/s",
                      f"takes max_voltage {self.limits.max_voltage:g} V to 0", self.limits.max_voltage)]
            if hold is not None:
                travel = max(self.limits.max_stretch - hold, hold - 1.0)
                ramps.append(("stretch_rate", travel / self.pause.stretch_rate, "/s",
                              f"takes the stretch to hold_stretch {hold:g} from as far as the limits allow", travel))
            for name, seconds, unit, what, distance in ramps:
                most = min(MAX_PAUSE_RAMP, MAX_PAUSE_RAMP_SAMPLES / self.sample_rate)
                if seconds > most:
                    raise SpecError("", f"pause.{name}", f"{getattr(self.pause, name):.4g} {unit} {what} in "
                                    f"{seconds:.4g} s; allowed: a ramp of at most {most:.4g} s (at least "
                                    f"{distance / most:.4g} {unit})")
        problem = suspenders_problem(self.suspend)
        if problem is not None:
            raise problem
        return self

    @model_validator(mode="after")
    def _below_nyquist(self) -> "ProtocolSpec":
        # a sine above half the sample rate is sampled as another (aliased) one: never what was asked for
        nyquist = 0.5 * self.sample_rate
        if self.preset is not None:
            items = [("settings", self.settings)]
        else:
            items = [(f"{c}[{i}]", seg) for c in CHANNELS for i, seg in enumerate(getattr(self, c))]
        for where, model in items:
            for key in ("frequency", "f_start", "f_end"):
                value = getattr(model, key, None)
                if value is not None and not value < nyquist:
                    raise SpecError("", f"{where}.{key}", f"{rate_text(value, 6)} is not below the Nyquist frequency "
                                    f"{rate_text(nyquist, 6)} of the sample rate {rate_text(self.sample_rate, 6)}; "
                                    f"allowed: 0 < {key} < sample_rate / 2")
        return self

    @model_validator(mode="after")
    def _same_duration(self) -> "ProtocolSpec":
        if self.preset is not None:  # the samples its expansion will have
            check_sample_count(self.settings.duration, self.sample_rate)
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

    spec_kind = "protocols"
    yaml_dumper = _Dumper

    @classmethod
    def _from_form(cls, mapping: dict, source: str) -> "ProtocolSpec":
        return cls.from_yaml_mapping(mapping, source).with_origin(source)

    def _form(self) -> dict:
        """The YAML form; a preset is written as ``preset`` and the settings that were given."""
        data: dict[str, Any] = {"name": self.name, "kind": self.kind}
        for key in ("description", "source"):
            if getattr(self, key) is not None:
                data[key] = getattr(self, key)
        data["sample_rate"] = rate_text(self.sample_rate)
        data["measure"] = _FlowList(self.measure)
        data["limits"] = self.limits._form()
        if self.probe is not None:
            data["probe"] = _Flow({"amplitude": format_quantity(self.probe.amplitude, "V"),
                                   "frequency": format_quantity(self.probe.frequency, "Hz")})
        if self.pause is not None:
            data["pause"] = _Flow(self.pause._form())
        if self.suspend:
            data["suspend"] = [_Flow(s._form()) for s in self.suspend]
        if self.preset is not None:
            data["preset"] = self.preset
            settings = _dump_fields(self.settings, "settings", only_set=True)
            if settings:
                data["settings"] = settings
        else:
            for channel in CHANNELS:
                data[channel] = [_Flow(_dump_fields(s, channel)) for s in getattr(self, channel)]
        return data


def protocol_from_mapping(mapping: Any, source: str = "<mapping>") -> ProtocolSpec:
    """`ProtocolSpec.from_mapping`: a protocol given as a mapping (as read from YAML)."""
    return ProtocolSpec.from_mapping(mapping, source)


def protocol_from_yaml(text: str, source: str = "<string>") -> ProtocolSpec:
    """`ProtocolSpec.from_yaml`: a protocol given as YAML text (e.g. a dataset attr)."""
    return ProtocolSpec.from_yaml(text, source)


def load_protocol(path: str | os.PathLike) -> ProtocolSpec:
    """`ProtocolSpec.load`: read and validate a protocol YAML file.

    Parameters
    ----------
    path : str or path-like
        The YAML file; a path that does not exist may name a packaged reference file
        (``"blocking_force"``, ``"blocking_force.yaml"`` or ``"protocols/blocking_force.yaml"``).

    Returns
    -------
    ProtocolSpec
        Frozen, in SI units.
        A preset stays a preset (`rdea_lab.protocols.expand` turns it into setpoints).

    Raises
    ------
    SpecError
        The file is missing, too large, not YAML, not a mapping, or a value is invalid; one line naming
        the file, the field and what is allowed.
    """
    return ProtocolSpec.load(path)


# ---------------------------------------------------------------- dump
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
    if getattr(model, "kind", None) == "table":  # the values in SI, the unit once (exact round trip)
        unit = {"unit": "V"} if channel == "voltage" else {}
        return {"kind": "table", "duration": format_quantity(model.duration, "s"), **unit,
                "values": _FlowList(float(v) for v in model.values)}
    out = {}
    for name, field in type(model).model_fields.items():
        if only_set and name not in model.model_fields_set:
            continue
        value = getattr(model, name)
        if value is not None:
            out[field.alias or name] = value if name == "kind" else _write(name, value, channel)
    return out


def dump_protocol(spec: ProtocolSpec) -> str:
    """`ProtocolSpec.dump`: a protocol as YAML with units; `protocol_from_yaml` reads it back equal."""
    return spec.dump()


__all__ = [
    "CHANNELS", "KINDS", "MAX_SAMPLES", "MAX_SAMPLE_RATE", "MEASURABLE", "PRESETS", "REST", "SEGMENTS",
    "SEGMENT_KINDS", "STRETCH_SEGMENTS", "VOLTAGE_SEGMENTS",
    "BlockingForceSettings", "CapacitanceSweepSettings", "Limits", "MAX_PROBE_AMPLITUDE", "PresetSchema", "Probe",
    "ProtocolSpec",
    "StretchChirp", "StretchHold", "StretchRamp", "StretchRampSine", "StretchSegment", "StretchSine", "StretchStep",
    "StretchTable", "VoltageTable", "MAX_TABLE_VALUES",
    "TensileRampSineSettings", "VoltageChirp", "VoltageHold", "VoltageRamp", "VoltageRampSine", "VoltageSegment",
    "VoltageSine", "VoltageStep",
    "channel_duration", "check_sample_count", "rate_text", "sample_count", "dump_protocol", "format_angle",
    "load_protocol", "protocol_from_mapping", "protocol_from_yaml",
]

