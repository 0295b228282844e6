"""The emergency stop gets through whatever the server is doing; strangers cannot starve the server.

Against a `RigServer` on loopback, each load of the audit of issue 25: every connection slot taken, a
slowloris, a controller computing a 1e6-sample ``FETC?``, a realtime run at 100 kHz whose producer is
behind, a controller that never reads its replies. The latency of ``ABOR`` is measured from the wall clock
of this process (send to reply) and the voltage is read off the controller right after the reply.

The default suite checks that the stop is served and the voltage off, within 1 s (the audit measured 9.6 to
33 s, or never); the figures against the 50 ms of docs/rig-protocol.md, as medians and worst cases over
many tries, are the `slow` tests, run one at a time on a machine not busy with the rest of the suite, each
against a server in a process of its own (`ServerProcess`), as a rig server runs: the test session's
interpreter lock and garbage are not the server's.
"""

import gc
import hashlib
import hmac
import socket
import statistics
import threading
import time

import numpy as np
import pytest

from rdea_lab.emulator import RigServer

from .helpers import Client, ServerProcess

#: The e-stop guarantee of docs/rig-protocol.md [s].
ESTOP = 0.050
TOKEN = "a-token-of-sixteen-or-more"


def ramp(n):
    """Stretch and voltage setpoints for ``n`` samples: a slow stretch to 1.3 at 1 kV."""
    x = 1.0 + 0.3 * np.sin(np.linspace(0.0, np.pi / 2, n)) ** 2
    return x, np.full(n, 1000.0)


def running(address, n=2000, rate=1000.0, token=None):
    """A controlling client with a run of ``n`` samples going (INIT sent).

    Waits until the previous controller's connection is released (the server sees the close a moment
    after the client makes it): only then may a new connection configure the rig.
    """
    c = Client(address)
    if token:
        assert c.auth(token) == "OK"
    t0 = time.monotonic()
    while c.q("SYST:CTRL?") == "OTHER" and time.monotonic() - t0 < 5:
        time.sleep(0.01)
    c.configure(rate=rate)
    c.start(*ramp(n))
    return c


def abor(address, token=None) -> tuple[float, str]:
    """Connect, send ABOR (first line: no authentication needed), return (seconds to the reply, reply).

    This process's garbage collector waits while the clock runs. The time is the server's and the wire's,
    and, where a test drives a load from this process (a ``FETC?`` reader, a slowloris), its threads' too.
    """
    s = socket.create_connection(address, timeout=30)
    collecting = gc.isenabled()
    try:
        f = s.makefile("rb")
        gc.disable()
        t0 = time.perf_counter()
        s.sendall(b"ABOR\n")
        reply = f.readline()
        seconds = time.perf_counter() - t0
        return seconds, reply.decode().strip()
    finally:
        if collecting:
            gc.enable()
        s.close()


def _stop_and_check(srv, address, bound):
    seconds, reply = abor(address)
    assert reply == "OK"
    assert not srv.controller.voltage_on  # off by the time the reply is read
    assert seconds < bound, f"ABOR answered after {seconds * 1e3:.1f} ms"
    return seconds


def test_abor_is_served_with_every_slot_taken(card, quiet):
    with RigServer(card, quiet, port=0, max_connections=4) as srv:
        ctl = running(srv.address)
        idle = [Client(srv.address) for _ in range(3)]
        try:
            for c in idle:
                assert c.q("*IDN?").startswith("rdea-lab,")
            assert srv.controller.voltage_on
            _stop_and_check(srv, srv.address, 1.0)
            assert ctl.q("STAT?").startswith("ABORTED,")
            late = Client(srv.address)  # anything but ABOR beyond the cap: told so and closed
            assert late.q("*IDN?").startswith('ERR -310,"too many connections') and late.closed()
            late.close()
        finally:
            for c in [ctl, *idle]:
                c.close()


def test_abor_needs_no_token_but_rst_does(card, quiet):
    with RigServer(card, quiet, port=0, token=TOKEN) as srv:
        ctl = running(srv.address, token=TOKEN)
        try:
            stranger = Client(srv.address)
            assert stranger.q("*RST").startswith('ERR -300,"token required') and stranger.closed()
            assert srv.controller.voltage_on
            _stop_and_check(srv, srv.address, 1.0)
        finally:
            ctl.close()


def test_abor_during_a_million_sample_fetch(card, quiet):
    n = 1_000_000
    with RigServer(card, quiet, port=0) as srv:
        ctl = running(srv.address, n=n, rate=100e3)
        got = {}

        def fetch():
            got["rows"] = ctl.fetch(n)

        worker = threading.Thread(target=fetch)
        worker.start()
        time.sleep(0.3)  # the FETC? is computing
        try:
            _stop_and_check(srv, srv.address, 1.0)
            worker.join(30)
            assert not worker.is_alive()
            # the FETC? returned what was made, the rest of the run never is
            assert 0 < got["rows"].shape[0] < n
            other = Client(srv.address)
            assert other.q("STAT?").startswith("ABORTED,")
            other.close()
        finally:
            ctl.close()


