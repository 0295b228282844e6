"""Tests of rdea_lab.emulator.server over real loopback sockets (raw and PyVISA clients).

The reference data of a run come from `EmulatedRig` directly, with the seed of
the truth: the server must deliver exactly those samples, once each, in order.
"""

import json
import re
import time

import numpy as np
import pytest

from rdea_lab import __version__
from rdea_lab.emulator import EmulatedRig, RigServer, RunConfig
from rdea_lab.specs.truth import truth_from_mapping

from .helpers import Client

N = 1001
RATE = 100.0


def trajectory(n=N, rate=RATE):
    t = np.arange(n) / rate
    x = 1.0 + 0.2 * np.sin(np.pi * t / t[-1]) ** 2
    v = np.where(t > 0.4 * t[-1], 2000.0, 0.0)
    return x, v


def expected_rows(card, truth, x, v, rate=RATE, measure=("force", "capacitance"), **kwargs):
    cfg = RunConfig(rate, x, v, L1=0.034, L3=4.8e-05, max_voltage=3000.0, max_stretch=1.6, max_force=50.0,
                    max_field=8e7, measure=measure)
    return EmulatedRig(card, truth, np.random.default_rng(truth.seed), cfg, **kwargs).produce(len(x))


@pytest.fixture
def server(card, truth, request):
    kwargs = getattr(request, "param", {})
    srv = RigServer(card, truth, port=0, **kwargs)
    srv.start()
    yield srv
    srv.shutdown()


@pytest.fixture
def client(server):
    c = Client(server.address)
    yield c
    c.close()


def wait_for_state(address, state, timeout=3.0):
    other = Client(address)
    try:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            reply = other.q("STAT?")
            if reply.startswith(state):
                return reply
            time.sleep(0.02)
        raise AssertionError(f"state never became {state}; last {reply}")
    finally:
        other.close()


def test_the_session_of_the_doc(card, truth, client):
    assert client.q("*IDN?") == f"rdea-lab,rig-emulator,specimen-2,{__version__}"
    for command in ("CONF:RATE 100", "CONF:MEAS FORC,CAP", "CONF:LENG 0.034", "CONF:THIC 4.8e-05",
                    "LIM:VOLT 3000", "LIM:STR 1.6", "LIM:FORC 50", "LIM:FIEL 8e+07"):
        assert client.q(command) == "OK", command
    x, v = trajectory()
    assert client.upload("TRAJ:STR", x) == "OK"
    assert client.upload("TRAJ:VOLT", v) == "OK"
    assert client.q("TRAJ:POIN?") == "1001"
    assert client.q("LIM?") == "3000.0,1.6,50.0,80000000.0"
    assert client.q("CONF:MEAS?") == "FORC,CAP" and client.q("CONF:RATE?") == "100.0"
    assert client.q("STAT?") == 'IDLE,0,0,""'
    assert re.fullmatch(r"OK,[0-9a-f]{8}", client.q("ARM")) and client.q("STAT?") == 'ARMED,0,0,""'
    assert client.q("INIT") == "OK"
    first = client.fetch(1000)   # virtual time: the rows are made as they are asked for
    assert first.shape == (1000, 8)
    assert client.q("STAT?") == 'RUNNING,1000,1000,""'
    rest = client.fetch(1000)
    assert rest.shape == (1, 8)
    assert client.q("STAT?") == 'DONE,1001,1001,""'
    assert client.fetch(1000).shape == (0, 8)
    rows = np.concatenate([first, rest])
    np.testing.assert_array_equal(rows, expected_rows(card, truth, x, v))
    np.testing.assert_array_equal(rows[:, 0], np.arange(N) / RATE)
    np.testing.assert_array_equal(rows[:, 6], x)
    np.testing.assert_array_equal(rows[:, 7], v)


