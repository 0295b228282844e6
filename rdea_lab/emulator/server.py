"""The rig emulator's TCP server: `RigController` behind ``docs/rig-protocol.md`` framing.

One thread per connection (``socketserver.ThreadingTCPServer``); every
command goes through one `RigController`, so there is one rig and one run
at a time. A connection that ends (closed, reset, server shut down) aborts a
run it drives: voltage off.
"""

from __future__ import annotations

import hmac
import ipaddress
import itertools
import socket
import socketserver
import threading

from .controller import CloseConnection, RigController, check_faults
from .framing import ByteBudget, CommandReader, ConnectionClosed, FramingError
from .truth import true_geometry

LOOPBACK_NAMES = ("localhost",)


def is_loopback(host: str) -> bool:
    """True for ``127.0.0.0/8``, ``::1`` and ``localhost``; anything else may be reachable."""
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


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
    faults : sequence of (str, float)
        Injected faults at a run time [s]: ``disconnect`` (the connection
        is closed), ``breakdown`` (dielectric breakdown), ``stall`` (no new
        samples, the rig keeps saying RUNNING).
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
        Block bytes held at once over all connections (a bound on memory).
    truth_source : str, optional
        Where `truth` came from, for messages.

    Raises
    ------
    ValueError
        A non-loopback `host` without a token, an empty token, a bad fault.
    SpecError
        The truth's radii factors do not fit the card.
    """

    def __init__(self, card, truth, host="127.0.0.1", port=5025, token=None, realtime=False, faults=(), *,
                 truth_source=None, limits=None, heartbeat=10.0, max_connections=16, auth_timeout=5.0,
                 idle_timeout=300.0, block_timeout=2.0, max_upload_bytes=256 * 2**20):
        if token is not None and (not isinstance(token, str) or not token.strip() or any(c.isspace() for c in token)):
            raise ValueError("the token must be a non-empty string without whitespace")
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
        self.block_timeout = block_timeout
        self._budget = ByteBudget(max_upload_bytes)
        self._server: _TCPServer | None = None
        self._thread: threading.Thread | None = None
        self._sessions: dict[int, socket.socket] = {}
        self._busy: set[int] = set()  # sessions executing or answering a command (see _drop_line)
        self._sessions_lock = threading.Lock()
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
        """Listen, and serve in a background thread; returns the bound ``(host, port)``."""
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
            full = len(self._sessions) >= self.max_connections
            if not full:
                self._sessions[session] = sock
        if full:  # a cap on connections (and so on threads): say so and close
            try:
                _send(sock, f'ERR -310,"too many connections: {self.max_connections} already served"')
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            return
        if self._closing:
            self._close_session(session)
        authenticated = self._token is None

        def idle():  # the controlling connection may be silent between runs; the heartbeat guards a run
            if not authenticated:
                return self.auth_timeout
            return None if self.controller.owner == session else self.idle_timeout

        reader = CommandReader(sock, idle=idle, budget=self._budget, block_timeout=self.block_timeout)
        try:
            while True:
                try:
                    text, block = reader.read_command()
                except FramingError as err:
                    if not authenticated:
                        _send(sock, 'ERR -300,"token required"')
                        break
                    _send(sock, f'ERR {err.code},"{err.message}"')
                    if err.fatal:
                        break
                    continue
                if not text.strip() and block is None:
                    continue  # an empty line is no command
                if not authenticated:
                    if not self._authenticates(text):
                        _send(sock, 'ERR -300,"token required"')
                        break
                    authenticated = True  # (the closure `idle` sees it)
                    _send(sock, "OK")
                    continue
                with self._sessions_lock:
                    self._busy.add(session)
                try:
                    try:
                        reply = self.controller.execute(session, text, block)
                    except CloseConnection:
                        break
                    _send(sock, reply)
                finally:
                    with self._sessions_lock:
                        self._busy.discard(session)
        except (ConnectionClosed, OSError):
            pass
        finally:
            reader.release()
            self.controller.session_closed(session)
            with self._sessions_lock:
                self._sessions.pop(session, None)
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def _authenticates(self, text: str) -> bool:
        header, _, arg = text.strip().partition(" ")
        return header.upper() == "SYST:AUTH" and hmac.compare_digest(arg.strip().encode(), self._token.encode())


def _send(sock: socket.socket, reply: str | bytes) -> None:
    data = reply if isinstance(reply, bytes) else reply.encode("ascii", "replace")
    sock.sendall(data + b"\n")


__all__ = ["RigServer", "is_loopback"]
