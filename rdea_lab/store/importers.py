"""Import of measurements made elsewhere (CSV, TDMS, MATLAB .mat) as rdea-lab runs.

A foreign file becomes a dataset of the same schema as every run (DESIGN.md,
"Data: one run = one netCDF file"), with ``backend: import``: its columns are
mapped to ``time``, ``position``, ``force`` (and ``voltage``,
``capacitance`` where measured), converted to SI with pint, and the stretch
is ``1 + position / L1`` with ``L1`` the specimen's unstretched length. The
file's name, its SHA-256 and the mapping are kept in the attributes.

Nothing is repaired silently: a missing column, a cell that is not a number,
a time that does not increase, an unknown unit or one of the wrong
dimension, a stretch below 1 beyond noise each raise a `SpecError` naming
the file, the column and the row. Positions a little below 0 (a load cell
and an encoder near zero load) are kept as measured, and the smallest
position is recorded in ``min_position_m``.
"""

from __future__ import annotations

import hashlib
import json
import re
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

from .._version import __version__
from ..physics.geometry import geometry_from_card
from ..specs import SpecError, dump_specimen, ureg
from ..specs.errors import show
from .csvtable import read_csv
from .journal import utc_now, write_dataset
from .outputs import check_new
from .schema import VARIABLES, global_attrs, portable_command, time_attrs, variable_attrs
from .tables import Table, read_mat, read_tdms
from ..specs.importing import FORMATS, KINDS, MAX_STRETCH, MIN_STRETCH  # noqa: F401  (what import accepts; re-exported)

#: mapped quantity -> (its dimension in pint's terms, name, SI unit, example unit)
QUANTITIES = {
    "time": ("[time]", "time", "s", "s"),
    "position": ("[length]", "length", "m", "mm"),
    "force": ("[force]", "force", "N", "N"),
    "voltage": ("[electric_potential]", "voltage", "V", "kV"),
    "capacitance": ("[capacitance]", "capacitance", "F", "pF"),
}
REQUIRED = ("time", "position", "force")
_KEY = re.compile(r",\s*(?=[A-Za-z_][A-Za-z0-9_]*\s*=)")


def parse_pairs(text: str, option: str) -> dict[str, str]:
    """``"time=0,position=Disp (mm)"`` -> ``{"time": "0", "position": "Disp (mm)"}``.

    A comma separates pairs only where ``key=`` follows, so a value may hold
    commas (``data[:, 1]``).
    """
    out: dict[str, str] = {}
    for item in _KEY.split(text.strip()):
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key or not value:
            raise SpecError("command line", option, f"{show(item.strip())} is not KEY=VALUE "
                                                    f"(e.g. {option} time=0,position=1,force=2)")
        if key not in QUANTITIES:
            raise SpecError("command line", option, f"unknown key {show(key)}; allowed: {', '.join(QUANTITIES)}")
        if key in out:
            raise SpecError("command line", option, f"{show(key)} is given twice")
        out[key] = value
    return out


def parse_map(text: str) -> dict[str, str]:
    """The ``--map`` option: quantity -> column; time, position and force required."""
    mapping = parse_pairs(text, "--map")
    missing = [k for k in REQUIRED if k not in mapping]
    if missing:
        raise SpecError("command line", "--map", f"missing {', '.join(missing)}; time, position and force are "
                                                 "required (e.g. --map time=0,position=1,force=2)")
    return mapping


def parse_units(text: str | None, mapping: dict[str, str]) -> dict[str, str]:
    """The ``--units`` option: quantity -> unit, each checked with pint."""
    units = parse_pairs(text, "--units") if text else {}
    for key, unit in units.items():
        if key not in mapping:
            raise SpecError("command line", "--units", f"a unit for {show(key)}, which --map does not map")
        si_converter(unit, key, "command line", f"--units {key}")
    return units


def si_converter(unit: str, quantity: str, source: str, field: str):
    """A function taking values in `unit` to the SI unit of `quantity`.

    Decimal prefixes scale by an exact integer (mm: divide by 1000), so a
    value in mm comes out as the same float as ``value / 1000``.

    Raises
    ------
    SpecError
        A unit pint does not know, or one of another dimension.
    """
    dim, name, si, example = QUANTITIES[quantity]
    try:
        parsed = ureg.parse_units(unit)
    except Exception:  # pint raises several kinds on text that is no unit
        raise SpecError(source, field, f"unknown unit {show(unit)}; give a {name} unit, e.g. {example}") from None
    if parsed.dimensionality != ureg.get_dimensionality(dim):
        raise SpecError(source, field, f"unit {show(unit)} is not a {name} unit ({quantity} needs one, e.g. {example})")
    factor = float(ureg.Quantity(1.0, parsed).to(si).magnitude)
    if factor >= 1.0 and factor == round(factor):
        return lambda v: v * round(factor)
    inverse = round(1.0 / factor)
    if abs(1.0 / factor - inverse) <= 1e-9 * inverse:
        return lambda v: v / inverse
    return lambda v: v * factor