def test_every_sample_fetched_once_in_order(card, truth, client):
    client.configure()
    x, v = trajectory()
    client.start(x, v)
    sizes = iter([1, 7, 0, 50, 333, 2, 10_000])
    parts = []
    while True:
        n = next(sizes, 64)
        parts.append(client.fetch(n))
        assert parts[-1].shape[0] <= n
        if client.q("STAT?").startswith("DONE") and parts[-1].shape[0] == 0:
            break
    np.testing.assert_array_equal(np.concatenate(parts), expected_rows(card, truth, x, v))


@pytest.mark.parametrize("server", [{"realtime": True}], indirect=True)
def test_realtime_samples_exist_only_up_to_the_wall_clock(card, truth, server, client):
    rate, n = 1000.0, 300          # a 0.3 s run
    client.configure(rate=rate)
    x, v = trajectory(n, rate)
    start = time.monotonic()
    client.start(x, v)
    parts = []
    while True:
        parts.append(client.fetch(1000))
        state, acquired, fetched, _ = client.q("STAT?").split(",")
        # never ahead of the wall clock since INIT (sample k exists from t = k / rate on)
        assert int(acquired) <= (time.monotonic() - start) * rate + 1
        if state == "DONE" and acquired == fetched:
            break
        time.sleep(0.01)
    assert time.monotonic() - start >= (n - 1) / rate
    assert len(parts) > 2  # it really came in pieces
    np.testing.assert_array_equal(np.concatenate(parts), expected_rows(card, truth, x, v, rate=rate))


def test_arm_refuses_a_trajectory_over_a_limit(client):
    client.configure()
    x, v = np.ones(2000), np.zeros(2000)
    v[1250] = 3200.0
    assert client.upload("TRAJ:STR", x) == "OK" and client.upload("TRAJ:VOLT", v) == "OK"
    assert client.q("ARM") == 'ERR -222,"voltage 3200 V at t = 12.5 s is above LIM:VOLT 3000 V"'
    assert client.q("STAT?") == 'IDLE,0,0,""'
    assert client.q("INIT").startswith('ERR -221,"settings conflict: INIT needs an armed run')
    x[10] = 1.7
    v[1250] = 0.0
    assert client.upload("TRAJ:STR", x) == "OK" and client.upload("TRAJ:VOLT", v) == "OK"
    assert client.q("ARM") == 'ERR -222,"stretch 1.7 at t = 0.1 s is above LIM:STR 1.6"'
    assert client.upload("TRAJ:VOLT", v[:5]) == "OK"
    assert client.q("ARM") == 'ERR -221,"TRAJ:STR has 2000 setpoints but TRAJ:VOLT 5; need as many"'
    assert client.q("SYST:ERR?") == '-222,"voltage 3200 V at t = 12.5 s is above LIM:VOLT 3000 V"'


def test_arm_refuses_without_limits(client):
    assert client.q("CONF:RATE 100") == "OK"
    assert client.upload("TRAJ:STR", np.ones(10)) == "OK" and client.upload("TRAJ:VOLT", np.zeros(10)) == "OK"
    assert client.q("LIM:STR 1.6") == "OK"
    reply = client.q("ARM")
    assert reply.startswith('ERR -221,"no limit in force for LIM:VOLT, LIM:FORC, LIM:FIEL: set LIM:VOLT <V>')


def test_force_limit_aborts_the_run(client):
    client.configure(force=0.5)
    x, v = trajectory()
    client.start(x, v)
    rows = client.drain(100)
    state, acquired, fetched, reason = client.q("STAT?").split(",", 3)
    assert (state, int(acquired), int(fetched)) == ("ABORTED", rows.shape[0], rows.shape[0])
    assert reason.startswith('"force ') and reason.endswith('above LIM:FORC 0.5 N"')
    force = rows[:, 4]
    assert abs(force[-1]) > 0.5 and np.all(np.abs(force[:-1]) <= 0.5)
    assert f"at t = {rows[-1, 0]:.10g} s" in reason


