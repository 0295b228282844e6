"""Crash-safe streaming of a run: an append-only journal, turned into netCDF at the end.

An HDF5 (netCDF-4) file killed in the middle of a write can be left unreadable,
so samples are not streamed into it. While a run goes, ``<out>.part/`` holds

* ``header.json``: the column names, variable attributes and dataset attributes;
* ``samples.f8``: rows of little-endian float64, one per sample, appended and
  ``fsync``-ed after every block (at most a second of samples).

* ``writer.lock``: held with an OS lock (``flock``) by the writing process for
  as long as it runs; the header names it (``writer``: pid, host, start time).

When the run ends (complete, aborted, or interrupted by Ctrl-C or SIGTERM) the
journal becomes ``<out>`` (compressed netCDF-4) by an atomic rename, and the
journal is removed. If the process is killed outright (SIGKILL, power loss)
the journal stays and the OS drops its lock; :func:`recover` rebuilds the
dataset from every whole row written, with ``status: interrupted``. A journal
whose writer still holds its lock is a run in progress: `recover` leaves it
alone (`RunInProgress`) and the catalogue lists it as ``running``.
"""

from __future__ import annotations

import errno
import fcntl
import json
import math
import os
import shutil
import socket
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import xarray as xr

from ..specs.errors import SpecError, UserError
from .overview import OVERVIEW_ABOVE, write_overview
from .schema import EXTRA_VARIABLES, TIME_ENCODING, VARIABLES, time_attrs, variable_attrs

FORMAT = "rdea-lab-journal-1"
LOCK = "writer.lock"


class RunInProgress(UserError):
    """The journal belongs to a run still going (its writer holds the lock): nothing to recover yet."""


class JournalInUse(SpecError):
    """Another run is writing this dataset (its journal exists)."""


class EmptyJournal(FileNotFoundError):
    """A journal folder claimed by a run that never started: nothing to recover (it is removed)."""


class DiskFull(UserError):
    """The disk (or quota) is full: every sample received so far is safe in the journal, which says so."""


_FULL = (errno.ENOSPC, errno.EDQUOT)


def _disk_full(exc: OSError, what, journal: Path, samples: int) -> DiskFull:
    return DiskFull(f"disk full writing {what}; {samples} samples are safe in {journal}; free space and run "
                    f"rdea-lab recover {journal} (or recover --out ELSEWHERE)")


def _is_full(exc: BaseException, out: Path, nbytes: int) -> bool:
    """Whether writing failed for want of space: ENOSPC/EDQUOT, or whatever netCDF reports then (a bare
    "HDF error", or "Permission denied" on the temporary file) on a file system with less free space than
    the dataset needs (a folder that cannot be written at all was refused before the run)."""
    if isinstance(exc, OSError) and exc.errno in _FULL:
        return True
    if isinstance(exc, (OSError, RuntimeError)):
        try:
            return shutil.disk_usage(Path(out).parent).free < 2 * nbytes + 2**20
        except OSError:
            return False
    return False


#: Bytes kept for ``status.json`` from the run's start, so that a full disk can still say how the run ended.
STATUS_BYTES = 4096


def _reserve_status(folder: Path) -> None:
    """Claim the space of ``status.json`` while the disk has room (blanks: no status noted yet)."""
    try:
        (folder / "status.json").write_bytes(b" " * STATUS_BYTES)
    except OSError:
        pass


