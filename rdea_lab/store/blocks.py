"""Writing a dataset over ``time`` block by block (a prediction of a day-long run), in bounded memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..specs.variables import variable_attrs
from ._hdf5 import create, publish, remove_own, unlock
from .journal import CHUNK, COMPRESSION, _fsync_dir, actual_range, netcdf_attrs
from .outputs import check_dataset_name, check_new


def write_blocks(path, samples: int, blocks, attrs, *, time_attrs=None, overwrite: bool = False) -> Path:
    """Write the blocks ``(start, stop, {name: array})`` of a dataset over ``time`` to a netCDF file, one at a time.

    Parameters
    ----------
    path : path
        The ``.nc`` file to write; written as ``<path>.tmp`` and renamed when complete (a file that is
        there is whole).
    samples : int
        Samples of every variable (the blocks cover 0 to ``samples - 1`` in order).
    blocks : iterable
        ``(start, stop, data)``: ``data`` maps each variable (its ``units`` and ``long_name`` from
        `rdea_lab.specs.variables`) to samples ``start`` to ``stop - 1``; one of them is ``time`` [s].
    attrs : callable
        ``attrs()`` gives the global attributes, asked for after the last block (so they can say what the
        blocks found).
    time_attrs : dict, optional
        The ``time`` coordinate's attributes (the run's: ``units`` ``seconds since ...``).
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputError
        ``path`` exists (and not ``overwrite``), is no ``.nc`` name or cannot be written.
    ValueError
        Blocks that do not cover the samples in order.
    """

    path = Path(path)
    check_dataset_name(path)
    check_new(path, overwrite)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    ranges = {}
    ident = None
    try:
        nc, ident = create(tmp)  # a dead write's half file removed; of two writers that made way, one makes it
        with nc:
            nc.createDimension("time", samples)
            made, end = {}, 0
            for start, stop, data in blocks:
                if start != end:
                    raise ValueError(f"write_blocks: a block starts at sample {start}, after {end} were written")
                for name, values in data.items():
                    values = np.asarray(values)
                    if name not in made:
                        made[name] = _variable(nc, name, values.dtype, samples, time_attrs)
                    made[name][start:stop] = values
                    if values.dtype.kind == "f" and name != "time":
                        ranges[name] = actual_range(values, ranges.get(name))
                end = stop
            if end != samples:
                raise ValueError(f"write_blocks: the blocks end at sample {end} of {samples}")
            for name, span in ranges.items():
                if span is not None:
                    made[name].setncattr("actual_range", span)
            nc.setncatts(netcdf_attrs(attrs()))
            unlock(nc, ident)  # no lock of HDF5's outlives the close, in a descriptor a process forked meanwhile holds
        publish(tmp, path, ident)  # as the journal's datasets: fsync'd, renamed only if still the file made here
        _fsync_dir(path.parent)
    finally:
        remove_own(tmp, ident)  # never a half-written file left behind, nor another writer's removed
    return path


def _variable(nc, name: str, dtype, samples: int, time_attrs):
    """A variable over ``time`` compressed as a run's (`~rdea_lab.store.journal.COMPRESSION`), with its CF
    attributes (NaN as the fill value of a float)."""
    chunk = (min(samples, CHUNK),) if samples else None
    fill = np.nan if dtype.kind == "f" and name != "time" else False
    var = nc.createVariable(name, dtype, ("time",), **COMPRESSION, chunksizes=chunk, fill_value=fill)
    var.setncatts(dict(time_attrs or {}) if name == "time" else variable_attrs(name))
    return var