@pytest.mark.parametrize("server", [{"faults": [("disconnect", 2.0)]}], indirect=True)
def test_fault_disconnect(server, client):
    client.configure()
    client.start(*trajectory())
    for _ in range(4):
        assert client.fetch(50).shape == (50, 8)   # t = 0 .. 1.99 s
    with pytest.raises(ConnectionError):
        client.fetch(50)                           # would reach t = 2 s: the connection drops
    assert wait_for_state(server.address, "ABORTED") == 'ABORTED,200,200,"client disconnected"'
    assert not server.controller.voltage_on


@pytest.mark.parametrize("server", [{"faults": [("disconnect", 0.2)], "realtime": True}], indirect=True)
def test_fault_disconnect_in_realtime_while_the_client_waits(server, client):
    client.configure()
    client.start(*trajectory())
    assert client.closed()                         # nobody fetched: the rig's own clock reached 0.2 s
    assert wait_for_state(server.address, "ABORTED") == 'ABORTED,20,0,"client disconnected"'


@pytest.mark.parametrize("server", [{"faults": [("breakdown", 1.5)]}], indirect=True)
def test_fault_breakdown(server, client):
    client.configure()
    client.start(*trajectory())
    rows = client.drain(64)
    assert rows.shape[0] == 151 and rows[-1, 0] == 1.5
    reply = client.q("STAT?")
    assert reply.startswith('ABORTED,151,151,"dielectric breakdown at t = 1.5 s (field ')
    assert reply.endswith('; injected fault)"')


@pytest.mark.parametrize("server", [{"faults": [("stall", 3.0)]}], indirect=True)
def test_fault_stall(server, client):
    client.configure()
    client.start(*trajectory())
    assert client.fetch(1000).shape == (300, 8)    # t < 3 s only
    for _ in range(3):
        assert client.fetch(1000).shape == (0, 8)
        assert client.q("STAT?") == 'RUNNING,300,300,""'  # still "running": the client must notice
    assert client.q("ABOR") == "OK"
    assert client.q("STAT?") == 'ABORTED,300,300,"aborted by ABOR"'


def test_abort_mid_run(server, client):
    client.configure()
    client.start(*trajectory())
    assert client.fetch(100).shape == (100, 8)
    assert server.controller.voltage_on
    assert client.q("ABOR") == "OK"
    assert not server.controller.voltage_on
    assert client.q("STAT?") == 'ABORTED,100,100,"aborted by ABOR"'
    assert client.fetch(100).shape == (0, 8)


def test_client_disconnecting_mid_run_aborts_it(server, client):
    client.configure()
    client.start(*trajectory())
    client.fetch(100)
    client.close()
    assert wait_for_state(server.address, "ABORTED") == 'ABORTED,100,100,"client disconnected"'
    assert not server.controller.voltage_on


def test_a_second_client_may_only_look_or_stop(server, client):
    client.configure()
    client.start(*trajectory())
    client.fetch(10)
    other = Client(server.address)
    try:
        assert other.q("*IDN?").startswith("rdea-lab,rig-emulator,")
        assert other.q("STAT?") == 'RUNNING,10,10,""'
        for command in ("FETC? 10", "LIM:VOLT 1", "CONF:RATE 10", "ARM", "INIT"):
            assert other.q(command).startswith('ERR -200,"another connection controls the rig (RUNNING)')
        assert server.controller.voltage_on
        assert other.q("ABOR") == "OK"  # the emergency stop: anyone may turn the voltage off
        assert not server.controller.voltage_on
        assert other.q("STAT?").startswith('ABORTED,')
        assert other.q("LIM:VOLT 1").startswith('ERR -200')  # stopping the run gave it no control
    finally:
        other.close()


