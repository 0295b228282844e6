"""The suspender state machine (rdea_lab.protocols.suspend): hand-written readings and a fake clock."""

import pytest

from rdea_lab.protocols.suspend import Action, SuspenderWatch
from rdea_lab.specs.suspenders import Suspender

C = 273.15  # [K] 0 degC: readings are kelvin


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def watch(*suspenders):
    clock = Clock()
    return SuspenderWatch(suspenders, clock=clock), clock


DOOR = Suspender(name="door", when="interlock == open", wait=60.0)
HOT = Suspender(name="hot", when="amplifier_temperature > 60 degC", resume="amplifier_temperature < 50 degC",
                wait=600.0)


def run(w, clock, steps, paused_by_user=False):
    """Feed ``(t, readings)`` steps; the actions, one per step (None for nothing)."""
    out = []
    for t, readings in steps:
        clock.t = t
        out.append(w.update(readings, paused_by_user))
    return out


def test_interlock_pauses_and_resumes_once_closed():
    w, clock = watch(DOOR)
    got = run(w, clock, [(0, {"interlock": "closed"}), (1, {"interlock": "open"}), (2, {"interlock": "open"}),
                         (3, {"interlock": "closed"}), (4, {"interlock": "closed"})])
    assert got == [None, Action("pause", "suspended: interlock == open (suspender 'door')"), None,
                   Action("resume", "resumed: interlock == open no longer holds (suspender 'door')"), None]
    assert not w.suspended and w.blocking() is None


def test_hysteresis_pauses_above_60_and_resumes_only_below_50_degc():
    w, clock = watch(HOT)
    temps = [55, 61, 58, 52, 50, 49.9, 55, 59.9]  # [degC]
    got = run(w, clock, [(k, {"amplifier_temperature": C + x}) for k, x in enumerate(temps)])
    assert [a and a.kind for a in got] == [None, "pause", None, None, None, "resume", None, None]
    assert got[1].reason == "suspended: amplifier_temperature > 60 degC (suspender 'hot')"
    assert got[5].reason == "resumed: amplifier_temperature < 50 degC (suspender 'hot')"
    # between 50 and 60 degC after recovering: still running (the resume condition is not the when one)


def test_two_overlapping_suspenders_resume_only_when_both_recovered():
    w, clock = watch(DOOR, HOT)
    cool, hot = C + 40, C + 65
    got = run(w, clock, [
        (0, {"interlock": "closed", "amplifier_temperature": cool}),
        (1, {"interlock": "open", "amplifier_temperature": cool}),  # door fires: pause
        (2, {"interlock": "open", "amplifier_temperature": hot}),  # hot fires too: already paused
        (3, {"interlock": "closed", "amplifier_temperature": hot}),  # door recovered, hot not
        (4, {"interlock": "closed", "amplifier_temperature": C + 55}),  # hot not below 50 degC yet
        (5, {"interlock": "closed", "amplifier_temperature": C + 45}),  # both recovered: resume
    ])
    assert [a and a.kind for a in got] == [None, "pause", None, None, None, "resume"]
    assert got[5].reason == ("resumed: interlock == open no longer holds (suspender 'door'); "
                             "amplifier_temperature < 50 degC (suspender 'hot')")


def test_two_firing_at_once_both_named():
    w, clock = watch(DOOR, HOT)
    (a,) = run(w, clock, [(0, {"interlock": "open", "amplifier_temperature": C + 70})])
    assert a == Action("pause", "suspended: interlock == open (suspender 'door'); "
                                "amplifier_temperature > 60 degC (suspender 'hot')")


def test_the_blocking_reason_lists_the_active_ones():
    w, clock = watch(DOOR, HOT)
    run(w, clock, [(0, {"interlock": "open", "amplifier_temperature": C + 70})])
    assert w.blocking() == ("suspender 'door' (interlock == open) is active; the run resumes once interlock == "
                            "open no longer holds; suspender 'hot' (amplifier_temperature > 60 degC) is active; the "
                            "run resumes once amplifier_temperature < 50 degC")
    assert w.active == (DOOR, HOT)
    run(w, clock, [(1, {"interlock": "closed", "amplifier_temperature": C + 70})])
    assert w.active == (HOT,) and w.blocking().startswith("suspender 'hot'")


