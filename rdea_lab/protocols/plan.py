"""Plans: a protocol expanded into immutable setpoint arrays, checked against its limits.

A `Plan` describes; a backend executes it. It can be printed (`Plan.describe`)
and checked (`check_plan`) without any backend.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..specs.errors import SpecError
from ..specs.protocol import REST, Limits, ProtocolSpec, dump_protocol, load_protocol, rate_text, sample_count
from ..specs.limits import SLACK as _SLACK, limit_violations
from ..specs.units import format_quantity
from . import segments as seg
from .presets import expand_preset

def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class Plan:
    """A protocol as setpoints sampled at ``t_k = k / sample_rate``.

    Attributes
    ----------
    name, kind : str
    sample_rate : float
        [Hz].
    measure : tuple of str
        What the run records besides the setpoints (``force``, ``capacitance``).
    limits : Limits
    time : numpy.ndarray
        ``k / sample_rate`` for ``k = 0 .. N-1``, ``N = round(duration * rate) + 1`` [s]
        (`rdea_lab.specs.protocol.sample_count`).
    stretch : numpy.ndarray
        Stretch setpoints [-].
    voltage : numpy.ndarray
        Voltage setpoints [V], with the probe (``spec.probe``) added if there is one.
    stretch_segment, voltage_segment : numpy.ndarray of int32
        Index of the segment each sample belongs to, per channel.
    duration : float
        Sum of the segment durations [s].
    source : str
        File path, ``"<string>"`` or ``"<python>"``.
    spec : ProtocolSpec
        The protocol with explicit segments (a preset expanded).
    yaml : str
        `spec` as canonical YAML with units.

    All arrays are read-only.
    """

    name: str
    kind: str
    sample_rate: float
    measure: tuple[str, ...]
    limits: Limits
    time: np.ndarray
    stretch: np.ndarray
    voltage: np.ndarray
    stretch_segment: np.ndarray
    voltage_segment: np.ndarray
    duration: float
    source: str
    spec: ProtocolSpec
    yaml: str

    @property
    def samples(self) -> int:
        """Number of samples N."""
        return int(self.time.size)

    def summary(self) -> dict:
        """Plain numbers describing the plan (JSON-serializable)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "duration_s": float(self.duration),
            "samples": self.samples,
            "sample_rate_hz": float(self.sample_rate),
            "stretch_min": float(self.stretch.min()),
            "stretch_max": float(self.stretch.max()),
            "voltage_min_V": float(self.voltage.min()),
            "voltage_max_V": float(self.voltage.max()),
            "measure": list(self.measure),
            "segments": {"stretch": len(self.spec.stretch), "voltage": len(self.spec.voltage)},
        }

    def describe(self) -> str:
        """A few human lines: name, kind, duration, samples, envelope, limits, each segment."""
        s, lim = self.summary(), self.limits
        kv = lambda v: format_quantity(v, "kV", digits=4)  # noqa: E731
        lines = [
            f"{self.name} ({self.kind}) from {self.source}",
            f"  {_seconds(self.duration)}, {self.samples} samples at {rate_text(self.sample_rate, 6)};"
            f" measures {', '.join(self.measure)}",
            f"  stretch {s['stretch_min']:.6g} .. {s['stretch_max']:.6g}; "
            f"voltage {kv(s['voltage_min_V'])} .. {kv(s['voltage_max_V'])}",
            f"  limits: |voltage| <= {kv(lim.max_voltage)}, stretch <= {lim.max_stretch:g}, "
            f"|force| <= {format_quantity(lim.max_force, 'N', digits=4)}, "
            f"field <= {format_quantity(lim.max_field, 'V/um', digits=4)}",
        ]
        if self.spec.probe is not None:
            p = self.spec.probe
            lines.append(f"  probe: {format_quantity(p.amplitude, 'V', digits=6)} sine at "
                         f"{format_quantity(p.frequency, 'Hz', digits=6)} on the voltage (self-sensing)")
        for channel in ("stretch", "voltage"):
            start, previous = 0.0, REST[channel]
            for i, segment in enumerate(getattr(self.spec, channel)):
                end = start + segment.duration
                what = seg.describe(channel, segment, previous)
                lines.append(f"  {channel}[{i}] {_seconds(start)} .. {_seconds(end)}: {what}")
                start, previous = end, seg.end_value(segment, previous)
        return "\n".join(lines)

    def block_slices(self, seconds: float = 1.0) -> list[slice]:
        """Consecutive slices of at most `seconds` [s] worth of samples, covering all samples.

        Each block holds ``floor(seconds * sample_rate)`` samples (the last
        one may hold fewer).

        Raises
        ------
        ValueError
            If `seconds` holds less than one sample.
        """
        per = math.floor(seconds * self.sample_rate * (1.0 + _SLACK)) if math.isfinite(seconds) else 0
        if per < 1:
            raise ValueError(
                f"blocks of {seconds!r} s hold no sample at {self.sample_rate:g} Hz; "
                f"give at least {1.0 / self.sample_rate:g} s"
            )
        n = self.samples
        return [slice(a, min(a + per, n)) for a in range(0, n, per)]


