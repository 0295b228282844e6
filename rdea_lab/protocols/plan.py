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
from ..specs.protocol import REST, Limits, ProtocolSpec, dump_protocol, load_protocol, rate_text
from ..specs.units import format_quantity
from . import segments as seg
from .presets import expand_preset

#: relative slack of the limit checks: rounding of a ramp or sine that ends
#: exactly on a limit (a stretch of 1 - 1e-16) is not a violation
_SLACK = 1e-12


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
        ``k / sample_rate`` for ``k = 0 .. N-1``, ``N = round(duration * rate) + 1`` [s].
    stretch : numpy.ndarray
        Stretch setpoints [-].
    voltage : numpy.ndarray
        Voltage setpoints [V].
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

    Parameters
    ----------
    spec : ProtocolSpec
    source : str, optional
        Where `spec` came from, for messages and `Plan.source`; by default
        ``spec.origin`` (the file `load_protocol` read).

    Raises
    ------
    SpecError
        Attributed to `source`: the expanded preset has too many samples.
    """
    source = spec.origin if source is None else source
    try:
        explicit = expand_preset(spec.with_origin(source))
    except SpecError as err:
        raise err.with_source(source) from None
    duration, rate = explicit.duration, explicit.sample_rate
    n = round(duration * rate) + 1
    stretch, stretch_segment = seg.render("stretch", explicit.stretch, rate, n)
    voltage, voltage_segment = seg.render("voltage", explicit.voltage, rate, n)
    return Plan(
        name=explicit.name, kind=explicit.kind, sample_rate=rate, measure=explicit.measure,
        limits=explicit.limits, time=_readonly(np.arange(n, dtype=float) / rate),
        stretch=_readonly(stretch), voltage=_readonly(voltage),
        stretch_segment=_readonly(stretch_segment), voltage_segment=_readonly(voltage_segment),
        duration=duration, source=source, spec=explicit, yaml=dump_protocol(explicit),
    )


def load_plan(path: str | os.PathLike) -> Plan:
    """`expand` (`load_protocol` (path)): read, validate and expand a protocol file."""
    return expand(load_protocol(path))


# ---------------------------------------------------------------- limits
def _shown(value: float, limit: float, fmt) -> str:
    """`value` with just enough digits to differ from `limit`."""
    for digits in (4, 6, 9, 12, 17):
        text = fmt(value, digits)
        if text != fmt(limit, digits):
            return text
    return text


def check_plan(plan: Plan, L3: float | None = None) -> list[SpecError]:
    """Every limit violation of a plan, one `SpecError` per check and segment.

    Checks: stretch >= 1 (the roll must stay in tension), stretch <=
    ``max_stretch``, ``|voltage| <= max_voltage`` and, if `L3` is given, the
    field estimate ``E = |v| sqrt(stretch) / L3 <= max_field``. ``max_force``
    is enforced while running, not here.

    Parameters
    ----------
    plan : Plan
    L3 : float, optional
        Membrane thickness of the specimen [m].

    Returns
    -------
    list of SpecError
        Field ``stretch[i]`` or ``voltage[i]`` (the segment holding the worst
        sample); the message names the worst value, its time, the limit and,
        if more than one sample exceeds it, the span. Ordered by the time the
        limit is first exceeded. Empty if the plan is within its limits.
    """
    lim, t = plan.limits, plan.time
    found: list[tuple[float, int, SpecError]] = []

    def report(order, mask, excess, channel, segment, message):
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            return
        for group in np.split(idx, np.flatnonzero(np.diff(segment[idx])) + 1):
            worst = int(group[np.argmax(excess[group])])
            span = f" (exceeded from t = {_seconds(t[group[0]])} to {_seconds(t[group[-1]])})" if group.size > 1 else ""
            text = f"{message(worst)}{span}"
            found.append((t[group[0]], order, SpecError(plan.source, f"{channel}[{segment[worst]}]", text)))

    x, v = plan.stretch, plan.voltage
    at = lambda k: f"at t = {_seconds(t[k])}"  # noqa: E731
    plain = lambda value, digits: f"{value:.{digits}g}"  # noqa: E731
    volts = lambda value, digits: format_quantity(value, "kV", digits=digits)  # noqa: E731
    field = lambda value, digits: format_quantity(value, "V/um", digits=digits)  # noqa: E731

    report(0, x < 1.0 - _SLACK, 1.0 - x, "stretch", plan.stretch_segment,
           lambda k: f"stretch {_shown(x[k], 1.0, plain)} {at(k)} is below 1; the roll must stay in tension")
    report(1, x > lim.max_stretch * (1.0 + _SLACK), x - lim.max_stretch, "stretch", plan.stretch_segment,
           lambda k: f"stretch {_shown(x[k], lim.max_stretch, plain)} {at(k)} is above the limit "
                     f"max_stretch = {lim.max_stretch:g}")
    av = np.abs(v)
    report(2, av > lim.max_voltage * (1.0 + _SLACK), av, "voltage", plan.voltage_segment,
           lambda k: f"voltage {_shown(v[k], math.copysign(lim.max_voltage, v[k]), volts)} {at(k)} is "
                     f"{'above' if v[k] > 0 else 'beyond (in magnitude)'} the limit "
                     f"max_voltage = {volts(lim.max_voltage, 4)}")
    if L3 is not None:
        if not (math.isfinite(L3) and L3 > 0.0):
            raise ValueError(f"L3 must be a finite thickness > 0 m, got {L3!r}")
        E = av * np.sqrt(np.maximum(x, 0.0)) / L3
        report(3, E > lim.max_field * (1.0 + _SLACK), E, "voltage", plan.voltage_segment,
               lambda k: f"field estimate |v| sqrt(stretch) / L3 = {_shown(E[k], lim.max_field, field)} "
                         f"(voltage {volts(v[k], 4)}, stretch {x[k]:.4g}, L3 = {format_quantity(L3, 'um', digits=4)}) "
                         f"{at(k)} is above the limit max_field = {field(lim.max_field, 4)}")
    found.sort(key=lambda item: (item[0], item[1]))
    return [err for _, _, err in found]


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


__all__ = ["Plan", "check_plan", "expand", "first_violation", "load_plan"]