@pytest.mark.parametrize("last, expected", [(60.0, None), (60.000001, "abort")])
def test_the_wait_expires_only_past_its_boundary(last, expected):
    # the door fires at t = 10 s; its wait is 60 s: at exactly 70 s the run still waits, just after it aborts
    w, clock = watch(DOOR)
    got = run(w, clock, [(0, {"interlock": "closed"}), (10, {"interlock": "open"}), (40, {"interlock": "open"}),
                         (10 + last, {"interlock": "open"})])
    assert [a and a.kind for a in got] == [None, "pause", None, expected]
    if expected:
        assert got[-1].reason == ("aborted: suspender 'door' (interlock == open) waited longer than its wait of "
                                  "1 min for its resume condition (interlock == open no longer holds)")
        assert run(w, clock, [(100, {"interlock": "closed"})]) == [None]  # aborted: nothing more


def test_a_recovery_on_the_last_update_of_the_wait_resumes():
    w, clock = watch(DOOR)
    got = run(w, clock, [(0, {"interlock": "open"}), (60, {"interlock": "closed"})])
    assert [a and a.kind for a in got] == ["pause", "resume"]


def test_each_active_suspender_has_its_own_wait():
    w, clock = watch(DOOR, HOT)
    got = run(w, clock, [(0, {"interlock": "closed", "amplifier_temperature": C + 70}),  # hot: wait 600 s
                         (500, {"interlock": "open", "amplifier_temperature": C + 70}),  # door: wait 60 s
                         (561, {"interlock": "open", "amplifier_temperature": C + 70})])
    assert [a and a.kind for a in got] == ["pause", None, "abort"]
    assert got[2].reason.startswith("aborted: suspender 'door'")


def test_missing_readings_neither_pause_nor_resume():
    w, clock = watch(DOOR, HOT)
    got = run(w, clock, [(0, {}), (1, {"amplifier_temperature": float("nan")}),
                         (2, {"interlock": "open"}),  # pause
                         (3, {}),  # the interlock cannot be told: no resume
                         (4, {"amplifier_temperature": C + 20}),  # still no interlock reading
                         (5, {"interlock": "closed"})])
    assert [a and a.kind for a in got] == [None, None, "pause", None, None, "resume"]


def test_a_missing_resume_channel_does_not_resume():
    s = Suspender(name="drift", when="|force_offset_drift| > 5 mN", resume="interlock == closed")
    w, clock = watch(s)
    got = run(w, clock, [(0, {"force_offset_drift": -0.006}), (1, {"force_offset_drift": 0.0}),
                         (2, {"force_offset_drift": 0.0, "interlock": "closed"})])
    assert [a and a.kind for a in got] == ["pause", None, "resume"]


def test_a_resume_condition_that_holds_while_when_holds_does_not_resume():
    # resume: interlock closed, but the drift is still too large: no resume into a bad condition (no ping-pong)
    s = Suspender(name="drift", when="force_offset_drift > 5 mN", resume="interlock == closed")
    w, clock = watch(s)
    got = run(w, clock, [(0, {"force_offset_drift": 0.01, "interlock": "closed"}),
                         (1, {"force_offset_drift": 0.01, "interlock": "closed"}),
                         (2, {"force_offset_drift": 0.0, "interlock": "closed"})])
    assert [a and a.kind for a in got] == ["pause", None, "resume"]


def test_an_unnamed_suspender_is_named_by_its_condition():
    w, clock = watch(Suspender(when="interlock == open", wait=1.0))
    got = run(w, clock, [(0, {"interlock": "open"}), (2, {"interlock": "open"})])
    assert got[0].reason == "suspended: interlock == open"
    assert got[1].reason == ("aborted: suspender 'interlock == open' waited longer than its wait of 1 s for its "
                             "resume condition (interlock == open no longer holds)")


