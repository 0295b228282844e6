"""Plans: a protocol expanded into immutable setpoint arrays, checked against its limits.

A `Plan` describes; a backend executes it. It can be printed (`Plan.describe`)
and checked (`check_plan`) without any backend.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..physics.selection import envelope, envelope_indices
from ..specs.errors import SpecError
from ..specs.protocol import REST, Limits, ProtocolSpec, dump_protocol, load_protocol, rate_text, sample_count
from ..specs.limits import SLACK as _SLACK, Violations, limit_violations
from ..specs.units import format_quantity
from . import segments as seg
from .presets import expand_preset

#: Samples rendered at once when a plan is scanned whole without being held (summary, check, envelope).
CHUNK = 1 << 20
_ARRAYS = ("time", "stretch", "voltage", "stretch_segment", "voltage_segment")


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


class PlanWindow(NamedTuple):
    """Samples ``start .. stop-1`` of a plan (`Plan.window`): the same slices of its whole arrays.

    Attributes
    ----------
    time : numpy.ndarray
        ``k / sample_rate`` [s].
    stretch : numpy.ndarray
        Stretch setpoints [-].
    voltage : numpy.ndarray
        Voltage setpoints [V] (with the probe, if any).
    stretch_segment, voltage_segment : numpy.ndarray of int32
        Segment of each sample, per channel.
    """

    time: np.ndarray
    stretch: np.ndarray
    voltage: np.ndarray
    stretch_segment: np.ndarray
    voltage_segment: np.ndarray


class _Lazy:
    """A plan's array: given to the constructor, or rendered from its spec on first use and kept."""

    def __set_name__(self, owner, name):
        self.name, self.slot = name, "_" + name

    def __get__(self, plan, owner=None):
        if plan is None:
            return None  # the dataclass default: render from the spec
        value = plan.__dict__.get(self.slot)
        if value is None:
            value = plan._whole(self.name)
            plan.__dict__[self.slot] = value
        return value

    def __set__(self, plan, value):
        plan.__dict__[self.slot] = None if value is None else np.asarray(value)