def test_status_and_heartbeat_answer_during_a_long_fetch(card, quiet):
    n = 1_000_000
    with RigServer(card, quiet, port=0) as srv:
        ctl = running(srv.address, n=n, rate=100e3)
        worker = threading.Thread(target=lambda: ctl.fetch(n))
        worker.start()
        time.sleep(0.3)
        other = Client(srv.address)
        try:
            t0 = time.perf_counter()
            assert other.q("STAT?").startswith("RUNNING,")
            assert time.perf_counter() - t0 < 1.0
        finally:
            worker.join(60)
            other.close()
            ctl.close()


def test_a_controller_that_never_reads_is_cut_off_and_its_run_aborted(card, quiet):
    with RigServer(card, quiet, port=0, send_timeout=0.5) as srv:
        ctl = running(srv.address, n=1_000_000, rate=100e3)
        ctl.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        t0 = time.monotonic()
        for _ in range(20):  # ~10 MB of replies asked for, none read
            try:
                ctl.send("FETC? 20000")
            except OSError:
                break
        deadline = t0 + 10.0
        while srv.controller.voltage_on and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not srv.controller.voltage_on, "a client that does not read kept the voltage on"
        other = Client(srv.address)
        assert other.q("STAT?").startswith("ABORTED,")
        other.close()
        ctl.close()


def test_a_slowloris_is_closed_at_its_line_deadline(card, quiet):
    with RigServer(card, quiet, port=0, line_timeout=1.0, idle_timeout=60.0) as srv:
        s = socket.create_connection(srv.address, timeout=10)
        t0 = time.monotonic()
        closed_after = None
        try:
            for ch in b"*IDN" * 10:  # a byte every 0.2 s: never 2 s without one, never a whole line
                s.sendall(bytes([ch]))
                time.sleep(0.2)
        except OSError:
            closed_after = time.monotonic() - t0
        if closed_after is None:  # the server may close without the sends failing: read the EOF
            s.settimeout(5)
            assert s.recv(100) == b""
            closed_after = time.monotonic() - t0
        s.close()
        assert closed_after < 3.0, f"a byte every 0.2 s kept the connection {closed_after:.1f} s"


def test_unauthenticated_connections_hold_no_budget_and_no_slot(card, quiet):
    with RigServer(card, quiet, port=0, token=TOKEN, max_connections=2, max_upload_bytes=1 << 20) as srv:
        strangers = []
        for _ in range(2):
            s = socket.create_connection(srv.address, timeout=10)
            s.sendall(b"TRAJ:STR #7" + b"1000000")  # a block header: refused before authentication
            strangers.append(s)
        for s in strangers:
            s.settimeout(5)
            assert s.recv(200).startswith(b'ERR -300,"token required')
            s.close()
        ctl = Client(srv.address)
        assert ctl.auth(TOKEN) == "OK"
        ctl.configure()
        ctl.start(*ramp(1000))  # the upload is taken: nothing of the budget was held
        ctl.close()


def test_the_auth_window_is_a_deadline(card, quiet):
    with RigServer(card, quiet, port=0, token=TOKEN, auth_timeout=1.0) as srv:
        s = socket.create_connection(srv.address, timeout=10)
        t0 = time.monotonic()
        try:
            for _ in range(30):  # a byte every 0.2 s of a line that never ends
                s.sendall(b"S")
                time.sleep(0.2)
        except OSError:
            pass
        s.settimeout(5)
        try:
            while s.recv(200):
                pass
        except OSError:
            pass
        assert time.monotonic() - t0 < 3.0
        s.close()


def test_a_captured_answer_does_not_replay(card, quiet):
    with RigServer(card, quiet, port=0, token=TOKEN) as srv:
        first = Client(srv.address)
        nonce = first.q("SYST:AUTH?")
        answer = hmac.new(TOKEN.encode(), nonce.encode(), hashlib.sha256).hexdigest()
        assert first.q(f"SYST:AUTH {answer}") == "OK"
        again = Client(srv.address)  # the overheard line on a new connection, with or without a nonce first
        assert again.q(f"SYST:AUTH {answer}").startswith("ERR -300") and again.closed()
        again = Client(srv.address)
        assert len(again.q("SYST:AUTH?")) == 32
        assert again.q(f"SYST:AUTH {answer}").startswith("ERR -300") and again.closed()
        assert first.q("*IDN?").startswith("rdea-lab,")
        first.close()


def test_a_non_ascii_byte_before_a_hash_is_answered_once(card, quiet):
    with RigServer(card, quiet, port=0) as srv:
        c = Client(srv.address)
        c.send(b"\xd5#\n")
        assert c.line().startswith("ERR -101,")
        assert c.q("*IDN?").startswith("rdea-lab,")  # the next line is the next reply: one ERR only
        c.close()


def test_who_controls_the_rig(card, quiet):
    with RigServer(card, quiet, port=0) as srv:
        a, b = Client(srv.address), Client(srv.address)
        assert a.q("SYST:CTRL?") == "NONE"
        a.configure()
        assert (a.q("SYST:CTRL?"), b.q("SYST:CTRL?")) == ("THIS", "OTHER")
        a.close()
        b.close()


