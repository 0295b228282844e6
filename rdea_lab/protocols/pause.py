"""The setpoints of a paused run: the plan's, with pauses put in, one implementation for every backend.

A pause takes the voltage to 0 at the protocol's ramp-down rate (``pause: {ramp_rate: 1 kV/s}``), holding the
stretch where it was (or taking it, once the voltage is 0, to a safe stretch the protocol declares,
``hold_stretch``, at ``stretch_rate``), and holds there until resumed; a resume goes back the same way (the
stretch first, then the voltage, at the same rates) to the setpoints the plan had when the pause began, and
the plan goes on from the sample it would have driven next. No plan sample is skipped or driven twice: the
samples of the plan are exactly the ones flagged `RUNNING`, in order.

`PausedSetpoints` is that sequence, taken sample by sample (``take(m)``) by whoever drives the specimen: the
twin (`rdea_lab.backends.twin`) and the emulated rig (`rdea_lab.emulator`), which is the stand-in for a rig's
own controller. A pause or a resume acts from the next sample taken. While held, the samples are paced by
the wall clock (a held run measures for as long as it is held, whether the backend runs in real time or
faster), so a pause of 10 s holds 10 s of samples.

Every sample carries its phase, the run's ``paused`` flag (CF flag values `FLAG_VALUES`, meanings
`FLAG_MEANINGS`).
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from ..specs.protocol_pause import DEFAULT_RAMP_RATE, DEFAULT_STRETCH_RATE  # the pause: mapping's defaults
from ..specs.variables import PAUSE_FLAG_MEANINGS, PAUSE_FLAG_VALUES

#: The phases of a sample: the ``paused`` flag variable's values (declared with the variable table, in the specs).
FLAG_VALUES = PAUSE_FLAG_VALUES
RUNNING, RAMPING_DOWN, HELD, RAMPING_UP = FLAG_VALUES
#: CF ``flag_meanings`` of the ``paused`` flag (blank-separated, in the order of `FLAG_VALUES`).
FLAG_MEANINGS = PAUSE_FLAG_MEANINGS


@dataclass(frozen=True)
class PauseSpec:
    """How a run pauses (SI): the protocol's ``pause:`` mapping.

    Attributes
    ----------
    ramp_rate : float
        Voltage ramp to 0 and back [V/s], > 0.
    hold_stretch : float or None
        The stretch held while paused; None holds the stretch the plan had at the pause.
    stretch_rate : float
        Stretch rate to and from `hold_stretch` [1/s], > 0.
    """

    ramp_rate: float = DEFAULT_RAMP_RATE
    hold_stretch: float | None = None
    stretch_rate: float = DEFAULT_STRETCH_RATE

    def __post_init__(self):
        for name in ("ramp_rate", "stretch_rate"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} {value!r} must be a finite number > 0")
        if self.hold_stretch is not None and not (math.isfinite(self.hold_stretch) and self.hold_stretch >= 1.0):
            raise ValueError(f"hold_stretch {self.hold_stretch!r} must be a finite stretch >= 1")

    def ramp_down_time(self, voltage: float) -> float:
        """Seconds the voltage takes from ``voltage`` to 0 [s]."""
        return abs(float(voltage)) / self.ramp_rate


def pause_spec_of(plan) -> PauseSpec:
    """The `PauseSpec` of a plan: its protocol's ``pause:`` mapping, else the defaults."""
    given = getattr(getattr(plan, "spec", None), "pause", None)
    if given is None:
        return PauseSpec()
    if isinstance(given, PauseSpec):
        return given
    return PauseSpec(ramp_rate=float(given.ramp_rate), hold_stretch=given.hold_stretch,
                     stretch_rate=float(given.stretch_rate))


class Setpoints(NamedTuple):
    """Samples taken from `PausedSetpoints`: one entry per sample."""

    stretch: np.ndarray
    voltage: np.ndarray
    #: the phase of each sample (`RUNNING`, `RAMPING_DOWN`, `HELD`, `RAMPING_UP`)
    paused: np.ndarray
    #: the plan sample each `RUNNING` sample drives; for the others, the one the plan goes on with
    plan_index: np.ndarray