def test_before_arm_a_second_connection_cannot_change_the_first_ones_setup(server, client):
    client.configure(volt=2000.0)
    other = Client(server.address)
    try:
        assert other.q("LIM:VOLT 2500").startswith('ERR -200,"another connection controls the rig (IDLE)')
        assert other.upload("TRAJ:VOLT", np.full(10, 2500.0)).startswith("ERR -200")
    finally:
        other.close()
    assert client.q("LIM?").startswith("2000.0,")
    assert client.q("SYST:REL") == "OK"  # released: now another connection may take control
    other = Client(server.address)
    try:
        assert other.q("LIM:VOLT 2500") == "OK"
    finally:
        other.close()


def test_the_rig_keeps_its_own_limits_whatever_a_client_says(server, client):
    """Hard limits (here the defaults: 3 kV, stretch 2, 50 N, 80 V/um) no client command can raise; the field
    is checked with the rig's own card thickness (48 um), not CONF:THIC."""
    for command, limit in (("LIM:VOLT 1e9", "3000"), ("LIM:FIEL 1e15", "8e+07"), ("LIM:STR 5", "2"),
                           ("LIM:FORC 1e6", "50")):
        reply = client.q(command)
        assert reply.startswith("ERR -222") and "the rig's own limit" in reply and limit in reply, reply
    client.configure(L3=1.0)  # a client claiming a 1 m thick membrane ...
    x = np.full(N, 1.5)
    v = np.full(N, 2900.0)  # ... 2.9 kV at stretch 1.5 on 48 um is 74 V/um: under 80, but ...
    client.configure(L3=1.0, field=5e7)  # ... a client's lower LIM:FIEL still binds, with the rig's own L3
    assert client.upload("TRAJ:STR", x) == "OK" and client.upload("TRAJ:VOLT", v) == "OK"
    reply = client.q("ARM")
    assert reply.startswith('ERR -222,"field estimate') and "4.8e-05" in reply, reply
    assert not server.controller.voltage_on


def test_a_silent_controlling_connection_is_aborted_after_the_heartbeat(truth, card):
    from rdea_lab.emulator import RigServer

    with RigServer(card, truth, port=0, heartbeat=0.3) as srv:
        c = Client(srv.address)
        try:
            c.configure()
            c.start(*trajectory())
            c.fetch(10)
            time.sleep(1.0)  # a frozen client: no command at all
            assert not srv.controller.voltage_on
            state = c.q("STAT?")
            assert state.startswith("ABORTED,") and "heartbeat 0.3 s" in state
        finally:
            c.close()


def test_the_rigs_own_computing_is_not_the_controllers_silence(truth, card, monkeypatch):
    """A FETC? whose block takes longer than the heartbeat to compute (the truth's physics without numba on
    a busy machine): the run goes on, and the heartbeat counts from the reply."""
    from rdea_lab.emulator import RigServer, rig as rig_module

    real = rig_module.EmulatedRig._compute_block

    def slow(self):
        time.sleep(0.8)  # longer than the 0.3 s heartbeat
        return real(self)

    monkeypatch.setattr(rig_module.EmulatedRig, "_compute_block", slow)
    with RigServer(card, truth, port=0, heartbeat=0.3) as srv:
        c = Client(srv.address)
        try:
            c.configure()
            c.start(*trajectory())
            c.fetch(10)  # computes a block: 0.8 s under the lock
            assert c.q("STAT?").split(",")[0] in ("RUNNING", "DONE")
            time.sleep(1.0)  # then a frozen client: the heartbeat still trips, 0.3 s after the last reply
            state = c.q("STAT?")
            assert state.startswith("ABORTED,") and "heartbeat 0.3 s" in state, state
        finally:
            c.close()


def test_rst_aborts_and_clears(server, client):
    client.configure()
    client.start(*trajectory())
    client.fetch(10)
    assert client.q("CONF:RATE 10").startswith('ERR -221,"settings conflict: CONF:RATE while RUNNING')
    assert client.q("*RST") == "OK"
    assert not server.controller.voltage_on
    assert client.q("STAT?") == 'IDLE,0,0,""'
    assert client.q("TRAJ:POIN?") == "0"
    assert client.q("LIM?") == "3000.0,2.0,50.0,80000000.0"  # nothing set: the rig's own limits are in force