@dataclass(frozen=True)
class ImportOptions:
    """How to read foreign files: the ``rdea-lab import`` options.

    Attributes
    ----------
    fmt : str
        One of `FORMATS`.
    mapping : dict
        Quantity (``time``, ``position``, ``force``, ``voltage``,
        ``capacitance``) -> column name or 0-based index, as text.
    units : dict
        Quantity -> unit; quantities not here take the file's unit.
    protocol_kind : str
        One of `KINDS`.
    protocol_name : str or None
        Default: the file's stem.
    encoding : str or None
        Text encoding of a CSV file; default: detected.
    credit : str or None
        Where the data come from (``source_credit``).
    min_stretch : float
        Lowest stretch accepted as noise [-].
    skip_start : float
        Seconds [s] at the start of the file left out (samples with ``time - time[0] < skip_start``), e.g. a
        machine's start-up spike; the rest keeps its times. Recorded as ``skipped_start_s`` and
        ``skipped_start_samples``.
    """

    fmt: str
    mapping: dict
    units: dict = field(default_factory=dict)
    protocol_kind: str = "custom"
    protocol_name: str | None = None
    encoding: str | None = None
    credit: str | None = None
    min_stretch: float = MIN_STRETCH
    skip_start: float = 0.0


def check_format(fmt: str, source) -> None:
    """Refuse a format that is not one of `FORMATS`, naming the file to be read."""
    if fmt not in FORMATS:
        raise SpecError(str(source), "--format", f"unknown format {fmt!r}; allowed: {', '.join(FORMATS)}")


def read_table(path: Path, fmt: str, raw: bytes, encoding: str | None = None) -> Table:
    """The columns of `path` read as `fmt`."""
    check_format(fmt, path)
    if fmt != "csv" and encoding:
        raise SpecError("command line", "--encoding", "only for --format csv")
    if fmt == "csv":
        return read_csv(path, raw, encoding)
    if not raw:
        raise SpecError(str(path), "<document>", "the file is empty")
    return read_tdms(path) if fmt == "tdms" else read_mat(path)


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise SpecError(str(path), "<document>", "file not found") from None
    except IsADirectoryError:
        raise SpecError(str(path), "<document>", "is a directory; expected a data file") from None
    except OSError as exc:
        raise SpecError(str(path), "<document>", f"cannot read file: {exc.strerror}") from None


def _column(table: Table, key: str, j: int, unit: str, origin: str) -> np.ndarray:
    """Column `j` in SI, every sample finite (capacitance may be NaN: not measured)."""
    where_unit = f"--units {key}" if origin == "--units" else f"{table.label(j)} (unit {show(unit)} in the file)"
    convert = si_converter(unit, key, "command line" if origin == "--units" else table.source, where_unit)
    values = table.values(j)
    if key != "capacitance":
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            text = table.text(j, i)
            what = "an empty field" if not text.strip() else f"{show(text)} is not a finite number"
            raise SpecError(table.source, f"{table.where(i)}, {table.label(j)}", f"{what} ({key})")
    return convert(values)


def _check_time(table: Table, j: int, t: np.ndarray) -> None:
    if t.size < 2:
        raise SpecError(table.source, "<document>", f"{t.size} data row(s); need at least 2")
    bad = np.diff(t) <= 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        raise SpecError(table.source, f"{table.where(i)}, {table.label(j)}",
                        f"time does not increase: {table.text(j, i).strip()} after {table.text(j, i - 1).strip()} "
                        f"({table.where(i - 1)}; samples {i - 1} and {i})")


