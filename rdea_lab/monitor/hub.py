"""What every viewer of one monitor shares: the followed runs, their states, the catalogue of finished runs.

One `Hub` per monitor. Each viewer's periodic callback calls `Hub.update`, which does the work at most once per
`TICK` whoever calls: the journals below the folder looked for every `SCAN_EVERY`, each followed run's new
rows read (`RunFeed.update`), each run's published state read (`rdea_lab.runs.control.read_state`); the
catalogue (`rdea_lab.store.catalog`, about a second on a large folder) is refreshed on a worker thread every
`CATALOG_EVERY`. The viewers then take what is new from the hub: a page costs a few array slices, not a read.
"""

from __future__ import annotations

import math
import threading
import time as _time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..runs.control import read_state
from .feed import CHANNELS, RunFeed
from .tail import Follower

#: Seconds between two reads of the journals (the viewers' callbacks run at this period too).
TICK = 0.1
#: Seconds between two looks for new journals.
SCAN_EVERY = 1.0
#: Seconds between two reads of each run's published state.
STATE_EVERY = 0.5
#: Seconds between two refreshes of the catalogue of finished runs.
CATALOG_EVERY = 5.0
#: Points per channel of a finished run's figure at most (a min/max envelope of 2500 columns).
FINISHED_POINTS = 5000
#: Runs that ended kept in the list of followed runs (shown as finished) before the oldest is dropped.
ENDED_KEPT = 20
#: The catalogue's columns shown.
CATALOG_COLUMNS = ("file", "specimen", "protocol", "backend", "model", "status", "duration_s", "samples", "created")


class Hub:
    """The runs below ``folder`` for every viewer of a monitor.

    Parameters
    ----------
    folder : path
    params : ParameterSet, optional
        The twin's predicted force beside every followed run's measured force.
    model : str
        The twin's model (``su``, ``1r``, ``3r``, ``cr`` or ``auto``).
    clock : callable
        Monotonic seconds (tests).
    """

    def __init__(self, folder, params=None, model: str = "su", clock=_time.monotonic):
        self.folder = Path(folder)
        self.params, self.model = params, model
        self.clock = clock
        self.follower = Follower(self.folder)
        self.feeds: dict[str, RunFeed] = {}  # by journal path, in the order found
        self.states: dict[str, dict] = {}
        self.runs_version = 0  # changes when a run appears or ends
        self.catalog_rows: dict | None = None
        self.catalog_version = 0
        self.catalog_error = ""
        self._lock = threading.Lock()
        self._last = {"update": -math.inf, "scan": -math.inf, "state": -math.inf, "catalog": -math.inf}
        self._catalog_running = False
        self.pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="rdea-lab-monitor")

    # -------------------------------------------------------------- runs in progress
    def update(self, force: bool = False) -> None:
        """Read what is new, at most once per `TICK` (``force``: now)."""
        with self._lock:
            now = self.clock()
            if not force and now - self._last["update"] < TICK * 0.8:
                return
            self._last["update"] = now
            if force or now - self._last["scan"] >= SCAN_EVERY:
                self._last["scan"] = now
                self._scan()
            for feed in self.feeds.values():
                was = feed.finished
                feed.update()
                if feed.finished and not was:
                    self.runs_version += 1
            if force or now - self._last["state"] >= STATE_EVERY:
                self._last["state"] = now
                for key, feed in self.feeds.items():
                    if not feed.finished:
                        self.states[key] = read_state(feed.journal) or {}
        if now - self._last["catalog"] >= CATALOG_EVERY and not self._catalog_running:
            self._last["catalog"] = now
            self.refresh_catalog()

    def _scan(self) -> None:
        new, gone = self.follower.poll()
        for journal in gone:  # first: a journal replaced by a new run's at the same path is in both
            feed = self.feeds.get(str(journal))
            if feed is not None and not feed.finished:
                feed.update()  # the last rows, if the folder is still readable
                feed.finished = True
        for journal in new:
            key = str(journal)
            self.feeds.pop(key, None)  # a finished run on the same output gives way (and goes to the end)
            self.feeds[key] = RunFeed(journal, self.params, self.model)
        ended = [k for k, f in self.feeds.items() if f.finished]
        for key in ended[:max(0, len(ended) - ENDED_KEPT)]:
            del self.feeds[key]
        if new or gone:
            self.runs_version += 1

    def runs(self) -> list[tuple[str, str]]:
        """``(journal, label)`` of every followed run, newest first; an ended run is labelled finished."""
        out = []
        for key, feed in reversed(list(self.feeds.items())):
            try:
                name = str(Path(key).relative_to(self.folder))
            except ValueError:
                name = key
            name = name[:-len(".part")] if name.endswith(".part") else name
            out.append((key, f"{name} (finished)" if feed.finished else name))
        return out

    # -------------------------------------------------------------- finished runs
    def refresh_catalog(self) -> None:
        """Refresh the catalogue of finished runs on a worker thread (`catalog_rows`, `catalog_version`)."""
        self._catalog_running = True
        self.pool.submit(self._refresh_catalog)

    def _refresh_catalog(self) -> None:
        from ..store import catalog

        try:
            table = catalog(self.folder)
            if "file_state" in table.columns:
                table = table[table["file_state"] != "journal"]  # runs in progress are followed above
            rows = {c: [str(v) if c != "duration_s" and c != "samples" else v for v in table[c]]
                    for c in CATALOG_COLUMNS if c in table.columns}
            if rows != self.catalog_rows:
                self.catalog_rows = rows
                self.catalog_version += 1
            self.catalog_error = ""
        except Exception as exc:  # noqa: BLE001 - said on the page, tried again at the next refresh
            self.catalog_error = f"catalogue: {type(exc).__name__}: {exc}"
            self.catalog_version += 1
        finally:
            self._catalog_running = False

    def finished_run(self, path) -> dict:
        """A finished run's channels for display: ``{"time": ..., channel: ..., "title": str}``, each channel
        at most `FINISHED_POINTS` points (a min/max envelope, drawn as strokes, when the run is longer)."""
        from ..reports.decimate import stroke
        from ..reports.long_plots import series_envelopes
        from ..store import open_run

        ds = open_run(Path(path))
        try:
            names = [c for c in CHANNELS if c in ds.data_vars and ds[c].dims == ("time",)]
            n = int(ds.sizes.get("time", 0))
            if n <= FINISHED_POINTS:
                out = {"time": np.asarray(ds["time"].values, float),
                       **{c: np.asarray(ds[c].values, float) for c in names}}
            else:
                _, t, env, _ = series_envelopes(ds, names, {}, n, FINISHED_POINTS // 2)
                out = {"time": stroke(t, t, t)[0]}
                for c in names:
                    out[c] = stroke(t, *env[c])[1]
            a = ds.attrs
            out["title"] = (f"{Path(path).name}: {a.get('protocol_name', '?')} on {a.get('specimen_id', '?')}, "
                            f"{a.get('status', '?')}, {n} samples"
                            + (f" (shown as a min/max envelope of {FINISHED_POINTS // 2} columns)"
                               if n > FINISHED_POINTS else ""))
            return out
        finally:
            ds.close()

    def close(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)


__all__ = ["CATALOG_COLUMNS", "CATALOG_EVERY", "FINISHED_POINTS", "Hub", "SCAN_EVERY", "TICK"]
