"""Crash-safe streaming of a run: an append-only journal, turned into netCDF at the end.

An HDF5 (netCDF-4) file killed in the middle of a write can be left unreadable,
so the journal, not the netCDF file, is the record of a run. While a run goes,
``<out>.part/`` holds

* ``header.json``: the column names, variable attributes and dataset attributes;
* ``samples.f8``: rows of little-endian float64, one per sample, each block (at
  most a second of samples) written with one ``os.write`` as it arrives;
* ``pauses.jsonl``: for a run that pauses, why and by whom each pause began (`JournalWriter.note_pause`;
  the pause table the dataset gets: `rdea_lab.store.pauses`);
* ``writer.lock``: held with an OS lock (``flock``) by the writing process for
  as long as it runs; the header names it (``writer``: pid, host, start time);
* ``shadow.nc``: for a long run (from `SHADOW_FROM` rows), the netCDF file being
  written from the journal by a background thread while the run goes, so that
  only the tail is left to convert at the end. It is a cache: a killed run's
  shadow is discarded and `recover` converts the journal again.

Durability, exactly. A block is in the journal once `JournalWriter.append`
returns: a process killed (SIGKILL, a crash) after that loses nothing of it,
since what is ``os.write``-n lives in the kernel's page cache whatever happens
to the process; a kill during an append loses at most that block (a torn row is
dropped). The journal is ``fsync``-ed when at least `FSYNC_EVERY` (1 s) of wall
time has passed since the last ``fsync`` (checked at each append), and when the
run ends, so a power loss or kernel crash loses at most the blocks of the last
second of wall time (plus the block in flight). An ``fsync`` per block would cost
about 0.3 ms each, 27 s over a day-long run at 1 kHz in 1000-sample blocks,
whereas the second's bound is the same in real time and the twin, far faster than
real time, gets its ~1e6 blocks written for one ``fsync`` a second.

When the run ends (complete, aborted, or interrupted by Ctrl-C or SIGTERM) the
journal becomes ``<out>`` (compressed netCDF-4: zlib level `COMPRESSION`, shuffle,
HDF5 chunks of `CHUNK` samples; each float variable gets ``actual_range``) by an
atomic rename, and the journal is removed. The conversion streams: `READ_ROWS`
rows at a time, never the whole run in memory. If the process is killed
outright (SIGKILL, power loss) the journal stays and the OS drops its lock;
:func:`recover` rebuilds the dataset from every whole row written, with
``status: interrupted``, streaming as well. A journal whose writer still holds
its lock is a run in progress: `recover` leaves it alone (`RunInProgress`) and
the catalogue lists it as ``running``. The dataset is written as ``<out>.tmp``
(renamed into place) only by the holder of the journal's lock, so a ``<out>.tmp``
found when a conversion begins is a dead conversion's: it is discarded, and the
dataset written from the journal (`_Converter`).
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import math
import os
import shutil
import socket
import threading
import time as _time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import xarray as xr

from ..specs.errors import SpecError, UserError
from . import pauses as _pauses
from ._hdf5 import close_unlocked, create, publish, remove_own
from .overview import OVERVIEW_ABOVE, OverviewBuilder, add_overview
from .schema import EXTRA_VARIABLES, TEXT_VARIABLES, TIME_ENCODING, VARIABLES, time_attrs, variable_attrs

FORMAT = "rdea-lab-journal-1"
LOCK = "writer.lock"
SHADOW = "shadow.nc"

#: Wall time [s] between two ``fsync`` of the journal (the bound on what a power loss can take).
FSYNC_EVERY = 1.0
#: netCDF compression of every variable: zlib level 1 with the shuffle filter (level 4 costs ~1.6x the time
#: for ~2 % smaller files on twin data; shuffle makes them ~25 % smaller and the writing faster).
COMPRESSION = {"zlib": True, "complevel": 1, "shuffle": True}
#: HDF5 chunk of each variable [samples] (256 kB of float64: a display or analysis slice reads little more).
CHUNK = 1 << 15
#: Rows read from the journal at a time when converting it (2**16 rows of 10 columns: 5 MB).
READ_ROWS = 1 << 16
#: Journal rows from which a background thread writes the netCDF file while the run goes (shorter runs are
#: converted at the end, in well under a second).
SHADOW_FROM = 1 << 17
#: Seconds a new claim waits for its lock held by another (a look that takes milliseconds), or for its folder to
#: go (a recover removing it as abandoned), before it is refused.
CLAIM_WAIT = 2.0


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


def _try_lock(folder: Path, create: bool = True):
    """An exclusive, non-blocking lock on a journal's ``writer.lock``: its file descriptor, or None if another
    process (or another call here) holds it. Journals older than the lock have none: with ``create`` the file is
    made, and None is never returned for them.

    The protocol: whoever removes a journal holds its lock and unlinks ``writer.lock`` last (`_remove_journal`),
    so a lock taken on a file that is no longer the one at its path belongs to a journal being removed:
    FileNotFoundError, as for a lock file missing when ``create`` is False."""
    path = Path(folder) / LOCK
    fd = os.open(path, os.O_RDWR | (os.O_CREAT if create else 0), 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        if not os.path.samestat(os.fstat(fd), os.stat(path)):  # (os.stat: FileNotFoundError once unlinked)
            raise FileNotFoundError(errno.ENOENT, "the journal was removed while its lock was taken", str(path))
    except BlockingIOError:
        os.close(fd)
        return None
    except BaseException:
        os.close(fd)
        raise
    return fd


def _let_go(fd: int, owner: int | None = None) -> None:
    """Undo a journal's lock (`_try_lock`'s descriptor ``fd``) and close it. Undone first: the ``flock``
    belongs to the open file description, of which a process forked meanwhile by another thread (a subprocess
    starting) holds a copy until it closes it; closing ours alone would leave the journal locked meanwhile,
    and a `recover` (in this process too) would find it a run in progress. ``owner``: the pid that took the
    lock; another process (a child forked with a copy of the descriptor) only closes its copy."""
    try:
        if owner is None or owner == os.getpid():
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def _remove_journal(folder: Path, held: int | None = None, ignore_errors: bool = False) -> None:
    """Remove a journal whose lock the caller holds (``held``, its descriptor): its files, then
    ``writer.lock``, then the folder (so a lock another process takes meanwhile is on a file gone from its
    path: `_try_lock` says so). Something written into the folder meanwhile (a pause request, a lock file a
    recover made for a journal older than the lock) is removed on a second pass, unless the folder's lock
    file is no longer the one held: then another claim owns the folder and it is left to it."""
    folder = Path(folder)
    lock = folder / LOCK
    for attempt in range(3):
        try:
            if held is not None:
                try:
                    if not os.path.samestat(os.stat(lock), os.fstat(held)):
                        return  # a new claim's folder now
                except FileNotFoundError:
                    if attempt:
                        held = None  # ours is gone already (first pass): a lock file made since is no claim's
            for entry in os.scandir(folder):
                if entry.name == LOCK:
                    continue
                if entry.is_dir(follow_symlinks=False):
                    shutil.rmtree(entry.path)
                else:
                    os.unlink(entry.path)
            with contextlib.suppress(FileNotFoundError):
                os.unlink(lock)
            os.rmdir(folder)
            return
        except FileNotFoundError:
            if not folder.exists():
                return
            if attempt == 2 and not ignore_errors:
                raise
        except OSError as exc:
            if (exc.errno != errno.ENOTEMPTY or attempt == 2) and not ignore_errors:
                raise
            _time.sleep(0.01)


def journal_writer(folder: Path) -> dict | None:
    """The live writer of a journal (``pid``, ``host``, ``started``), or None when no process holds it."""
    folder = Path(folder)
    if not (folder / LOCK).exists():
        return None
    try:
        fd = _try_lock(folder, create=False)
    except FileNotFoundError:  # the journal went meanwhile
        return None
    if fd is not None:
        _let_go(fd)  # nobody held it: the writer is gone (the lock goes with the descriptor)
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


def walk_runs(folder) -> tuple[list[str], list[Path]]:
    """The datasets (``*.nc``, as text) and journals (``*.nc.part``) below ``folder``, by path (a journal's
    inside is not entered)."""
    datasets, journals = [], []
    for root, dirs, files in os.walk(folder):
        for d in list(dirs):
            if d.endswith(".nc.part"):
                journals.append(Path(root) / d)
                dirs.remove(d)
        datasets += [os.path.join(root, f) for f in files if f.endswith(".nc")]
    return sorted(datasets, key=lambda p: p.split(os.sep)), sorted(journals)


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
    background : bool
        Write the netCDF file in a background thread while the run goes, once the journal holds
        `SHADOW_FROM` rows (the module's docstring); False: all of it at `finish`.
    """

    def __init__(self, out: Path, attrs: dict | None, extra=(), background: bool = True):
        self.out = Path(out)
        self.dir = journal_path(self.out)
        self.columns = ["time", *VARIABLES, *extra]
        self.samples = 0
        self.background = background
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self._lock = self._claim()  # held until the dataset is written and the journal gone
        self.writer = {"pid": os.getpid(), "host": socket.gethostname(), "started": utc_now()}
        self._fd = None
        self._synced = _time.monotonic()
        self._shadow = None
        if attrs is not None:
            self.begin(attrs)

    def _claim(self) -> int:
        """Make the journal folder and its lock file (once, right after the folder) and take the lock: its
        file descriptor. The lock may be busy for a moment (a catalogue or `recover` looking whether a writer
        holds it): tried again for `CLAIM_WAIT`, never making the file again. A `recover` that looks in
        between (the folder made, its lock not yet taken) takes it for the claim of a run killed before it
        began and removes it, holding its lock: once the folder is gone the claim is made again."""
        for _ in range(20):
            try:
                self.dir.mkdir(exist_ok=False)
            except FileExistsError:
                raise JournalInUse(str(self.out), "out", f"another run is writing it (its journal {self.dir} "
                                   "exists); choose another output") from None
            try:
                os.close(os.open(self.dir / LOCK, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644))
            except (FileNotFoundError, FileExistsError):  # removed under us already, or being removed
                pass
            deadline = _time.monotonic() + CLAIM_WAIT
            while True:
                try:
                    lock = _try_lock(self.dir, create=False)
                except FileNotFoundError:  # removed under us
                    break
                if lock is not None:
                    return lock
                if _time.monotonic() > deadline:
                    raise JournalInUse(str(self.out), "out", f"its journal {self.dir} is held by another "
                                       "process; choose another output")
                _time.sleep(0.005)
            deadline = _time.monotonic() + CLAIM_WAIT
            while self.dir.exists() and _time.monotonic() < deadline:  # its removal under way: let it end
                _time.sleep(0.005)
        raise JournalInUse(str(self.out), "out", f"its journal {self.dir} keeps being removed; choose another "
                           "output")

    def begin(self, attrs: dict) -> None:
        """Write the header (the attributes known once the run starts) and open the sample file."""
        header = {"format": FORMAT, "columns": self.columns, "attrs": attrs, "writer": self.writer}
        tmp = self.dir / "header.json.tmp"
        tmp.write_text(json.dumps(header, indent=1))
        os.replace(tmp, self.dir / "header.json")
        _reserve_status(self.dir)
        self._fd = os.open(self.dir / "samples.f8", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        _fsync_dir(self.dir)
        self._synced = _time.monotonic()

    def abandon(self) -> None:
        """Give up a run that never acquired (nothing was measured; `begin` may have been under way or
        done): the folder goes, the lock with it."""
        converter = self._stop_shadow()
        if converter is not None:
            converter.discard()
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self.samples == 0:
            _remove_journal(self.dir, self._lock, ignore_errors=True)
        self._release()

    def append(self, block: dict) -> int:
        """Write one block (arrays keyed by column name) with one ``os.write``; ``fsync`` the journal if
        `FSYNC_EVERY` seconds have passed since the last (the module's docstring says what is promised)."""
        n = len(block["time"])
        rows = np.empty((n, len(self.columns)), dtype="<f8")
        for j, name in enumerate(self.columns):
            rows[:, j] = block.get(name, np.nan)
        view = memoryview(rows).cast("B")
        try:
            while view:
                written = os.write(self._fd, view)
                view = view[written:]
            if _time.monotonic() - self._synced >= FSYNC_EVERY:
                os.fsync(self._fd)
                self._synced = _time.monotonic()
        except OSError as exc:  # a torn last row is dropped when the journal is read
            self.samples += (rows.nbytes - len(view)) // rows.shape[1] // 8  # the whole rows that did get out
            if exc.errno in _FULL:
                raise _disk_full(exc, self.dir, self.dir, self.samples) from None
            raise
        self.samples += n
        if self._shadow is not None:
            self._shadow.wake.set()
        elif self.background and self.samples >= SHADOW_FROM:
            self._shadow = _Shadow(self)
            self._shadow.start()
        return n

    def note_pause(self, first: int, reason: str, by: str) -> None:
        """Note why a pause began at sample ``first`` (the run's first sample not running after running ones)
        and who or what paused it: one line of ``pauses.jsonl``, written with one ``os.write`` and ``fsync``-ed
        (a killed run's `recover` reads it as `finish` does). The dataset's pause table takes ``reason`` and
        ``by`` for the pause the sample falls in (`rdea_lab.store.pauses`).

        Parameters
        ----------
        first : int
            Index along ``time`` of the pause's first sample, >= 0.
        reason, by : str
            Why the run was paused; who or what paused it.

        Raises
        ------
        ValueError
            ``first`` not an integer >= 0, ``reason`` or ``by`` not text.
        DiskFull
            No room for the note (the samples so far are safe).
        """
        line = _pauses.note_line(first, reason, by)
        try:
            _pauses.write_note(self.dir, line)
        except OSError as exc:
            if exc.errno in _FULL:
                raise _disk_full(exc, self.dir / _pauses.NOTES, self.dir, self.samples) from None
            raise

    def close(self):
        """Stop writing and let go of the journal (as a killed process would): `recover` may take it."""
        converter = self._stop_shadow()
        if converter is not None:  # closed; the file stays, as a killed run's would (recover drops it)
            converter.discard(keep=True)
        self._close_fd()
        self._release()

    def _close_fd(self):
        """fsync (best effort: a full disk keeps what it has) and close the sample file."""
        if self._fd is not None:
            try:
                os.fsync(self._fd)
            except OSError:
                pass
            os.close(self._fd)
            self._fd = None

    def _release(self):
        if getattr(self, "_lock", None) is not None:
            _let_go(self._lock, getattr(self, "writer", {}).get("pid"))
            self._lock = None

    def _stop_shadow(self):
        """Stop the background conversion; its converter (None if it failed or never started)."""
        shadow, self._shadow = self._shadow, None
        if shadow is None:
            return None
        shadow.stop = True
        shadow.wake.set()
        shadow.join()
        return shadow.converter if shadow.failed is None else None

    def finish(self, status: str, reason: str, history: str = "") -> Path:
        """Close the journal and write the dataset with its final status (the lock is kept until the end):
        the tail the background thread has not converted yet, or the whole journal, streamed."""
        converter = self._stop_shadow()
        self._close_fd()
        try:
            try:
                if converter is None:
                    converter = _Converter(self.dir, _tmp_of(self.out))
                n = converter.convert(_journal_rows(self.dir, len(self.columns)))
                converter.close(final_attrs(converter.attrs, status, reason, history), self.out)
            except (OSError, RuntimeError) as exc:  # the journal stays, with how the run ended
                if converter is not None:
                    converter.discard()
                _note_status(self.dir, status, reason)
                n = _journal_rows(self.dir, len(self.columns))
                if _is_full(exc, self.out, n * 8 * len(self.columns)):
                    raise _disk_full(exc, self.out, self.dir, n) from None
                raise
            except BaseException:
                if converter is not None:
                    converter.discard()
                raise
            _remove_journal(self.dir, self._lock)
        finally:
            self._release()
        return self.out


class _Shadow(threading.Thread):
    """The background conversion of a running journal into ``<out>.part/shadow.nc``: wakes at each append
    (or each second) and converts the rows written so far. A failure (a full disk, anything) is kept in
    ``failed`` and the shadow dropped: `JournalWriter.finish` then converts the journal itself."""

    def __init__(self, writer: JournalWriter):
        super().__init__(name=f"rdea-lab netCDF {writer.out.name}", daemon=True)
        self.writer, self.wake, self.stop = writer, threading.Event(), False
        self.converter, self.failed = None, None

    def run(self):
        try:
            self.converter = _Converter(self.writer.dir, self.writer.dir / SHADOW)
            while not self.stop:
                self.wake.wait(FSYNC_EVERY)
                self.wake.clear()
                # whole reads only (the HDF5 chunks are written once each); the tail is finish's
                self.converter.convert(self.writer.samples // READ_ROWS * READ_ROWS, stop=lambda: self.stop)
        except BaseException as exc:  # noqa: BLE001 - kept for finish, which falls back to the journal
            try:
                if self.converter is not None:
                    self.converter.discard()  # at once: a full disk gets the space back
            finally:
                self.failed = exc  # said once the file is gone


def final_attrs(attrs: dict, status: str, reason: str, history: str) -> dict:
    now = utc_now()
    line = f"{now}: status {status}" + (f" ({reason})" if reason else "")
    if history:
        line += f"; {history}"
    return {"status": status, "status_reason": reason, "finished": now,
            "history": (attrs.get("history", "") + "\n" + line).strip()}


def _read_header(folder: Path) -> dict:
    """A journal's header, checked: ``format``, ``columns`` (``time`` first, known variables, each once)
    and ``attrs`` (a mapping)."""
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
    return header


def _journal_rows(folder: Path, ncolumns: int) -> int:
    """Whole rows in a journal's ``samples.f8`` (a torn last row is not counted)."""
    try:
        return (Path(folder) / "samples.f8").stat().st_size // (8 * ncolumns)
    except FileNotFoundError:
        return 0


def _read_rows(folder: Path, ncolumns: int, start: int, stop: int) -> np.ndarray:
    """Rows ``start:stop`` of a journal, shape (stop - start, ncolumns)."""
    raw = np.fromfile(Path(folder) / "samples.f8", dtype="<f8", count=(stop - start) * ncolumns,
                      offset=start * ncolumns * 8)
    return raw[: raw.size // ncolumns * ncolumns].reshape(-1, ncolumns)


def _column(name: str, values: np.ndarray) -> np.ndarray:
    """A journal column (float64) as its variable stores it: float64, or the integer dtype of an extra
    variable (a NaN there, a sample without a value, becomes -1)."""
    if name == "time" or name in VARIABLES or EXTRA_VARIABLES[name][2] == "f8":
        return values
    return np.nan_to_num(values, nan=-1).astype(EXTRA_VARIABLES[name][2])


def _dataset(header: dict, rows: np.ndarray, notes=None) -> xr.Dataset:
    """The dataset of journal rows (all of them, or none: the layout of the file to write); with ``notes``
    (`rdea_lab.store.pauses.read_notes`; all the rows), the pause table of a run that can pause too."""
    columns = header["columns"]
    data_vars = {name: ("time", _column(name, rows[:, j]), variable_attrs(name))
                 for j, name in enumerate(columns) if j}
    attrs = dict(header["attrs"])
    writer = header.get("writer") if isinstance(header.get("writer"), dict) else {}
    start = str(attrs.get("created") or writer.get("started") or utc_now())
    coords = {"time": ("time", rows[:, 0], time_attrs(start))}
    ds = xr.Dataset(data_vars, coords=coords, attrs=attrs)
    ds.attrs["samples"] = int(rows.shape[0])
    if notes is not None and "paused" in columns:
        edges = _pauses.PauseEdges()
        edges.add(_column("paused", rows[:, columns.index("paused")]), rows[:, 0])
        intervals = edges.intervals(attrs.get("sample_rate"))
        ds = ds.assign(_pauses.table_variables(_pauses.table(intervals, notes), coords["time"][2]["units"]))
        ds.attrs["pauses"] = len(intervals)
    return ds


def read_journal(folder: Path) -> xr.Dataset:
    """The dataset a journal holds, in memory: every whole row written (a torn last row is dropped).
    For a short journal (a test, a look); `finish` and `recover` stream it instead."""
    folder = Path(folder)
    header = _read_header(folder)
    n = _journal_rows(folder, len(header["columns"]))
    return _dataset(header, _read_rows(folder, len(header["columns"]), 0, n), _pauses.read_notes(folder))


def actual_range(values: np.ndarray, current=None):
    """``[min, max]`` of the finite values of a float array merged into ``current`` (None: none yet);
    None when neither has a finite value (CF's ``actual_range``)."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return current
    lo, hi = finite.min(), finite.max()
    if current is not None:
        lo, hi = min(lo, current[0]), max(hi, current[1])
    return np.array([lo, hi], dtype=values.dtype)


def _encoding(ds: xr.Dataset) -> dict:
    """How each variable of a run is written: compressed, in chunks of `CHUNK` samples along ``time``."""
    encoding = {name: {**COMPRESSION, **({"chunksizes": (CHUNK,)} if ds[name].dims == ("time",) else {})}
                for name in ds.data_vars if ds[name].dtype.kind in "biuf"}  # text (the pause table) uncompressed
    for name in ("pause_start", "pause_end"):  # times, written as time is (no _FillValue)
        if name in ds.data_vars:
            encoding[name] = {**encoding[name], **TIME_ENCODING}
    for name in TEXT_VARIABLES:  # CF character arrays (the checkers refuse netCDF-4 strings)
        if name in ds.data_vars:
            encoding[name] = {"dtype": "S1"}
    encoding["time"] = {**COMPRESSION, **({"chunksizes": (CHUNK,)} if "time" in ds.dims else {}), **TIME_ENCODING}
    return encoding


def _tmp_of(out: Path) -> Path:
    return Path(out).with_name(Path(out).name + ".tmp")


class _Converter:
    """A journal written into a netCDF file chunk by chunk: the layout (variables, attributes, encoding)
    from an empty dataset through xarray, as `write_dataset` writes it, then `READ_ROWS` rows at a time
    with netCDF4, each float variable's ``actual_range`` kept as it goes; `close` sets the final
    attributes and renames the file into place.

    The file is made afresh and opened once, for the whole conversion. Only the holder of the journal's
    lock writes it (a run's `JournalWriter.finish`, or `recover`), so a file found at its path is what a
    conversion that died left (a killed process's half file): it is discarded, never reopened, and the
    dataset is written from the journal. Never opening the file a second time matters: HDF5 holds an
    ``flock`` on a file for as long as it is open, and an ``flock`` belongs to the open file description,
    which a process forked meanwhile by another thread (a subprocess starting) holds too until it closes its
    copy; a second open of the same file is refused by that lock ("NetCDF: HDF error") though nobody
    else writes it. A new file (a new inode) carries no such lock. And `close` undoes the writer's own lock
    before closing (`_hdf5.close_unlocked`), so that no copy of its descriptor keeps it either: what reads
    the dataset at once (its catalogue row, `open_run`) would be refused the same way."""

    def __init__(self, folder: Path, tmp: Path):
        from xarray.backends import NetCDF4DataStore
        from xarray.backends.locks import HDF5_LOCK

        self.folder, self.tmp, self._lock = Path(folder), Path(tmp), HDF5_LOCK
        header = _read_header(self.folder)
        self.columns = header["columns"]
        layout = _dataset(header, np.empty((0, len(self.columns))))
        self.attrs = dict(layout.attrs)
        self.tmp.parent.mkdir(parents=True, exist_ok=True)
        self.done, self.ranges, self._nc, self._made, self._pid = 0, {}, None, None, os.getpid()
        self.overview = OverviewBuilder()  # min/max per block, for the figure of a long run (store.overview)
        self.edges = _pauses.PauseEdges() if "paused" in self.columns else None  # the pauses so far
        try:
            layout.attrs = netcdf_attrs(layout.attrs)
            # a dead conversion's file removed (the journal is the record); made here, kept open. The file made
            # (its identity) is the only one ever renamed to the output, or removed
            self._nc, self._made = create(self.tmp, self._lock)
            # the layout through xarray, into the open file (xarray takes the HDF5 lock itself)
            layout.dump_to_store(NetCDF4DataStore(self._nc), unlimited_dims=["time"], encoding=_encoding(layout))
            with self._lock:
                self._nc.set_auto_maskandscale(False)
                for name in self.columns:  # a small cache: the chunks are written once, in order
                    self._nc[name].set_var_chunk_cache(size=4 * CHUNK * 8, nelems=17, preemption=1.0)
        except BaseException:
            self.discard()
            raise

    def convert(self, upto: int, stop=lambda: False) -> int:
        """Write journal rows ``done:upto``, `READ_ROWS` at a time (``stop()`` true: return early);
        returns the rows written in all."""
        while self.done < upto and not stop():
            b = min(upto, self.done + READ_ROWS)
            rows = _read_rows(self.folder, len(self.columns), self.done, b)
            if not rows.shape[0]:  # the journal is shorter than said (never, short of a truncation)
                break
            b = self.done + rows.shape[0]
            with self._lock:
                for j, name in enumerate(self.columns):
                    values = _column(name, np.ascontiguousarray(rows[:, j]))
                    self._nc[name][self.done:b] = values
                    if j and values.dtype.kind == "f":
                        self.ranges[name] = actual_range(values, self.ranges.get(name))
                    elif name == "paused":
                        self.edges.add(values, rows[:, 0])
                self.overview.add({name: rows[:, j] for j, name in enumerate(self.columns)  # views, no copies
                                   if name == "time" or name in VARIABLES or EXTRA_VARIABLES[name][2] == "f8"})
            self.done = b
        return self.done

    def close(self, final: dict, out: Path) -> None:
        """Set the dataset's attributes (the header's, ``samples``, then ``final``) and each float
        variable's ``actual_range``, and the pause table of a run that can pause (the notes of the journal's
        ``pauses.jsonl``); fsync and rename the file to ``out``."""
        attrs = {**self.attrs, "samples": int(self.done), **final}
        values = None
        if self.edges is not None:
            intervals = self.edges.intervals(self.attrs.get("sample_rate"))
            values = _pauses.table(intervals, _pauses.read_notes(self.folder))
            attrs["pauses"] = len(intervals)
        attrs = netcdf_attrs(attrs)
        with self._lock:
            if values is not None:
                _pauses.write_table(self._nc, values)
            for name, span in self.ranges.items():
                if span is not None:
                    self._nc[name].setncattr("actual_range", span)
            for key, value in attrs.items():
                self._nc.setncattr(key, value)
            if self.done > OVERVIEW_ABOVE:
                self.overview.write(self._nc)
            nc, self._nc = self._nc, None
            if os.getpid() == self._pid:  # no lock left on the file for what reads it next (its row, open_run)
                close_unlocked(nc, self._made)
            else:  # a copy of the converter in a forked child: its copy of the descriptor closed, no more
                nc.close()
        publish(self.tmp, out, self._made)  # fsync'd, and renamed only if it is still the file made here
        _fsync_dir(Path(out).parent)

    def discard(self, keep: bool = False) -> None:
        """Close and remove the file it made (never a half-written one left behind; ``keep``: close only)."""
        if self._nc is not None:
            try:
                with self._lock:
                    self._nc.close()
            except Exception:  # noqa: BLE001 - a broken file (full disk) is removed all the same
                pass
            self._nc = None
        if not keep:
            remove_own(self.tmp, self._made)


def write_dataset(ds: xr.Dataset, out: Path) -> None:
    """Write ``ds`` to ``out`` atomically (temporary file, fsync, rename), compressed as a run's journal is
    (`COMPRESSION`, chunks of `CHUNK`), each float data variable with its ``actual_range``, and a long run's
    overview (`~rdea_lab.store.overview`).

    The temporary file is made afresh (one left by a write that died is discarded), opened once, written
    through xarray and the overview added into the same open file, and closed with no lock of HDF5's left on
    it (`_hdf5.close_unlocked`): a file closed and opened again can be refused by HDF5's lock, held through a
    descriptor a process forked meanwhile copied (see `_Converter`), and so can what reads the dataset next.
    """
    from xarray.backends import NetCDF4DataStore
    from xarray.backends.common import ArrayWriter
    from xarray.backends.locks import HDF5_LOCK

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    ds.attrs = netcdf_attrs(ds.attrs)
    tmp = _tmp_of(out)
    if ("time" in ds.coords and np.issubdtype(ds["time"].dtype, np.number)
            and " since " not in str(ds["time"].attrs.get("units", ""))):
        ds["time"].attrs.update(time_attrs(str(ds.attrs.get("created") or utc_now())))  # float seconds, CF-1.8
    for name, var in ds.data_vars.items():
        if var.dtype.kind == "f" and var.dims == ("time",):
            span = actual_range(np.asarray(var.values))
            if span is not None:
                var.attrs["actual_range"] = span
    nc = ident = None
    try:
        # a dead write's half file removed (this one's is a new file, carrying no old lock)
        nc, ident = create(tmp, HDF5_LOCK)
        # as to_netcdf writes it, into the open file (xarray takes the HDF5 lock itself; dask data at sync)
        writer = ArrayWriter()
        ds.dump_to_store(NetCDF4DataStore(nc), writer=writer, unlimited_dims=["time"], encoding=_encoding(ds))
        writer.sync()
        with HDF5_LOCK:
            if ds.sizes.get("time", 0) > OVERVIEW_ABOVE:  # a long run: its figure drawn from the overview
                add_overview(nc)
            whole, nc = nc, None  # (closed here, not again below)
            close_unlocked(whole, ident)
        publish(tmp, out, ident)  # fsync'd, and renamed only if it is still the file made here
    except BaseException:
        if nc is not None:
            try:
                with HDF5_LOCK:
                    close_unlocked(nc, ident)
            except Exception:  # noqa: BLE001 - a broken file (full disk) is removed all the same
                pass
        remove_own(tmp, ident)  # never a half-written file left behind (nor another writer's removed)
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
            try:
                claim, removed = _try_lock(folder, create=False), False
            except FileNotFoundError:  # removed meanwhile
                claim, removed = None, True
            if claim is None and not removed:
                raise RunInProgress(f"{folder}: a run is starting on it; left alone")
            if claim is not None:
                try:  # a claim whose run never began (killed before it started): removed holding its lock
                    _remove_journal(folder, claim, ignore_errors=True)
                finally:
                    _let_go(claim)
                raise EmptyJournal(f"{folder}: the claim of a run that never started (no samples); removed")
        raise FileNotFoundError(f"{path}: no run journal here (expected {folder}/header.json)")
    gone = FileNotFoundError(f"{path}: no run journal here (its run closed it meanwhile)")
    try:
        lock = _try_lock(folder, create=not (folder / LOCK).exists())
    except FileNotFoundError:
        raise gone from None
    if lock is None:
        w = journal_writer(folder) or {}
        raise RunInProgress(f"{folder}: a run is still writing it (pid {w.get('pid', '?')} on "
                            f"{w.get('host', '?')} since {w.get('started', '?')}); left alone")
    if not (folder / "header.json").is_file():  # the run closed it between the look and the lock
        _let_go(lock)
        raise gone
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
        _let_go(lock)
        raise
    try:
        out = Path(out)
        if out.exists():
            raise FileExistsError(f"{out} exists already; move it away to recover {folder}")
        converter = None
        try:
            converter = _Converter(folder, _tmp_of(out))  # streamed: a day-long journal in bounded memory
            n = converter.convert(_journal_rows(folder, len(converter.columns)))
            status, reason = "interrupted", (f"the process stopped without closing the run; {n} samples "
                                             "recovered from the journal by rdea-lab recover")
            try:
                noted = json.loads((folder / "status.json").read_text())
                status = noted["status"]
                reason = f"{noted['status_reason']}; {n} samples recovered from the journal by rdea-lab recover"
            except (OSError, ValueError, KeyError, TypeError):
                pass
            converter.close(final_attrs(converter.attrs, status, reason, "rdea-lab recover"), out)
        except BaseException as exc:
            if converter is not None:
                converter.discard()
            if isinstance(exc, (OSError, RuntimeError)):
                n = _journal_rows(folder, len(_read_header(folder)["columns"]))
                if _is_full(exc, out, n * 8 * len(_read_header(folder)["columns"])):
                    raise _disk_full(exc, out, folder, n) from None
            raise
        _remove_journal(folder, lock)
    finally:
        _let_go(lock)
    from .index import index_quietly

    index_quietly(out)  # the catalogue row; a catalogue that cannot be written says so and changes nothing else
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
