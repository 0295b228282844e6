"""A live plot of a run: a subscriber of the run engine.

The engine calls a subscriber with each block of samples (a ``RunBlock``:
``block["time"]``, ``block["force"]``, ..., ``block.samples``,
``block.planned``, ``block.status``), and, when it has them, calls its
``start(attrs)`` once before the first block and ``stop(result)`` once at the
end. :class:`LivePlot` keeps the samples it has seen and redraws force,
stretch and voltage against time at most once per ``interval``, and always at
``stop``: into a PNG file rewritten atomically (headless, e.g. a rig PC
watched over a file share), or into a pyplot window.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from ..store.outputs import check_writable

#: The channels kept and drawn: name, scale to the plotted unit, axis label.
CHANNELS = (("force", 1.0, "force [N]"), ("stretch", 1.0, "stretch λ1 [-]"), ("voltage", 1e-3, "voltage [kV]"))


class LivePlot:
    """Redraw force, stretch and voltage against time while a run goes on.

    Parameters
    ----------
    path : str or path-like, optional
        A ``.png`` file, rewritten atomically (a temporary file in the same
        folder, then :func:`os.replace`) at each redraw, so a viewer never
        reads half a file. No pyplot is used. Without it, an interactive
        pyplot window (needs a GUI backend).
    interval : float
        Least time between two redraws [s]; the last one, at ``stop``, always
        happens.
    clock : callable
        Returns the current time [s] (default :func:`time.monotonic`;
        injectable for tests).
    window_seconds : float, optional
        Draw only the last ``window_seconds`` of run time [s]; default: every
        sample kept.

    Raises
    ------
    ValueError
        A ``path`` that is no ``.png`` file, a negative ``interval``, a ``window_seconds`` that is not
        above 0 s.
    OutputError
        ``path`` cannot be written (checked before the run, not at its first redraw).

    Notes
    -----
    At most :attr:`max_samples` of the latest samples are drawn; older ones
    are dropped (memory holds at most twice that; the run's dataset keeps
    every sample). :attr:`draws` counts the redraws.
    """

    #: Most samples kept in memory (per channel).
    max_samples = 200_000
    #: Size of the figure [in] and resolution of the PNG [dpi].
    figsize = (9.0, 6.5)
    dpi = 100

    def __init__(self, path=None, *, interval=1.0, clock=time.monotonic, window_seconds=None):
        if path is not None and Path(path).suffix.lower() != ".png":
            raise ValueError(f"live plot path {os.fspath(path)!r} is not a .png file")
        if not (math.isfinite(interval) and interval >= 0):
            raise ValueError(f"live plot interval {interval!r} s must be >= 0 s")
        if window_seconds is not None and not (math.isfinite(window_seconds) and window_seconds > 0):
            raise ValueError(f"live plot window_seconds {window_seconds!r} s must be > 0 s")
        self.path = None if path is None else Path(path)
        if self.path is not None:
            check_writable(self.path, "live")  # before the run, not at its first redraw
        self.interval = float(interval)
        self.clock = clock
        self.window_seconds = window_seconds
        self.attrs: dict = {}
        self.draws = 0
        self.fig = None
        self._reset()

    def _reset(self):
        self._chunks = {name: [] for name in ("time", *(c[0] for c in CHANNELS))}
        self._kept = 0
        self._last_draw = None
        self._status, self._samples, self._planned = "waiting", 0, None

    # -- the subscriber interface -------------------------------------------------
    def start(self, attrs: dict) -> None:
        """A new run: forget earlier samples, keep its attributes for the title.

        Parameters
        ----------
        attrs : dict
            The dataset attributes known before the run starts (``protocol_name``, ``specimen_id``,
            ``backend``, ...).
        """
        self._reset()
        self.attrs = dict(attrs)

    def __call__(self, block) -> None:
        """Keep a block's samples; redraw if ``interval`` has passed since the last redraw."""
        for name, chunks in self._chunks.items():
            chunks.append(np.array(block[name], dtype=float))  # a copy: the engine may reuse its buffers
        self._kept += len(self._chunks["time"][-1])
        if self._kept > 2 * self.max_samples:
            self._consolidate()
        self._status, self._samples, self._planned = block.status, block.samples, block.planned
        now = self.clock()
        if self._last_draw is None or now - self._last_draw >= self.interval:
            self.draw()
            self._last_draw = now

    def stop(self, result) -> None:
        """The last redraw, with the run's final status.

        Parameters
        ----------
        result : RunResult
            The run's result: its ``status`` (and ``reason``) and ``samples`` go into the title.
        """
        self._status = result.status + (f" ({result.reason})" if getattr(result, "reason", "") else "")
        self._samples = result.samples
        self.draw()

    # -- drawing ------------------------------------------------------------------
    def _consolidate(self) -> dict[str, np.ndarray]:
        """Join the kept blocks into one array per channel, the latest ``max_samples`` only."""
        data = {}
        for name, chunks in self._chunks.items():
            joined = np.concatenate(chunks) if chunks else np.empty(0)
            data[name] = joined[-self.max_samples:]
            self._chunks[name] = [data[name]]
        self._kept = data["time"].size
        return data

    def data(self) -> dict[str, np.ndarray]:
        """The samples that would be drawn now: ``time`` [s] and each channel (SI units).

        Returns
        -------
        dict of str to numpy.ndarray
            ``time`` [s], ``force`` [N], ``stretch`` [-], ``voltage`` [V]: the latest `max_samples`,
            within the last ``window_seconds`` if given.
        """
        data = self._consolidate()
        if self.window_seconds is not None and data["time"].size:
            first = np.searchsorted(data["time"], data["time"][-1] - self.window_seconds)
            data = {name: values[first:] for name, values in data.items()}
        return data

    def title(self) -> str:
        """The figure's title: protocol, specimen, backend, status and samples so far.

        Returns
        -------
        str
            E.g. ``blocking_force on specimen-2 (twin): running, 1200 / 2501 samples``.
        """
        a = self.attrs
        planned = f" / {self._planned}" if self._planned is not None else ""
        return (f"{a.get('protocol_name', '?')} on {a.get('specimen_id', '?')} ({a.get('backend', '?')}): "
                f"{self._status}, {self._samples}{planned} samples")

    def _build(self, fig):
        axes = fig.subplots(len(CHANNELS), 1, sharex=True)
        self._lines = []
        for ax, (_, _, label) in zip(axes, CHANNELS):
            (line,) = ax.plot([], [], lw=0.8)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            self._lines.append(line)
        axes[-1].set_xlabel("time [s]")
        # a fixed layout: tight_layout would cost one more draw each time
        fig.subplots_adjust(left=0.09, right=0.98, bottom=0.08, top=0.93, hspace=0.12)
        self._axes = axes
        self._title = fig.suptitle("")
        return fig

    def draw(self) -> None:
        """Redraw now: the PNG (atomically) or the window."""
        if self.fig is None:
            if self.path is not None:
                from matplotlib.figure import Figure

                self.fig = self._build(Figure(figsize=self.figsize))
            else:
                import matplotlib.pyplot as plt

                plt.ion()
                self.fig = self._build(plt.figure(figsize=self.figsize))
        data = self.data()
        for line, ax, (name, scale, _) in zip(self._lines, self._axes, CHANNELS):
            line.set_data(data["time"], data[name] * scale)
            ax.relim()
            ax.autoscale_view()
        self._title.set_text(self.title())
        if self.path is not None:
            self._write_png()
        else:
            import matplotlib.pyplot as plt

            self.fig.canvas.draw_idle()
            plt.pause(0.001)
        self.draws += 1

    def _write_png(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                self.fig.savefig(fh, format="png", dpi=self.dpi)
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private; the PNG is for anyone who may read the folder
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
