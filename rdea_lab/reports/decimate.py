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

#: Samples read per variable and chunk (about 8 MB of float64).
CHUNK = 1 << 20


def samples_per_column(n: int, columns: int) -> int:
    """Samples per pixel column, ``ceil(n / columns)`` (at least 1): `envelope` then has at most ``columns``
    columns."""
    return max(1, math.ceil(int(n) / max(1, int(columns))))


def envelope(values, per: int) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest finite value of each column of ``per`` consecutive samples.

    Parameters
    ----------
    values : array_like, shape (n,)
        A series (any unit; NaN ignored).
    per : int
        Samples per column, >= 1 (`samples_per_column`).

    Returns
    -------
    lo, hi : numpy.ndarray, shape (ceil(n / per),)
        Column ``j`` covers samples ``j * per`` to ``min((j + 1) * per, n) - 1`` (the last column holds the
        remainder, fewer than ``per`` samples); NaN where a column has no finite value.

    Raises
    ------
    ValueError
        ``per`` below 1.
    """
    if per < 1:
        raise ValueError(f"per: {per}; allowed: an integer >= 1")
    v = np.asarray(values, float).ravel()
    whole = (v.size // per) * per
    parts = [v[:whole].reshape(-1, per)] if whole else []
    if whole < v.size:
        parts.append(v[whole:].reshape(1, -1))
    lo = [np.fmin.reduce(p, axis=1) for p in parts]  # fmin/fmax skip NaN (an all-NaN column stays NaN)
    hi = [np.fmax.reduce(p, axis=1) for p in parts]
    if not parts:
        return np.empty(0), np.empty(0)
    return np.concatenate(lo), np.concatenate(hi)


def column_chunk(per: int, chunk: int = CHUNK) -> int:
    """Samples per read: a whole number of columns of ``per`` samples, about ``chunk`` samples."""
    return per * max(1, chunk // per)


def _slice(source, a: int, b: int) -> np.ndarray:
    """Samples ``a`` to ``b - 1`` of a variable (xarray, lazily opened or loaded, or an array) as float."""
    part = source[a:b]
    return np.asarray(getattr(part, "values", part), float)


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


def occupancy(x, y, n: int, xlim, ylim, shape, chunk: int = CHUNK // 4) -> np.ndarray:
    """Which cells of a raster over ``xlim`` x ``ylim`` hold at least one sample of the curve (x, y).

    Parameters
    ----------
    x, y : sliceable
        ``n`` samples each (``ds[name]`` or arrays; NaN samples are skipped).
    n : int
        Samples.
    xlim, ylim : (float, float)
        The raster's extent, in the unit of ``x`` and ``y`` (samples outside are skipped).
    shape : (int, int)
        Cells (rows along y, columns along x), about the panel's size in pixels.
    chunk : int
        Samples read at once.

    Returns
    -------
    numpy.ndarray of int64, shape ``shape``
        Samples per cell (row 0 at ``ylim[0]``).
    """
    rows, cols = (int(s) for s in shape)
    counts = np.zeros(rows * cols, np.int64)
    (x0, x1), (y0, y1) = (map(float, xlim)), (map(float, ylim))
    sx = cols / (x1 - x0) if x1 > x0 else 0.0
    sy = rows / (y1 - y0) if y1 > y0 else 0.0
    for a in range(0, n, chunk):
        b = min(a + chunk, n)
        xs, ys = _slice(x, a, b), _slice(y, a, b)
        i = np.floor((xs - x0) * sx)
        j = np.floor((ys - y0) * sy)
        i[xs == x1] = cols - 1  # the upper edge belongs to the last cell
        j[ys == y1] = rows - 1
        ok = (i >= 0) & (i < cols) & (j >= 0) & (j < rows)
        j *= cols
        j += i
        counts += np.bincount(j[ok].astype(np.int64), minlength=rows * cols)
    return counts.reshape(rows, cols)