def test_truth_query_identifies_the_data(truth, client):
    assert truth_from_mapping(json.loads(client.q("SYST:TRUTH?"))) == truth


def test_errors_for_bad_commands_and_the_server_lives_on(server, client):
    replies = {
        "FOO": 'ERR -113,"undefined header',
        "CONF:RATE abc": 'ERR -104,"\'abc\' is not a plain decimal number',
        "CONF:RATE 1e9": 'ERR -222,"sample rate 1e+09 Hz is outside 1 Hz to 100000 Hz"',
        "CONF:RATE": 'ERR -109,"missing parameter',
        "CONF:MEAS FORC,VOLT": 'ERR -224,"unknown channel \'VOLT\'',
        "LIM:STR 0.5": 'ERR -222,"LIM:STR 0.5 must be >= 1"',
        "FETC? -1": 'ERR -104,',
        "*IDN? please": 'ERR -108,"parameter not allowed',
        "TRAJ:STR 1,2,3": 'ERR -104,"TRAJ:STR takes a definite-length binary block',
    }
    for command, start in replies.items():
        assert client.q(command).startswith(start), command
    client.send(b"TRAJ:STR #216" + b"\x01" * 24 + b"\n")  # longer than announced
    assert client.line().startswith('ERR -161,"block longer than its header says')
    client.send(b"TRAJ:STR #212" + b"\x00" * 12 + b"\n")  # not whole float64 values
    assert client.line().startswith('ERR -161,"block of 12 bytes')
    client.send(b"\n\n")                                  # empty lines: no command, no reply
    assert client.q("*IDN?").startswith("rdea-lab,")
    assert client.q("SYST:ERR?").startswith('-113,"undefined header')
    # garbage, including a block header announcing gigabytes: the connection may close, the server lives
    rng = np.random.default_rng(0)
    junk = Client(server.address)
    try:
        for _ in range(20):
            junk.send(rng.integers(0, 256, 1000, dtype=np.uint8).tobytes() + b"\n")
        junk.send(b"TRAJ:STR #9999999999\n")
    except OSError:
        pass
    finally:
        junk.close()
    fresh = Client(server.address)
    assert fresh.q("*IDN?").startswith("rdea-lab,rig-emulator,")
    fresh.close()


def test_a_failing_handler_is_an_error_reply(server, client, monkeypatch):
    def boom(session, arg, block):
        raise RuntimeError("boom")

    monkeypatch.setitem(server.controller._commands, "*IDN?", (boom, False))
    assert client.q("*IDN?") == 'ERR -100,"RuntimeError: boom"'
    assert client.q("STAT?") == 'IDLE,0,0,""'


@pytest.mark.parametrize("server", [{"token": "s3cret-Token"}], indirect=True)
def test_token_required_first(server):
    c = Client(server.address)
    assert c.q("*IDN?").startswith('ERR -300,"token required') and c.closed()
    c = Client(server.address)
    assert c.q("SYST:AUTH wrong").startswith('ERR -300,"token required') and c.closed()
    c = Client(server.address)  # the token in clear is no answer: it never travels
    assert c.q("SYST:AUTH s3cret-Token").startswith('ERR -300,"token required') and c.closed()
    c = Client(server.address)
    assert c.auth("s3cret-Token") == "OK"
    assert c.q("*IDN?").startswith("rdea-lab,rig-emulator,")
    c.close()


def test_non_loopback_needs_a_token(card, truth):
    with pytest.raises(ValueError, match="not a loopback address, without a token"):
        RigServer(card, truth, host="0.0.0.0", port=0)
    with pytest.raises(ValueError, match="unknown fault 'melt'"):
        RigServer(card, truth, port=0, faults=[("melt", 1.0)])


