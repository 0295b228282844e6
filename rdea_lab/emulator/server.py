"""The rig emulator's TCP server: `RigController` behind ``docs/rig-protocol.md`` framing.

One thread per connection (``socketserver.ThreadingTCPServer``); every
command goes through one `RigController`, so there is one rig and one run
at a time. A connection that ends (closed, reset, server shut down) aborts a
run it drives: voltage off.
"""

from __future__ import annotations

import gc
import hmac
import ipaddress
import itertools
import socket
import socketserver
import threading
import time

from .controller import CloseConnection, RigController, check_faults
from .framing import ByteBudget, CommandReader, ConnectionClosed, FramingError
from ..specs.rigwire import (BEFORE_AUTH, COMMANDS, TOKEN_REQUIRED, TOO_MANY_CONNECTIONS, auth_response, error_reply,
                             new_nonce)
from ..specs.tokens import check_token
from .truth import true_geometry

LOOPBACK_NAMES = ("localhost",)
#: Largest block payload an authenticated connection may send [bytes] (10 million float64).
MAX_BLOCK = 8 * 10_000_000
#: Longest line before authentication [bytes] (``SYST:AUTH`` and a 64-digit HMAC fit; no blocks).
PREAUTH_LINE = 128
#: Seconds a connection beyond the cap has to send its first line (served only if it is ``ABOR``).
OVERFLOW_TIMEOUT = 1.0
#: Connections beyond the cap read at once; more are refused without a read.
MAX_OVERFLOW = 64
#: Bytes sent at a time; each must leave within ``send_timeout``.
SEND_CHUNK = 1 << 18


def is_loopback(host: str) -> bool:
    """True for ``127.0.0.0/8``, ``::1`` and ``localhost``; anything else may be reachable."""
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def dedicate_process() -> int:
    """Settle the heap of a process that serves the rig and does nothing else (``rdea-lab rig serve``, which
    undoes it with `gc.unfreeze` when it stops serving).

    Call it once the server is started. It collects, then hands every object alive (the imports, the card,
    the truth, the model's compiled code: about 2e5 objects) to `gc.freeze`, which keeps them out of every
    later collection. A full collection then scans only what serving has made since.

    Why: a collection holds the interpreter lock while it runs, and an ``ABOR`` arriving then waits for it.
    Over the whole heap, a full collection takes longer than the 50 ms an emergency stop is given
    (docs/rig-protocol.md); the collector starts one on its own, when enough objects have outlived younger
    collections, so a rare stop was late by that much. Not for a process that goes on with other work (the
    in-process ``emulator`` backend): frozen objects are never collected, whatever becomes of them.

    Returns
    -------
    int
        The number of objects frozen.
    """
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


class _TCPServer(socketserver.ThreadingTCPServer):
    allow_reuse_address = True
    daemon_threads = False
    block_on_close = True

    def __init__(self, address, rig: "RigServer"):
        self.rig = rig
        family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.address_family = family
        super().__init__(address, _Handler)


class _Handler(socketserver.BaseRequestHandler):
    def handle(self):
        self.server.rig._serve_connection(self.request, self.client_address)


