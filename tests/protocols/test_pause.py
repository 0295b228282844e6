"""The setpoints of a paused run (rdea_lab.protocols.pause), against the plan they come from."""

import numpy as np
import pytest

from rdea_lab.protocols.pause import (HELD, RAMPING_DOWN, RAMPING_UP, RUNNING, PausedSetpoints, PauseSpec,
                                      pause_intervals, ramp)

RATE = 100.0


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def plan(n):
    k = np.arange(n)
    return 1.0 + 0.5 * k / n, 2600.0 * np.sin(2 * np.pi * k / 250.0) ** 2


def cursor(n, spec=None):
    s, v = plan(n)
    clock = Clock()
    return PausedSetpoints(lambda a, b: (s[a:b], v[a:b]), n, RATE, spec or PauseSpec(), clock=clock), clock, (s, v)


def test_ramp_ends_exactly_and_never_overshoots():
    r = ramp(2600.0, 0.0, 1000.0, RATE)
    assert r[-1] == 0.0 and r.size == 260
    assert np.all(np.diff(r) <= 0) and np.all(r >= 0)
    assert np.allclose(-np.diff(np.concatenate(([2600.0], r))), 10.0)
    assert ramp(5.0, 5.0, 1.0, RATE).size == 0
    up = ramp(0.0, 3.0, 1000.0, RATE)  # shorter than one step
    assert up.tolist() == [3.0]


@pytest.mark.parametrize("seed", range(20))
def test_random_pauses_lose_and_repeat_no_plan_sample(seed):
    rng = np.random.default_rng(seed)
    n = 3000
    c, clock, (s, v) = cursor(n, PauseSpec(ramp_rate=rng.uniform(200, 5000),
                                           hold_stretch=None if seed % 2 else 1.0, stretch_rate=0.5))
    out = []
    while not c.done:
        m = int(rng.integers(1, 200))
        act = rng.random()
        if act < 0.1:
            c.pause()
        elif act < 0.2:
            c.resume()
        clock.t += rng.uniform(0, 0.5)
        out.append(c.take(m))
        if c.phase == HELD and rng.random() < 0.3:
            c.resume()
        if len(out) > 100000:
            raise AssertionError("never done")
    stretch = np.concatenate([o.stretch for o in out])
    voltage = np.concatenate([o.voltage for o in out])
    flag = np.concatenate([o.paused for o in out])
    index = np.concatenate([o.plan_index for o in out])
    running = flag == RUNNING
    assert running.sum() == n  # no plan sample lost or driven twice, in order
    assert np.array_equal(index[running], np.arange(n))
    assert np.array_equal(stretch[running], s) and np.array_equal(voltage[running], v)
    # the voltage never moves faster than the ramp rate outside the plan's own samples
    dv = np.abs(np.diff(voltage))
    off_plan = ~(running[1:] & running[:-1])
    assert np.all(dv[off_plan] <= c.spec.ramp_rate / RATE * (1 + 1e-9) + np.abs(np.diff(v)).max())
    assert np.all(voltage[flag == HELD] == 0.0)
    # every pause reached 0 V within its ramp-down time and came back to the plan's setpoint
    for a, b in pause_intervals(flag):
        seg = flag[a:b]
        if (seg == HELD).any():
            first_held = a + int(np.argmax(seg == HELD))
            start_v = voltage[a - 1] if a else 0.0
            down_v = int(np.ceil(abs(start_v) / (c.spec.ramp_rate / RATE) - 1e-9))
            assert voltage[a + down_v - 1 if down_v else a] == 0.0 or down_v == 0
            assert first_held - a >= down_v
        if b < flag.size:
            assert index[b] == index[a]  # the plan goes on where it paused


def test_held_samples_follow_the_wall_clock():
    c, clock, _ = cursor(1000, PauseSpec(ramp_rate=1e6))
    c.take(10)
    c.pause()
    got = c.take(1000)
    assert got.paused[-1] in (RAMPING_DOWN, HELD) and got.voltage[-1] == 0.0
    assert c.take(1000).paused.size == 0  # no wall time has passed: no held sample
    clock.t += 2.5
    held = c.take(1000)
    assert held.paused.size == 250 and np.all(held.paused == HELD)
    assert c.resume()
    back = c.take(5)
    assert back.paused[0] == RAMPING_UP or back.paused[0] == RUNNING


def test_a_pause_before_the_first_sample_starts_from_zero_volts_and_requests_are_idempotent():
    c, clock, (s, v) = cursor(100)
    assert c.pause() and not c.pause()
    assert c.take(5).paused.size == 0  # at 0 V already: held at once, and no wall time has passed
    clock.t += 0.05
    got = c.take(10)
    assert got.paused.tolist() == [HELD] * 5 and np.all(got.stretch == s[0]) and np.all(got.voltage == 0.0)
    assert c.resume() and not c.resume()
    back = c.take(10)
    assert back.paused.tolist() == [RUNNING] * 10 and np.array_equal(back.voltage, v[:10])
    assert pause_intervals(np.array([0, 1, 2, 2, 3, 0, 0, 1])) == [(1, 5), (7, 8)]


def test_untake_gives_back_only_the_plan_samples_at_the_end_of_the_last_take():
    """A backend that computed ahead gives back what it has not driven; only the plan samples at the end of
    the last take can be taken again (a ramp was driven as it came), and a pause then ramps down from what
    was driven last. Checked against the plan: every plan sample is driven once, in order."""
    from rdea_lab.protocols.pause import Setpoints

    n = 1000
    stretch, volt = 1 + np.arange(n) * 1e-4, np.full(n, 500.0)
    now = [0.0]
    sp = PausedSetpoints(lambda a, b: (stretch[a:b], volt[a:b]), n, 100.0, PauseSpec(ramp_rate=1000.0),
                         clock=lambda: now[0])
    driven = [sp.take(100)]
    sp.pause()
    driven.append(sp.take(100))  # the ramp down (50 samples), then held: none yet
    now[0] = 1.0
    driven.append(sp.take(1000))  # 100 held
    sp.resume()
    c = sp.take(100)  # 50 ramping up, then 50 plan samples
    assert np.bincount(c.paused).tolist() == [50, 0, 0, 50]
    assert not sp.untake(80)  # 30 of them were the ramp, driven as they came: nothing given back
    assert sp.untake(50)  # the plan samples: given back
    driven.append(Setpoints(*(x[:50] for x in c)))
    sp.pause()  # from where the ramp up ended (the plan's voltage at the pause), not the plan's next sample
    down = sp.take(10)
    assert down.paused[0] == 1 and down.voltage[0] == 500.0 - 10.0
    sp.resume()
    now[0] = 2.0
    rest = sp.take(100000)
    driven += [down, rest]
    plan = np.concatenate([d.plan_index[d.paused == 0] for d in driven])
    assert np.array_equal(plan, np.arange(n))