def test_a_token_the_protocol_cannot_carry_is_refused(card, quiet, tmp_path):
    from rdea_lab.specs import SpecError, read_token

    for bad in ("with#hash-sixteen-chars", "non-ascii-\u00e9-sixteen-chars"):
        path = tmp_path / "token"
        path.write_text(bad, encoding="utf-8")
        path.chmod(0o600)
        with pytest.raises(SpecError, match="allowed: printable ASCII"):
            read_token(path)
        with pytest.raises(ValueError, match="printable ASCII"):
            RigServer(card, quiet, port=0, token=bad)


# ------------------------------------------------------------------ the figures (slow)
def _latencies(srv, address, tries, make_run, load=None):
    out = []
    for _ in range(tries):
        ctl = make_run()
        try:
            if load is not None:
                load(ctl)
            out.append(_stop_and_check(srv, address, 1.0))
        finally:
            ctl.close()
        time.sleep(0.05)
    return out


def _report(name, seconds):
    med, worst = statistics.median(seconds), max(seconds)
    print(f"ABOR {name}: median {med * 1e3:.2f} ms, worst {worst * 1e3:.2f} ms over {len(seconds)}")
    assert worst <= ESTOP, f"{name}: worst {worst * 1e3:.1f} ms > {ESTOP * 1e3:.0f} ms"


@pytest.mark.slow
def test_estop_latency_with_every_slot_taken(card, quiet):
    with ServerProcess(card, quiet, max_connections=16) as srv:
        holders = [Client(srv.address) for _ in range(15)]
        try:
            for c in holders:
                assert c.q("*IDN?").startswith("rdea-lab,")
            _report("16 slots taken", _latencies(srv, srv.address, 30, lambda: running(srv.address)))
        finally:
            for c in holders:
                c.close()


@pytest.mark.slow
def test_estop_latency_with_slowloris(card, quiet):
    with ServerProcess(card, quiet, max_connections=16) as srv:
        stop = threading.Event()
        lorises = [socket.create_connection(srv.address) for _ in range(15)]

        def dribble():
            while not stop.is_set():
                for s in lorises:
                    try:
                        s.sendall(b"S")
                    except OSError:
                        pass
                stop.wait(0.5)

        t = threading.Thread(target=dribble, daemon=True)
        t.start()
        try:
            _report("slowloris", _latencies(srv, srv.address, 30, lambda: running(srv.address)))
        finally:
            stop.set()
            for s in lorises:
                s.close()


@pytest.mark.slow
def test_estop_latency_during_a_million_sample_fetch(card, quiet):
    n = 1_000_000
    with ServerProcess(card, quiet) as srv:
        def load(ctl):
            threading.Thread(target=lambda: _quietly(ctl.fetch, n), daemon=True).start()
            time.sleep(0.2)
        _report("during FETC? 1e6", _latencies(srv, srv.address, 15, lambda: running(srv.address, n, 100e3),
                                               load))


@pytest.mark.slow
def test_estop_status_and_heartbeat_during_a_realtime_run_at_100_kHz(card, quiet):
    with ServerProcess(card, quiet, realtime=True, heartbeat=2.0) as srv:
        seconds, status = [], []
        for _ in range(15):
            ctl = running(srv.address, n=500_000, rate=100e3)
            try:
                time.sleep(0.5)  # the producer falls behind at 100 kHz
                other = Client(srv.address)
                t0 = time.perf_counter()
                assert other.q("STAT?").split(",")[0] in ("RUNNING", "ABORTED", "DONE")
                status.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                assert ctl.q("SYST:BEAT") == "OK"
                status.append(time.perf_counter() - t0)
                other.close()
                seconds.append(_stop_and_check(srv, srv.address, 1.0))
            finally:
                ctl.close()
        _report("realtime 100 kHz", seconds)
        print(f"STAT?/SYST:BEAT realtime 100 kHz: median {statistics.median(status) * 1e3:.2f} ms, "
              f"worst {max(status) * 1e3:.2f} ms")
        assert max(status) < 0.25  # the lock is held for at most PRODUCE_SLICE (0.1 s) and a block

        # the heartbeat fires on time while the producer is behind: a silent controller is stopped
        ctl = running(srv.address, n=500_000, rate=100e3)
        t0 = time.monotonic()
        while srv.controller.voltage_on and time.monotonic() - t0 < 10:
            time.sleep(0.02)
        late = time.monotonic() - t0
        ctl.close()
        print(f"heartbeat 2 s under a 100 kHz realtime run: stopped after {late:.2f} s")
        assert 2.0 <= late < 2.6


def _quietly(fn, *args):
    """A load in a thread of its own, which ends where the test closes its connection: a read on the closed
    socket's file raises ValueError (seen once, in a slow step run beside other tests), a reset OSError."""
    try:
        fn(*args)
    except (OSError, ConnectionError, AssertionError, ValueError):
        pass
