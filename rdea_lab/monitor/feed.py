"""One followed run as a feed of display points: its journal's new rows, decimated, with the twin's prediction.

`RunFeed.update` reads the rows the run appended (`rdea_lab.monitor.tail.JournalTail`), keeps at most
`COLUMNS_PER_UPDATE` columns of them (a min/max envelope per column, drawn as a vertical stroke: a one-sample
spike stays visible; `rdea_lab.store.overview.envelope`), steps the twin on them when a parameter set is given
(`rdea_lab.twin.simulate.TwinStream`, predicted ``force_pred`` beside the measured ``force``), and keeps the
newest `KEEP` points. Every viewer asks `RunFeed.since` for the points after the last it has, so one read of
the journal and one twin step serve every viewer.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from ..store.overview import envelope
from .tail import JournalTail, dataset_of

#: The channels shown, in order, when the journal has them (``paused`` is 0/1 where the engine records it).
CHANNELS = ("force", "stretch", "voltage", "capacitance", "current", "paused")
#: Envelope columns per update at most (each two points): a run up to 2 kHz is shown sample by sample (read
#: every 100 ms); one of 1e6 samples/s gives 1e5 rows a read, shown as 100 columns of 1000 samples.
COLUMNS_PER_UPDATE = 100
#: Points a feed keeps (older ones fall off; the viewers' sources roll over at the same length): the live
#: window is 10 s at 1 kHz, 5 s for a faster run. The browser's work at each update grows with it: with 30000
#: points a headless chromium on a loaded 2-core machine fell behind (benchmarks/monitor_latency.py).
KEEP = 10_000
#: Rows of a journal joined late that are read at the start (the newest ones).
START_ROWS = 500_000


def decimate(rows: np.ndarray, columns: list[str], max_columns: int = COLUMNS_PER_UPDATE) -> tuple[dict, np.ndarray]:
    """Display points of journal rows: all of them when they are few, else a min/max stroke per column.

    Parameters
    ----------
    rows : numpy.ndarray, shape (n, len(columns))
        Journal rows (``time`` [s] first).
    columns : list of str
        The journal's column names.
    max_columns : int
        Rows above ``2 * max_columns`` are cut into at most ``max_columns`` columns of consecutive rows.

    Returns
    -------
    points : dict of str to numpy.ndarray
        ``time`` and each channel of `CHANNELS` present; decimated, each column gives two points at its first
        time, its smallest and its largest value.
    picked : numpy.ndarray
        The row indices the twin is stepped on (every row, or each column's first), increasing.
    """
    n = rows.shape[0]
    index = {name: j for j, name in enumerate(columns)}
    names = [c for c in CHANNELS if c in index]
    if n <= 2 * max_columns:
        return {"time": rows[:, 0].copy(), **{c: rows[:, index[c]].copy() for c in names}}, np.arange(n)
    per = math.ceil(n / max_columns)
    first = np.arange(0, n, per)
    points = {"time": np.repeat(rows[first, 0], 2)}
    for c in names:
        lo, hi = envelope(rows[:, index[c]], per)
        points[c] = np.column_stack([lo, hi]).ravel()
    return points, first


class Prediction:
    """The twin stepped along a followed run: built from the journal header's ``specimen`` card.

    Parameters
    ----------
    attrs : dict
        The journal header's ``attrs`` (``specimen``: the card as YAML; ``protocol``: for ``model="auto"``).
    params : ParameterSet
    model : {"su", "1r", "3r", "cr", "auto"}
        ``auto``: the cheapest model within 1 % of CR over the run's planned (stretch, voltage) envelope
        (`rdea_lab.physics.selection.select_model`), else over the first rows received.
    """

    def __init__(self, attrs: dict, params, model: str = "su"):
        from ..physics.geometry import geometry_from_card
        from ..specs import specimen_from_yaml

        card = specimen_from_yaml(str(attrs["specimen"]), "the journal's header (attribute 'specimen')")
        self.geom, self.params, self.requested = geometry_from_card(card), params, model
        self.model = None if model == "auto" else model
        self.reason = ""
        self._protocol = attrs.get("protocol")
        self._stream = None
        self._t_end = -math.inf

    def _choose(self, stretch, voltage) -> None:
        from ..physics.selection import select_model

        if self._protocol:
            try:
                from ..protocols import expand
                from ..specs import protocol_from_yaml

                plan = expand(protocol_from_yaml(str(self._protocol), "the journal's header (attribute 'protocol')"))
                stretch, voltage = plan.envelope() if hasattr(plan, "envelope") else (plan.stretch, plan.voltage)
            except Exception:  # noqa: BLE001 - the rows received then stand in for the plan
                pass
        choice = select_model(self.geom, self.params, stretch, voltage)
        self.model, self.reason = choice.model, choice.reason

    def step(self, t, stretch, voltage) -> np.ndarray:
        """Predicted force [N] at the times ``t`` [s] (increasing, after the previous call's)."""
        t, stretch, voltage = (np.asarray(a, float) for a in (t, stretch, voltage))
        keep = t > self._t_end
        keep[1:] &= np.diff(t) > 0  # a repeated time (never in a journal, but cheap to refuse) is skipped
        force = np.full(t.shape, np.nan)
        if not keep.any():
            return force
        if self._stream is None:
            from ..twin.simulate import TwinStream

            if self.model is None:
                self._choose(stretch[keep], voltage[keep])
            self._stream = TwinStream(self.geom, self.params, self.model)
        force[keep] = self._stream.step(t[keep], stretch[keep], voltage[keep], summary=False)["force"]
        self._t_end = float(t[keep][-1])
        return force


class RunFeed:
    """One run in progress, followed: its display points and its state.

    Parameters
    ----------
    journal : path
        The run's journal folder.
    params : ParameterSet, optional
        With it, the twin's predicted force (``force_pred``) beside the measured.
    model : str
        The twin's model (`Prediction`).
    keep : int
        Points kept.
    """

    def __init__(self, journal, params=None, model: str = "su", keep: int = KEEP, start_rows: int = START_ROWS):
        self.journal = journal
        self.dataset = dataset_of(journal)
        self.tail = JournalTail(journal, start_rows=start_rows)
        self.params, self.model_choice, self.keep = params, model, keep
        self.prediction: Prediction | None = None
        self.prediction_error = ""
        self.finished = False
        self.measured: set[str] = set()  # channels with a finite value so far
        self.samples = 0  # rows consumed
        self.seq = 0  # points produced so far (the last one's number)
        self._chunks: list[tuple[int, dict]] = []  # (seq of the first point, points), oldest first
        self._lock = threading.Lock()

    @property
    def header(self) -> dict | None:
        return self.tail.read_header()

    @property
    def channels(self) -> list[str]:
        """The channels of `CHANNELS` this run records (empty until its header is written)."""
        return [c for c in CHANNELS if c in self.tail.columns]

    @property
    def keys(self) -> list[str]:
        """The point columns: ``time``, the channels, ``force_pred`` with a parameter set."""
        return ["time", *self.channels, *(["force_pred"] if self.params is not None else [])]

    def update(self) -> int:
        """Read what the run appended; returns the points added (0 when nothing new or the run ended)."""
        if self.finished:
            return 0
        if self.tail.gone:
            self.finished = True
            return 0
        rows = self.tail.read()
        if not rows.size:
            return 0
        columns = self.tail.columns
        points, picked = decimate(rows, columns)
        self.measured |= {c for c in self.channels if c not in self.measured and np.isfinite(points[c]).any()}
        if self.params is not None:
            points["force_pred"] = self._predict(rows, columns, picked, points["time"].size)
        with self._lock:
            self._chunks.append((self.seq + 1, points))
            self.seq += points["time"].size
            self.samples = self.tail.rows
            while len(self._chunks) > 1 and self.seq - self._chunks[1][0] + 1 >= self.keep:
                self._chunks.pop(0)
        return points["time"].size

    def _predict(self, rows, columns, picked, npoints) -> np.ndarray:
        index = {c: j for j, c in enumerate(columns)}
        if self.prediction is None and not self.prediction_error:
            try:
                self.prediction = Prediction(self.tail.header["attrs"], self.params, self.model_choice)
            except Exception as exc:  # noqa: BLE001 - said on the page; the measurement is shown regardless
                self.prediction_error = f"no prediction: {type(exc).__name__}: {exc}"
        if self.prediction is None or "stretch" not in index:
            return np.full(npoints, np.nan)
        r = rows[picked]
        voltage = r[:, index["voltage"]] if "voltage" in index else np.zeros(len(picked))
        try:
            force = self.prediction.step(r[:, 0], r[:, index["stretch"]], voltage)
        except Exception as exc:  # noqa: BLE001
            self.prediction_error = f"prediction stopped: {type(exc).__name__}: {exc}"
            self.prediction = None
            return np.full(npoints, np.nan)
        return force if len(picked) == npoints else np.repeat(force, 2)[:npoints]

    def since(self, seq: int, limit: int | None = None) -> tuple[int, dict | None, bool]:
        """The points after number ``seq``: ``(newest number, points or None, reset)``.

        ``reset`` is true when points after ``seq`` have already fallen off (a new viewer, or one far behind):
        the points are then all those kept, and replace the viewer's. With ``limit``, more points than that
        are thinned to about ``limit`` by a stride (a catch-up, never a live tick of `COLUMNS_PER_UPDATE`).
        """
        with self._lock:
            chunks, newest = list(self._chunks), self.seq
        if newest <= seq or not chunks:
            return newest, None, False
        reset = seq < chunks[0][0] - 1
        parts = []
        for first, points in chunks:
            last = first + points["time"].size - 1
            if last <= seq:
                continue
            skip = max(0, seq + 1 - first)
            parts.append({k: v[skip:] for k, v in points.items()})
        out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        n = out["time"].size
        if limit is not None and n > limit:
            stride = math.ceil(n / limit)
            out = {k: v[::stride] for k, v in out.items()}
        return newest, out, reset


__all__ = ["CHANNELS", "COLUMNS_PER_UPDATE", "KEEP", "Prediction", "RunFeed", "decimate"]