def import_file(path, card, options: ImportOptions, command: str = "") -> xr.Dataset:
    """Read one foreign file into a run dataset (not written).

    Parameters
    ----------
    path : path-like
        The file.
    card : rdea_lab.specs.SpecimenCard
        The specimen measured; its unstretched length ``L1`` [m] turns
        positions into stretches.
    options : ImportOptions
    command : str
        The command line, for ``history``.

    Returns
    -------
    xarray.Dataset
        The rdea-lab schema, ``backend: import``, ``status: complete``.

    Raises
    ------
    SpecError
        Every problem of the file or the options, naming the file, column and row.
    """
    path = Path(path)
    raw = _read_bytes(path)
    table = read_table(path, options.fmt, raw, options.encoding)
    cols = {key: table.find(col, f"--map {key}") for key, col in options.mapping.items()}
    if hasattr(table, "length"):  # arrays: every mapped one must have as many samples
        lengths = {key: table.length(j) for key, j in cols.items()}
        if len(set(lengths.values())) > 1:
            raise SpecError(table.source, "--map", "the mapped columns differ in length: "
                                                   + ", ".join(f"{k} {n}" for k, n in lengths.items()))
    units, origins, si = {}, {}, {}
    for key, j in cols.items():
        if key in options.units:
            units[key], origins[key] = options.units[key], "--units"
        elif table.file_units[j]:
            units[key], origins[key] = table.file_units[j], "file"
        else:
            _, _, _, example = QUANTITIES[key]
            raise SpecError(table.source, f"--units {key}", f"no unit for {key} ({table.label(j)}): the file gives "
                                                            f"none; give one, e.g. --units {key}={example}")
        si[key] = _column(table, key, j, units[key], origins[key])
    t = si["time"]
    _check_time(table, cols["time"], t)
    dropped = 0
    if options.skip_start > 0:
        keep = t - t[0] >= options.skip_start
        dropped = int(np.count_nonzero(~keep))
        if keep.sum() < 2:
            raise SpecError("command line", "--skip-start", f"{options.skip_start:g} s leaves {int(keep.sum())} "
                                                             f"sample(s) of {table.source}; allowed: less than "
                                                             f"{t[-2] - t[0]:g} s")
        si = {k: v[keep] for k, v in si.items()}
        t = si["time"]
    L1 = geometry_from_card(card).L1
    stretch = 1.0 + si["position"] / L1
    low = stretch < options.min_stretch
    if low.any():
        i, j = int(np.argmax(low)), cols["position"]
        raise SpecError(table.source, f"{table.where(i)}, {table.label(j)}",
                        f"position {table.text(j, i).strip()} gives stretch {stretch[i]:.6g} with L1 = "
                        f"{L1 * 1e3:g} mm, below {options.min_stretch:g} (more than noise below 1); check the "
                        "position's zero and sign")
    high = ~(stretch <= MAX_STRETCH)
    if high.any():
        i, j = int(np.argmax(high)), cols["position"]
        given = (f"unit {show(units['position'])} from --units" if origins["position"] == "--units"
                 else f"unit {show(units['position'])} in the file")
        raise SpecError(table.source, f"{table.where(i)}, {table.label(j)}",
                        f"position {table.text(j, i).strip()} ({given}) gives stretch {stretch[i]:.3g} with L1 = "
                        f"{L1 * 1e3:g} mm; allowed: stretch {options.min_stretch:g} to {MAX_STRETCH:g} (no elastomer "
                        "is drawn further); check the position's unit")
    n = t.size
    data = {"stretch": stretch, "position": si["position"], "voltage": si.get("voltage", np.zeros(n)),
            "force": si["force"], "capacitance": si.get("capacitance", np.full(n, np.nan)),
            "stretch_setpoint": np.full(n, np.nan), "voltage_setpoint": np.full(n, np.nan)}
    data_vars = {k: ("time", np.asarray(data[k], np.float64), variable_attrs(k)) for k in VARIABLES}
    attrs = _attrs(path, raw, card, options, table, units, origins, float(np.min(si["position"])), t, command,
                   dropped)
    time = {**time_attrs(attrs["created"]),
            "comment": f"times as {path.name} gives them; the file does not say when it was measured, so the "
                       "reference time in units is the time of the import"}
    return xr.Dataset(data_vars, coords={"time": ("time", t, time)}, attrs=attrs)