def _seconds(t: float) -> str:
    return format_quantity(t, "s", digits=6)


def expand(spec: ProtocolSpec, *, source: str | None = None) -> Plan:
    """Expand a protocol (its preset first, if any) into a `Plan`.

    The spec was checked whole when it was made (`ProtocolSpec`: its sample count, a preset's
    expansion's too); expanding it only computes. Its limits are checked on the plan, by `check_plan`.

    Parameters
    ----------
    spec : ProtocolSpec
    source : str, optional
        Where `spec` came from, for messages and `Plan.source`; by default
        ``spec.origin`` (the file `load_protocol` read).

    Returns
    -------
    Plan
        Read-only setpoints at ``t_k = k / sample_rate``.
    """
    source = spec.origin if source is None else source
    explicit = expand_preset(spec.with_origin(source))
    duration, rate = explicit.duration, explicit.sample_rate
    n = sample_count(duration, rate)
    time = np.arange(n, dtype=float) / rate
    stretch, stretch_segment = seg.render("stretch", explicit.stretch, rate, n)
    voltage, voltage_segment = seg.render("voltage", explicit.voltage, rate, n)
    if explicit.probe is not None:  # on the whole channel, phase 0 at t = 0 (where the voltage rests at 0 V)
        voltage = voltage + explicit.probe.amplitude * np.sin(2.0 * np.pi * explicit.probe.frequency * time)
    return Plan(
        name=explicit.name, kind=explicit.kind, sample_rate=rate, measure=explicit.measure,
        limits=explicit.limits, time=_readonly(time),
        stretch=_readonly(stretch), voltage=_readonly(voltage),
        stretch_segment=_readonly(stretch_segment), voltage_segment=_readonly(voltage_segment),
        duration=duration, source=source, spec=explicit, yaml=dump_protocol(explicit),
    )


def load_plan(path: str | os.PathLike) -> Plan:
    """`expand` (`load_protocol` (path)): read, validate and expand a protocol file."""
    return expand(load_protocol(path))


def as_plan(protocol) -> Plan:
    """A `Plan` from a plan, a `ProtocolSpec` or the path of a protocol file."""
    if isinstance(protocol, Plan):
        return protocol
    if isinstance(protocol, ProtocolSpec):
        return expand(protocol)
    if isinstance(protocol, (str, os.PathLike)):
        return load_plan(protocol)
    raise TypeError(f"protocol: expected a Plan, a ProtocolSpec or the path of a protocol file (YAML), "
                    f"got {type(protocol).__name__}")


# ---------------------------------------------------------------- limits
def check_plan(plan: Plan, L3: float | None = None) -> list[SpecError]:
    """Every limit violation of a plan, one `LimitError` per check and segment.

    Checks: stretch >= 1 (the roll must stay in tension), stretch <=
    ``max_stretch``, ``|voltage| <= max_voltage`` (with the probe, if any) and, if `L3` is given, the
    field estimate ``E = |v| sqrt(stretch) / L3 <= max_field``. ``max_force``
    is enforced while running, not here.

    Parameters
    ----------
    plan : Plan
    L3 : float, optional
        Membrane thickness of the specimen [m].

    Returns
    -------
    list of LimitError
        Field ``stretch[i]`` or ``voltage[i]`` (the segment holding the worst
        sample); see `rdea_lab.specs.limits.limit_violations`. Empty if the
        plan is within its limits.
    """
    problems = limit_violations(plan.limits, plan.source, plan.time, plan.stretch, plan.voltage, L3,
                                plan.stretch_segment, plan.voltage_segment)
    probe = getattr(getattr(plan, "spec", None), "probe", None)  # a plan-like object may have no spec
    if probe is None:
        return problems
    with_probe = (f" (with the probe's {format_quantity(probe.amplitude, 'V', digits=6)} at "
                  f"{format_quantity(probe.frequency, 'Hz', digits=6)} on top: lower the voltage or the probe "
                  "amplitude)")
    return [type(p)(p.source, p.field, p.message + with_probe) if p.field.startswith("voltage") else p
            for p in problems]


def first_violation(plan: Plan, L3: float | None = None) -> None:
    """Raise the first `SpecError` of `check_plan` (plan, L3), if any.

    Raises
    ------
    SpecError
        The limit violation that happens first in time.
    """
    problems = check_plan(plan, L3)
    if problems:
        raise problems[0]


__all__ = ["Plan", "as_plan", "check_plan", "expand", "first_violation", "load_plan"]
