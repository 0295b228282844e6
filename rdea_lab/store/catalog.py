"""Reading runs back: open one, list a folder of them."""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..specs import SpecError
from ..specs.errors import show
from .schema import REQUIRED_ATTRS, TEXT_VARIABLES

#: Attributes rdea-lab writes as numbers: name -> (what, numpy kinds allowed); every other attribute of
#: `REQUIRED_ATTRS` is a text string (and those of `TEXT_ATTRS` when present).
#: (A seed netCDF cannot hold as an integer is written as its digits: the journal keeps every run recoverable.)
NUMBER_ATTRS = {"sample_rate": ("a number [Hz]", "fiu"), "seed": ("an integer from 0 to 2**63 - 1", "iuU")}
TEXT_ATTRS = tuple(a for a in REQUIRED_ATTRS if a not in NUMBER_ATTRS) + (
    "protocol_source", "measured", "metadata", "finished", "comment", "emulator_truth", "rig_idn", "model")


def _kind(value) -> str:
    """numpy's kind letter of an attribute value (``"U"`` text, ``"i"`` integer, ``"f"`` float, ...)."""
    if isinstance(value, bool):
        return "b"
    return np.asarray(value).dtype.kind if np.ndim(value) == 0 else "array"


def check_run(ds: xr.Dataset, source: str) -> None:
    """Refuse a dataset whose attributes or variables are not of the types rdea-lab writes (a file made
    elsewhere): attributes and dtypes only, no data read. Variables hold numbers, but for the text of the
    pause table (`rdea_lab.store.schema.TEXT_VARIABLES`).

    Raises
    ------
    SpecError
        Naming `source`, the attribute or variable, and what rdea-lab writes there.
    """
    attrs = {k: v.item() if isinstance(v, np.generic) else v for k, v in ds.attrs.items()}
    for name in TEXT_ATTRS:
        if name in attrs and _kind(attrs[name]) != "U":
            raise SpecError(source, f"attribute '{name}'", f"{show(attrs[name])} is not text; allowed: a text "
                            "string (as rdea-lab writes it)")
    for name, (what, kinds) in NUMBER_ATTRS.items():
        if name in attrs and _kind(attrs[name]) not in kinds:
            raise SpecError(source, f"attribute '{name}'", f"{show(attrs[name])}; allowed: {what}")
    for name, var in ds.variables.items():
        if name in TEXT_VARIABLES and var.dtype.kind in "OSU":  # the pause table's text
            continue
        if var.dtype.kind not in "biuf":
            raise SpecError(source, f"variable '{name}'", f"holds {var.dtype} values; allowed: numbers (float or "
                            "integer, as rdea-lab writes them)")


#: Runs up to this many samples get their ``time`` index at `open_run` (8 MB read, a few ms), so a short run
#: behaves as an in-memory Dataset always did (``ds.sel(time=...)``, alignment); a longer one is opened
#: without it (reading the ``time`` of a day-long run would take seconds): ``ds.set_xindex("time")`` makes it.
INDEX_SAMPLES = 1 << 20


#: Whether this xarray can open a file without building its index coordinates (``create_default_indexes``,
#: xarray 2025.07 and later); without it the ``time`` index of a long run is read at open (slower, same data).
_LAZY_INDEX = "create_default_indexes" in inspect.signature(xr.open_dataset).parameters


