"""A run's overview: min/max envelopes of fixed blocks and the loop's raster, stored in the file beside the data.

Reading a day-long run (8.64e7 samples at 1 kHz, 7 variables: 4.8 GB as float64, zlib-compressed) takes
tens of seconds however it is sliced; its figure needs only each pixel column's smallest and largest value.
`write_overview` stores, in the netCDF group ``overview`` (which ``xarray.open_dataset`` does not open: the
run's own variables are as they were), for every float variable over ``time`` the `envelope` of each block
of `BLOCK` samples (``<name>_min``, ``<name>_max`` over the dimension ``block``) and the `occupancy` raster of
the force-displacement loop; `read_overview` gives it back. An envelope of whole blocks is the envelope of
the samples: the smallest of the blocks' minima is the smallest sample (`rdea_lab.reports.decimate`
draws from it when the samples per pixel column are a multiple of `BLOCK`).
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Samples read per variable and chunk (about 8 MB of float64).
CHUNK = 1 << 20
#: Samples per overview value (1 s at 1 kHz).
BLOCK = 1000
#: Runs of more samples than this get an overview when written.
OVERVIEW_ABOVE = 1_000_000
#: The loop raster's cells (rows along force, columns along displacement).
LOOP_SHAPE = (400, 500)
#: The netCDF group of the overview.
GROUP = "overview"


def _slice(source, a: int, b: int) -> np.ndarray:
    """Samples ``a`` to ``b - 1`` of a variable (xarray, lazily opened or loaded, netCDF4, or an array) as float."""
    part = source[a:b]
    return np.asarray(getattr(part, "values", part), float)


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
        with np.errstate(invalid="ignore"):  # a non-finite sample (inf * 0, NaN) falls outside every cell
            i = np.floor((xs - x0) * sx)
            j = np.floor((ys - y0) * sy)
        i[xs == x1] = cols - 1  # the upper edge belongs to the last cell
        j[ys == y1] = rows - 1
        ok = (i >= 0) & (i < cols) & (j >= 0) & (j < rows)
        j *= cols
        j += i
        counts += np.bincount(j[ok].astype(np.int64), minlength=rows * cols)
    return counts.reshape(rows, cols)


@dataclass(frozen=True)
class Overview:
    """What `read_overview` gives.

    Attributes
    ----------
    samples : int
        Samples of the run.
    block : int
        Samples per overview value.
    envelopes : dict of str to (numpy.ndarray, numpy.ndarray)
        Per float variable (``time`` included), the `envelope` of each block, ``(lo, hi)``.
    loop : numpy.ndarray or None
        `occupancy` counts of (position [m], force [N]) over `LOOP_SHAPE`; None without a position.
    loop_extent : tuple of float
        ``(position min, position max, force min, force max)`` [m, N] of the raster.
    """

    samples: int
    block: int
    envelopes: dict
    loop: np.ndarray | None
    loop_extent: tuple


class OverviewBuilder:
    """An overview gathered while a run's variables are written chunk by chunk (of any sizes, in order).

    Parameters
    ----------
    block : int
        Samples per overview value.

    Examples
    --------
    A writer that streams a run into a netCDF file ``nc`` (netCDF4, open for writing)::

        overview = OverviewBuilder()
        for start, stop, data in chunks:      # data: name -> the samples start..stop-1
            ...                                # write them
            overview.add(data)
        overview.write(nc)                     # before closing the file: the group and the loop's raster
    """

    def __init__(self, block: int = BLOCK):
        self.block = int(block)
        self.samples = 0
        self._parts = {}  # name -> (lo, hi) of the whole blocks so far (compact arrays: 8 bytes a value)
        self._open = {}  # name -> [samples, lo, hi] of the block being filled (its envelope so far, no samples)

    def add(self, data: dict) -> None:
        """Add the next samples of every float variable over ``time`` (``data``: name -> array, equal lengths)."""
        floats = {k: np.asarray(v, float) for k, v in data.items() if np.asarray(v).dtype.kind == "f"}
        for name, v in floats.items():
            parts = self._parts.setdefault(name, (array("d"), array("d")))
            part = self._open.setdefault(name, [0, math.nan, math.nan])
            k = min(self.block - part[0], v.size) if part[0] else 0  # the open block's missing samples first
            if k:
                head = v[:k]
                part[:] = [part[0] + k, np.fmin(part[1], np.fmin.reduce(head)), np.fmax(part[2], np.fmax.reduce(head))]
            if part[0] == self.block:
                parts[0].append(part[1])
                parts[1].append(part[2])
                part[:] = [0, math.nan, math.nan]
            whole = k + ((v.size - k) // self.block) * self.block
            if whole > k:
                lo, hi = envelope(v[k:whole], self.block)
                parts[0].extend(lo.tolist())
                parts[1].extend(hi.tolist())
            if whole < v.size:
                part[:] = [v.size - whole, np.fmin.reduce(v[whole:]), np.fmax.reduce(v[whole:])]
        if floats:
            self.samples += len(next(iter(floats.values())))

    def envelopes(self) -> dict:
        """``(lo, hi)`` of every block so far per variable (the last, partial block included)."""
        out = {}
        for name, (lo, hi) in self._parts.items():
            filled, *last = self._open[name]
            lo, hi = (np.concatenate([np.frombuffer(p, float) if len(p) else np.empty(0), [x] if filled else []])
                      for p, x in ((lo, last[0]), (hi, last[1])))
            out[name] = (lo, hi)
        return out

    def write(self, nc) -> None:
        """Write the ``overview`` group into ``nc`` (a netCDF4.Dataset open for writing that holds the run's
        ``position`` and ``force``: the loop's raster is a pass over those two, after their ranges are known).

        Raises
        ------
        ValueError
            ``nc`` already has an overview.
        """
        if GROUP in nc.groups:
            raise ValueError(f"{nc.filepath()}: already has an overview")
        n = self.samples
        g = nc.createGroup(GROUP)
        g.setncatts({"samples_per_block": np.int64(self.block), "samples": np.int64(n),
                     "comment": "min/max of each block of samples_per_block samples of each variable "
                                "(rdea_lab.store.overview), and the force-displacement loop's raster"})
        g.createDimension("block", math.ceil(n / self.block) if n else 0)
        ranges = {}
        for k, (lo, hi) in sorted(self.envelopes().items()):
            for suffix, values in (("min", lo), ("max", hi)):
                var = g.createVariable(f"{k}_{suffix}", "f8", ("block",), zlib=True, complevel=4)
                var[:] = values
            finite = np.isfinite(lo)
            ranges[k] = (float(lo[finite].min()), float(hi[finite].max())) if finite.any() else None
        if ranges.get("position") and ranges.get("force"):
            (x0, x1), (y0, y1) = ranges["position"], ranges["force"]
            x, y = nc.variables["position"], nc.variables["force"]
            x.set_auto_maskandscale(False)
            y.set_auto_maskandscale(False)
            counts = occupancy(x, y, n, (x0, x1), (y0, y1), LOOP_SHAPE)
            g.createDimension("loop_force", LOOP_SHAPE[0])
            g.createDimension("loop_position", LOOP_SHAPE[1])
            var = g.createVariable("loop", "i8", ("loop_force", "loop_position"), zlib=True, complevel=4)
            var[:] = counts
            var.setncatts({"extent": np.array([x0, x1, y0, y1]), "long_name": "samples per cell of (position "
                           "[m], force [N]) over extent = (position min, max, force min, max)"})


def write_overview(path, block: int = BLOCK, chunk: int = CHUNK) -> None:
    """Add the overview group to a run's netCDF file written by any writer (`add_overview`, the file opened
    for appending and closed; HDF5's lock is left to the close, as the file is not this process's alone).

    Parameters
    ----------
    path : path
        A run's ``.nc`` file, written and closed; opened for appending.
    block : int
        Samples per overview value.
    chunk : int
        About how many samples are read at once.

    Raises
    ------
    ValueError
        The file already has an overview.
    """
    import netCDF4
    from xarray.backends.locks import HDF5_LOCK  # HDF5 is not thread-safe: one call at a time, as xarray's

    with HDF5_LOCK:
        nc = netCDF4.Dataset(path, "a")
        try:
            add_overview(nc, block, chunk)
        finally:
            nc.close()


def add_overview(nc, block: int = BLOCK, chunk: int = CHUNK) -> None:
    """Add the overview group to a run's netCDF file open for writing (``nc``, a netCDF4.Dataset holding
    the run's variables: read chunk by chunk, every float variable over ``time``, then position and force
    again for the loop's raster). Call it holding xarray's ``HDF5_LOCK``.

    Raises
    ------
    ValueError
        The file already has an overview.
    """
    n = len(nc.dimensions["time"])
    names = [k for k, v in nc.variables.items() if v.dimensions == ("time",) and v.dtype.kind == "f"]
    for k in names:
        nc.variables[k].set_auto_maskandscale(False)  # the raw values (NaN is NaN); no masked arrays
    builder = OverviewBuilder(block)
    for a in range(0, n, chunk):
        builder.add({k: nc.variables[k][a:min(a + chunk, n)] for k in names})
    builder.write(nc)


def read_overview(ds) -> Overview | None:
    """The overview of a run: of its file (``ds.encoding["source"]``, or a path), or None when it has none.

    Parameters
    ----------
    ds : xarray.Dataset or path
        A run opened from its file, or the file.

    Returns
    -------
    Overview or None
        None also when ``ds`` is a dataset whose variables are in memory (loaded, maybe edited) or whose file
        now holds another run: the overview describes the file's values, not necessarily the dataset's.
    """
    import netCDF4
    from xarray.backends.locks import HDF5_LOCK  # HDF5 is not thread-safe: one call at a time, as xarray's

    given = not isinstance(ds, (str, Path))
    source = getattr(ds, "encoding", {}).get("source") if given else ds
    if not source or not Path(source).is_file():
        return None
    if given and any(getattr(v.variable, "_in_memory", True) for v in ds.data_vars.values() if "time" in v.dims):
        return None  # loaded, so perhaps changed since: the file's overview may not be of these values
    try:
        with HDF5_LOCK, netCDF4.Dataset(source) as nc:
            if GROUP not in nc.groups:
                return None
            if given and str(getattr(nc, "run_id", "")) != str(ds.attrs.get("run_id", "")):
                return None  # the file was replaced since the dataset was opened (another run written there)
            g = nc.groups[GROUP]
            g.set_auto_maskandscale(False)
            names = [k[:-4] for k in g.variables if k.endswith("_min")]
            env = {k: (np.asarray(g.variables[f"{k}_min"][:], float), np.asarray(g.variables[f"{k}_max"][:], float))
                   for k in names}
            loop = np.asarray(g.variables["loop"][:]) if "loop" in g.variables else None
            extent = tuple(float(x) for x in g.variables["loop"].getncattr("extent")) if loop is not None else ()
            return Overview(int(g.getncattr("samples")), int(g.getncattr("samples_per_block")), env, loop, extent)
    except (OSError, KeyError, AttributeError):
        return None
