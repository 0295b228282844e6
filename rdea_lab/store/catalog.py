"""Reading runs back: open one, list a folder of them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..specs import SpecError
from ..specs.errors import show
from .journal import FORMAT, journal_writer
from .schema import REQUIRED_ATTRS, is_emulated

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


def _journal_row(folder: Path) -> dict:
    header = json.loads((folder / "header.json").read_text())
    if header.get("format") != FORMAT:
        raise ValueError("not a journal")
    a = header["attrs"]
    size = (folder / "samples.f8").stat().st_size if (folder / "samples.f8").exists() else 0
    n = size // (8 * len(header["columns"]))
    rate = float(a.get("sample_rate", 0.0)) or float("nan")
    writer = journal_writer(folder)
    status = (f"running (pid {writer.get('pid', '?')} on {writer.get('host', '?')})" if writer is not None
              else "unfinished (rdea-lab recover)")
    return {"file": str(folder), "specimen": a.get("specimen_id", "?"), "protocol": a.get("protocol_name", "?"),
            "backend": a.get("backend", "?"), "model": a.get("model", "-"),
            "status": status, "duration_s": (n - 1) / rate if n else 0.0,
            "samples": int(n), "created": a.get("created", "?"), "metadata": metadata_text(user_metadata(a)),
            "_md": user_metadata(a)}


def user_metadata(attrs) -> dict:
    """The user's metadata of a run (its ``metadata`` attribute, JSON), {} if none or unreadable."""
    try:
        value = json.loads(attrs.get("metadata") or "{}")
    except (TypeError, ValueError):
        return {}
    return {str(k): str(v) for k, v in value.items()} if isinstance(value, dict) else {}


def metadata_text(metadata: dict) -> str:
    return "; ".join(f"{k}={v}" for k, v in metadata.items())


COLUMNS = ["file", "specimen", "protocol", "backend", "model", "status", "duration_s", "samples", "created",
           "metadata"]


def catalog(folder: Path) -> pd.DataFrame:
    """One row per run below ``folder`` (datasets ``*.nc`` and unfinished journals), as a DataFrame.

    Parameters
    ----------
    folder : str or path-like
        Searched recursively; a ``*.nc`` file that cannot be read is listed with the status
        ``unreadable (<error>)``.

    Returns
    -------
    pandas.DataFrame
        Columns ``file``, ``specimen``, ``protocol``, ``backend`` (``(emulator)``
        marked), ``model``, ``status``, ``duration_s`` [s], ``samples``,
        ``created``, ``metadata`` (``key=value; ...``) and one ``md.<key>``
        column per metadata key that any run has: the datasets by path, then the journals by path.
    """
    rows = catalog_rows(folder)
    keys = list(dict.fromkeys(k for r in rows for k in r.get("_md", {})))
    table = pd.DataFrame([{**{c: r[c] for c in COLUMNS}, **{f"md.{k}": r.get("_md", {}).get(k, "") for k in keys}}
                          for r in rows], columns=COLUMNS + [f"md.{k}" for k in keys])
    return table


def catalog_rows(folder: Path) -> list[dict]:
    """The rows of `catalog` as dicts (``_md`` holds each run's metadata as a dict)."""
    folder = Path(folder)
    rows = []
    for path in sorted(folder.rglob("*.nc")):
        try:
            with xr.open_dataset(path, engine="netcdf4", decode_times=False) as ds:
                a = ds.attrs
                t = ds["time"].values if "time" in ds else np.array([])
                backend = a.get("backend", "?") + (" (emulator)" if is_emulated(a) else "")
                rows.append({"file": str(path), "specimen": a.get("specimen_id", "?"),
                             "protocol": a.get("protocol_name", "?"), "backend": backend,
                             "model": a.get("model", "-"), "status": a.get("status", "?"),
                             "duration_s": float(t[-1] - t[0]) if t.size else 0.0, "samples": int(t.size),
                             "created": a.get("created", "?"), "metadata": metadata_text(user_metadata(a)),
                             "_md": user_metadata(a)})
        except Exception as exc:  # a foreign or broken file: list it, say why
            rows.append({"file": str(path), "specimen": "?", "protocol": "?", "backend": "?", "model": "-",
                         "status": f"unreadable ({type(exc).__name__})", "duration_s": 0.0, "samples": 0,
                         "created": "?", "metadata": ""})
    for part in sorted(folder.rglob("*.nc.part")):
        try:
            rows.append(_journal_row(part))
        except Exception:
            continue
    return rows


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
    """A few lines on one run: provenance, status and the range of each variable (`finite_range`: read
    chunk by chunk, or from ``actual_range``)."""
    a = ds.attrs
    t = ds["time"]
    span = float(t[-1] - t[0]) if t.size else 0.0
    lines = [f"{a.get('title', '?')}",
             f"  status {a.get('status', '?')}" + (f": {a['status_reason']}" if a.get("status_reason") else ""),
             f"  backend {a.get('backend', '?')}, model {a.get('model', '-')}, run {a.get('run_id', '?')}",
             f"  created {a.get('created', '?')}, rdea-lab {a.get('rdea_lab_version', '?')}",
             *([f"  metadata {metadata_text(user_metadata(a))}"] if user_metadata(a) else []),
             f"  {t.size} samples over {span:.4g} s at {float(a.get('sample_rate', 0)):g} Hz"]
    from .overview import read_overview

    overview = read_overview(ds) if not all("actual_range" in v.attrs for v in ds.data_vars.values()) else None
    for name, var in ds.data_vars.items():
        r = finite_range(var, overview=overview)
        lines.append(f"  {name:<17} [{var.attrs.get('units', '?')}] "
                     + (f"{r[0]:.5g} .. {r[1]:.5g}" if r is not None else "not measured"))
    return "\n".join(lines)
