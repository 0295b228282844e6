"""Pause, resume and the rig's condition channels (issue 29): CONF:PAUS, PAUS, CONT, PAUS?, COND? over real
loopback sockets, and `EmulatedRig` with `PausedSetpoints` directly (a fake wall clock paces the holds)."""

import pickle
import time

import numpy as np
import pytest

from rdea_lab.emulator import EmulatedRig, Fault, RigServer, RunConfig
from rdea_lab.emulator.conditions import DRIFT_STEP, NOMINAL_TEMPERATURE, OVERHEAT_TEMPERATURE
from rdea_lab.emulator.controller import parse_faults
from rdea_lab.emulator.rig import BLOCK
from rdea_lab.protocols.pause import HELD, RAMPING_DOWN, RAMPING_UP, RUNNING, PauseSpec
from rdea_lab.specs import SpecError

from .helpers import Client

RATE = 100.0
PAUSE = (1000.0, 0.0, 0.05)  # CONF:PAUS: 1 kV/s, hold where it is, 0.05 /s
T, S, V, X_SP, V_SP, PAUSED = 0, 1, 3, 6, 7, 8  # columns of a pausable run's rows (no CUR)


def trajectory(n=1001):
    t = np.arange(n) / RATE
    x = 1.0 + 0.2 * np.sin(np.pi * t / t[-1]) ** 2
    v = np.where(t > 0.4 * t[-1], 2000.0, 0.0)  # 2 kV from t = 4.01 s
    return x, v


@pytest.fixture
def server(card, truth, request):
    srv = RigServer(card, truth, port=0, **getattr(request, "param", {}))
    srv.start()
    yield srv
    srv.shutdown()


@pytest.fixture
def client(server):
    c = Client(server.address)
    yield c
    c.close()


def fetch(c, rows):
    """Exactly `rows` rows (a FETC? returns what the rig made in 0.1 s of computing: ask again)."""
    out = [c.fetch(rows)]
    while sum(o.shape[0] for o in out) < rows:
        got = c.fetch(rows - sum(o.shape[0] for o in out))
        assert got.shape[0] or c.q("STAT?").startswith("RUNNING"), "the run ended early"
        out.append(got)
    return np.concatenate(out)


def fetch_now(c):
    """Every row the rig can make now (a held run: until the wall clock allows no more)."""
    out = []
    while True:
        got = c.fetch(100_000)
        if not got.shape[0]:
            return np.concatenate(out) if out else np.empty((0, c.width))
        out.append(got)


def drain(c):
    """Every row to the run's end: its state says DONE or ABORTED and every sample it acquired is fetched (in
    realtime, samples come between a FETC? and the STAT? after it)."""
    out = []
    while True:
        out.append(c.fetch(1000))
        if not out[-1].shape[0]:
            state, acquired, fetched, _ = c.q("STAT?").split(",", 3)
            if state in ("DONE", "ABORTED") and acquired == fetched:
                return np.concatenate(out)


def assert_plan_driven_once(rows, x, v):
    """The rows flagged running are the uploaded trajectories, in order, each sample once; time is k / rate."""
    running = rows[:, PAUSED] == RUNNING
    np.testing.assert_array_equal(rows[running, X_SP], x)
    np.testing.assert_array_equal(rows[running, V_SP], v)
    np.testing.assert_array_equal(rows[:, T], np.arange(rows.shape[0]) / RATE)


# ------------------------------------------------------------------ the wire
def test_conf_paus_is_a_setting_parsed_and_cleared_by_rst(client):
    assert client.q("CONF:PAUS?") == "NONE"
    assert client.q("CONF:PAUS 1000").startswith('ERR -109,"CONF:PAUS takes three numbers')
    assert client.q("CONF:PAUS 1e3,x,0.05").startswith("ERR -104,\"'x' is not a plain decimal")
    assert client.q("CONF:PAUS 0,0,0.05") == 'ERR -222,"CONF:PAUS ramp_rate 0 V/s must be > 0"'
    assert client.q("CONF:PAUS 1000,0.5,0.05") == \
        'ERR -222,"CONF:PAUS hold_stretch 0.5 must be 0 (hold where it is) or >= 1"'
    assert client.q("CONF:PAUS 1000,1.1,0.05") == "OK"
    assert client.q("CONF:PAUS?") == "1000.0,1.1,0.05"
    assert client.q("*RST") == "OK" and client.q("CONF:PAUS?") == "NONE"