def test_a_user_pause_is_the_users():
    w, clock = watch(DOOR)
    # the user paused; the door opens: nothing reported, but a resume by the user is refused
    got = run(w, clock, [(0, {"interlock": "closed"}), (1, {"interlock": "open"}), (500, {"interlock": "open"})],
              paused_by_user=True)
    assert got == [None, None, None]  # no pause, and no abort however long the user's pause
    assert w.blocking() == ("suspender 'door' (interlock == open) is active; the run resumes once interlock == "
                            "open no longer holds")
    # the door closes while the user holds the run: no resume (the user resumes it), and no more refusal
    assert run(w, clock, [(501, {"interlock": "closed"})], paused_by_user=True) == [None]
    assert w.blocking() is None
    assert run(w, clock, [(502, {"interlock": "closed"})]) == [None]  # the user resumed: running


def test_a_user_pause_takes_over_the_watchs_and_the_wait_begins_again_after_it():
    w, clock = watch(DOOR)
    assert run(w, clock, [(0, {"interlock": "open"})])[0].kind == "pause"
    assert run(w, clock, [(10, {"interlock": "open"}), (1000, {"interlock": "open"})], paused_by_user=True) == \
        [None, None]
    assert not w.suspended
    # the user resumed (despite blocking): the door is still open, so the watch pauses again, its wait from now
    got = run(w, clock, [(1001, {"interlock": "open"}), (1061, {"interlock": "open"}),
                         (1061.5, {"interlock": "open"})])
    assert [a and a.kind for a in got] == ["pause", None, "abort"]


def test_a_suspender_that_fires_in_a_users_pause_pauses_once_the_user_resumes():
    w, clock = watch(HOT)
    run(w, clock, [(0, {"amplifier_temperature": C + 70})], paused_by_user=True)
    assert run(w, clock, [(5, {"amplifier_temperature": C + 55})]) == \
        [Action("pause", "suspended: amplifier_temperature > 60 degC (suspender 'hot')")]  # not below 50 degC yet


def test_bad_input():
    with pytest.raises(TypeError, match="expected Suspender objects"):
        SuspenderWatch(["interlock == open"])
    with pytest.raises(ValueError, match="action 'stop' is not one of pause, resume, abort"):
        Action("stop", "x")
    w, _ = watch(DOOR)
    with pytest.raises(ValueError, match="interlock reading True is not one of open, closed"):
        w.update({"interlock": True})


@pytest.mark.parametrize("seed", range(10))
def test_random_readings_keep_the_rules(seed):
    """Pauses and resumes alternate, a resume comes only with nothing active, nothing while the user holds the
    run, and nothing after an abort."""
    import numpy as np

    rng = np.random.default_rng(seed)
    w, clock = watch(DOOR, HOT, Suspender(when="|force_offset_drift| > 5 mN", wait=30.0))
    suspended, aborted, user = False, False, False
    for k in range(2000):
        clock.t += float(rng.uniform(0.0, 2.0))
        readings = {"interlock": "open" if rng.random() < 0.05 else "closed",
                    "amplifier_temperature": C + float(rng.uniform(40, 65)),
                    "force_offset_drift": float(rng.normal(0, 0.003))}
        for key in list(readings):
            if rng.random() < 0.05:
                del readings[key]
        if not suspended and rng.random() < 0.02:
            user = not user if w.blocking() is None or not user else user  # a user's resume may be refused
        action = w.update(readings, paused_by_user=user)
        if user or aborted:
            assert action is None
            continue
        if action is None:
            continue
        if action.kind == "pause":
            assert not suspended and w.active
            suspended = True
        elif action.kind == "resume":
            assert suspended and not w.active and w.blocking() is None
            suspended = False
        else:
            assert suspended and w.active
            aborted = True
        assert action.reason.startswith({"pause": "suspended: ", "resume": "resumed: ", "abort": "aborted: "}[
            action.kind])