def test_shutdown_turns_the_voltage_off(server, client):
    client.configure()
    client.start(*trajectory())
    client.fetch(500)
    assert server.controller.voltage_on
    server.shutdown()
    assert not server.controller.voltage_on
    assert (server.controller.state, server.controller.reason) == ("ABORTED", "server shut down")
    assert client.closed()


def test_pyvisa_session(card, truth, server):
    pyvisa = pytest.importorskip("pyvisa")
    rm = pyvisa.ResourceManager("@py")
    host, port = server.address
    inst = rm.open_resource(f"TCPIP::{host}::{port}::SOCKET", read_termination="\n", write_termination="\n",
                            timeout=5000)
    try:
        assert inst.query("*IDN?").startswith("rdea-lab,rig-emulator,specimen-2,")
        for command in ("*RST", "CONF:RATE 100.0", "CONF:MEAS FORC,CAP", "CONF:LENG 0.034",
                        "CONF:THIC 4.8e-05", "LIM:VOLT 3000.0", "LIM:STR 1.6", "LIM:FORC 50.0", "LIM:FIEL 80000000.0"):
            assert inst.query(command) == "OK", command
        x, v = trajectory()
        inst.write_binary_values("TRAJ:STR ", x, datatype="d", is_big_endian=False)
        assert inst.read() == "OK"
        inst.write_binary_values("TRAJ:VOLT ", v, datatype="d", is_big_endian=False)
        assert inst.read() == "OK"
        assert inst.query("ARM").startswith("OK,") and inst.query("INIT") == "OK"
        parts = []
        while True:
            data = inst.query_binary_values("FETC? 300", datatype="d", is_big_endian=False, container=np.array)
            if data.size == 0:   # the empty block #10
                break
            parts.append(data.reshape(-1, 8))
        assert inst.query("STAT?") == 'DONE,1001,1001,""'
        np.testing.assert_array_equal(np.concatenate(parts), expected_rows(card, truth, x, v))
    finally:
        inst.close()
        rm.close()


def test_connections_are_capped(truth, card):
    from rdea_lab.emulator import RigServer

    with RigServer(card, truth, port=0, max_connections=3) as srv:
        clients = [Client(srv.address) for _ in range(3)]
        try:
            for c in clients:
                assert c.q("*IDN?").startswith("rdea-lab,")
            extra = Client(srv.address)  # (it is read for an ABOR for a second first)
            assert extra.line().startswith('ERR -310,"too many connections: 3 already served') and extra.closed()
            clients[0].close()
            time.sleep(0.2)
            again = Client(srv.address)  # a place is free again
            assert again.q("*IDN?").startswith("rdea-lab,")
            again.close()
        finally:
            for c in clients[1:]:
                c.close()


def test_a_connection_that_does_not_authenticate_in_time_is_closed(truth, card):
    from rdea_lab.emulator import RigServer

    with RigServer(card, truth, port=0, token="a-long-enough-token-0123", auth_timeout=0.3) as srv:
        c = Client(srv.address)
        t0 = time.monotonic()
        assert c.closed()  # nothing sent: closed after the authentication timeout
        assert 0.2 < time.monotonic() - t0 < 3.0


def test_idle_connections_are_closed_but_not_the_controlling_one(truth, card):
    from rdea_lab.emulator import RigServer

    with RigServer(card, truth, port=0, idle_timeout=0.3) as srv:
        owner, onlooker = Client(srv.address), Client(srv.address)
        try:
            assert owner.q("CONF:RATE 100") == "OK"  # now it controls the rig
            assert onlooker.q("STAT?").startswith("IDLE")
            time.sleep(0.8)
            assert onlooker.closed()
            assert owner.q("CONF:RATE?") == "100.0"  # still served
        finally:
            owner.close()
