"""Subscribers of the run engine: it calls them with each block of samples.

As Bluesky's RunEngine does with its callbacks, the engine knows nothing about
what a subscriber does: a live table, a live plot, a progress bar or a user's
own function are all the same to it. A subscriber is a callable
``cb(block: RunBlock)``; it may also have ``start(attrs)`` (called once,
before the backend starts, with the dataset attributes known then; one that
raises stops the run before anything moves) and ``stop(result)`` (called once
at the end, with the `RunResult`, whatever the status).

A subscriber that raises aborts the run (voltage off, every sample kept,
status ``aborted`` with the error as the reason) and the error is raised
again once the dataset is written.
"""

from __future__ import annotations

import sys
import time as _time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RunBlock:
    """One block of samples as the engine received it.

    Attributes
    ----------
    data : Mapping[str, numpy.ndarray]
        ``time`` [s], ``stretch``, ``position`` [m], ``voltage`` [V], ``force``
        [N], ``capacitance`` [F], ``stretch_setpoint``, ``voltage_setpoint``
        (and the backend's extra variables), of equal length.
    first : int
        Index in the run of the block's first sample.
    samples : int
        Samples received so far, this block included.
    planned : int
        Samples in the plan.
    status : str
        ``running``.
    """

    data: Mapping
    first: int
    samples: int
    planned: int
    status: str = "running"

    def __getitem__(self, key):
        return self.data[key]

    def __len__(self):
        return len(self.data["time"])


#: How the live table marks a sample that is not running the plan (the ``paused`` flag's phases).
PHASE_WORDS = {1: "pausing", 2: "paused", 3: "resuming"}


def subscriber_name(cb) -> str:
    return getattr(cb, "__qualname__", None) or type(cb).__name__


class LiveTable:
    """A live text table: one line a second (of wall time) with the latest sample.

    Parameters
    ----------
    file : file-like, optional
        Where the lines go (default: standard output).
    interval : float
        Seconds of wall time between lines [s]; the first and the last block always print.
    columns : sequence of str
        Variables shown, with their units (time [s], stretch [-], position [mm], voltage [kV],
        force [N], capacitance [pF]).
    clock : callable
        Returns the current wall time [s] (default :func:`time.monotonic`; injectable for tests).

    Examples
    --------
    ``run_protocol(..., callbacks=[LiveTable()])`` prints the run's latest sample once a second.
    """

    UNITS = {"time": ("s", 1.0), "stretch": ("-", 1.0), "position": ("mm", 1e3), "voltage": ("kV", 1e-3),
             "force": ("N", 1.0), "capacitance": ("pF", 1e12)}

    def __init__(self, file=None, *, interval=1.0, columns=("time", "stretch", "voltage", "force", "capacitance"),
                 clock=_time.monotonic):
        self.file = file
        self.interval = float(interval)
        self.columns = tuple(columns)
        self._clock = clock
        self._last = None
        self._block = None

    def _out(self):
        return self.file if self.file is not None else sys.stdout

    def _line(self, text):
        print(text, file=self._out(), flush=True)

    def start(self, attrs):
        """A new run: print its title (protocol, specimen, backend) and the column heads.

        Parameters
        ----------
        attrs : Mapping
            The dataset attributes known before the run starts (``protocol_name``, ``specimen_id``,
            ``backend``, ...).
        """
        self._last = self._block = None  # each run of a campaign prints its first block
        head = [f"{c} [{self.UNITS.get(c, ('', 1))[0]}]" for c in self.columns]
        self._line(f"{attrs.get('protocol_name', '?')} on {attrs.get('specimen_id', '?')} "
                   f"({attrs.get('backend', '?')})")
        self._line("  ".join(f"{h:>14}" for h in ["samples", *head]))

    def _row(self, block):
        cells = [f"{block.samples:>8d}/{block.planned:<5d}"]
        for c in self.columns:
            unit, scale = self.UNITS.get(c, ("", 1.0))
            values = np.asarray(block.data.get(c, [np.nan]), float)
            value = values[-1] * scale if values.size else np.nan
            cells.append(f"{value:>14.6g}" if np.isfinite(value) else f"{'-':>14}")
        line = "  ".join(f"{cell:>14}" for cell in cells)
        phase = np.asarray(block.data.get("paused", ()))
        if phase.size and phase[-1] in PHASE_WORDS:  # a run paused (or ramping to or from a pause) says so
            line += f"  [{PHASE_WORDS[int(phase[-1])]}]"
        self._line(line)

    def __call__(self, block):
        self._block = block
        now = self._clock()
        if self._last is None or now - self._last >= self.interval:
            self._last = now
            self._row(block)
            self._block = None

    def stop(self, result):
        """The run ended: print its last block if it has not been printed.

        Parameters
        ----------
        result : RunResult
            The run's result (any status).
        """
        if self._block is not None:
            self._row(self._block)
        self._line(f"{result.status}" + (f": {result.reason}" if result.reason else "")
                   + f", {result.samples} samples -> {result.path}")