def test_pause_and_resume_are_refused_when_they_cannot_act(client):
    assert client.q("PAUS") == 'ERR -221,"settings conflict: PAUS needs a RUNNING run, the rig is IDLE"'
    assert client.q("PAUS?").startswith('ERR -221,"settings conflict: PAUS? describes a run started by INIT')
    client.configure()  # no CONF:PAUS: rows as before, and the run cannot pause
    client.start(*trajectory())
    assert client.fetch(10).shape == (10, 8)
    assert client.q("PAUS") == ('ERR -221,"settings conflict: PAUS: this run was armed without CONF:PAUS, so it '
                                'cannot pause (send CONF:PAUS before ARM; ABOR stops it)"')
    assert client.q("PAUS?") == "RUNNING,0"
    assert client.q("ABOR") == "OK"
    client.configure(pause=PAUSE)
    client.start(*trajectory())
    assert client.q("CONF:PAUS 1000,0,0.05") == \
        'ERR -221,"settings conflict: CONF:PAUS while RUNNING; send ABOR or *RST first"'
    assert client.q("CONT") == 'ERR -221,"settings conflict: CONT: the run is not paused (PAUS? RUNNING)"'
    assert client.fetch(10).shape == (10, 9)
    other = Client(client.sock.getpeername())
    try:  # the queries are anyone's; PAUS and CONT the controller's
        assert other.q("PAUS?") == "RUNNING,0"
        assert other.q("COND?").startswith("interlock=closed,")
        assert other.q("PAUS").startswith("ERR -200,")
    finally:
        other.close()


def test_conf_paus_while_armed_and_a_hold_stretch_above_the_limit_are_refused(client):
    client.configure(pause=(1000.0, 1.7, 0.05))  # LIM:STR 1.6
    x, v = trajectory()
    assert client.upload("TRAJ:STR", x) == "OK" and client.upload("TRAJ:VOLT", v) == "OK"
    assert client.q("ARM") == 'ERR -222,"CONF:PAUS hold_stretch 1.7 is above LIM:STR 1.6"'
    assert client.q("CONF:PAUS 1000,1.5,0.05") == "OK"
    client.sent = client.sent[:6] + (1000.0, 1.5, 0.05)
    client.start(x, v)  # the ARM checksum covers the CONF:PAUS values (helpers.crc_of_what_was_sent)
    assert client.q("ABOR") == "OK"
    assert client.q("ARM").startswith("OK,")
    assert client.q("CONF:PAUS 1000,0,0.05") == \
        'ERR -221,"settings conflict: CONF:PAUS while ARMED; send ABOR or *RST first"'


def test_a_ramp_longer_than_a_trajectory_is_refused_at_arm(client):
    client.configure(pause=(1e-6, 0.0, 0.05))  # 2 kV at 1 uV/s: 2e11 samples at 100 Hz
    x, v = trajectory()
    assert client.upload("TRAJ:STR", x) == "OK" and client.upload("TRAJ:VOLT", v) == "OK"
    assert client.q("ARM") == ('ERR -222,"CONF:PAUS ramp_rate 1e-06 V/s takes 2e+11 samples from 2000 V to 0; '
                               'at most 1e+07"')