@dataclass(frozen=True, eq=False, repr=False)
class Plan:
    """A protocol as setpoints sampled at ``t_k = k / sample_rate``.

    The arrays are computed from `spec` when first read and kept (read-only); a plan too long to hold
    is read in windows instead (`window`), and `summary`, `describe`, `block_slices` and `check_plan`
    never hold it whole.

    Attributes
    ----------
    name, kind : str
    sample_rate : float
        [Hz].
    measure : tuple of str
        What the run records besides the setpoints (``force``, ``capacitance``).
    limits : Limits
    duration : float
        Sum of the segment durations [s].
    source : str
        File path, ``"<string>"`` or ``"<python>"``.
    spec : ProtocolSpec
        The protocol with explicit segments (a preset expanded).
    yaml : str
        `spec` as canonical YAML with units.
    time : numpy.ndarray
        ``k / sample_rate`` for ``k = 0 .. N-1``, ``N = round(duration * rate) + 1`` [s]
        (`rdea_lab.specs.protocol.sample_count`).
    stretch : numpy.ndarray
        Stretch setpoints [-].
    voltage : numpy.ndarray
        Voltage setpoints [V], with the probe (``spec.probe``) added if there is one.
    stretch_segment, voltage_segment : numpy.ndarray of int32
        Index of the segment each sample belongs to, per channel.

    All arrays are read-only. An array given to the constructor (``dataclasses.replace(plan,
    voltage=...)``) is the plan's; the others come from `spec`.
    """

    name: str
    kind: str
    sample_rate: float
    measure: tuple[str, ...]
    limits: Limits
    duration: float
    source: str
    spec: ProtocolSpec
    yaml: str
    time: np.ndarray = _Lazy()
    stretch: np.ndarray = _Lazy()
    voltage: np.ndarray = _Lazy()
    stretch_segment: np.ndarray = _Lazy()
    voltage_segment: np.ndarray = _Lazy()

    def __repr__(self) -> str:
        return f"Plan({self.name!r}, {self.kind!r}, {self.samples} samples at {self.sample_rate:g} Hz, {self.source!r})"

    @property
    def samples(self) -> int:
        """Number of samples N."""
        given = self.__dict__.get("_time")
        return int(given.size) if given is not None else sample_count(self.duration, self.sample_rate)

    # ------------------------------------------------------------ rendering
    def _layout(self, channel: str) -> seg.Layout:
        key = "_layout_" + channel
        if key not in self.__dict__:
            self.__dict__[key] = seg.layout(channel, getattr(self.spec, channel), self.sample_rate, self.samples)
        return self.__dict__[key]

    def _render(self, name: str, start: int, stop: int, at=None) -> np.ndarray:
        """One array of the plan over ``[start, stop)`` (or at the indices ``at``), computed from `spec`."""
        if name == "time":
            return (np.arange(start, stop, dtype=float) if at is None else at.astype(float)) / self.sample_rate
        channel = name.partition("_")[0]
        values, index = seg.render(channel, getattr(self.spec, channel), self.sample_rate, self.samples, start,
                                   stop, at=at, where=self._layout(channel))
        if name.endswith("_segment"):
            return index
        probe = self.spec.probe
        if channel == "voltage" and probe is not None:  # on the whole channel, phase 0 at t = 0 (0 V rest)
            values = values + probe.amplitude * np.sin(2.0 * np.pi * probe.frequency * self._render("time", start,
                                                                                                   stop, at))
        return values

    def _whole(self, name: str) -> np.ndarray:
        return _readonly(self._render(name, 0, self.samples))

    def held(self) -> dict:
        """The arrays the plan holds (given to it, or computed and kept since first read), by name."""
        return {name: self.__dict__["_" + name] for name in _ARRAYS if self.__dict__.get("_" + name) is not None}

    def rendered(self, name: str, size: int | None = None):
        """One array (``time``, ``stretch``, ...) as computed from `spec`, window by window (an array held
        is not read): yields arrays of at most `size` samples (default `CHUNK`)."""
        if name not in _ARRAYS:
            raise ValueError(f"{name!r} is not an array of a plan; allowed: {', '.join(_ARRAYS)}")
        n, size = self.samples, CHUNK if size is None else size
        for a in range(0, n, size):
            yield self._render(name, a, min(a + size, n))

    def definition(self) -> str:
        """What the arrays not held are computed from, as text: `spec` (JSON, floats exact), the rate [Hz],
        the duration [s] and the number of samples."""
        return json.dumps([self.spec.model_dump_json(), float(self.sample_rate).hex(), float(self.duration).hex(),
                           self.samples])

    def window(self, start: int, stop: int) -> PlanWindow:
        """Samples ``start .. stop-1`` of the plan, without computing the others.

        Equal, bit for bit, to the same slices of the whole arrays (an array already held, or given, is
        sliced: a view).

        Parameters
        ----------
        start, stop : int
            ``0 <= start <= stop <= samples``.

        Returns
        -------
        PlanWindow
            Read-only arrays of ``stop - start`` samples.

        Raises
        ------
        ValueError
            A window outside ``[0, samples]``.
        """
        n = self.samples
        start, stop = int(start), int(stop)
        if not 0 <= start <= stop <= n:
            raise ValueError(f"window [{start}, {stop}) is not within the plan's {n} samples")
        out = []
        for name in _ARRAYS:
            held = self.__dict__.get("_" + name)
            out.append(held[start:stop] if held is not None else _readonly(self._render(name, start, stop)))
        return PlanWindow(*out)

    def at(self, indices) -> PlanWindow:
        """The samples at `indices` (increasing, each in ``[0, samples)``), without computing the others."""
        at = np.asarray(indices, dtype=np.int64)
        out = []
        for name in _ARRAYS:
            held = self.__dict__.get("_" + name)
            out.append(held[at] if held is not None else self._render(name, 0, 0, at))
        return PlanWindow(*out)

    def windows(self, size: int | None = None):
        """Consecutive windows of at most `size` samples (default `CHUNK`) covering the plan: yields
        ``(start, PlanWindow)``."""
        n, size = self.samples, CHUNK if size is None else size
        for a in range(0, n, size):
            yield a, self.window(a, min(a + size, n))

    def _scan(self, also=None) -> dict:
        """Extremes of the setpoints over the whole plan, window by window (kept); ``also(start, window)``
        is called with each window on the way (one pass for the check and the extremes)."""
        if "_scanned" in self.__dict__ and also is not None:
            for a, w in self.windows():
                also(a, w)
        if "_scanned" not in self.__dict__:
            x_lo = x_hi = v_lo = v_hi = None
            x_arg = v_arg = 0
            finite = True
            x_top = v_top = -np.inf
            for a, w in self.windows():
                if also is not None:
                    also(a, w)
                av = np.abs(w.voltage)
                finite = finite and bool(np.isfinite(w.stretch).all() and np.isfinite(av).all())
                parts = (w.stretch.min(), w.stretch.max(), w.voltage.min(), w.voltage.max())
                x_lo, x_hi, v_lo, v_hi = parts if x_lo is None else (
                    min(x_lo, parts[0]), max(x_hi, parts[1]), min(v_lo, parts[2]), max(v_hi, parts[3]))
                i, j = int(np.argmax(w.stretch)), int(np.argmax(av))
                if w.stretch[i] > x_top:  # the first of equal largest ones, as numpy.argmax over the whole
                    x_top, x_arg = w.stretch[i], a + i
                if av[j] > v_top:
                    v_top, v_arg = av[j], a + j
            self.__dict__["_scanned"] = {"stretch_min": float(x_lo), "stretch_max": float(x_hi),
                                         "voltage_min": float(v_lo), "voltage_max": float(v_hi),
                                         "stretch_argmax": x_arg, "abs_voltage_argmax": v_arg,
                                         "finite": finite}
        return self.__dict__["_scanned"]

    def envelope(self, max_points: int = 2000) -> tuple[np.ndarray, np.ndarray]:
        """The (stretch, |voltage|) samples `rdea_lab.physics.selection.envelope` picks from the whole
        arrays, computed without them: evenly spaced samples and those of largest stretch and |voltage|.

        Parameters
        ----------
        max_points : int
            At most this many samples.

        Returns
        -------
        stretch : numpy.ndarray
            [-].
        voltage : numpy.ndarray
            ``|voltage|`` [V].
        """
        scan = self._scan()
        if not scan["finite"]:  # envelope drops non-finite samples first: only the whole arrays say which
            return envelope(self.stretch, self.voltage, max_points)
        w = self.at(envelope_indices(self.samples, scan["stretch_argmax"], scan["abs_voltage_argmax"], max_points))
        return np.asarray(w.stretch, float), np.abs(np.asarray(w.voltage, float))

    def decimated(self, columns: int = 2000) -> dict:
        """The setpoints to draw: each channel's smallest and largest sample in each of `columns` runs
        of consecutive samples, at their own times and in their order, so a spike stays visible; the
        whole arrays when the plan has at most ``2 columns`` samples. Window by window.

        Parameters
        ----------
        columns : int
            Runs of samples (pixel columns of a figure), >= 1.

        Returns
        -------
        dict
            ``{"stretch": (time [s], stretch [-]), "voltage": (time [s], voltage [V]), "per_column": k}``
            with ``k`` the samples per run (1: not decimated).
        """
        n = self.samples
        if n <= 2 * columns:
            w = self.window(0, n)
            return {"stretch": (w.time, w.stretch), "voltage": (w.time, w.voltage), "per_column": 1}
        per = -(-n // columns)
        size = max(per, CHUNK // per * per)
        picks = {"stretch": [], "voltage": []}
        for a, w in self.windows(size):
            whole = w.time.size // per * per
            for name in picks:
                values = getattr(w, name)
                rows = [values[:whole].reshape(-1, per)] if whole else []
                starts = [np.arange(0, whole, per)] if whole else []
                if whole < values.size:  # the last, shorter run
                    rows.append(values[whole:][None, :])
                    starts.append(np.array([whole]))
                for r, first in zip(rows, starts):
                    lo, hi = np.argmin(r, axis=1), np.argmax(r, axis=1)
                    k = np.sort(np.stack([first + lo, first + hi], axis=1), axis=1).ravel()
                    picks[name].append(a + k)
        out = {"per_column": per}
        for name, parts in picks.items():
            k = np.concatenate(parts)
            w = self.at(np.unique(k))
            out[name] = (w.time, getattr(w, name))
        return out

    def summary(self) -> dict:
        """Plain numbers describing the plan (JSON-serializable)."""
        scan = self._scan()
        return {
            "name": self.name,
            "kind": self.kind,
            "duration_s": float(self.duration),
            "samples": self.samples,
            "sample_rate_hz": float(self.sample_rate),
            "stretch_min": scan["stretch_min"],
            "stretch_max": scan["stretch_max"],
            "voltage_min_V": scan["voltage_min"],
            "voltage_max_V": scan["voltage_max"],
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
        pause = self.spec.pause
        if pause is not None:
            held = ("the stretch it had" if pause.hold_stretch is None else
                    f"stretch {pause.hold_stretch:g} (reached at {pause.stretch_rate:.6g} /s)")
            lines.append(f"  pause: voltage to 0 at {format_quantity(pause.ramp_rate, 'kV/s', digits=6)}, "
                         f"holding {held}")
        for s in self.spec.suspend:
            name = f" ({s.name})" if s.name else ""
            wait = format_quantity(s.wait, "min" if s.wait >= 60.0 else "s", digits=6)
            lines.append(f"  suspend{name}: pause while {s.when.text}; resume once {s.resume_text}; "
                         f"abort if not resumed within {wait}")
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
        Read-only setpoints at ``t_k = k / sample_rate``, computed when first read (or in windows).
    """
    source = spec.origin if source is None else source
    explicit = expand_preset(spec.with_origin(source))
    return Plan(
        name=explicit.name, kind=explicit.kind, sample_rate=explicit.sample_rate, measure=explicit.measure,
        limits=explicit.limits, duration=explicit.duration, source=source, spec=explicit,
        yaml=dump_protocol(explicit),
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
    if hasattr(plan, "windows"):  # window by window: a long plan is never held whole
        found = Violations(plan.limits, plan.source, L3)

        def add(_, w):
            found.add(w.time, w.stretch, w.voltage, w.stretch_segment, w.voltage_segment)

        if isinstance(plan, Plan):  # the plan's extremes (summary, envelope) in the same pass
            plan._scan(also=add)
        else:
            for a, w in plan.windows():
                add(a, w)
        problems = found.errors()
    else:  # a plan-like object with whole arrays
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


__all__ = ["CHUNK", "Plan", "PlanWindow", "as_plan", "check_plan", "expand", "first_violation", "load_plan"]