def open_run(path: Path) -> xr.Dataset:
    """Open a run dataset lazily: its attributes are read, its variables when they are used.

    Parameters
    ----------
    path : str or path-like
        A run's netCDF file (``*.nc``), as `run_protocol`, `recover` or `import_files` write it.

    Returns
    -------
    xarray.Dataset
        The run: ``time`` [s] as float seconds since the run's start, as the file stores it (its
        ``units``, ``seconds since <start, ISO 8601 UTC>``, say when that was; times are not decoded
        to dates, so ``ds.time.values`` arithmetic is in seconds), ``stretch`` [-], ``voltage`` [V],
        ``force`` [N], ... with ``units`` and ``long_name`` (docs/data-schema.md), and ``ds.rdea``.
        Backed by the open file: a variable is read (and kept) the first time its values are used,
        ``ds[name][a:b]`` reads only those samples (`iter_chunks` reads a long run chunk by chunk),
        ``ds.load()`` reads it all. ``ds.close()`` (or ``with open_run(path) as ds:``) closes the
        file; until then it stays open (a file replaced or removed meanwhile is not seen: the dataset
        keeps what it opened). Runs longer than `INDEX_SAMPLES` have no ``time`` index.

    Raises
    ------
    SpecError
        An attribute or variable not of the type rdea-lab writes (`check_run`).
    """
    lazy = {"create_default_indexes": False} if _LAZY_INDEX else {}  # older xarray: the time index is read
    ds = xr.open_dataset(path, engine="netcdf4", decode_times=False, **lazy)
    try:
        check_run(ds, str(path))
        if ("time" in ds.coords and ds["time"].dims == ("time",) and ds.sizes["time"] <= INDEX_SAMPLES
                and "time" not in ds.xindexes):
            ds = ds.set_xindex("time")
    except BaseException:
        ds.close()
        raise
    return ds


def iter_chunks(ds: xr.Dataset, n: int = 1 << 20, names=None):
    """The samples of a run, ``n`` at a time along ``time``, without reading the rest.

    Parameters
    ----------
    ds : xarray.Dataset
        A run (`open_run`: lazily read, or in memory).
    n : int
        Samples per chunk (> 0); 2**20 by default (8 MB per float variable).
    names : sequence of str, optional
        The variables to read (``time`` included if wanted); default ``time`` and every data variable
        along ``time``.

    Yields
    ------
    tuple
        ``(start, stop, {name: numpy.ndarray})``: the samples ``start:stop`` of each variable.

    Raises
    ------
    ValueError
        ``n`` is not a positive integer.
    """
    if int(n) != n or n <= 0:
        raise ValueError(f"iter_chunks: n = {n!r}; allowed: a positive integer")
    n = int(n)
    if names is None:
        names = [name for name in ("time", *ds.data_vars) if name in ds.variables and ds[name].dims == ("time",)]
    size = ds.sizes.get("time", 0)
    for start in range(0, size, n):
        stop = min(size, start + n)
        yield start, stop, {name: np.asarray(ds.variables[name][start:stop].values) for name in names}


def user_metadata(attrs) -> dict:
    """The user's metadata of a run (its ``metadata`` attribute, JSON), {} if none or unreadable."""
    try:
        value = json.loads(attrs.get("metadata") or "{}")
    except (TypeError, ValueError):
        return {}
    return {str(k): str(v) for k, v in value.items()} if isinstance(value, dict) else {}


def metadata_text(metadata: dict) -> str:
    return "; ".join(f"{k}={v}" for k, v in metadata.items())


def catalog(folder=".", where=None, since=None, columns=None, catalog=None, limit=None) -> pd.DataFrame:
    """One row per run below ``folder`` (datasets ``*.nc`` and unfinished journals), as a DataFrame.

    The catalogue index (`rdea_lab.store.index`) answers; a dataset below ``folder`` that it does not hold yet (a
    folder never listed, a file copied in) is indexed first, the others are only stat-ed: one whose size
    or mtime differs from the indexed ones is marked ``changed since indexed``, one gone ``missing``
    (column ``file_state``; ``rdea-lab catalog rebuild`` re-reads them). Unfinished journals are found by
    scanning ``folder``.

    Parameters
    ----------
    folder : str or path-like, optional
        Searched recursively; a ``*.nc`` file that cannot be read is listed with the status
        ``unreadable (<error>)``. None: every run of the catalogue (``catalog`` or ``RDEA_LAB_CATALOG``),
        no folder scanned.
    where : str, optional
        A query, e.g. ``"specimen == 'specimen-2' and status == 'complete' and md.batch == 'B7'"``
        (`rdea_lab.store.query`).
    since : str or datetime, optional
        Only runs created at or after this (ISO 8601 date or date-time, UTC unless an offset is given).
    columns : sequence of str, optional
        The columns to return (`rdea_lab.store.index.RUN_COLUMNS`, ``metadata``, ``file_state``,
        ``md.<key>``) instead of the default ones.
    catalog : str, optional
        The catalogue's URL (a SQLite file or ``postgresql://...``); default `~rdea_lab.store.index.resolve_catalog`.
    limit : int, optional
        At most this many runs (by file); ``table.attrs["total"]`` says how many matched.

    Returns
    -------
    pandas.DataFrame
        Columns ``file``, ``specimen``, ``protocol``, ``backend`` (``(emulator)``
        marked), ``model``, ``status``, ``duration_s`` [s], ``samples``,
        ``created``, ``metadata`` (``key=value; ...``), ``file_state`` and one ``md.<key>``
        column per metadata key that any run has: the datasets by path, then the journals by path.

    Raises
    ------
    SpecError
        A bad query (with its position), ``since``, column or catalogue URL.
    CatalogUnavailable
        The catalogue cannot be read or written.
    """
    from .listing import listing

    return listing(folder, where=where, since=since, columns=columns, url=catalog, limit=limit)