# ------------------------------------------------------------------ a pause through the server
def test_a_run_paused_and_resumed_drives_every_plan_sample_once(server, client):
    client.configure(pause=PAUSE)
    x, v = trajectory()
    client.start(x, v)
    before = fetch(client, 500)  # t = 0 .. 4.99 s, 2 kV since 4.01 s
    assert client.q("PAUS") == "OK"
    assert client.q("PAUS") == "OK"  # asked twice: one pause
    assert client.q("PAUS?") == "PAUSING,0"
    down = fetch_now(client)
    assert client.q("PAUS?") == "PAUSED,1" and client.q("CONT") == "OK"
    rest = client.drain(300)
    rows = np.concatenate([before, down, rest])
    assert client.q("STAT?") == f'DONE,{rows.shape[0]},{rows.shape[0]},""'
    assert client.q("PAUS?") == "RUNNING,1"
    assert_plan_driven_once(rows, x, v)
    flag = rows[:, PAUSED]
    first = int(np.argmax(flag != RUNNING))
    assert first == 500  # from the next sample produced
    # 2 kV to 0 at 1 kV/s: 2 s, 200 samples; the stretch held where it was
    ramp = rows[first:first + 200]
    assert np.all(ramp[:, PAUSED] == RAMPING_DOWN) and ramp[-1, V_SP] == 0.0
    np.testing.assert_allclose(ramp[:, V_SP], 2000.0 - 10.0 * np.arange(1, 201), rtol=0, atol=1e-9)
    assert np.all(rows[first:, PAUSED][:200] == RAMPING_DOWN) and np.all(ramp[:, X_SP] == x[499])
    assert set(np.unique(flag)) <= {RUNNING, RAMPING_DOWN, HELD, RAMPING_UP}
    up = rows[flag == RAMPING_UP]
    assert up.shape[0] == 200 and up[-1, V_SP] == v[499]  # back to the plan's setpoint at the pause
    assert not server.controller.voltage_on


def test_a_declared_hold_stretch_is_reached_at_zero_volts_and_left_the_same_way(client):
    client.configure(pause=(1000.0, 1.1, 0.05))
    x, v = trajectory()
    client.start(x, v)
    before = fetch(client, 500)  # stretch 1.2 at 2 kV
    assert client.q("PAUS") == "OK"
    down = fetch_now(client)
    assert client.q("CONT") == "OK"
    rows = np.concatenate([before, down, client.drain(300)])
    assert_plan_driven_once(rows, x, v)
    paused = rows[rows[:, PAUSED] != RUNNING]
    at_hold = paused[:, X_SP] == 1.1
    assert at_hold.any() and np.all(paused[at_hold, V_SP] == 0.0)  # held at 1.1, at 0 V
    moving = paused[:, X_SP] != x[499]  # the stretch moves only at 0 V, at 0.05 /s
    assert np.all(paused[moving, V_SP] == 0.0)
    assert np.max(np.abs(np.diff(paused[:, X_SP]))) <= 0.05 / RATE * (1 + 1e-9)


@pytest.mark.parametrize("server", [{"realtime": True}], indirect=True)
def test_in_realtime_a_pause_acts_within_a_short_block(server, client):
    client.configure(pause=(1e4, 0.0, 0.05))  # 2 kV to 0 in 0.2 s
    x, v = trajectory(301)  # 3 s; 2 kV from 1.21 s
    client.start(x, v)
    time.sleep(1.5)
    asked = float(client.q("STAT?").split(",")[1]) / RATE  # the rig's run time before PAUS is sent
    assert client.q("PAUS") == "OK"
    answered = float(client.q("STAT?").split(",")[1]) / RATE  # ... and once it was answered
    deadline = time.monotonic() + 10.0  # the ramp takes 0.2 s; a busy machine's producer may lag behind
    while client.q("PAUS?") != "PAUSED,1" and time.monotonic() < deadline:
        time.sleep(0.05)
    assert client.q("PAUS?") == "PAUSED,1"
    rows = fetch_now(client)
    first = rows[int(np.argmax(rows[:, PAUSED] != RUNNING)), T]
    # a block of 2048 samples (20 s) is computed ahead, and rewound; the pause acts within a short block
    # (0.05 s) and the producer's turn (0.02 s) of the rig's run time when it answered PAUS
    assert asked <= first <= answered + 0.05 + 0.02 + 1 / RATE, (asked, answered, first)
    assert client.q("CONT") == "OK"
    rows = np.concatenate([rows, drain(client)])
    assert_plan_driven_once(rows, x, v)


