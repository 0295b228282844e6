"""Operating a run between two blocks: pause, resume and abort requests, suspenders, and the pause record.

`Operator` is the engine's one place for what happens to a run while it goes (the engine itself only reads
blocks and writes them). After each block it

- reads the requests (`rdea_lab.runs.control.RunControl`: from Python, the CLI in another terminal, the
  first Ctrl-C, the live view) and acts on them through the backend's ``pause()`` / ``resume()``, or ends
  the run (``abort``: status ``aborted``, voltage off, every sample kept);
- asks the backend for its condition channels (``conditions()``: interlock, amplifier temperature, load-cell
  zero drift) and lets the protocol's suspenders (`rdea_lab.protocols.suspend.SuspenderWatch`) pause the run,
  resume it when the condition has cleared, or abort it when it waited longer than the suspender allows;
- follows the ``paused`` flag of the samples (each sample's phase, `rdea_lab.protocols.pause`): a pause that
  begins is noted in the journal with its reason and who asked (`JournalWriter.note_pause`), whoever asked
  (a rig that paused by itself, its interlock open, is noted as such);
- publishes the run's state (``running``, ``pausing``, ``paused``, ``resuming``) for other processes.

A backend that cannot pause (a `~rdea_lab.backends.Backend` of one's own without ``pause``) has its pause
requests refused, saying so; abort always works.
"""

from __future__ import annotations

import time as _time

import numpy as np

from ..protocols.pause import HELD, RAMPING_DOWN, RAMPING_UP, RUNNING

#: The published state of a sample's phase.
PHASE_STATE = {RUNNING: "running", RAMPING_DOWN: "pausing", HELD: "paused", RAMPING_UP: "resuming"}
#: Wall time between two looks at the control folder [s] (requests made in this process, and the backend's
#: conditions where suspenders watch them, are read after every block).
POLL_EVERY = 0.02
#: Wall time between two publications of an unchanged state (its sample count) [s].
PUBLISH_EVERY = 0.5


