"""Helpers of the emulator tests: paths, a truth with other instrument values, a raw-socket client."""

import multiprocessing
import socket
from pathlib import Path

import zlib

import numpy as np

from rdea_lab.specs.truth import truth_as_mapping, truth_from_mapping

ROOT = Path(__file__).resolve().parents[2]

#: An amplifier this fast has exp(-2 pi f dt) == 0.0 at any rate <= 100 kHz: an ideal follower.
IDEAL_BANDWIDTH = "1e12 Hz"


def truth_with(truth, **instrument):
    """`truth` with some instrument values replaced (YAML strings with units)."""
    data = truth_as_mapping(truth)
    data["instrument"] = {**data["instrument"], **instrument}
    return truth_from_mapping(data)


def quiet_truth(truth):
    """`truth` without instrument effects (no noise, offset, drift, lag, parasitics; breakdown far away)
    and without the roll's effects beyond the models (`rdea_lab.emulator.roll`): the truth's model and
    material seen through ideal instruments."""
    quiet = truth_with(truth, force_noise="0 N", force_offset="0 N", force_drift="0 N/s", actuator_lag="0 s",
                       amplifier_bandwidth=IDEAL_BANDWIDTH, parasitic_capacitance="0 F", capacitance_noise="0 F",
                       breakdown_field="1e6 V/um")
    return quiet.model_copy(update={"effects": type(quiet.effects)()})


def block(values) -> bytes:
    data = np.asarray(values, "<f8").tobytes()
    n = str(len(data))
    return f"#{len(n)}{n}".encode() + data


class Client:
    """A raw-socket client of the rig command set."""

    def __init__(self, address, timeout=5.0):
        self.sock = socket.create_connection(address, timeout=timeout)
        self.file = self.sock.makefile("rb")

    def send(self, data: bytes | str) -> None:
        self.sock.sendall(data if isinstance(data, bytes) else data.encode() + b"\n")

    def line(self) -> str:
        raw = self.file.readline()
        if not raw:
            raise ConnectionError("closed by the server")
        return raw.decode().rstrip("\n")

    def q(self, command: str) -> str:
        self.send(command)
        return self.line()

    def upload(self, header: str, values) -> str:
        self.send(header.encode() + b" " + block(values) + b"\n")
        return self.line()

    width = 8  # columns of a row: 8, + 1 with CUR, + 1 with CONF:PAUS (`configure`)

    def fetch(self, n: int) -> np.ndarray:
        self.send(f"FETC? {n}")
        head = self.file.read(2)
        if len(head) < 2:
            raise ConnectionError("closed by the server")
        assert head[:1] == b"#", head
        size = int(self.file.read(int(head[1:2])))
        data = self.file.read(size)
        assert self.file.read(1) == b"\n"
        return np.frombuffer(data, "<f8").reshape(-1, self.width)

    def auth(self, token: str) -> str:
        """The challenge-response of docs/rig-protocol.md, written out here from the spec (not the
        server's own function): ``SYST:AUTH?`` gives a nonce; ``SYST:AUTH <hex HMAC-SHA256(token, nonce)>``."""
        import hashlib
        import hmac

        nonce = self.q("SYST:AUTH?")
        assert len(nonce) == 32 and int(nonce, 16) >= 0, nonce
        return self.q("SYST:AUTH " + hmac.new(token.encode(), nonce.encode(), hashlib.sha256).hexdigest())

    def closed(self) -> bool:
        """True if the server closed the connection (EOF); our end is then closed too."""
        if self.file.read(1) != b"":
            return False
        self.close()
        return True

    def close(self) -> None:
        self.file.close()
        self.sock.close()

    def configure(self, rate=100.0, meas="FORC,CAP", L1=0.034, L3=4.8e-05, volt=3000.0, stretch=1.6,
                  force=50.0, field=8e7, pause=None) -> None:
        """The settings of a run; `pause` ``(ramp_rate, hold_stretch or 0, stretch_rate)`` sends ``CONF:PAUS``."""
        for command in (f"CONF:RATE {rate!r}", f"CONF:MEAS {meas}", f"CONF:LENG {L1!r}", f"CONF:THIC {L3!r}",
                        f"LIM:VOLT {volt!r}", f"LIM:STR {stretch!r}", f"LIM:FORC {force!r}",
                        f"LIM:FIEL {field!r}"):
            reply = self.q(command)
            assert reply == "OK", f"{command}: {reply}"
        if pause is not None:
            command = "CONF:PAUS " + ",".join(repr(float(p)) for p in pause)
            assert self.q(command) == "OK", command
        self.sent = (rate, volt, stretch, force, field, L3, *(pause or ()))
        self.width = 8 + ("CUR" in meas.upper()) + (pause is not None)

    def start(self, x, v) -> None:
        assert self.upload("TRAJ:STR", x) == "OK"
        assert self.upload("TRAJ:VOLT", v) == "OK"
        assert self.q("ARM") == f"OK,{crc_of_what_was_sent(self.sent, x, v)}"
        assert self.q("INIT") == "OK"

    def drain(self, rows=100) -> np.ndarray:
        """Fetch until the run has ended and every sample is fetched."""
        out = []
        for _ in range(100_000):  # a stalled rig would loop forever
            got = self.fetch(rows)
            out.append(got)
            if got.shape[0] == 0:
                state = self.q("STAT?").split(",")[0]
                if state in ("DONE", "ABORTED"):
                    return np.concatenate(out)
        raise AssertionError("the run never ended")


