"""The pauses of a run (issue 29): each sample's phase, the notes of why, and the table the dataset gets.

A run that can pause has the per-sample flag ``paused`` (a journal column like ``model_status``; CF flag values
0 running, 1 ramping_down, 2 held, 3 ramping_up: `rdea_lab.specs.variables.PAUSE_FLAG_VALUES`). A pause is a
maximal range of samples whose flag is not running (1, 2 or 3; a sample without a value, -1, counts as
running), so it is read off the column itself, whatever was noted.

Why a run paused, and who paused it, the engine notes as the pause begins (`JournalWriter.note_pause`): one
JSON line per note in the journal's ``pauses.jsonl`` (`NOTES`), written with one ``os.write`` and ``fsync``-ed
at once (pauses are rare: an ``fsync`` each costs nothing), so `recover` of a killed run reads them as
``finish`` does; a torn last line (a kill during the write) is skipped.

When the journal becomes the dataset, `PauseEdges` follows the flag chunk by chunk (a pause may span any
number of chunks) and the dataset gets, for a run with at least one pause, a dimension ``pause`` and

* ``pause_start``, ``pause_end`` (in the units of ``time``: seconds since the run's start, so a CF reader
  decodes them as it decodes ``time``): the time of the pause's first sample, and the time of the first
  running sample after it, or, for a run that ended paused, its last sample's time plus one sample interval
  (1 / ``sample_rate``; without a usable ``sample_rate``, the last step of ``time``);
* ``pause_first``, ``pause_samples`` (int32): the index along ``time`` of its first sample and its number of
  samples (``ds.isel(time=slice(first, first + samples))`` are its samples); left out of a run of more than
  2**31 - 1 samples (CF 1.8, as both checkers read it, has no 64-bit integers);
* ``pause_reason``, ``pause_by`` (UTF-8 text in CF character arrays, as xarray writes text with dtype
  ``S1``; xarray reads them back as strings): from the note whose sample index falls in the pause (the
  first such note); "not recorded" (`NOT_RECORDED`) for a pause without one. A note in no pause is dropped.

A run without a pause has no ``pause`` dimension and no table (a zero-length dimension would be unlimited in
netCDF-4 terms and gains a reader nothing). Every run with the ``paused`` flag has the global attribute
``pauses``: the number of pauses (0 included).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ..specs.variables import PAUSE_VARIABLES, pause_attrs

#: The journal's file of pause notes (JSON lines: ``first``, ``reason``, ``by``).
NOTES = "pauses.jsonl"
#: ``pause_reason`` and ``pause_by`` of a pause nobody noted.
NOT_RECORDED = "not recorded"
#: The variables of the table, in the order written.
TABLE = tuple(name for name in PAUSE_VARIABLES if name != "paused")


def note_line(first, reason, by) -> bytes:
    """One note as the line `NOTES` holds, checked.

    Parameters
    ----------
    first : int
        Index along ``time`` of the first sample of the pause (its first sample not running), >= 0.
    reason, by : str
        Why the run was paused; who or what paused it (an operator, ``rdea-lab pause``, a limit, ...).

    Raises
    ------
    ValueError
        ``first`` not an integer >= 0, or ``reason`` or ``by`` not text.
    """
    if isinstance(first, bool) or not isinstance(first, (int, np.integer)) or first < 0:
        raise ValueError(f"note_pause: first = {first!r}; allowed: the sample index (an integer >= 0) of the "
                         "pause's first sample")
    for key, value in (("reason", reason), ("by", by)):
        try:
            value.encode("utf-8")  # the dataset holds it as UTF-8
        except (AttributeError, UnicodeEncodeError):
            raise ValueError(f"note_pause: {key} = {value!r}; allowed: text (UTF-8)") from None
    return (json.dumps({"first": int(first), "reason": reason, "by": by}) + "\n").encode()


def write_note(folder: Path, line: bytes) -> None:
    """Append one note to the journal ``folder``'s `NOTES` with one ``os.write``, then ``fsync`` it."""
    path = Path(folder) / NOTES
    new = not path.exists()
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    try:
        view = memoryview(line)
        while view:
            view = view[os.write(fd, view):]
        os.fsync(fd)
    finally:
        os.close(fd)
    if new:
        from .journal import _fsync_dir

        _fsync_dir(Path(folder))


def read_notes(folder: Path) -> list[tuple[int, str, str]]:
    """The notes of a journal folder, ``[(first, reason, by)]`` in the order written; a line that is not a whole
    note (a torn last line) is skipped."""
    try:
        text = (Path(folder) / NOTES).read_bytes().decode("utf-8", "replace")
    except FileNotFoundError:
        return []
    notes = []
    for line in text.splitlines():
        try:
            note = json.loads(line)
            first, reason, by = note["first"], note["reason"], note["by"]
        except (ValueError, KeyError, TypeError):
            continue
        if isinstance(first, int) and not isinstance(first, bool) and first >= 0 and isinstance(reason, str) \
                and isinstance(by, str):
            notes.append((first, reason, by))
    return notes


