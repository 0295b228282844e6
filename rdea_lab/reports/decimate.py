"""Decimation for display: a min/max envelope per pixel column, read chunk by chunk.

A line of a day-long run (8.64e7 samples at 1 kHz) has far more samples than a
figure has pixel columns. `envelope` cuts a series into columns of ``per``
consecutive samples and keeps each column's smallest and largest finite value;
drawn as a vertical stroke per column (`stroke`), that is what the full line
looks like at that resolution, and a single-sample spike stays visible (it is
its column's maximum). `envelopes` computes it for several variables of a
dataset that is opened lazily (:func:`rdea_lab.store.open_run`), reading
``ds[name][a:b]`` slices of whole columns, so memory stays bounded by one chunk.
`occupancy` does the same for an x-y curve (the force-displacement loop): the
pixels of a raster that any sample falls in, accumulated chunk by chunk.
"""

from __future__ import annotations

import math

import numpy as np

from ..store.overview import CHUNK, _slice, envelope, occupancy  # noqa: F401 (the store writes overviews with them)


def samples_per_column(n: int, columns: int) -> int:
    """Samples per pixel column, ``ceil(n / columns)`` (at least 1): `envelope` then has at most ``columns``
    columns."""
    return max(1, math.ceil(int(n) / max(1, int(columns))))


def column_chunk(per: int, chunk: int = CHUNK) -> int:
    """Samples per read: a whole number of columns of ``per`` samples, about ``chunk`` samples."""
    return per * max(1, chunk // per)


def envelopes(sources: dict, n: int, per: int, chunk: int = CHUNK) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """`envelope` of several series, read ``column_chunk(per, chunk)`` samples at a time.

    Parameters
    ----------
    sources : dict of str to sliceable
        Each ``n`` samples long: ``ds[name]`` of a dataset (opened lazily or loaded), or an array;
        ``sources[name][a:b]`` is all that is read.
    n : int
        Samples of each series.
    per : int
        Samples per column.
    chunk : int
        About how many samples are read at once per series.

    Returns
    -------
    dict of str to (numpy.ndarray, numpy.ndarray)
        ``(lo, hi)`` per name, the same as ``envelope(whole_series, per)``.
    """
    step = column_chunk(per, chunk)
    parts = {name: ([], []) for name in sources}
    for a in range(0, n, step):
        b = min(a + step, n)
        for name, source in sources.items():
            lo, hi = envelope(_slice(source, a, b), per)
            parts[name][0].append(lo)
            parts[name][1].append(hi)
    return {name: (np.concatenate(lo) if lo else np.empty(0), np.concatenate(hi) if hi else np.empty(0))
            for name, (lo, hi) in parts.items()}


def first_of_columns(source, n: int, per: int, chunk: int = CHUNK) -> np.ndarray:
    """The first sample of each column (the abscissa of a column: its start time [s] for ``time``)."""
    step = column_chunk(per, chunk)
    return np.concatenate([_slice(source, a, min(a + step, n))[::per] for a in range(0, n, step)]
                          or [np.empty(0)])


def stroke(x, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Vertices of a line that draws each column from its ``lo`` to its ``hi`` at abscissa ``x`` and joins
    the columns (``x0, x0, x1, x1, ...`` against ``lo0, hi0, lo1, hi1, ...``)."""
    x, lo, hi = (np.asarray(a, float) for a in (x, lo, hi))
    return np.repeat(x, 2), np.column_stack([lo, hi]).ravel()