def _note_status(folder: Path, status: str, reason: str) -> None:
    """Best effort: how the run ended, for `recover`, written over the space `_reserve_status` claimed (in
    place, padded with blanks: no new block needed on a full disk)."""
    text = json.dumps({"status": status, "status_reason": reason[:STATUS_BYTES // 2]}).encode()
    try:
        with open(folder / "status.json", "r+b" if (folder / "status.json").exists() else "wb") as fh:
            fh.write(text.ljust(STATUS_BYTES))
            fh.flush()
            os.fsync(fh.fileno())
    except OSError:
        pass


def _try_lock(folder: Path):
    """An exclusive, non-blocking lock on a journal's ``writer.lock``: its file descriptor, or None if a
    live process holds it. Journals older than the lock have none: None is never returned for them."""
    fd = os.open(Path(folder) / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    except BaseException:
        os.close(fd)
        raise
    return fd


def journal_writer(folder: Path) -> dict | None:
    """The live writer of a journal (``pid``, ``host``, ``started``), or None when no process holds it."""
    folder = Path(folder)
    if not (folder / LOCK).exists():
        return None
    fd = _try_lock(folder)
    if fd is not None:
        os.close(fd)  # nobody held it: the writer is gone (the lock goes with the descriptor)
        return None
    try:
        header = json.loads((folder / "header.json").read_text())
        writer = header.get("writer") if isinstance(header, dict) else None
    except (OSError, ValueError):
        writer = None
    return writer if isinstance(writer, dict) else {"pid": "?", "host": "?", "started": "?"}


def utc_now() -> str:
    """Current UTC time, ISO 8601 to the second."""
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def journal_path(out: Path) -> Path:
    """The journal folder of the dataset ``out``."""
    out = Path(out)
    return out.with_name(out.name + ".part")


class JournalWriter:
    """Append blocks of samples to a run's journal; finish into a netCDF file.

    Parameters
    ----------
    out : Path
        The dataset to produce (``.nc``).
    attrs : dict or None
        Dataset attributes (strings and numbers only). None only claims the
        journal (its folder and lock, so no other run can take this output) and
        `begin` writes the header later; `abandon` gives a claim up.
    extra : sequence of str
        Extra variables (keys of :data:`EXTRA_VARIABLES`) the backend writes.
    """

    def __init__(self, out: Path, attrs: dict | None, extra=()):
        self.out = Path(out)
        self.dir = journal_path(self.out)
        self.columns = ["time", *VARIABLES, *extra]
        self.samples = 0
        self.out.parent.mkdir(parents=True, exist_ok=True)
        try:
            self.dir.mkdir(exist_ok=False)
        except FileExistsError:
            raise JournalInUse(str(self.out), "out", f"another run is writing it (its journal {self.dir} "
                               "exists); choose another output") from None
        self._lock = _try_lock(self.dir)  # held until the dataset is written and the journal gone
        self.writer = {"pid": os.getpid(), "host": socket.gethostname(), "started": utc_now()}
        self._fd = None
        if attrs is not None:
            self.begin(attrs)

    def begin(self, attrs: dict) -> None:
        """Write the header (the attributes known once the run starts) and open the sample file."""
        header = {"format": FORMAT, "columns": self.columns, "attrs": attrs, "writer": self.writer}
        tmp = self.dir / "header.json.tmp"
        tmp.write_text(json.dumps(header, indent=1))
        os.replace(tmp, self.dir / "header.json")
        _reserve_status(self.dir)
        self._fd = os.open(self.dir / "samples.f8", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        _fsync_dir(self.dir)

    def abandon(self) -> None:
        """Give up a run that never acquired (nothing was measured; `begin` may have been under way or
        done): the folder goes, the lock with it."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self.samples == 0:
            shutil.rmtree(self.dir, ignore_errors=True)
        self._release()

    def append(self, block: dict) -> int:
        """Write one block (arrays keyed by column name) and make it durable."""
        n = len(block["time"])
        rows = np.empty((n, len(self.columns)), dtype="<f8")
        for j, name in enumerate(self.columns):
            rows[:, j] = block.get(name, np.nan)
        data = rows.tobytes()
        view = memoryview(data)
        try:
            while view:
                written = os.write(self._fd, view)
                view = view[written:]
            os.fsync(self._fd)
        except OSError as exc:  # a torn last row is dropped when the journal is read
            self.samples += (len(data) - len(view)) // rows.shape[1] // 8  # the whole rows that did get out
            if exc.errno in _FULL:
                raise _disk_full(exc, self.dir, self.dir, self.samples) from None
            raise
        self.samples += n
        return n

    def close(self):
        """Stop writing and let go of the journal (as a killed process would): `recover` may take it."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        self._release()

    def _release(self):
        if getattr(self, "_lock", None) is not None:
            os.close(self._lock)
            self._lock = None

    def finish(self, status: str, reason: str, history: str = "") -> Path:
        """Close the journal and write the dataset with its final status (the lock is kept until the end)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        try:
            ds = read_journal(self.dir)
            ds.attrs.update(final_attrs(ds.attrs, status, reason, history))
            try:
                write_dataset(ds, self.out)
            except (OSError, RuntimeError) as exc:  # the journal stays, with how the run ended
                _note_status(self.dir, status, reason)
                if _is_full(exc, self.out, int(ds.attrs["samples"]) * 8 * len(self.columns)):
                    raise _disk_full(exc, self.out, self.dir, int(ds.attrs["samples"])) from None
                raise
            shutil.rmtree(self.dir)
        finally:
            self._release()
        return self.out


def final_attrs(attrs: dict, status: str, reason: str, history: str) -> dict:
    now = utc_now()
    line = f"{now}: status {status}" + (f" ({reason})" if reason else "")
    if history:
        line += f"; {history}"
    return {"status": status, "status_reason": reason, "finished": now,
            "history": (attrs.get("history", "") + "\n" + line).strip()}


def read_journal(folder: Path) -> xr.Dataset:
    """The dataset a journal holds: every whole row written (a torn last row is dropped)."""
    folder = Path(folder)
    try:
        header = json.loads((folder / "header.json").read_text())
    except ValueError as exc:
        raise ValueError(f"{folder}: header.json is not JSON ({exc})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        got = header.get("format") if isinstance(header, dict) else type(header).__name__
        raise ValueError(f"{folder}: not an rdea-lab journal (format {got!r})")
    columns = header.get("columns")
    known = {"time", *VARIABLES, *EXTRA_VARIABLES}
    if (not isinstance(columns, list) or not columns or columns[0] != "time"
            or not all(isinstance(c, str) and c in known for c in columns) or len(set(columns)) != len(columns)):
        raise ValueError(f"{folder}: header.json 'columns' must list 'time' first, then known variables "
                         f"({', '.join(sorted(known))}), each once; got {str(columns)[:80]}")
    if not isinstance(header.get("attrs"), dict):
        raise ValueError(f"{folder}: header.json 'attrs' must be a mapping")
    raw = np.fromfile(folder / "samples.f8", dtype="<f8")
    n = raw.size // len(columns)
    rows = raw[: n * len(columns)].reshape(n, len(columns))
    data_vars = {}
    for j, name in enumerate(columns[1:], start=1):
        if name in VARIABLES or EXTRA_VARIABLES[name][2] == "f8":
            values = rows[:, j]
        else:
            values = np.nan_to_num(rows[:, j], nan=-1).astype(EXTRA_VARIABLES[name][2])
        data_vars[name] = ("time", values, variable_attrs(name))
    attrs = dict(header["attrs"])
    writer = header.get("writer") if isinstance(header.get("writer"), dict) else {}
    start = str(attrs.get("created") or writer.get("started") or utc_now())
    coords = {"time": ("time", rows[:, 0], time_attrs(start))}
    ds = xr.Dataset(data_vars, coords=coords, attrs=attrs)
    ds.attrs["samples"] = int(n)
    return ds


def write_dataset(ds: xr.Dataset, out: Path) -> None:
    """Write ``ds`` to ``out`` atomically (temporary file, fsync, rename)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    ds.attrs = netcdf_attrs(ds.attrs)
    tmp = out.with_name(out.name + ".tmp")
    if ("time" in ds.coords and np.issubdtype(ds["time"].dtype, np.number)
            and " since " not in str(ds["time"].attrs.get("units", ""))):
        ds["time"].attrs.update(time_attrs(str(ds.attrs.get("created") or utc_now())))  # float seconds, CF-1.8
    encoding = {name: {"zlib": True, "complevel": 4} for name in ds.data_vars}
    encoding["time"] = {"zlib": True, "complevel": 4, **TIME_ENCODING}
    try:
        ds.to_netcdf(tmp, engine="netcdf4", unlimited_dims=["time"], encoding=encoding)
        if ds.sizes.get("time", 0) > OVERVIEW_ABOVE:  # a long run: its figure drawn from the overview
            write_overview(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)  # never a half-written file left behind
        raise
    _fsync_dir(out.parent)


def netcdf_attrs(attrs: dict) -> dict:
    """Attributes as netCDF can store them: an integer outside int64, a bool, None, a list or a mapping
    becomes text (JSON where it is structured), so no attribute's type can make a run unwritable."""
    out = {}
    for key, value in attrs.items():
        if isinstance(value, bool):
            value = int(value)
        elif isinstance(value, int) and not -2**63 <= value < 2**63:
            value = str(value)
        elif isinstance(value, float) and not math.isfinite(value):
            value = repr(value)
        elif value is None:
            value = ""
        elif isinstance(value, (list, tuple, dict)):
            value = json.dumps(value, default=str)
        elif not isinstance(value, (str, int, float, np.generic, np.ndarray)):
            value = str(value)
        out[str(key)] = value
    return out


def recover(path: Path, out: Path | None = None) -> Path:
    """Rebuild the dataset of a run that died without closing its journal.

    Parameters
    ----------
    path : str or path-like
        The journal folder (``<out>.part``) or the dataset path whose journal exists.
    out : str or path-like, optional
        Write the dataset there instead (e.g. another disk when this one is full); default: the
        dataset the run was writing.

    Returns
    -------
    pathlib.Path
        The dataset written, marked ``interrupted``, or with the status the run recorded when it
        could not write its dataset (a full disk). The journal is removed once it is written.

    Raises
    ------
    RunInProgress
        The journal belongs to a run still writing it (or starting on it): left alone.
    EmptyJournal
        The claim of a run that never started (no samples); it is removed.
    FileNotFoundError
        No journal at ``path``.
    FileExistsError
        The dataset to write exists already.
    OutputError
        ``out`` is no dataset name or cannot be written.
    """
    path = Path(path)
    folder = path if path.name.endswith(".part") else journal_path(path)
    if not (folder / "header.json").is_file():
        if folder.is_dir() and (folder / LOCK).exists() and not (folder / "samples.f8").exists():
            if journal_writer(folder) is not None:
                raise RunInProgress(f"{folder}: a run is starting on it; left alone")
            shutil.rmtree(folder, ignore_errors=True)  # a claim whose run never began (killed before it started)
            raise EmptyJournal(f"{folder}: the claim of a run that never started (no samples); removed")
        raise FileNotFoundError(f"{path}: no run journal here (expected {folder}/header.json)")
    lock = _try_lock(folder)
    if lock is None:
        w = journal_writer(folder) or {}
        raise RunInProgress(f"{folder}: a run is still writing it (pid {w.get('pid', '?')} on "
                            f"{w.get('host', '?')} since {w.get('started', '?')}); left alone")
    from .outputs import OutputError, check_dataset_name, check_writable, shown

    try:
        if out is not None:
            check_dataset_name(out)
            check_writable(out)
        else:  # the dataset the run was writing: a name the run could not write is said, with the way out
            out = folder.with_name(folder.name[: -len(".part")])
            try:
                check_writable(out)
            except OutputError as exc:
                raise OutputError(shown(folder), "dataset", f"{exc.message}; give --out NAME.nc to write its "
                                  "samples there instead") from None
    except BaseException:
        os.close(lock)
        raise
    try:
        out = Path(out)
        if out.exists():
            raise FileExistsError(f"{out} exists already; move it away to recover {folder}")
        ds = read_journal(folder)
        n = ds.attrs["samples"]
        status, reason = "interrupted", (f"the process stopped without closing the run; {n} samples recovered "
                                         "from the journal by rdea-lab recover")
        try:
            noted = json.loads((folder / "status.json").read_text())
            status = noted["status"]
            reason = f"{noted['status_reason']}; {n} samples recovered from the journal by rdea-lab recover"
        except (OSError, ValueError, KeyError, TypeError):
            pass
        ds.attrs.update(final_attrs(ds.attrs, status, reason, "rdea-lab recover"))
        try:
            write_dataset(ds, out)
        except (OSError, RuntimeError) as exc:
            if _is_full(exc, out, n * 8 * (len(ds.data_vars) + 1)):
                raise _disk_full(exc, out, folder, n) from None
            raise
        shutil.rmtree(folder)
    finally:
        os.close(lock)
    return out


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
