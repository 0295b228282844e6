"""The emulated rig's injected faults and its condition channels (``COND?``): door interlock, amplifier
temperature, load-cell zero drift.

A fault happens at a run time (the sample time ``k / rate``): ``disconnect``, ``breakdown`` and ``stall``
at one instant; ``interlock`` (the door opens), ``overheat`` (the amplifier runs hot) and ``drift`` (the
load cell's zero steps) from an instant for a duration, or to the end of the run. On the command line
``KIND-at=SECONDS`` or ``KIND-at=SECONDS:DURATION`` (`rdea_lab.emulator.controller.parse_fault`); in Python
a `Fault`, or the pair ``(kind, seconds)`` / the triple ``(kind, seconds, duration)``.
"""

from __future__ import annotations

import math

import numpy as np

#: Faults that can be injected, each at a run time [s].
FAULTS = ("disconnect", "breakdown", "stall", "interlock", "overheat", "drift")
#: The faults that last a while (a duration, or to the end of the run): the condition channels'.
WINDOWED = ("interlock", "overheat", "drift")
#: The amplifier's temperature in normal running, and with the ``overheat`` fault [K] (35 and 70 degC).
NOMINAL_TEMPERATURE = 308.15
OVERHEAT_TEMPERATURE = 343.15
#: The step of the load cell's zero offset with the ``drift`` fault [N] (10 mN).
DRIFT_STEP = 0.010


class Fault(tuple):
    """An injected fault: the pair ``(kind, at)`` [s] (it unpacks as the pair of old), and its `duration` [s]
    (None: to the end of the run; only the `WINDOWED` kinds have one)."""

    def __new__(cls, kind: str, at: float, duration: float | None = None):
        self = super().__new__(cls, (kind, at))
        self.duration = duration
        return self

    def __getnewargs__(self):
        return (self[0], self[1], self.duration)

    kind = property(lambda self: self[0])
    at = property(lambda self: self[1])

    @property
    def until(self) -> float:
        """The run time the fault ends [s] (inf: never)."""
        return math.inf if self.duration is None else self[1] + self.duration

    def __eq__(self, other):
        if isinstance(other, Fault) and self.duration != other.duration:
            return False
        return tuple.__eq__(self, other)

    def __ne__(self, other):
        return not self == other

    def __hash__(self):
        return hash(tuple(self)) if self.duration is None else hash((*self, self.duration))

    def __repr__(self):
        return f"Fault({self[0]!r}, {self[1]!r}" + (f", {self.duration!r})" if self.duration is not None else ")")

    def __str__(self):
        """``interlock-at=5:2`` (the command line's form)."""
        return f"{self[0]}-at={self[1]:g}" + (f":{self.duration:g}" if self.duration is not None else "")


def check_faults(faults) -> dict[str, Fault]:
    """``[("stall", 3.0), ("interlock", 5.0, 2.0), ...]`` -> ``{"stall": Fault("stall", 3.0), ...}``; ValueError
    naming the bad item."""
    out: dict[str, Fault] = {}
    for item in faults:
        try:
            kind, at, *rest = item
            duration = rest[0] if rest else getattr(item, "duration", None)
            if len(rest) > 1:
                raise ValueError
            at = float(at)
            duration = None if duration is None else float(duration)
        except (TypeError, ValueError):
            raise ValueError(f"fault {item!r} is not (kind, seconds) or (kind, seconds, duration); kinds: "
                             f"{', '.join(FAULTS)}") from None
        if kind not in FAULTS:
            raise ValueError(f"unknown fault {kind!r}; allowed: {', '.join(FAULTS)}")
        if not (math.isfinite(at) and at >= 0.0):
            raise ValueError(f"fault {kind} at {at!r} s: the time must be a finite number of seconds >= 0")
        if duration is not None:
            if kind not in WINDOWED:
                raise ValueError(f"fault {kind} takes no duration (only {', '.join(WINDOWED)} do)")
            if not (math.isfinite(duration) and duration > 0.0):
                raise ValueError(f"fault {kind} for {duration!r} s: the duration must be a finite number of "
                                 "seconds > 0")
        if kind in out:
            raise ValueError(f"fault {kind} given twice")
        out[kind] = Fault(kind, at, duration)
    return out


class Conditions:
    """The condition channels of the emulated rig over a run's time, from the injected faults.

    Parameters
    ----------
    faults : dict
        `check_faults`' result (only the `WINDOWED` kinds matter here).
    force_drift : float
        The load cell's steady drift of its zero offset [N/s] (the truth's ``force_drift``).
    """

    def __init__(self, faults=None, force_drift: float = 0.0):
        self.windows = {k: f for k, f in (faults or {}).items() if k in WINDOWED}
        self.force_drift = float(force_drift)

    def active(self, kind: str, t):
        """Whether fault `kind` is on at run time(s) `t` [s] (a bool array for an array)."""
        f = self.windows.get(kind)
        t = np.asarray(t, float)
        if f is None:
            return np.zeros(t.shape, bool)
        return (t >= f.at) & (t < f.until)

    def opening(self) -> float | None:
        """The run time the door opens [s], None if it never does."""
        f = self.windows.get("interlock")
        return None if f is None else f.at

    @property
    def drifts(self) -> bool:
        """Whether the load cell's zero steps (the ``drift`` fault)."""
        return "drift" in self.windows

    def offset_step(self, t) -> np.ndarray:
        """The injected step of the load cell's zero offset at run times `t` [N]."""
        return np.where(self.active("drift", t), DRIFT_STEP, 0.0)

    def reading(self, t: float) -> dict:
        """The channels at run time `t` [s]: ``interlock`` (``open``/``closed``), ``amplifier_temperature`` [K],
        ``force_offset_drift`` [N] (the zero offset then minus at the run's start: the steady drift and the
        injected step)."""
        return {"interlock": "open" if self.active("interlock", t) else "closed",
                "amplifier_temperature": OVERHEAT_TEMPERATURE if self.active("overheat", t) else NOMINAL_TEMPERATURE,
                "force_offset_drift": self.force_drift * t + float(self.offset_step(t))}


__all__ = ["Conditions", "DRIFT_STEP", "FAULTS", "Fault", "NOMINAL_TEMPERATURE", "OVERHEAT_TEMPERATURE", "WINDOWED",
           "check_faults"]
