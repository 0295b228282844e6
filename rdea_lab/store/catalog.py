"""Reading runs back: open one, list a folder of them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..specs import SpecError
from ..specs.errors import show
from .schema import REQUIRED_ATTRS

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
    elsewhere): attributes and dtypes only, no data read.

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
        if var.dtype.kind not in "biuf":
            raise SpecError(source, f"variable '{name}'", f"holds {var.dtype} values; allowed: numbers (float or "
                            "integer, as rdea-lab writes them)")


def open_run(path: Path) -> xr.Dataset:
    """Open a run dataset (loaded into memory, file closed).

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

    Raises
    ------
    SpecError
        An attribute or variable not of the type rdea-lab writes (`check_run`).
    """
    with xr.open_dataset(path, engine="netcdf4", decode_times=False) as ds:
        check_run(ds, str(path))
        return ds.load()


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


def describe_run(ds: xr.Dataset) -> str:
    """A few lines on one run: provenance, status and the range of each variable."""
    a = ds.attrs
    t = ds["time"].values
    lines = [f"{a.get('title', '?')}",
             f"  status {a.get('status', '?')}" + (f": {a['status_reason']}" if a.get("status_reason") else ""),
             f"  backend {a.get('backend', '?')}, model {a.get('model', '-')}, run {a.get('run_id', '?')}",
             f"  created {a.get('created', '?')}, rdea-lab {a.get('rdea_lab_version', '?')}",
             *([f"  metadata {metadata_text(user_metadata(a))}"] if user_metadata(a) else []),
             f"  {t.size} samples over {float(t[-1] - t[0]) if t.size else 0:.4g} s "
             f"at {float(a.get('sample_rate', 0)):g} Hz"]
    for name, var in ds.data_vars.items():
        v = np.asarray(var.values, float)
        finite = v[np.isfinite(v)]
        span = f"{finite.min():.5g} .. {finite.max():.5g}" if finite.size else "not measured"
        lines.append(f"  {name:<17} [{var.attrs.get('units', '?')}] {span}")
    return "\n".join(lines)