class RigServer:
    """The built-in rig emulator as a TCP server.

    Parameters
    ----------
    card : SpecimenCard
        The specimen on the emulated rig (its id is the ``*IDN?`` serial).
    truth : TruthSpec
        Its true physics and the instrument effects.
    host : str
        Address to bind; ``127.0.0.1`` by default. Any non-loopback address
        needs a `token`.
    port : int
        TCP port; 0 picks a free one (see `start`).
    token : str, optional
        When given, every connection must first send ``SYST:AUTH <token>``,
        else it gets ``ERR -300`` and is closed.
    realtime : bool
        Pace runs at wall-clock speed; default: virtual time (samples are
        made as fast as they are fetched).
    faults : sequence
        Injected faults at a run time [s], ``(kind, seconds)`` or `Fault`:
        ``disconnect`` (the connection is closed), ``breakdown`` (dielectric
        breakdown), ``stall`` (no new samples, the rig keeps saying RUNNING);
        and, for a duration (``(kind, seconds, duration)``) or to the end of
        the run, ``interlock`` (the door opens), ``overheat`` (the amplifier
        at 343 K), ``drift`` (the load cell's zero steps by 10 mN).
    limits : Limits, optional
        The rig's own hard limits, which no client can raise (default
        `rdea_lab.specs.Limits()`: 3 kV, stretch 2, 50 N, 80 V/um); the field is
        checked with the card's own thickness.
    heartbeat : float
        Seconds a run may go without a command from its controlling connection
        before the rig aborts it [s].
    max_connections : int
        Connections served at once; one more is told so and closed.
    auth_timeout : float
        With a token: seconds a new connection has to authenticate [s].
    idle_timeout : float
        Seconds a connection that does not control the rig may stay silent [s].
    block_timeout : float
        Seconds a block upload may go without a byte arriving [s] (a slow but
        steady upload is never cut off).
    max_upload_bytes : int
        Block bytes held at once over all connections (a bound on memory) [B].
    line_timeout : float
        Seconds a command line has to be whole after its first byte arrives [s].
    send_timeout : float
        Seconds a peer may take none of a reply before it is cut off [s].
    truth_source : str, optional
        Where `truth` came from, for messages.

    Raises
    ------
    ValueError
        A non-loopback `host` without a token, an empty token or one with spaces or '#', a port
        outside 0..65535, a bad fault.
    SpecError
        The truth's radii factors do not fit the card.
    """

    def __init__(self, card, truth, host="127.0.0.1", port=5025, token=None, realtime=False, faults=(), *,
                 truth_source=None, limits=None, heartbeat=10.0, max_connections=16, auth_timeout=5.0,
                 idle_timeout=300.0, block_timeout=2.0, max_upload_bytes=256 * 2**20, line_timeout=5.0,
                 send_timeout=2.0):
        if token is not None:
            check_token(token)
        if not is_loopback(host) and token is None:
            raise ValueError(f"refusing to listen on {host}, which is not a loopback address, without a token: "
                             "anyone who can reach it could drive the rig; give a token (rdea-lab rig serve "
                             "--token-file FILE)")
        if not (isinstance(port, int) and 0 <= port < 65536):
            raise ValueError(f"port {port!r} is not an integer 0..65535")
        check_faults(faults)
        true_geometry(card, truth, source=truth_source)  # refuse a truth that does not fit, before listening
        self.card, self.truth = card, truth
        self.host, self.port = host, port
        self._token = token
        self.controller = RigController(card, truth, realtime=realtime, faults=faults, truth_source=truth_source,
                                        close_session=self._drop_line, limits=limits, heartbeat=heartbeat)
        self.max_connections, self.auth_timeout, self.idle_timeout = int(max_connections), auth_timeout, idle_timeout
        self.block_timeout, self.line_timeout, self.send_timeout = block_timeout, line_timeout, send_timeout
        self._budget = ByteBudget(max_upload_bytes)
        self._server: _TCPServer | None = None
        self._thread: threading.Thread | None = None
        self._sessions: dict[int, socket.socket] = {}
        self._busy: set[int] = set()  # sessions executing or answering a command (see _drop_line)
        self._sessions_lock = threading.Lock()
        self._pending = 0  # connections waiting to authenticate (a token is set)
        self._overflowing = 0  # connections beyond the cap being read for an ABOR
        self._ids = itertools.count(1)
        #: connections accepted so far (a run refused before anything moves never connects)
        self.connections = 0
        self._closing = False
        self._serving = False

    # ------------------------------------------------------------ life
    def _bind(self) -> None:
        if self._server is None:
            self._server = _TCPServer((self.host, self.port), self)

    @property
    def address(self) -> tuple[str, int]:
        """The bound ``(host, port)`` (after `start` or `serve_forever`)."""
        if self._server is None:
            raise RuntimeError("the server is not listening yet; call start()")
        host, port = self._server.server_address[:2]
        return host, port

    def start(self) -> tuple[str, int]:
        """Listen, and serve in a background thread; returns the bound ``(host, port)``.

        Returns
        -------
        tuple of (str, int)
            The bound address: with ``port=0``, the free port picked.

        Raises
        ------
        OSError
            The address cannot be bound (in use, not this machine's).
        """
        self._bind()
        self._serving = True  # before the thread runs: a shutdown right after start must still stop it
        self._thread = threading.Thread(target=self.serve_forever, daemon=True, name="rig-emulator-server")
        self._thread.start()
        return self.address

    def serve_forever(self) -> None:
        """Listen and serve in this thread until `shutdown` (from another thread)."""
        self._bind()
        self._serving = True
        try:
            self._server.serve_forever(poll_interval=0.1)
        finally:
            self._serving = False

    def shutdown(self) -> None:
        """Voltage off (abort any run), stop listening, close every connection, join the threads."""
        self._closing = True
        self.controller.shutdown()
        if self._server is None:
            return
        if self._serving:
            self._server.shutdown()  # waits for serve_forever to return
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        with self._sessions_lock:
            sessions = list(self._sessions)
        for session in sessions:
            self._close_session(session)
        self._server.server_close()  # joins the connection threads
        self._server = None

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.shutdown()

    # ----------------------------------------------------- connections
    def _close_session(self, session) -> None:
        with self._sessions_lock:
            sock = self._sessions.get(session)
        if sock is None:
            return
        try:
            sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    def _drop_line(self, session) -> None:
        """The injected disconnect: close ``session``'s connection unless it is executing or answering a
        command (then the controller closes it at its next one), so no reply in flight is cut."""
        with self._sessions_lock:
            if session in self._busy:
                return
        self._close_session(session)

    def _serve_connection(self, sock: socket.socket, peer) -> None:
        session = next(self._ids)
        with self._sessions_lock:
            self.connections += 1
            if self._token is None:  # no token: every connection takes a slot at once
                admitted = len(self._sessions) < self.max_connections
                if admitted:
                    self._sessions[session] = sock
            else:  # a token: slots and budgets are for authenticated connections; strangers wait apart
                admitted = self._pending < self.max_connections
                if admitted:
                    self._pending += 1
        if not admitted:
            self._overflow(sock)
            return
        if self._closing:
            sock.close()
            return
        state = {"authenticated": self._token is None, "nonce": None, "slot": self._token is None,
                 "until": time.monotonic() + self.auth_timeout}

        def idle():  # the controlling connection may be silent between runs; the heartbeat guards a run
            if not state["authenticated"]:
                return max(0.0, state["until"] - time.monotonic())  # the auth window: a deadline from connecting
            return None if self.controller.owner == session else self.idle_timeout

        reader = CommandReader(sock, idle=idle, budget=None if self._token is not None else self._budget,
                               block_timeout=self.block_timeout, line_timeout=self.line_timeout,
                               max_block=0 if self._token is not None else MAX_BLOCK,
                               max_line=PREAUTH_LINE if self._token is not None else 4096)
        try:
            while True:
                try:
                    text, block = reader.read_command()
                except FramingError as err:
                    if not state["authenticated"]:
                        self._send(sock, error_reply(TOKEN_REQUIRED,
                                                     "token required: SYST:AUTH? then SYST:AUTH <HMAC>"))
                        break
                    self._send(sock, error_reply(err.code, err.message))
                    if err.fatal:
                        break
                    continue
                if not text.strip() and block is None:
                    continue  # an empty line is no command
                if not state["authenticated"]:
                    reply, done = self._preauth(session, text, state)
                    if reply is not None:
                        self._send(sock, reply)
                    if done:
                        break
                    if state["authenticated"]:  # now a slot, the budget and full-size lines and blocks
                        with self._sessions_lock:
                            self._pending -= 1
                            full = len(self._sessions) >= self.max_connections
                            if not full:
                                self._sessions[session] = sock
                                state["slot"] = True
                        if full:
                            self._send(sock, error_reply(TOO_MANY_CONNECTIONS, f"too many connections: "
                                                         f"{self.max_connections} already served (ABOR is served "
                                                         "on any connection)"))
                            break
                        self._send(sock, "OK")
                        reader.budget, reader.max_block, reader.max_line = self._budget, MAX_BLOCK, 4096
                    continue
                with self._sessions_lock:
                    self._busy.add(session)
                try:
                    try:
                        reply = self.controller.execute(session, text, block)
                    except CloseConnection:
                        break
                    self._send(sock, reply)
                finally:
                    with self._sessions_lock:
                        self._busy.discard(session)
        except (ConnectionClosed, OSError):
            pass
        finally:
            reader.release()
            self.controller.session_closed(session)
            with self._sessions_lock:
                if state["slot"]:
                    self._sessions.pop(session, None)
                elif self._token is not None and not state["authenticated"]:
                    self._pending -= 1
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def _preauth(self, session, text: str, state: dict) -> tuple[str | None, bool]:
        """A command before authentication: ``(reply, close)``. Served: ``ABOR`` (an emergency stop needs
        no credential), ``SYST:AUTH?`` (a fresh nonce), ``SYST:AUTH <mac>`` (the HMAC of that nonce)."""
        header, _, arg = text.strip().partition(" ")
        header = header.upper()
        refusal = error_reply(TOKEN_REQUIRED, "token required: SYST:AUTH? then SYST:AUTH <HMAC-SHA256 of the nonce>")
        if header not in COMMANDS or COMMANDS[header].access != BEFORE_AUTH:  # the protocol's table says which
            return refusal, True
        if header == "ABOR":
            return self.controller.execute(session, text), False
        if header == "SYST:AUTH?":
            state["nonce"] = new_nonce()
            return state["nonce"], False
        if header == "SYST:AUTH" and state["nonce"] is not None:
            nonce, state["nonce"] = state["nonce"], None  # one answer per nonce: a captured one does not replay
            if hmac.compare_digest(arg.strip().lower().encode("ascii", "replace"),
                                   auth_response(self._token, nonce).encode("ascii")):
                state["authenticated"] = True
                return None, False
        return refusal, True

    def _overflow(self, sock: socket.socket) -> None:
        """A connection beyond the cap: its first line is read (for at most `OVERFLOW_TIMEOUT` s) and served
        if it is ``ABOR``, the emergency stop no cap may refuse; anything else is told the cap and closed.
        Threads doing this are bounded too (`MAX_OVERFLOW`); past them a connection is refused at once."""
        with self._sessions_lock:
            served = self._overflowing < MAX_OVERFLOW
            if served:
                self._overflowing += 1
        refusal = error_reply(TOO_MANY_CONNECTIONS, f"too many connections: {self.max_connections} already served "
                                                    "(ABOR is served on any)")
        try:
            if served:
                until = time.monotonic() + OVERFLOW_TIMEOUT
                reader = CommandReader(sock, idle=lambda: max(0.0, until - time.monotonic()), max_block=0,
                                       max_line=PREAUTH_LINE, line_timeout=OVERFLOW_TIMEOUT)
                try:
                    text, _ = reader.read_command()
                except (FramingError, ConnectionClosed, OSError):
                    text = ""
                if text.strip().upper() == "ABOR":
                    self._send(sock, self.controller.execute(None, "ABOR"))
                    return
            self._send(sock, refusal)
        except OSError:
            pass
        finally:
            if served:
                with self._sessions_lock:
                    self._overflowing -= 1
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def _send(self, sock: socket.socket, reply: str | bytes) -> None:
        """Send one reply; a peer that takes none of it for `send_timeout` s is cut off (OSError): a client
        that does not read cannot stall its connection's thread (the connection ends; a run it drives
        aborts, voltage off)."""
        data = memoryview((reply if isinstance(reply, bytes) else reply.encode("ascii", "replace")) + b"\n")
        sock.settimeout(self.send_timeout)
        try:
            for i in range(0, len(data), SEND_CHUNK):  # the timeout per chunk: a slow reader is not cut off
                sock.sendall(data[i:i + SEND_CHUNK])
        finally:
            sock.settimeout(None)


__all__ = ["RigServer", "auth_response", "dedicate_process", "is_loopback"]