#: Samples read at once where a variable's range is computed (`finite_range`).
RANGE_CHUNK = 1 << 21


def finite_range(var, chunk: int = RANGE_CHUNK, overview=None) -> tuple[float, float] | None:
    """Smallest and largest finite value of a run's variable: its ``actual_range`` attribute when it has one
    (written with the file), else from the file's ``overview`` (`rdea_lab.store.overview`), else read
    ``chunk`` samples at a time (a lazily opened run is not loaded whole).

    Parameters
    ----------
    var : xarray.DataArray
        A variable over ``time``.
    chunk : int
        Samples read at once.
    overview : Overview, optional
        The run's overview (`rdea_lab.store.overview.read_overview`).

    Returns
    -------
    (float, float) or None
        ``(min, max)`` in the variable's unit; None when no value is finite.
    """
    given = np.asarray(var.attrs.get("actual_range", ()), float).ravel()
    if given.size == 2 and np.all(np.isfinite(given)):
        return float(given[0]), float(given[1])
    if overview is not None and var.name in overview.envelopes and overview.samples == var.size:
        lo, hi = (e[np.isfinite(e)] for e in overview.envelopes[var.name])
        return (float(lo.min()), float(hi.max())) if lo.size else None
    lo, hi, n = np.inf, -np.inf, var.shape[0] if var.ndim else 1
    for a in range(0, n, chunk):
        v = np.asarray(var[a:a + chunk].values if var.ndim else var.values, float)
        v = v[np.isfinite(v)]
        if v.size:
            lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
    return (lo, hi) if lo <= hi else None


def describe_run(ds: xr.Dataset) -> str:
    """A few lines on one run: provenance, status and the range of each variable (its ``actual_range``,
    or read chunk by chunk: a day-long run is not loaded)."""
    a = ds.attrs
    n = ds.sizes.get("time", 0)
    t = np.asarray(ds["time"][[0, -1]].values, float) if n else np.array([])
    lines = [f"{a.get('title', '?')}",
             f"  status {a.get('status', '?')}" + (f": {a['status_reason']}" if a.get("status_reason") else ""),
             f"  backend {a.get('backend', '?')}, model {a.get('model', '-')}, run {a.get('run_id', '?')}",
             f"  created {a.get('created', '?')}, rdea-lab {a.get('rdea_lab_version', '?')}",
             *([f"  metadata {metadata_text(user_metadata(a))}"] if user_metadata(a) else []),
             f"  {n} samples over {float(t[-1] - t[0]) if t.size else 0:.4g} s "
             f"at {float(a.get('sample_rate', 0)):g} Hz"]
    from .overview import read_overview

    series = {name: var for name, var in ds.data_vars.items() if var.dims == ("time",)}
    overview = read_overview(ds) if not all("actual_range" in v.attrs for v in series.values()) else None
    for name, var in series.items():
        r = finite_range(var, overview=overview)
        lines.append(f"  {name:<17} [{var.attrs.get('units', '?')}] "
                     + (f"{r[0]:.5g} .. {r[1]:.5g}" if r is not None else "not measured"))
    if "paused" in ds.data_vars:
        from .pauses import pauses

        for p in pauses(ds).itertuples():
            lines.append(f"  paused {p.start:.6g} s .. {p.end:.6g} s ({p.samples} samples): {p.reason}, by {p.by}")
    return "\n".join(lines)