class Operator:
    """The run's operation between blocks (see the module).

    Parameters
    ----------
    control : RunControl
    backend : Backend
    writer : JournalWriter
        Its ``note_pause`` records each pause's reason.
    suspenders : sequence of Suspender
        The protocol's (and campaign's) suspenders.
    clock : callable
        Wall time [s].
    """

    def __init__(self, control, backend, writer, suspenders=(), clock=_time.monotonic):
        self.control, self.backend, self.writer = control, backend, writer
        self._clock = clock
        self.can_pause = callable(getattr(backend, "pause", None)) and callable(getattr(backend, "resume", None))
        self.watch = None
        if suspenders:
            from ..protocols.suspend import SuspenderWatch

            self.watch = SuspenderWatch(tuple(suspenders), clock=clock)
        self.phase = RUNNING  # of the last sample received
        self.asked = None  # (reason, by) of the pause asked for and not yet seen in the samples
        self.by_user = False  # the pause going on (or asked for) is a user's, not a suspender's
        self.pausing = False  # asked to pause (or paused by the rig itself), not yet resumed
        self.reason = ""  # of the pause going on
        self._polled = self._published = -float("inf")
        self._answered = False  # a request was acted on (or refused) since the last publication
        self._state = None

    # ------------------------------------------------------------------ the block
    def after_block(self, block, first: int, samples: int):
        """Follow the block's phases, then act on requests and conditions; returns ``(status, reason)`` when
        the run is to end (``aborted``), else None."""
        phase = block.get("paused")
        if phase is not None and len(phase):
            self._follow(np.asarray(phase), first)
        now = self._clock()
        look = now - self._polled >= POLL_EVERY  # the folder and the backend's conditions: not every block
        if look:
            self._polled = now
        # suspenders after every block: a backend faster than the wall clock (the twin, the emulator in
        # virtual time) must not run through a condition between two looks
        ended = self._requests(look) or self._suspenders()
        self.publish(samples, force=ended is not None or self._answered)
        self._answered = False
        return ended

    def _follow(self, phase: np.ndarray, first: int) -> None:
        """Note each pause that begins in the block (a non-running sample after a running one)."""
        if self.phase == RUNNING and not phase.any():  # the common case: running on, nothing to note
            if not self.pausing:
                self.by_user = False
            return
        # a pause begins where a sample ramps down or is held after one running or ramping back up (a rig
        # that pauses by itself while a resume ramps up begins a pause too: the table keeps one interval)
        down = (phase == RAMPING_DOWN) | (phase == HELD)
        before = np.concatenate(([self.phase in (RUNNING, RAMPING_UP)], ~down[:-1]))
        for i in np.flatnonzero(before & down):
            if self.asked is None:  # the rig paused by itself (its interlock opened): resumable as any pause
                self.pausing, self.by_user = True, False
                self.reason = "paused by the rig itself (e.g. its interlock opened)"
            reason, by = self.asked or (self.reason, "rig")
            self.writer.note_pause(first + int(i), reason, by)
            self.asked = None
        self.phase = int(phase[-1])
        if self.phase == RUNNING and not self.pausing:
            self.by_user = False

    # ------------------------------------------------------------------ requests
    def _requests(self, folder: bool):
        for req in self.control.poll(folder):
            self._answered = True  # published at once: the asker waits for it
            if req.action == "abort":
                reason = req.reason or f"aborted by the user ({req.by})"
                self.control.handled(req)
                return "aborted", reason
            refused = self._pause(req.reason or f"paused by the user ({req.by})", req.by, user=True) \
                if req.action == "pause" else self._resume(user=True)
            self.control.handled(req, refused or "")
        return None

    def _pause(self, reason: str, by: str, user: bool) -> str | None:
        """Pause the run; the reason it cannot (None: done)."""
        if not self.can_pause:
            return f"the backend {getattr(self.backend, 'name', '?')} cannot pause (it has no pause())"
        if self.pausing:
            if user and not self.by_user:  # held by a suspender or the rig: the user's now, resumed by the user
                self.by_user, self.reason = True, reason
                return None
            return "the run is paused already"
        from ..backends.base import PauseRefused

        try:
            self.backend.pause(reason)
        except PauseRefused as exc:
            return str(exc)
        self.pausing, self.asked, self.by_user, self.reason = True, (reason, by), user, reason
        return None

    def _resume(self, user: bool) -> str | None:
        if not self.pausing:
            return "the run is not paused"
        if user and self.watch is not None:
            blocking = self.watch.blocking()
            if blocking:
                return f"a suspender holds the run: {blocking}"
        from ..backends.base import PauseRefused

        try:
            self.backend.resume()
        except PauseRefused as exc:
            return str(exc)
        self.pausing = False
        if self.asked is not None and self.phase == RUNNING:
            self.asked = None  # asked for and withdrawn before any sample paused
        return None

    # ------------------------------------------------------------------ suspenders
    def _suspenders(self):
        if self.watch is None:
            return None
        conditions = getattr(self.backend, "conditions", None)
        readings = conditions() if callable(conditions) else {}
        action = self.watch.update(readings, paused_by_user=self.pausing and self.by_user)
        if action is None:
            return None
        if action.kind == "abort":
            return "aborted", action.reason
        if action.kind == "pause":
            if self.pausing:  # paused already (by the rig itself, or the user: the watch knows whose)
                return None
            refused = self._pause(action.reason, "suspender", user=False)
            if refused is not None and not self.pausable():  # a condition that must stop a run that cannot
                return "aborted", f"{action.reason}; the run cannot pause ({refused}), so it was aborted"
            # a pausable run that refuses now has driven its whole plan: it ends complete within a block
        elif action.kind == "resume" and self.pausing and not self.by_user:
            self._resume(user=False)
        return None

    def pausable(self) -> bool:
        """Whether the backend can pause at all (a rig of an older protocol says ``pausable = False``)."""
        return self.can_pause and bool(getattr(self.backend, "pausable", True))

    # ------------------------------------------------------------------ state
    def publish(self, samples: int, force: bool = False) -> None:
        state = PHASE_STATE.get(self.phase, "running")
        if self.pausing and state == "running":
            state = "pausing"
        now = self._clock()
        if force or state != self._state or now - self._published >= PUBLISH_EVERY:
            self._state, self._published = state, now
            self.control.publish(state, self.reason if state != "running" else "", samples=int(samples))


__all__ = ["Operator", "PHASE_STATE"]
