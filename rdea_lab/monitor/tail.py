"""Following runs in progress by their journals: the new whole rows of each, and which journals come and go.

A run of any backend, started from the CLI or from Python, writes ``<out>.part/`` (`rdea_lab.store.journal`):
``header.json`` (``columns``, ``attrs``) and ``samples.f8``, rows of little-endian float64 appended a block at a
time. `JournalTail` reads the rows appended since its last read, whole rows only (a row being written, torn
at the end of the file, waits for the next read); `Follower` finds the journals below a folder, new ones as
they appear, and says which have vanished (the run ended: its dataset was written and the journal removed).
Nothing here writes anything: a follower is invisible to the run.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..store.journal import walk_runs

#: Rows read at most per `JournalTail.read` (a follower that fell behind skips to the newest rows): half a
#: second of the twin (about 1e6 samples/s), 32 MB of 8 columns.
MAX_READ = 500_000


class JournalTail:
    """The rows of one journal, read as they are appended.

    Parameters
    ----------
    folder : path
        The journal (``<out>.nc.part``).
    start_rows : int or None
        On the first read of a journal that already holds more rows than this, skip to its newest
        ``start_rows`` rows (a long run joined late); None: from the first row.
    """

    def __init__(self, folder, start_rows: int | None = None):
        self.folder = Path(folder)
        self.header: dict | None = None
        self.columns: list[str] = []
        self.rows = 0  # whole rows consumed (read or skipped)
        self.skipped = 0  # rows passed over unread (joined late, or fell behind)
        self._start_rows = start_rows

    @property
    def gone(self) -> bool:
        """The journal folder no longer exists (the run ended and its dataset was written, or it was removed)."""
        return not self.folder.is_dir()

    def read_header(self) -> dict | None:
        """The journal's header once it is written and whole (None before)."""
        if self.header is None:
            try:
                header = json.loads((self.folder / "header.json").read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return None
            columns = header.get("columns") if isinstance(header, dict) else None
            if not isinstance(columns, list) or not columns or columns[0] != "time" \
                    or not isinstance(header.get("attrs"), dict):
                return None
            self.header, self.columns = header, [str(c) for c in columns]
        return self.header

    def available(self) -> int:
        """Whole rows in the journal now (a torn last row is not counted)."""
        if self.read_header() is None:
            return 0
        try:
            return os.stat(self.folder / "samples.f8").st_size // (8 * len(self.columns))
        except OSError:
            return 0

    def read(self, max_rows: int = MAX_READ) -> np.ndarray:
        """The whole rows appended since the last read, shape (n, columns) (n may be 0).

        At most ``max_rows`` rows: when more are waiting, the older ones are skipped (counted in
        `skipped`), so that a follower that fell behind shows the newest rows.
        """
        n = self.available()
        if not self.columns:
            return np.empty((0, 0))
        width = len(self.columns)
        if self.rows == 0 and self._start_rows is not None and n > self._start_rows:
            self.skipped += n - self._start_rows
            self.rows = n - self._start_rows
        if n - self.rows > max_rows:
            self.skipped += n - max_rows - self.rows
            self.rows = n - max_rows
        if n <= self.rows:
            return np.empty((0, width))
        try:
            raw = np.fromfile(self.folder / "samples.f8", dtype="<f8", count=(n - self.rows) * width,
                              offset=self.rows * width * 8)
        except (OSError, ValueError):  # removed between the stat and the read: the run just ended
            return np.empty((0, width))
        got = raw.size // width
        self.rows += got
        return raw[: got * width].reshape(got, width)


class Follower:
    """The journals below a folder: `poll` says which appeared and which vanished since the last poll.

    A journal is known by its path and its folder's inode, so that a run that ends and a new run on the same
    output between two polls are seen as one journal gone and one new.

    Parameters
    ----------
    folder : path
        Searched recursively (a journal's inside is not entered).
    """

    def __init__(self, folder):
        self.folder = Path(folder)
        self.known: dict[Path, int] = {}

    def poll(self) -> tuple[list[Path], list[Path]]:
        """``(new, gone)``: the journals that appeared and those that vanished since the last call, by path
        (a journal replaced by another at the same path is in both)."""
        _, journals = walk_runs(self.folder)
        now = {}
        for j in journals:
            try:
                now[Path(j)] = os.stat(j).st_ino
            except OSError:  # gone between the walk and the stat
                pass
        new = sorted(p for p, ino in now.items() if self.known.get(p) != ino)
        gone = sorted(p for p, ino in self.known.items() if now.get(p) != ino)
        self.known = now
        return new, gone


def dataset_of(journal) -> Path:
    """The dataset a journal becomes (``out.nc`` of ``out.nc.part``)."""
    journal = Path(journal)
    return journal.with_name(journal.name[: -len(".part")]) if journal.name.endswith(".part") else journal


__all__ = ["Follower", "JournalTail", "MAX_READ", "dataset_of"]
