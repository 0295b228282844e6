"""Foreign files as tables of columns: what `rdea-lab import` reads before mapping.

A `Table` holds the columns of one file (CSV text, TDMS channels, MATLAB
arrays) with their names and, where the file says, their units. It finds a
column by name or 0-based index and returns it as floats; every problem is a
`SpecError` naming the file, the column and the row.

This module holds the table itself and the TDMS and .mat readers;
`rdea_lab.store.csvtable` reads CSV.
"""

from __future__ import annotations

import contextlib
import logging
import re
import warnings
from pathlib import Path

import numpy as np

from ..specs import SpecError
from ..specs.errors import show

#: How many column names an error message lists before "..."
_LISTED = 24


def unit_text(text) -> str | None:
    """A unit as a file writes it (``"(mm)"``, ``"[N]"``, ``" s "``) without brackets; None if empty."""
    if text is None:
        return None
    text = str(text).strip()
    while len(text) >= 2 and text[0] + text[-1] in ("()", "[]", "{}", "<>"):
        text = text[1:-1].strip()
    return text or None


class Table:
    """Columns of one file.

    Attributes
    ----------
    source : str
        The file, for messages.
    names : list of str
        Column names in file order; a column's index is its position here.
    file_units : list of str or None
        The unit each column has in the file (units row, header suffix, TDMS
        ``unit_string``), None where the file says none.
    details : dict
        How the file was read (encoding, separator, ...), for provenance.
    """

    kind = "column"

    def __init__(self, source: str, names, file_units, details=None):
        self.source = source
        self.names = [str(n) for n in names]
        self.file_units = list(file_units)
        self.details = dict(details or {})
        self.aliases: dict[str, int] = {}
        self.ambiguous: dict[str, list[int]] = {}  # aliases several columns share

    @property
    def n_rows(self) -> int:
        raise NotImplementedError

    def values(self, j: int) -> np.ndarray:
        """Column `j` as float64 (NaN for an empty cell)."""
        raise NotImplementedError

    def text(self, j: int, i: int) -> str:
        """Cell (row `i`, column `j`) as the file writes it."""
        return repr(float(self.values(j)[i]))

    def where(self, i: int) -> str:
        """Row `i` (0-based among the data rows) for a message."""
        return f"sample {i}"

    def label(self, j: int) -> str:
        return f"{self.kind} {show(self.names[j])}" if self.names[j] else f"{self.kind} {j}"

    def listing(self) -> str:
        shown = [f"{j} {show(n)}" if n else f"{j} (no name)" for j, n in enumerate(self.names[:_LISTED])]
        more = f", ... ({len(self.names)} in all)" if len(self.names) > _LISTED else ""
        return ", ".join(shown) + more if shown else "none"

    def find(self, col: str, field: str) -> int:
        """Index of the column named `col` (a name, an alias or a 0-based index).

        Raises
        ------
        SpecError
            No such column (the message lists the available ones), or a name
            that several columns share.
        """
        col = col.strip()
        hits = [j for j, n in enumerate(self.names) if n.strip() == col]
        if len(hits) > 1:
            raise SpecError(self.source, field, f"{len(hits)} {self.kind}s are named {show(col)} "
                                                f"(indices {', '.join(map(str, hits))}); give the index instead")
        if hits:
            return hits[0]
        key = self.normalize(col)
        if key in self.aliases:
            return self.aliases[key]
        if key in self.ambiguous:
            shared = ", ".join(self.names[j] for j in self.ambiguous[key])
            raise SpecError(self.source, field,
                            f"{show(col)} names several {self.kind}s ({shared}); give the full name")
        if re.fullmatch(r"\d+", col):
            j = int(col)
            if j < len(self.names):
                return j
            raise SpecError(self.source, field, f"{self.kind} index {j} is out of range; the file has "
                                                f"{len(self.names)} {self.kind}s: {self.listing()}")
        raise SpecError(self.source, field, f"no {self.kind} {show(col)}; available: {self.listing()}")

    @staticmethod
    def normalize(col: str) -> str:
        return re.sub(r"\s+", "", col)


class ArrayTable(Table):
    """Columns that are numeric arrays already (TDMS channels, MATLAB arrays)."""

    def __init__(self, source, names, arrays, file_units, details=None, kind="column"):
        super().__init__(source, names, file_units, details)
        self.kind = kind
        self.arrays = list(arrays)

    @property
    def n_rows(self) -> int:
        return max((a.size for a in self.arrays), default=0)

    def length(self, j: int) -> int:
        return self.arrays[j].size

    def values(self, j: int) -> np.ndarray:
        a = np.asarray(self.arrays[j]).ravel()
        if np.issubdtype(a.dtype, np.datetime64):
            return (a - a[0]) / np.timedelta64(1, "s") if a.size else a.astype(float)
        if a.dtype == bool or not (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)):
            raise SpecError(self.source, self.label(j), f"holds {a.dtype} values, not real numbers")
        return a.astype(np.float64)