def test_held_samples_are_paced_by_the_wall_clock_in_virtual_time(client):
    client.configure(pause=PAUSE)
    client.start(*trajectory())
    fetch(client, 100)  # at 0 V: the pause holds at once
    assert client.q("PAUS") == "OK"
    t0 = time.monotonic()
    fetch_now(client)  # the hold begins with the first sample the rig makes after the pause
    time.sleep(0.5)
    held = fetch_now(client)
    wall = time.monotonic() - t0
    # at most the wall time's samples at 100 Hz since then, in whole blocks of 5 (0.05 s); at least the 0.5 s
    # slept (less a block), however slowly the rig computes them
    assert 45 <= held.shape[0] <= wall * RATE and held.shape[0] % 5 == 0
    assert np.all(held[:, PAUSED] == HELD) and np.all(held[:, V_SP] == 0.0)
    assert client.q("STAT?").startswith("RUNNING,")


@pytest.mark.slow  # the default suite has the heartbeat's abort outside a pause (test_rig_server.py)
def test_a_silent_client_is_aborted_by_the_heartbeat_during_a_pause(card, truth):
    with RigServer(card, truth, port=0, heartbeat=1.0) as srv:  # 1 s: the test's own steps fit in it when busy
        c = Client(srv.address)
        try:
            c.configure(pause=PAUSE)
            c.start(*trajectory())
            fetch(c, 500)
            assert c.q("PAUS") == "OK"
            fetch_now(c)
            assert c.q("PAUS?") == "PAUSED,1"
            time.sleep(2.0)  # a frozen client while the run is held (the watchdog looks every 0.25 s)
            assert not srv.controller.voltage_on
            state = c.q("STAT?")
            assert state.startswith("ABORTED,") and "heartbeat 1 s" in state, state
        finally:
            c.close()


def test_the_force_limit_is_enforced_during_a_pause(client):
    client.configure(pause=PAUSE, force=0.5)  # the force of the held stretch is above 0.5 N
    client.start(np.full(400, 1.3), np.zeros(400))
    assert client.q("PAUS") == "OK"  # before the first sample: held at the plan's start
    rows = client.drain(100)
    assert rows.shape[0] >= 1 and np.all(rows[:, PAUSED] == HELD)
    reply = client.q("STAT?")
    assert reply.startswith("ABORTED,") and "above LIM:FORC 0.5 N" in reply


# ------------------------------------------------------------------ the door interlock
@pytest.mark.parametrize("server", [{"faults": parse_faults(["interlock-at=5:3"])}], indirect=True)
def test_the_interlock_pauses_the_run_by_itself_and_cont_waits_for_the_door(server, client):
    client.configure(pause=PAUSE)
    x, v = trajectory()
    client.start(x, v)
    before = fetch(client, 500)  # t < 5 s: door closed
    assert client.q("COND?").startswith("interlock=closed,")
    down = fetch_now(client)  # the door opens at 5 s: the rig ramps to 0 V and holds
    assert down[0, T] == 5.0 and down[0, PAUSED] == RAMPING_DOWN
    assert client.q("PAUS?") == "PAUSED,1" and client.q("COND?").startswith("interlock=open,")
    assert client.q("CONT") == ('ERR -221,"settings conflict: CONT: the door interlock is open; the rig puts no '
                                'voltage on with its door open (close it, then CONT)"')
    held = [fetch_now(client)]
    while client.q("COND?").startswith("interlock=open"):  # run time 8 s: about 1 s of held samples
        time.sleep(0.05)
        held.append(fetch_now(client))
    assert client.q("PAUS?") == "PAUSED,1"  # a closed door does not resume by itself
    assert client.q("CONT") == "OK"
    rows = np.concatenate([before, down, *held, client.drain(300)])
    assert_plan_driven_once(rows, x, v)
    assert client.q("STAT?").startswith("DONE,")