class PauseEdges:
    """The pauses of a run's ``paused`` flag fed in order, chunk by chunk (`add`); `table` closes a pause
    the run ended in. Holds only the pauses and the last two times, never the samples."""

    def __init__(self):
        self.samples = 0
        self.closed: list[tuple[int, int, float, float]] = []  # (first, stop, start time, end time)
        self._open = None  # (first, start time) of the pause under way
        self._last = (math.nan, math.nan)  # the times of the last two samples fed

    def add(self, paused: np.ndarray, time: np.ndarray) -> None:
        """Feed the next samples: their ``paused`` flag and their ``time`` [s]."""
        paused, time = np.asarray(paused), np.asarray(time, float)
        n = paused.shape[0]
        if not n:
            return
        flag = np.empty(n + 1, np.int8)
        flag[0] = self._open is not None
        flag[1:] = paused > 0
        for i in np.flatnonzero(np.diff(flag)):  # the edges alternate: a start, a stop, ...
            if self._open is None:
                self._open = (self.samples + int(i), float(time[i]))
            else:
                first, start = self._open
                self.closed.append((first, self.samples + int(i), start, float(time[i])))
                self._open = None
        self._last = (self._last[1] if n == 1 else float(time[-2]), float(time[-1]))
        self.samples += n

    def intervals(self, sample_rate=None) -> list[tuple[int, int, float, float]]:
        """Every pause, ``[(first, stop, start time, end time)]``: the run ended paused, the last one ends one
        sample interval (1 / ``sample_rate`` [Hz], else the last step of the times) after its last sample."""
        out = list(self.closed)
        if self._open is not None:
            try:
                step = 1.0 / float(sample_rate)
            except (TypeError, ValueError, ZeroDivisionError):
                step = math.nan
            if not (math.isfinite(step) and step > 0):
                step = self._last[1] - self._last[0]
            step = step if math.isfinite(step) and step > 0 else 0.0
            first, start = self._open
            out.append((first, self.samples, start, self._last[1] + step))
        return out


def table(intervals, notes) -> dict[str, np.ndarray]:
    """The pause table's values, name -> array along ``pause``: the intervals (`PauseEdges.intervals`) with the
    reason and author of the first note in each (`read_notes`)."""
    firsts = np.array([i[0] for i in intervals], np.int64)
    stops = np.array([i[1] for i in intervals], np.int64)
    reason = [NOT_RECORDED] * len(intervals)
    by = [NOT_RECORDED] * len(intervals)
    taken = np.zeros(len(intervals), bool)
    for first, why, who in notes:
        k = int(np.searchsorted(firsts, first, side="right")) - 1  # the pause starting at or before the note
        if k >= 0 and first < stops[k] and not taken[k]:
            reason[k], by[k], taken[k] = why, who, True
    values = {"pause_start": np.array([i[2] for i in intervals], np.float64),
              "pause_end": np.array([i[3] for i in intervals], np.float64),
              "pause_first": firsts.astype(np.int32), "pause_samples": (stops - firsts).astype(np.int32),
              "pause_reason": np.array(reason, dtype=object), "pause_by": np.array(by, dtype=object)}
    if len(stops) and stops.max() > np.iinfo(np.int32).max:  # CF 1.8 has no int64: the times say it all
        del values["pause_first"], values["pause_samples"]
    return values


def table_variables(values: dict, time_units: str) -> dict:
    """The pause table as xarray variables, name -> ``("pause", values, attrs)``; {} for a run without a pause."""
    if not len(values["pause_start"]):
        return {}
    return {name: ("pause", values[name], pause_attrs(name, time_units)) for name in TABLE if name in values}


def write_table(nc, values: dict) -> None:
    """Write the pause table into an open netCDF4 dataset (of a run, ``time`` written): the ``pause`` dimension
    and its variables, nothing for a run without a pause; the times in ``time``'s units."""
    n = len(values["pause_start"])
    if not n:
        return
    nc.createDimension("pause", n)
    for name in (name for name in TABLE if name in values):
        attrs = pause_attrs(name, nc["time"].getncattr("units"))
        if PAUSE_VARIABLES[name][2] == "S1":  # UTF-8 in a character array, as xarray writes text with dtype S1
            text = np.array([str(x).encode("utf-8") for x in values[name]])
            width = max(1, text.dtype.itemsize)
            if f"string{width}" not in nc.dimensions:
                nc.createDimension(f"string{width}", width)
            var = nc.createVariable(name, "S1", ("pause", f"string{width}"))
            var.set_auto_chartostring(False)
            attrs["_Encoding"] = "utf-8"
            data = text.astype(f"S{width}").view("S1").reshape(n, width)
        else:
            var = nc.createVariable(name, np.dtype(PAUSE_VARIABLES[name][2]), ("pause",))
            data = values[name]
        for key, value in attrs.items():
            var.setncattr(key, value)
        var[:] = data


def pauses(ds):
    """A run's pauses as a table: a pandas DataFrame, one row per pause, columns ``start`` and ``end`` [s since
    the run's start, as ``time``], ``first``, ``samples``, ``reason``, ``by`` (no rows: a run without a pause,
    or one from before issue 29)."""
    import pandas as pd

    columns = {"start": "pause_start", "end": "pause_end", "first": "pause_first", "samples": "pause_samples",
               "reason": "pause_reason", "by": "pause_by"}
    if "pause" not in ds.dims:
        return pd.DataFrame({key: pd.Series(dtype=object if key in ("reason", "by") else
                                            (float if key in ("start", "end") else np.int64)) for key in columns})
    data = {key: np.asarray(ds[name].values) for key, name in columns.items()}
    for key in ("start", "end"):
        if data[key].dtype.kind == "M":  # decoded to dates (xarray's default): back to seconds since the start
            since = str(ds[columns[key]].encoding.get("units", "")).partition(" since ")[2].strip().rstrip("Z")
            data[key] = (data[key] - np.datetime64(since, "ns")) / np.timedelta64(1, "s")
    data["reason"] = [str(x) for x in data["reason"]]
    data["by"] = [str(x) for x in data["by"]]
    return pd.DataFrame(data)


__all__ = ["NOTES", "NOT_RECORDED", "PauseEdges", "TABLE", "note_line", "pauses", "read_notes", "table",
           "table_variables", "write_table"]