# -------------------------------------------------------------------- TDMS
@contextlib.contextmanager
def _quiet_library(name: str):
    """While the block runs, the library `name`'s log records and warnings are kept, not printed (npTDMS
    gives its loggers a console handler of its own); yields the list of what it said (warnings and above)."""
    said: list[str] = []

    class Keep(logging.Handler):
        def emit(self, record):
            if record.levelno >= logging.WARNING:
                said.append(record.getMessage())

    loggers = [logging.getLogger(n) for n in list(logging.root.manager.loggerDict)
               if n == name or n.startswith(name + ".")]
    saved = [(log, log.handlers[:], log.propagate) for log in loggers]
    keep = Keep()
    for log in loggers:
        log.handlers, log.propagate = [keep], False
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield said
        said.extend(str(w.message) for w in caught)
    finally:
        for log, handlers, propagate in saved:
            log.handlers, log.propagate = handlers, propagate


def read_tdms(path: Path) -> ArrayTable:
    """The channels of a TDMS file: names ``group/channel`` (a channel's own
    name finds it too when no other group has one so named), units from the
    ``unit_string`` property, timestamps as seconds since the first one."""
    from ..extras import require

    source = str(path)
    TdmsFile = require("nptdms", f"{source}: reading a TDMS file").TdmsFile
    with _quiet_library("nptdms") as said:
        try:
            tdms = TdmsFile.read(path)
        except Exception as exc:  # npTDMS raises ValueError, KeyError, struct.error... on foreign bytes
            raise SpecError(source, "<document>", f"not a readable TDMS file ({type(exc).__name__}: "
                            f"{show(str(exc), 200)})") from None
    if said:  # npTDMS read past a problem (a truncated last segment, ...): the file is not what was written
        raise SpecError(source, "<document>", f"an incomplete TDMS file (npTDMS: {show(said[0], 200)}); allowed: a "
                        "complete TDMS file (a recording that was closed)")
    names, arrays, units, owners = [], [], [], {}
    for group in tdms.groups():
        for ch in group.channels():
            j = len(names)
            names.append(f"{group.name}/{ch.name}")
            data = ch[:]
            arrays.append(np.asarray(data))
            unit = unit_text(ch.properties.get("unit_string"))
            units.append("s" if np.issubdtype(np.asarray(data).dtype, np.datetime64) else unit)
            owners.setdefault(Table.normalize(ch.name), []).append(j)
    table = ArrayTable(source, names, arrays, units, {"channels": len(names)}, kind="channel")
    table.aliases = {name: js[0] for name, js in owners.items() if len(js) == 1}
    table.ambiguous = {name: js for name, js in owners.items() if len(js) > 1}
    return table


# --------------------------------------------------------------------- MAT
def read_mat(path: Path) -> ArrayTable:
    """The numeric arrays of a MATLAB v4-v7.2 file.

    A vector ``x`` (``1 x n`` or ``n x 1``) is the column ``x``; a 2-D
    array ``data`` of ``n x k`` (n >= k) gives the columns ``data[:, 0]`` ..
    ``data[:, k-1]``; a wide one (``k x n``, k < n) gives its rows
    ``data[0, :]`` ... Scalars, text, cells and structs are not columns.
    """
    import scipy.io

    source = str(path)
    with open(path, "rb") as fh:
        head = fh.read(128)
    if b"MATLAB 7.3 MAT-file" in head or head[:8] == b"\x89HDF\r\n\x1a\n":
        raise SpecError(source, "<document>", "a MATLAB v7.3 (HDF5) file, which scipy.io cannot read; "
                                              "save it with save(..., '-v7') and import that")
    try:
        variables = scipy.io.loadmat(path, squeeze_me=False)
    except NotImplementedError:  # scipy's answer to an HDF5 file without the usual header
        raise SpecError(source, "<document>", "a MATLAB v7.3 (HDF5) file, which scipy.io cannot read; "
                                              "save it with save(..., '-v7') and import that") from None
    except Exception as exc:
        raise SpecError(source, "<document>", f"not a readable MATLAB .mat file ({type(exc).__name__}: {exc})") \
            from None
    names, arrays = [], []
    for var, a in variables.items():
        if var.startswith("__") or not isinstance(a, np.ndarray) or a.dtype.kind not in "iuf" or a.ndim != 2:
            continue
        r, c = a.shape
        if a.size < 2:
            continue
        if r == 1 or c == 1:
            names.append(var)
            arrays.append(a.ravel())
        elif r >= c:
            names += [f"{var}[:, {j}]" for j in range(c)]
            arrays += [a[:, j] for j in range(c)]
        else:
            names += [f"{var}[{i}, :]" for i in range(r)]
            arrays += [a[i, :] for i in range(r)]
    table = ArrayTable(source, names, arrays, [None] * len(names), {"variables": len(names)})
    table.aliases = {Table.normalize(n): j for j, n in enumerate(names)}
    return table
