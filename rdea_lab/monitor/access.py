"""Who may see the monitor and who may operate a run from it.

Seeing: the monitor listens on 127.0.0.1 unless told otherwise; any other address needs a token (a file as
the rig server's, `rdea_lab.specs.read_token`), and then every page must carry ``?token=<token>``: a session
without it is refused (the HTTP request gets 403, and a document built anyway holds nothing).

Operating: the monitor makes a random secret when it starts and prints a control URL that carries it
(``?control=<secret>``). A session opened with it is the controller; every other session is a viewer, whose
pause, resume and abort buttons are disabled. The page is never trusted: `Controls.press`, the server-side
handler of those buttons, checks the session's secret again before it writes a request into the run's
journal folder (`rdea_lab.runs.control.request`). Comparisons are constant-time (`hmac.compare_digest`).

A page closed or lost changes nothing for the run: the run's heartbeat is the rig's (its process's driver
talking to the rig), not the page's.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
import socket
from concurrent.futures import Future, ThreadPoolExecutor

from ..emulator.server import is_loopback  # the rig server's rule: 127.0.0.0/8, ::1, localhost
from ..runs.control import ACTIONS, request
from ..specs import SpecError

#: Seconds a button's request waits for the run to say it acted (off the page's event loop).
CONTROL_WAIT = 10.0


def check_bind(bind: str, token: str | None) -> None:
    """Refuse to listen on an address other than loopback without a token.

    Raises
    ------
    SpecError
        ``bind`` is not a loopback address and no token is given (field ``bind``).
    """
    if token is None and not is_loopback(bind):
        raise SpecError("arguments", "bind", f"{bind} is not a loopback address; give --token-file so that only "
                        "pages with ?token= can see the runs (the default, 127.0.0.1, needs none)")


def websocket_origins(bind: str, port: int) -> list[str]:
    """The ``host:port`` origins a page may be loaded from (Bokeh's ``allow_websocket_origin``): the bound
    address, and for loopback ``localhost`` too; for a wildcard bind (0.0.0.0, ::) this machine's name, its
    fully qualified name and their addresses, each with the port."""
    hosts = {bind.strip("[]")}
    if is_loopback(bind):
        hosts |= {"localhost", "127.0.0.1"}
    try:
        wildcard = ipaddress.ip_address(bind.strip("[]")).is_unspecified
    except ValueError:
        wildcard = False
    if wildcard:
        hosts |= {"localhost", "127.0.0.1", socket.gethostname(), socket.getfqdn()}
        try:
            hosts |= {info[4][0] for info in socket.getaddrinfo(socket.gethostname(), None)}
        except OSError:
            pass
        hosts.discard(bind.strip("[]"))
    return sorted(f"[{h}]:{port}" if ":" in h else f"{h}:{port}" for h in hosts if h)


def _argument(arguments: dict, name: str) -> str | None:
    """One request argument (Bokeh gives lists of bytes, or of str after a round trip through its token)."""
    values = arguments.get(name) or []
    if not values:
        return None
    value = values[0]
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)


def _same(given: str | None, secret: str) -> bool:
    return given is not None and hmac.compare_digest(given.encode("utf-8"), secret.encode("utf-8"))


class Access:
    """The monitor's two secrets: the viewing token (None: none needed) and the control secret.

    Parameters
    ----------
    token : str, optional
        Every session must present it (``?token=``); required for a non-loopback bind.
    secret : str, optional
        The control secret; default a fresh ``secrets.token_urlsafe(24)``.
    """

    def __init__(self, token: str | None = None, secret: str | None = None):
        self.token = token
        self.secret = secret if secret is not None else secrets.token_urlsafe(24)

    def may_view(self, arguments: dict) -> bool:
        """Whether a session with these request arguments may see the runs."""
        return self.token is None or _same(_argument(arguments, "token"), self.token)

    def may_control(self, given: str | None) -> bool:
        """Whether ``given`` (a session's ``control`` argument) is the control secret."""
        return _same(given, self.secret)

    def role(self, arguments: dict) -> str:
        """``"refused"``, ``"controller"`` or ``"viewer"`` for a session's request arguments."""
        if not self.may_view(arguments):
            return "refused"
        return "controller" if self.may_control(_argument(arguments, "control")) else "viewer"

    def urls(self, host: str, port: int) -> tuple[str, str]:
        """``(view URL, control URL)`` for pages on ``host:port``."""
        shown = f"[{host}]" if ":" in host else host
        base = f"http://{shown}:{port}/"
        view = base + (f"?token={self.token}" if self.token else "")
        return view, view + ("&" if self.token else "?") + f"control={self.secret}"


class NotController(PermissionError):
    """A session without the control secret pressed a control (the page is not trusted)."""


class Controls:
    """The server-side handler of the pause, resume and abort buttons (one for all sessions).

    Parameters
    ----------
    access : Access
    wait : float
        Seconds each request waits for the run's answer [s] (`rdea_lab.runs.control.request`).
    """

    def __init__(self, access: Access, wait: float = CONTROL_WAIT):
        self.access, self.wait = access, wait
        self.pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="rdea-lab-monitor-control")

    def press(self, given: str | None, journal, action: str, reason: str = "") -> Future:
        """Send ``action`` to the run of ``journal`` for a session whose ``control`` argument was ``given``.

        Returns the future of `rdea_lab.runs.control.request` (run on a worker thread: the page stays live
        while the run answers); its result is the run's state after it acted.

        Raises
        ------
        NotController
            ``given`` is not the control secret: nothing is written.
        ValueError
            An action other than pause, resume, abort.
        """
        if not self.access.may_control(given):
            raise NotController("only the page opened with the control URL may pause, resume or abort a run")
        if action not in ACTIONS:
            raise ValueError(f"action {action!r}; allowed: {', '.join(ACTIONS)}")
        reason = reason.strip() or f"{action} from rdea-lab monitor"
        return self.pool.submit(request, journal, action, reason, by="monitor", wait=self.wait)

    def close(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)


__all__ = ["Access", "CONTROL_WAIT", "Controls", "NotController", "check_bind", "is_loopback", "websocket_origins"]