def _attrs(path, raw, card, options, table, units, origins, min_position, t, command, dropped=0) -> dict:
    created = utc_now()
    sha = hashlib.sha256(raw).hexdigest()
    name = options.protocol_name or path.stem
    mapping = {"map": dict(options.mapping), "units": units, "units_from": origins,
               "columns": {k: table.names[table.find(c, k)] for k, c in options.mapping.items()}}
    protocol = {"import": {"source_file": path.name, "source_format": options.fmt, "map": dict(options.mapping),
                           "units": units, "read": table.details},
                "note": "measured elsewhere and imported: no setpoints (stretch_setpoint and voltage_setpoint "
                        "are NaN), voltage 0 and capacitance NaN where not mapped"}
    attrs = {
        "Conventions": "CF-1.8",
        "title": f"{name} on {card.id} (imported from {path.name})",
        "rdea_lab_version": __version__,
        "run_id": uuid.uuid4().hex,
        "backend": "import",
        "specimen_id": card.id,
        "specimen": dump_specimen(card),
        "protocol_name": name,
        "protocol_kind": options.protocol_kind,
        "protocol": yaml.safe_dump(protocol, sort_keys=False, allow_unicode=True, width=1000),
        "sample_rate": float(np.median(1.0 / np.diff(t))),
        "seed": 0,
        "created": created,
        "status": "complete",
        "status_reason": "",
        "history": f"{created}: {portable_command(command) or 'rdea-lab import'} ({path.name}, sha256 {sha[:12]})",
        "samples": int(t.size),
        "source_file": path.name,
        "source_sha256": sha,
        "source_format": options.fmt,
        "import_mapping": json.dumps(mapping, ensure_ascii=False),
        "min_position_m": min_position,
        **global_attrs(f"imported from {path.name}"),
    }
    if options.credit:
        attrs["source_credit"] = options.credit
    if options.skip_start > 0:
        attrs["skipped_start_s"] = float(options.skip_start)
        attrs["skipped_start_samples"] = int(dropped)
    return attrs


def output_paths(paths, card_id: str, out=None, overwrite: bool = False) -> list[Path]:
    """Where each imported file goes: ``out`` (a ``.nc`` file for one input, or
    a folder) or ``datasets/imported/<card_id>/``, as ``<file stem>.nc``.

    Raises
    ------
    SpecError
        Several inputs into one ``.nc``, two inputs with the same stem, or an
        existing dataset without `overwrite`.
    """
    paths = [Path(p) for p in paths]
    if out is not None and Path(out).suffix and Path(out).suffix.lower() != ".nc" and not Path(out).is_dir():
        raise SpecError(str(out), "--out", f"the suffix {Path(out).suffix!r}; allowed: a .nc file name (a dataset "
                        "is written as netCDF) or a folder")
    if out is not None and Path(out).suffix == ".nc" and not Path(out).is_dir():
        if len(paths) > 1:
            raise SpecError("command line", "--out", f"{out} is one file, for {len(paths)} inputs; give a folder")
        targets = [Path(out)]
    else:
        folder = Path(out) if out is not None else Path("datasets") / "imported" / card_id
        targets = [folder / f"{p.stem}.nc" for p in paths]
    seen: dict[Path, Path] = {}
    for p, target in zip(paths, targets):
        if target in seen:
            raise SpecError(str(p), "--out", f"{seen[target]} and {p} would both be written to {target}")
        seen[target] = p
        check_new(target, overwrite, "--out")
    return targets


def import_files(paths, card, options: ImportOptions, out=None, overwrite=False, command="") -> list[tuple]:
    """Import every file, then write them all: a bad file stops the import
    before anything is written.

    Parameters
    ----------
    paths : sequence of path-like
        The foreign files (CSV, Excel, TDMS, ...: `FORMATS`).
    card : rdea_lab.specs.SpecimenCard
        The specimen measured; its unstretched length ``L1`` [m] turns positions into stretches.
    options : ImportOptions
        The format, the column of each quantity and their units (``rdea-lab import``'s options).
    out : path-like, optional
        A ``.nc`` file (for one input) or a folder; default ``datasets/imported/<card id>/``, one
        ``<stem>.nc`` per input.
    overwrite : bool
        Replace existing datasets.
    command : str
        The command line, for each dataset's ``history``.

    Returns
    -------
    list of (Path, Path, xarray.Dataset)
        Each input, the dataset written, and the dataset.

    Raises
    ------
    SpecError
        Every problem of a file or the options, naming the file, column and row; an ``out`` that is
        not a ``.nc`` name or a folder, one file for several inputs, two inputs on one output;
        `OutputError` (a kind of it) for an existing output without ``overwrite``.
    """
    targets = output_paths(paths, card.id, out, overwrite)
    done = [(Path(p), target, import_file(p, card, options, command)) for p, target in zip(paths, targets)]
    from .index import index_quietly

    for _, target, ds in done:
        write_dataset(ds, target)
        index_quietly(target)  # the catalogue row (a warning line, not a failure, if it cannot be written)
    return done
