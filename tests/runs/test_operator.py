"""The engine's Operator between blocks (issue 29), with a backend and a journal of hand-written stand-ins:
whose pause it is (the user's, a suspender's, the rig's own), what a refusal does, and that every pause that
begins is noted once."""

from __future__ import annotations

import numpy as np

from rdea_lab.backends.base import PauseRefused
from rdea_lab.protocols.pause import HELD, RAMPING_DOWN, RAMPING_UP, RUNNING
from rdea_lab.runs.control import RunControl
from rdea_lab.runs.operate import Operator
from rdea_lab.specs import Suspender

DOOR = Suspender(name="door", when="interlock == open", wait=60.0)


class Backend:
    name = "stand-in"

    def __init__(self, refuse=None, pausable=True):
        self.calls, self.readings, self.refuse, self.pausable = [], {"interlock": "closed"}, refuse, pausable

    def pause(self, reason):
        if self.refuse:
            raise PauseRefused(self.refuse)
        self.calls.append("pause")

    def resume(self):
        self.calls.append("resume")

    def conditions(self):
        return dict(self.readings)


class Writer:
    def __init__(self):
        self.notes = []

    def note_pause(self, first, reason, by):
        self.notes.append((first, by))


def operator(backend, suspenders=(DOOR,)):
    now = [0.0]
    op = Operator(RunControl(), backend, Writer(), suspenders, clock=lambda: now[0])
    return op, now


def block(*phases):
    return {"paused": np.array(phases, np.int8)}


def test_a_users_pause_takes_over_a_suspenders_and_only_the_user_resumes_it():
    backend = Backend()
    op, now = operator(backend)
    backend.readings["interlock"] = "open"
    assert op.after_block(block(RUNNING), 0, 1) is None
    assert backend.calls == ["pause"]
    op.after_block(block(RAMPING_DOWN, HELD), 1, 3)
    op.control.pause("mine")
    op.after_block(block(HELD), 3, 4)
    assert op.control._handled[-1]["refused"] == ""  # taken over, not refused
    backend.readings["interlock"] = "closed"
    now[0] = 1.0
    op.after_block(block(HELD), 4, 5)
    assert backend.calls == ["pause"]  # the condition cleared: the user's pause holds
    op.control.resume()
    op.after_block(block(HELD), 5, 6)
    assert backend.calls == ["pause", "resume"]


def test_a_rig_that_pauses_itself_while_a_resume_ramps_up_can_be_resumed():
    backend = Backend()
    op, _ = operator(backend, suspenders=())
    op.control.pause("look")  # acted on after the block it came with: the next block pauses
    op.after_block(block(RUNNING), 0, 1)
    op.after_block(block(RAMPING_DOWN, HELD), 1, 3)
    op.control.resume()
    op.after_block(block(HELD), 3, 4)
    op.after_block(block(RAMPING_UP, RAMPING_UP, RAMPING_DOWN, HELD), 4, 8)  # the door opened: the rig paused
    assert op.writer.notes == [(1, "python"), (6, "rig")]
    op.control.resume()
    op.after_block(block(HELD), 8, 9)
    assert op.control._handled[-1]["refused"] == "" and backend.calls[-1] == "resume"


def test_a_refused_suspender_pause_ends_only_a_run_that_cannot_pause():
    done = Backend(refuse="the plan is driven to its end")
    op, _ = operator(done)
    done.readings["interlock"] = "open"
    assert op.after_block(block(RUNNING), 0, 1) is None  # it ends complete within a block
    old = Backend(refuse="an older rig", pausable=False)
    op, _ = operator(old)
    old.readings["interlock"] = "open"
    status, reason = op.after_block(block(RUNNING), 0, 1)
    assert status == "aborted" and "cannot pause" in reason
