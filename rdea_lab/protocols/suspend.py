"""Suspenders at work: when to pause a run, resume it or abort it, from the rig's readings (pure logic).

`SuspenderWatch` is fed the latest readings of the rig's channels once per block (``update``) and says
what the run should do (an `Action`), or nothing. It does no I/O and reads time only from the clock it
is given, so a test drives it with a fake clock and hand-written readings. The suspenders themselves
(``suspend:`` of a protocol or a campaign) are `rdea_lab.specs.suspenders.Suspender`.

The rules:

- A suspender *fires* when its ``when`` holds (a condition whose channel is missing, None or NaN does
  not hold); it is then *active* until its ``resume`` holds while its ``when`` does not (by default:
  until ``when`` no longer holds; a channel that cannot be told never resumes).
- A running run is paused (``pause``) as soon as a suspender is active.
- The run is resumed (``resume``) once no suspender is active: when several fired, all must have
  recovered (each on its own: one that recovered stays recovered until its ``when`` holds again).
- While paused by the watch, an active suspender that has waited longer than its ``wait`` (strictly:
  at exactly ``wait`` the run still waits, and one that recovered on that update resumes) aborts the
  run (``abort``); after an abort the watch reports nothing more.
- A pause the user asked for is the user's: while ``paused_by_user`` the watch neither resumes nor
  aborts (nor pauses) but still follows the suspenders, and `blocking` gives the reason a user's
  resume must be refused while one is active. A user's pause takes over the watch's own pause: once
  the user has resumed, the run runs (and is paused again at once if a suspender is still active, its
  wait counted afresh from then: a wait is the longest the watch's own pause waits).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from ..specs.suspenders import Suspender
from ..specs.units import format_quantity

#: The kinds of `Action`.
ACTIONS = ("pause", "resume", "abort")


@dataclass(frozen=True)
class Action:
    """What the run should do: ``kind`` is ``"pause"``, ``"resume"`` or ``"abort"``; ``reason`` says why
    in one line (``suspended: interlock == open (suspender 'door')``)."""

    kind: str
    reason: str

    def __post_init__(self):
        if self.kind not in ACTIONS:
            raise ValueError(f"action {self.kind!r} is not one of {', '.join(ACTIONS)}")


def _wait_text(seconds: float) -> str:
    unit = "h" if seconds >= 3600.0 else "min" if seconds >= 60.0 else "s"
    return format_quantity(seconds, unit, digits=6)


class SuspenderWatch:
    """The suspenders of a run, and their state (see the module for the rules).

    Parameters
    ----------
    suspenders : iterable of Suspender
        The protocol's (and the campaign's: `rdea_lab.specs.suspenders.merged_suspenders`).
    clock : callable
        Time [s], monotonic (`time.monotonic`); read once per `update`.
    """

    def __init__(self, suspenders: Iterable[Suspender], clock: Callable[[], float] = _time.monotonic):
        self.suspenders = tuple(suspenders)
        for s in self.suspenders:
            if not isinstance(s, Suspender):
                raise TypeError(f"expected Suspender objects, got {type(s).__name__}")
        self._clock = clock
        self._since: dict[int, float | None] = {}  # active suspender -> when its wait began (None: not yet)
        self._suspended = False  # the run is held by the watch's own pause
        self._fired: list[int] = []  # the suspenders that fired during the watch's current pause
        self._aborted = False

    # ------------------------------------------------------------------ state
    @property
    def active(self) -> tuple[Suspender, ...]:
        """The suspenders that fired and have not recovered, in the order they were given."""
        return tuple(self.suspenders[i] for i in sorted(self._since))

    @property
    def suspended(self) -> bool:
        """True while the run is held by a pause of the watch (from its ``pause`` to its ``resume``)."""
        return self._suspended

    def blocking(self) -> str | None:
        """Why a resume must be refused now (a suspender is active), or None when it may go on.

        Returns
        -------
        str or None
            E.g. ``suspender 'door' is active (interlock == open); the run resumes once interlock == open
            no longer holds``.
        """
        if not self._since:
            return None
        return "; ".join(f"{_who(s)} is active; the run resumes once {s.resume_text}" for s in self.active)

    # ----------------------------------------------------------------- update
    def update(self, readings: Mapping, paused_by_user: bool = False) -> Action | None:
        """Take the latest readings; what the run should do now, if anything.

        Parameters
        ----------
        readings : Mapping
            Channel -> latest reading, SI (`rdea_lab.specs.suspenders.Condition.holds`); a channel may be
            missing.
        paused_by_user : bool
            Whether the run is held by a pause the user asked for.

        Returns
        -------
        Action or None
            ``pause`` when a suspender is active and the run runs; ``resume`` when the watch paused it and
            none is active any longer; ``abort`` when an active one has waited longer than its ``wait``;
            None otherwise (always None while `paused_by_user`, and after an abort).
        """
        if self._aborted:
            return None
        now = self._clock()
        self._follow(readings, now, paused_by_user)
        if paused_by_user:
            self._suspended = False  # the user's pause has taken over the watch's
            self._fired = []
            self._since = dict.fromkeys(self._since)  # the waits begin again when the watch pauses next
            return None
        for i, start in self._since.items():  # a wait put off by a user's pause begins now
            if start is None:
                self._since[i] = now
        if not self._suspended:
            if not self._since:
                return None
            self._suspended = True
            self._fired = sorted(self._since)
            return Action("pause", "suspended: " + "; ".join(self._said(i) for i in self._fired))
        self._fired += [i for i in sorted(self._since) if i not in self._fired]
        if not self._since:
            self._suspended = False
            done, self._fired = self._fired, []
            return Action("resume", "resumed: " + "; ".join(self._said(i, resumed=True) for i in done))
        for i, start in sorted(self._since.items()):
            s = self.suspenders[i]
            if now - start > s.wait:
                self._aborted = True
                return Action("abort", f"aborted: {_who(s)} waited longer than its wait of {_wait_text(s.wait)} "
                              f"for its resume condition ({s.resume_text})")
        return None

    def _follow(self, readings: Mapping, now: float, paused_by_user: bool) -> None:
        """Fire the suspenders whose ``when`` holds; clear the recovered ones."""
        for i, s in enumerate(self.suspenders):
            when = s.when.holds(readings)
            if i in self._since:
                if when is not True and _recovered(s, readings, when):
                    del self._since[i]
            elif when is True:
                self._since[i] = None if paused_by_user else now

    def _said(self, i: int, resumed: bool = False) -> str:
        """``interlock == open (suspender 'door')`` (its resume condition when `resumed`)."""
        s = self.suspenders[i]
        text = s.resume_text if resumed else s.when.text
        return f"{text} ({s.label})" if s.name else text


def _who(s: Suspender) -> str:
    """``suspender 'door' (interlock == open)``; ``suspender 'interlock == open'`` for one without a name."""
    return f"{s.label} ({s.when.text})" if s.name else s.label


def _recovered(s: Suspender, readings: Mapping, when: bool | None) -> bool:
    """Whether `s`'s resume condition holds (a condition that cannot be told does not)."""
    if s.resume is None:
        return when is False
    return s.resume.holds(readings) is True


__all__ = ["ACTIONS", "Action", "SuspenderWatch"]