def crc_of_what_was_sent(sent, x, v) -> str:
    """docs/rig-protocol.md's ARM checksum, computed here from what the client sent (not by the server's code):
    CRC-32 of rate, LIM:VOLT, LIM:STR, LIM:FORC, LIM:FIEL, CONF:THIC, the CONF:PAUS values when sent, then
    TRAJ:STR and TRAJ:VOLT, as <f8."""
    data = np.array(sent, "<f8").tobytes() + np.asarray(x, "<f8").tobytes() + np.asarray(v, "<f8").tobytes()
    return f"{zlib.crc32(data):08x}"


def _serve_apart(card, truth, options, pipe) -> None:
    """The child of `ServerProcess`: serve, answer ``"voltage_on"`` on the pipe, stop on ``"stop"``."""
    from rdea_lab.emulator import RigServer
    from rdea_lab.emulator.server import dedicate_process

    with RigServer(card, truth, port=0, **options) as srv:
        dedicate_process()  # as rdea-lab rig serve does once it listens
        pipe.send(srv.address)
        while True:
            request = pipe.recv()
            if request == "stop":
                break
            pipe.send(srv.controller.voltage_on)


class _RemoteController:
    def __init__(self, pipe):
        self._pipe = pipe

    @property
    def voltage_on(self) -> bool:
        self._pipe.send("voltage_on")
        return self._pipe.recv()


class ServerProcess:
    """A `RigServer` in a process of its own, started fresh (``spawn``), as ``rdea-lab rig serve`` runs it.

    What a latency figure measures is the server: served in the test's own process it would share the
    interpreter lock and the garbage collector with whatever the test session holds (after the other slow
    tests, a heap whose full collection may alone take longer than the e-stop budget: 0.24 s for 12 million
    objects here). Its heap is settled as ``rdea-lab rig serve`` settles it (`dedicate_process`).
    ``controller.voltage_on`` asks the server process, as `RigServer.controller` answers in
    process, a pipe's round trip later (about 0.1 ms).
    """

    def __init__(self, card, truth, **options):
        context = multiprocessing.get_context("spawn")
        self._pipe, child = context.Pipe()
        self._process = context.Process(target=_serve_apart, args=(card, truth, options, child), daemon=True)
        self._process.start()
        child.close()
        try:
            if not self._pipe.poll(120):
                raise EOFError
            self.address = tuple(self._pipe.recv())
        except EOFError:  # died while starting (its traceback is on its stderr), or did not answer in 2 min
            self._process.kill()
            self._process.join()
            self._pipe.close()
            raise RuntimeError(f"the rig server process did not start (exit code {self._process.exitcode})") \
                from None
        self.controller = _RemoteController(self._pipe)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        try:
            self._pipe.send("stop")
        except OSError:
            pass
        self._process.join(30)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()
        self._pipe.close()