@pytest.mark.parametrize("server", [{"faults": [("interlock", 5.0)]}], indirect=True)
def test_without_conf_paus_the_interlock_aborts_a_run_with_the_voltage_on(server, client):
    client.configure()
    client.start(*trajectory())
    rows = client.drain(100)
    assert rows[-1, T] == 4.99  # the sample at 5 s is not driven
    reply = client.q("STAT?")
    assert reply.startswith('ABORTED,500,500,"the door interlock is open at t = 5 s with the voltage setpoint '
                            'at 2000 V: armed without CONF:PAUS'), reply
    assert not server.controller.voltage_on


@pytest.mark.parametrize("server", [{"faults": parse_faults(["interlock-at=1:1"])}], indirect=True)
def test_without_conf_paus_a_door_opened_at_zero_volts_does_not_abort(server, client):
    client.configure()
    client.start(*trajectory())  # 0 V until 4.01 s
    assert client.drain(100).shape[0] == 1001 and client.q("STAT?").startswith("DONE,")


# ------------------------------------------------------------------ conditions
@pytest.mark.parametrize("server", [{"faults": parse_faults(["interlock-at=1:0.5", "overheat-at=2:1", "drift-at=3"])}],
                         indirect=True)
def test_conditions_follow_the_injected_faults(server, client, card, truth):
    drift = truth.instrument.force_drift  # N/s
    assert client.q("COND?") == f"interlock=closed,amplifier_temperature={NOMINAL_TEMPERATURE!r},force_offset_drift=0.0"
    client.configure()
    client.start(*trajectory())

    def reading(t):
        fields = dict(p.split("=") for p in client.q("COND?").split(","))
        assert float(fields["force_offset_drift"]) == pytest.approx(drift * t + DRIFT_STEP * (t >= 3), abs=1e-12)
        return fields["interlock"], float(fields["amplifier_temperature"])

    rows = [fetch(client, 150)]  # latest t = 1.49 s
    assert reading(1.49) == ("open", NOMINAL_TEMPERATURE)
    rows.append(fetch(client, 100))  # 2.49 s
    assert reading(2.49) == ("closed", OVERHEAT_TEMPERATURE)
    rows.append(fetch(client, 100))  # 3.49 s
    assert reading(3.49) == ("closed", NOMINAL_TEMPERATURE)
    rows.append(client.drain(500))
    rows = np.concatenate(rows)
    # the force column shows the step: the same run without the drift fault differs by 10 mN from 3 s on
    with RigServer(card, truth, port=0) as plain:
        c = Client(plain.address)
        try:
            c.configure()
            c.start(*trajectory())
            reference = c.drain(500)
        finally:
            c.close()
    step = rows[:, 4] - reference[:, 4]
    late = rows[:, T] >= 3.0
    np.testing.assert_allclose(step[late], DRIFT_STEP, rtol=0, atol=1e-12)  # rounding of offset + noise
    np.testing.assert_array_equal(step[~late], 0.0)


def test_fault_texts_durations_and_the_old_pairs():
    faults = parse_faults(["interlock-at=5:2", "stall-at=3", ("breakdown", 4.0), ("drift", 1.0, 0.5)])
    assert faults == [Fault("interlock", 5.0, 2.0), ("stall", 3.0), ("breakdown", 4.0), Fault("drift", 1.0, 0.5)]
    kind, at = faults[0]  # unpacks as the pair of old (rdea_lab.runs.backend.Emulator.describe does)
    assert (kind, at, faults[0].duration) == ("interlock", 5.0, 2.0) and str(faults[0]) == "interlock-at=5:2"
    assert pickle.loads(pickle.dumps(faults[0])) == faults[0] and faults[0] != Fault("interlock", 5.0, 3.0)
    for text, message in (("stall-at=3:1", "stall takes no duration"), ("drift-at=1:0", "duration must be"),
                          ("overheat-at=1:soon", "'soon' is not a number of seconds"),
                          (("interlock", 1.0, -1.0), "the duration must be")):
        with pytest.raises(SpecError, match=message):
            parse_faults([text])