def ramp(start: float, end: float, rate: float, sample_rate: float) -> np.ndarray:
    """Setpoints from ``start`` to ``end`` at ``rate`` per second, one per sample, ``start`` excluded and ``end``
    included exactly (an empty array when they are equal).

    Parameters
    ----------
    start, end : float
    rate : float
        Units per second, > 0.
    sample_rate : float
        Samples per second [Hz].
    """
    step = rate / sample_rate
    distance = abs(end - start)
    if distance == 0.0:
        return np.empty(0)
    n = max(1, math.ceil(distance / step - 1e-9))
    k = np.arange(1, n + 1, dtype=float)
    out = start + np.copysign(step, end - start) * k
    out[-1] = end
    return out


class PausedSetpoints:
    """The setpoints a backend drives: the plan's, with the pauses asked for put in (see the module).

    Parameters
    ----------
    window : callable
        ``window(a, b) -> (stretch, voltage)``: the plan's setpoints of samples ``a`` to ``b``.
    samples : int
        Samples in the plan.
    sample_rate : float
        [Hz].
    spec : PauseSpec
    clock : callable
        Wall time [s] (`time.monotonic`); paces the held samples.
    """

    def __init__(self, window: Callable, samples: int, sample_rate: float, spec: PauseSpec | None = None, *,
                 clock=_time.monotonic):
        self._window = window
        self.samples = int(samples)
        self.rate = float(sample_rate)
        self.spec = spec or PauseSpec()
        self._clock = clock
        self.next = 0  # the plan sample driven next
        self.taken = 0  # samples taken in all (the run's samples)
        self.phase = RUNNING
        self._want = None  # "pause" or "resume", acted on at the next take
        self._queue: list = []  # the ramp still to drive: [(stretch, voltage, phase)] arrays
        self._current = None  # (stretch, voltage) last driven
        self._return = None  # (stretch, voltage) the plan had at the pause
        self._held_since = None  # (wall time, samples taken then) when the hold began
        self._tail = 0  # plan samples at the end of the last take
        self._before_tail = None  # (stretch, voltage) driven before them
        self.pauses = 0

    # ---------------------------------------------------------- requests
    @property
    def paused(self) -> bool:
        """True from a pause request until the ramp back up has ended."""
        return self.phase != RUNNING or self._want == "pause"

    @property
    def done(self) -> bool:
        """Every plan sample taken, and not paused."""
        return self.next >= self.samples and self.phase == RUNNING and self._want is None

    def pause(self) -> bool:
        """Pause from the next sample taken; False (nothing changes) when already pausing or held, or when
        the plan is done. A resume asked for and not yet acted on is withdrawn (True): the later request wins."""
        if self._want == "resume":
            self._want = None
            return True
        if self.phase in (RAMPING_DOWN, HELD) or self._want == "pause" or self.next >= self.samples:
            return False
        self._want = "pause"
        return True

    def resume(self) -> bool:
        """Go back to the plan from the next sample taken; False when not paused."""
        if self._want == "pause" and self.phase == RUNNING:
            self._want = None  # asked for and withdrawn before any sample: nothing happened
            return True
        if self.phase not in (RAMPING_DOWN, HELD) or self._want == "resume":
            return False
        self._want = "resume"
        return True

    # ------------------------------------------------------------- ramps
    def _down(self):
        s, v = self._current
        spec = self.spec
        volts = ramp(v, 0.0, spec.ramp_rate, self.rate)
        parts = [(np.full(volts.size, s), volts)]
        if spec.hold_stretch is not None:
            stretches = ramp(s, spec.hold_stretch, spec.stretch_rate, self.rate)
            parts.append((stretches, np.zeros(stretches.size)))
        self._queue = [(x, y, RAMPING_DOWN) for x, y in parts if x.size]
        self.phase = RAMPING_DOWN

    def _up(self):
        s, v = self._current
        s1, v1 = self._return
        stretches = ramp(s, s1, self.spec.stretch_rate, self.rate)
        volts = ramp(v, v1, self.spec.ramp_rate, self.rate)
        parts = [(stretches, np.full(stretches.size, v)), (np.full(volts.size, s1), volts)]
        self._queue = [(x, y, RAMPING_UP) for x, y in parts if x.size]
        self.phase = RAMPING_UP

    def _act(self):
        want, self._want = self._want, None
        if want == "pause":
            if self._current is None:  # before the first sample: the plan's start, at 0 V
                first = self._window(0, 1)
                self._current = (float(first[0][0]), 0.0)
            if self.phase == RUNNING:
                self._return = self._current
            self.pauses += 1
            self._down()
        elif want == "resume":
            self._held_since = None
            self._up()

    def held_due(self) -> int:
        """Held samples the wall clock allows now (0 unless held)."""
        if self.phase != HELD:
            return 0
        if self._held_since is None:
            self._held_since = (self._clock(), self.taken)
        t0, k0 = self._held_since
        return max(0, int((self._clock() - t0) * self.rate) - (self.taken - k0))

    # -------------------------------------------------------------- take
    def take(self, m: int) -> Setpoints:
        """The next at most ``m`` samples' setpoints: fewer when the plan ends, or while held, as many as the
        wall clock allows (maybe none)."""
        parts = []
        left = int(m)
        self._tail = 0  # plan samples at the end of this take (what `untake` may give back)
        while left > 0:
            if self._want is not None:
                self._act()
            if self.phase == RUNNING:
                n = min(left, self.samples - self.next)
                if n <= 0:
                    break
                s, v = self._window(self.next, self.next + n)
                s, v = np.asarray(s, float), np.asarray(v, float)
                parts.append((s, v, np.zeros(n, np.int8), np.arange(self.next, self.next + n)))
                self.next += n
                self._before_tail, self._tail = self._current, n  # driven before them (None: nothing yet)
                self._current = (float(s[-1]), float(v[-1]))
            elif self.phase == HELD:
                n = min(left, self.held_due())
                if n <= 0:
                    break
                s, v = self._current
                parts.append((np.full(n, s), np.full(n, v), np.full(n, HELD, np.int8), np.full(n, self.next)))
            else:  # a ramp
                if not self._queue:
                    self.phase = HELD if self.phase == RAMPING_DOWN else RUNNING
                    continue
                x, y, phase = self._queue[0]
                n = min(left, x.size)
                parts.append((x[:n], y[:n], np.full(n, phase, np.int8), np.full(n, self.next)))
                self._current = (float(x[n - 1]), float(y[n - 1]))
                if n == x.size:
                    self._queue.pop(0)
                else:
                    self._queue[0] = (x[n:], y[n:], phase)
            if self.phase != RUNNING:
                self._tail = 0
            left -= n
            self.taken += n
        if not parts:
            return Setpoints(np.empty(0), np.empty(0), np.empty(0, np.int8), np.empty(0, np.int64))
        if self.phase != HELD and self.phase != RUNNING and not self._queue:  # a ramp just ended
            self.phase = HELD if self.phase == RAMPING_DOWN else RUNNING
        if len(parts) == 1:  # one phase (running on, the common case): the arrays as they are
            return Setpoints(*parts[0])
        return Setpoints(*(np.concatenate(column) for column in zip(*parts)))


    def untake(self, m: int) -> bool:
        """Give back the last ``m`` samples of the last `take`, when all of them were plan samples taken while
        running (a backend that computed ahead and had not driven them yet: the next `take` starts with them
        again); False, and nothing changes, otherwise (some of them were a ramp or held: those were driven
        as they come, and a pause then acts after them)."""
        m = int(m)
        if m <= 0:
            return m == 0
        if self.phase != RUNNING or self._want is not None or m > self._tail:
            return False
        self.next -= m
        self.taken -= m
        self._tail -= m
        if self._tail:  # the sample before the given-back ones was a plan sample of the same take
            s, v = self._window(self.next - 1, self.next)
            self._current = (float(np.asarray(s, float)[-1]), float(np.asarray(v, float)[-1]))
        else:  # what was driven before this take's plan samples (the end of a ramp, or a plan sample)
            self._current = self._before_tail
        return True


def pause_intervals(paused) -> list[tuple[int, int]]:
    """``[(first, stop), ...]``: the sample ranges of a run's pauses (from its first sample not `RUNNING`
    to the first `RUNNING` one after it, or the end).

    Parameters
    ----------
    paused : numpy.ndarray
        The ``paused`` flag of a run's samples.
    """
    flag = np.asarray(paused) != RUNNING
    if not flag.size:
        return []
    edges = np.flatnonzero(np.diff(np.concatenate(([False], flag, [False])).astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2])]


__all__ = ["DEFAULT_RAMP_RATE", "DEFAULT_STRETCH_RATE", "FLAG_MEANINGS", "FLAG_VALUES", "HELD", "PauseSpec",
           "PausedSetpoints", "RAMPING_DOWN", "RAMPING_UP", "RUNNING", "Setpoints", "pause_intervals", "pause_spec_of",
           "ramp"]
