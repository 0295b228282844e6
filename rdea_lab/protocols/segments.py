"""Waveform segments sampled into setpoint arrays.

Each segment is evaluated at its local time ``t`` [s] (``0 <= t <= T``, ``T``
its duration) given ``previous``, the value at the end of the previous
segment (the channel's rest value for the first: stretch 1, voltage 0 V).
Evaluation is vectorized over ``t``; `render` loops over segments only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..specs.protocol import REST, format_angle
from ..specs.units import format_quantity

#: sample positions closer than this (relative) to a whole sample are snapped
#: to it, so a segment boundary at 0.1 + 0.2 s falls on sample 30 at 100 Hz
_SNAP = 1e-9


def evaluate(segment, t, previous: float) -> np.ndarray:
    """Values of `segment` at local times `t`.

    Parameters
    ----------
    segment : segment model
        One of `rdea_lab.specs.protocol.SEGMENTS` (either channel).
    t : array_like
        Time since the segment's start [s].
    previous : float
        Value at the end of the previous segment [-] or [V].

    Returns
    -------
    numpy.ndarray
        Setpoints [-] (stretch) or [V] (voltage), same shape as `t`.

    Notes
    -----
    ``hold``: value (default previous); ``step``: value; ``ramp``:
    from (default previous) + (to - from) t / T; ``sine``: mean + amplitude
    sin(2 pi f t + phase); ``ramp_sine``: base + (peak(t) - base)
    (1 - cos(2 pi f t)) / 2 with peak(t) = peak_start + (peak_end -
    peak_start) t / T; ``chirp``: mean + amplitude sin(2 pi (f_start t +
    (f_end - f_start) t^2 / (2 T))); ``table``: values[j] at t = j T / (n - 1), linear in between.
    Ramps, tables and the ramp sine are written as
    convex combinations ``a (1 - w) + b w``, so they hit their end points
    (w = 0, 1) exactly.
    """
    t = np.asarray(t, dtype=float)
    kind, T = segment.kind, segment.duration
    if kind in ("hold", "step"):
        value = previous if segment.value is None else segment.value
        return np.full(t.shape, value)
    if kind == "ramp":
        start = previous if segment.from_ is None else segment.from_
        w = t / T
        return start * (1.0 - w) + segment.to * w
    if kind == "sine":
        return segment.mean + segment.amplitude * np.sin(2.0 * np.pi * segment.frequency * t + segment.phase)
    if kind == "ramp_sine":
        peak = segment.peak_start + (segment.peak_end - segment.peak_start) * (t / T)
        w = 0.5 * (1.0 - np.cos(2.0 * np.pi * segment.frequency * t))
        return segment.base * (1.0 - w) + peak * w
    if kind == "table":
        values = np.asarray(segment.values, dtype=float)
        w = np.clip(t / T, 0.0, 1.0) * (values.size - 1)
        i = np.minimum(np.floor(w).astype(np.int64), values.size - 2)
        f = w - i
        return values[i] * (1.0 - f) + values[i + 1] * f
    if kind == "chirp":
        f0, f1 = segment.f_start, segment.f_end
        return segment.mean + segment.amplitude * np.sin(2.0 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2.0 * T)))
    raise ValueError(f"unknown segment kind {kind!r}")


def end_value(segment, previous: float) -> float:
    """Value of `segment` at its end, ``t = T`` (the next segment's `previous`)."""
    return float(evaluate(segment, np.array([segment.duration]), previous)[0])


def first_samples(durations, sample_rate: float, n: int) -> np.ndarray:
    """Index of the first sample of each segment.

    Sample ``k`` (at ``t_k = k / rate``) belongs to the last segment that
    starts at or before ``t_k``: a boundary sample belongs to the later
    segment.

    Parameters
    ----------
    durations : sequence of float
        Segment durations [s].
    sample_rate : float
        [Hz].
    n : int
        Number of samples.
    """
    starts = np.concatenate(([0.0], np.cumsum(np.asarray(durations, dtype=float))[:-1])) * sample_rate
    whole = np.round(starts)
    starts = np.where(np.abs(starts - whole) <= _SNAP * np.maximum(1.0, whole), whole, starts)
    return np.clip(np.ceil(starts), 0, n).astype(np.int64)


class Layout(NamedTuple):
    """Where a channel's segments lie in its samples (`layout`).

    Attributes
    ----------
    lo, hi : numpy.ndarray of int64
        First sample of each segment, and one past its last.
    begin : tuple of float
        Each segment's start time [s] (the running sum of the durations before it).
    previous : tuple of float
        The value each segment starts from (the previous segment's end value; the channel's rest value first).
    """

    lo: np.ndarray
    hi: np.ndarray
    begin: tuple
    previous: tuple


def layout(channel: str, segments, sample_rate: float, n: int) -> Layout:
    """The samples and start values of each segment of a channel of ``n`` samples (`render` reads it).

    Parameters
    ----------
    channel : {"stretch", "voltage"}
    segments : sequence of segment models
    sample_rate : float
        [Hz].
    n : int
        Number of samples.

    Returns
    -------
    Layout
    """
    lo = first_samples([s.duration for s in segments], sample_rate, n)
    hi = np.append(lo[1:], n)
    begins, previous = [], []
    begin, value = 0.0, REST[channel]
    for segment in segments:
        begins.append(begin)
        previous.append(value)
        value = end_value(segment, value)
        begin += segment.duration
    return Layout(lo, hi, tuple(begins), tuple(previous))


def render(channel: str, segments, sample_rate: float, n: int, start: int = 0, stop: int | None = None, *,
           at=None, where: Layout | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Sample one channel at ``t_k = k / rate`` for ``k = start .. stop-1`` (by default all ``n`` samples).

    A window is the same slice of the whole channel, bit for bit: each sample is
    evaluated by itself from ``k``, its segment and that segment's start.

    Parameters
    ----------
    channel : {"stretch", "voltage"}
    segments : sequence of segment models
    sample_rate : float
        [Hz].
    n : int
        Number of samples of the whole channel.
    start, stop : int, optional
        The window ``[start, stop)`` of sample indices, ``0 <= start <= stop <= n``; default ``[0, n)``.
    at : array_like of int, optional
        Instead of a window: these sample indices (increasing, each in ``[0, n)``).
    where : Layout, optional
        `layout` (channel, segments, sample_rate, n), computed once for many windows.

    Returns
    -------
    values : numpy.ndarray
        Setpoints [-] or [V], one per sample asked for.
    index : numpy.ndarray of int32
        Index of the segment each sample belongs to.

    Notes
    -----
    Local times are clipped to ``[0, T]``: the last sample may lie up to half
    a sample period after the protocol's end (``n = round(duration * rate) +
    1``) and then holds the last segment's end value.
    """
    lo, hi, begins, previous = layout(channel, segments, sample_rate, n) if where is None else where
    if at is None:
        stop = n if stop is None else stop
        if not 0 <= start <= stop <= n:
            raise ValueError(f"window [{start}, {stop}) is not within the {n} samples")
        m = stop - start
        time = np.arange(start, stop, dtype=float) / sample_rate
        first, last = np.clip(lo - start, 0, m), np.clip(hi - start, 0, m)
    else:
        at = np.asarray(at, dtype=np.int64)
        if at.size and (at[0] < 0 or at[-1] >= n or np.any(np.diff(at) <= 0)):
            raise ValueError(f"sample indices must increase within [0, {n})")
        m = at.size
        time = at.astype(float) / sample_rate
        first, last = np.searchsorted(at, lo), np.searchsorted(at, hi)
    values = np.empty(m)
    index = np.empty(m, dtype=np.int32)
    for i in np.flatnonzero(last > first).tolist():
        a, b = int(first[i]), int(last[i])
        t = np.clip(time[a:b] - begins[i], 0.0, segments[i].duration)
        values[a:b] = evaluate(segments[i], t, previous[i])
        index[a:b] = i
    return values, index


def _value(channel: str, value: float) -> str:
    return format_quantity(value, "kV", digits=6) if channel == "voltage" else f"{value:.6g}"


def describe(channel: str, segment, previous: float | None = None) -> str:
    """One short line on what `segment` does, e.g. ``ramp 0 kV -> 2.6 kV``.

    `previous` (the value the segment starts from) fills in a hold or ramp
    that continues from the previous segment.
    """
    v = lambda x: _value(channel, x)  # noqa: E731
    hz = lambda x: format_quantity(x, "Hz", digits=6)  # noqa: E731
    before = "the previous value" if previous is None else v(previous)
    kind = segment.kind
    if kind == "hold":
        return f"hold {before} (previous)" if segment.value is None else f"hold {v(segment.value)}"
    if kind == "step":
        return f"step to {v(segment.value)}"
    if kind == "ramp":
        start = f"{before} (previous)" if segment.from_ is None else v(segment.from_)
        return f"ramp {start} -> {v(segment.to)}"
    if kind == "sine":
        phase = "" if segment.phase == 0.0 else f", phase {format_angle(segment.phase)}"
        return f"sine {v(segment.mean)} +- {v(segment.amplitude)} at {hz(segment.frequency)}{phase}"
    if kind == "ramp_sine":
        return (f"ramp_sine base {v(segment.base)}, peak {v(segment.peak_start)} -> {v(segment.peak_end)} "
                f"at {hz(segment.frequency)}")
    if kind == "table":
        values = segment.values
        return (f"table of {len(values)} values {v(values[0])} -> {v(values[-1])} "
                f"(range {v(min(values))} .. {v(max(values))})")
    return (f"chirp {v(segment.mean)} +- {v(segment.amplitude)}, "
            f"{hz(segment.f_start)} -> {hz(segment.f_end)}")


__all__ = ["Layout", "describe", "end_value", "evaluate", "first_samples", "layout", "render"]