# ------------------------------------------------------------------ EmulatedRig directly
class Clock:
    """A wall clock the test moves."""

    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def pausable(card, truth, x, v, clock, pause=PauseSpec()):
    cfg = RunConfig(RATE, x, v, L1=0.034, L3=48e-6, max_voltage=3000.0, max_stretch=1.6, max_force=50.0,
                    max_field=80e6, measure=("force", "capacitance"), pause=pause)
    return EmulatedRig(card, truth, np.random.default_rng(0), cfg, clock=clock)


def slow_trajectory(n):
    t = np.arange(n) / RATE
    return 1.0 + 0.3 * np.sin(np.pi * t / t[-1]) ** 2, np.where((t > 2.0) & (t < 40.0), 1500.0, 0.0)


@pytest.mark.parametrize("sizes", [[1, 7, 333], [BLOCK - 1, 2], [3] * 1000])
def test_a_pausable_run_never_paused_is_the_same_run_bit_for_bit(card, truth, sizes):
    x, v = slow_trajectory(5001)
    plain = pausable(card, truth, x, v, Clock(), pause=None).produce(5001)
    r = pausable(card, truth, x, v, Clock())
    rows = np.concatenate([r.produce(s) for s in sizes] + [r.produce(10_000)])
    assert r.state == "done" and rows.shape == (5001, 9) and np.all(rows[:, PAUSED] == RUNNING)
    np.testing.assert_array_equal(rows[:, :8], plain)


def paused_run(card, truth, x, v, sizes):
    """A run paused after 1000 samples (mid-block), held 0.5 s of the fake wall clock, resumed; what the rig makes
    at each step asked for in chunks of `sizes` (then the last size over and over)."""
    clock = Clock()
    r = pausable(card, truth, x, v, clock)

    def drain():
        out, i = [], 0
        while True:
            got = r.produce(sizes[min(i, len(sizes) - 1)])
            i += 1
            if not got.shape[0]:
                return out
            out.append(got)

    rows = [r.produce(1000)]  # mid-block: the block computed ahead is rewound
    assert r.pause() and r.pause_state() == ("PAUSING", 0)
    rows += drain()
    clock.t += 0.5
    rows += drain()
    assert r.pause_state() == ("PAUSED", 1) and r.resume()
    rows += drain()
    assert r.state == "done" and r.pause_state() == ("RUNNING", 1)
    return np.concatenate(rows)


@pytest.mark.parametrize("sizes", [[1, 7, 333], pytest.param([3] * 50, marks=pytest.mark.slow)])
def test_a_pause_acts_from_the_next_sample_and_any_chunking_gives_the_same_data(card, truth, sizes):
    x, v = slow_trajectory(3001)
    rows = paused_run(card, truth, x, v, [10_000])
    flag = rows[:, PAUSED]
    assert int(np.argmax(flag != RUNNING)) == 1000
    assert np.count_nonzero(flag == RAMPING_DOWN) == 150 and np.count_nonzero(flag == HELD) == 50
    assert np.count_nonzero(flag == RAMPING_UP) == 150
    assert_plan_driven_once(rows, x, v)
    np.testing.assert_array_equal(rows[:1000, :8], pausable(card, truth, x, v, Clock(), pause=None).produce(1000))
    np.testing.assert_array_equal(paused_run(card, truth, x, v, sizes), rows)


def test_a_pause_asked_for_after_cont_and_before_the_next_sample_keeps_the_run_held(card, truth):
    """The later request wins (the door opening right after a CONT: the rig must not ramp up)."""
    x, v = slow_trajectory(1001)
    clock = Clock()
    r = pausable(card, truth, x, v, clock)
    r.produce(300)
    assert r.pause()
    r.produce(1000)
    assert r.pause_state() == ("PAUSED", 1)
    assert r.resume() and r.pause()  # CONT, then a pause before any sample: the resume is withdrawn
    clock.t += 0.2
    held = r.produce(1000)
    assert held.shape[0] == 20 and np.all(held[:, PAUSED] == HELD) and r.pause_state() == ("PAUSED", 1)
