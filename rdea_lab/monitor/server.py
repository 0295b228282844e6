"""The monitor's Bokeh server, started in this process (`bokeh.server.server.Server`).

Sessions are signed (a random key per start), so a session exists only through a page the server handed
out; with a viewing token every HTTP request must carry ``?token=`` (else 403), and the document of a session
without it holds nothing (`rdea_lab.monitor.app.refused_document`). Websocket origins are limited to the
bound address's (`rdea_lab.monitor.access.websocket_origins`).
"""

from __future__ import annotations

import asyncio
import secrets
import threading
from pathlib import Path

from bokeh.application import Application
from bokeh.application.handlers.function import FunctionHandler
from bokeh.server.auth_provider import AuthProvider
from bokeh.server.server import Server
from bokeh.server.views.ws import WSHandler
from tornado.ioloop import IOLoop
from tornado.web import RequestHandler

from ..specs import MODEL_CHOICES, SpecError
from .access import Access, Controls, check_bind, websocket_origins
from .app import make_document
from .hub import Hub

MODELS = MODEL_CHOICES  # su, 1r, 3r, cr, auto


class _Refused(RequestHandler):
    def get(self):
        self.set_status(403)
        self.set_header("Content-Type", "text/plain; charset=utf-8")
        self.finish("refused: this monitor needs ?token= with the token of its --token-file\n")


class _TokenAuth(AuthProvider):
    """Every HTTP request must carry ``?token=``; the websocket is let through to Bokeh, which accepts only
    a signed session token (handed out with a page, hence with the token) and rebuilds the session's
    request arguments from it, which `make_document` checks again."""

    def __init__(self, access: Access):
        self.access = access
        super().__init__()

    @property
    def get_user(self):
        def user(handler):
            if isinstance(handler, WSHandler):
                return "session"
            return "viewer" if self.access.may_view(handler.request.arguments) else None
        return user

    @property
    def login_url(self):
        return "/refused"

    @property
    def login_handler(self):
        return _Refused


class Monitor:
    """``rdea-lab monitor``: a live view of the runs below a folder, in the browser.

    Parameters
    ----------
    folder : path
        Followed recursively: every run in progress (its journal), and the catalogue of finished runs.
    port : int
        TCP port, 1 to 65535.
    bind : str
        Address to listen on; anything but loopback needs ``token``.
    token : str, optional
        Viewing token every page must carry (``?token=``).
    params : ParameterSet or path, optional
        The twin's predicted force beside every followed run's measured force.
    model : {"su", "1r", "3r", "cr", "auto"}
        The twin's model.
    on_session : callable, optional
        Called with each new page's `~rdea_lab.monitor.app.LiveView` (a benchmark's hook).

    Raises
    ------
    SpecError
        ``folder`` is no folder, a port out of range, a non-loopback ``bind`` without a token, an unknown
        model, a parameter file that cannot be read.
    """

    def __init__(self, folder=".", *, port: int = 5006, bind: str = "127.0.0.1", token: str | None = None,
                 params=None, model: str = "su", on_session=None):
        folder = Path(folder)
        if not folder.is_dir():
            raise SpecError("arguments", "DIR", f"{folder}: no such folder")
        if not isinstance(port, int) or not 1 <= port <= 65535:
            raise SpecError("arguments", "port", f"{port!r}; allowed: 1 to 65535")
        if model not in MODELS:
            raise SpecError("arguments", "model", f"{model!r}; allowed: {', '.join(MODELS)}")
        check_bind(bind, token)
        if params is not None:
            from ..specs import as_params
            from ..twin import simulate  # noqa: F401 - imported now, not in the page's first tick

            params = as_params(params)
        self.folder, self.port, self.bind = folder, port, bind
        self.access = Access(token)
        self.hub = Hub(folder, params, model)
        self.controls = Controls(self.access)
        self.on_session = on_session
        self.server: Server | None = None
        self._thread: threading.Thread | None = None

    @property
    def urls(self) -> tuple[str, str]:
        """``(view URL, control URL)``."""
        host = "127.0.0.1" if self.bind in ("0.0.0.0", "::") else self.bind
        return self.access.urls(host, self.port)

    def _document(self, doc) -> None:
        make_document(doc, self.hub, self.access, self.controls, self.on_session)

    def _make_server(self, io_loop) -> Server:
        kwargs = {}
        if self.access.token is not None:
            kwargs["auth_provider"] = _TokenAuth(self.access)
        return Server({"/": Application(FunctionHandler(self._document))}, io_loop=io_loop, port=self.port,
                      address=self.bind, allow_websocket_origin=websocket_origins(self.bind, self.port),
                      sign_sessions=True, secret_key=secrets.token_urlsafe(32), generate_session_ids=True,
                      num_procs=1, **kwargs)

    def serve_forever(self, stop: threading.Event | None = None) -> None:
        """Serve until Ctrl-C (KeyboardInterrupt in this thread) or ``stop`` is set; the server's event loop
        runs on a thread of its own, this thread waits (so that a signal reaches it at once)."""
        self.start()
        stop = stop or threading.Event()
        try:
            while not stop.wait(0.5):
                pass
        finally:
            self.stop()

    def start(self, timeout: float = 30.0) -> "Monitor":
        """Serve on a thread of its own (its own event loop); returns once listening."""
        ready, failed = threading.Event(), []

        def main():
            asyncio.set_event_loop(asyncio.new_event_loop())
            io_loop = IOLoop.current()
            try:
                self.server = self._make_server(io_loop)
                self.server.start()
            except OSError as exc:
                failed.append(SpecError("arguments", "port", f"cannot listen on {self.bind}:{self.port} "
                                        f"({exc.strerror or exc})"))
                ready.set()
                return
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                failed.append(exc)
                ready.set()
                return
            io_loop.add_callback(ready.set)
            io_loop.start()
            io_loop.close(all_fds=True)

        self._thread = threading.Thread(target=main, name="rdea-lab-monitor", daemon=True)
        self._thread.start()
        if not ready.wait(timeout):
            raise TimeoutError(f"the monitor did not start within {timeout:g} s")
        if failed:
            raise failed[0]
        return self

    def stop(self) -> None:
        """Stop serving (from any thread); the runs followed are not affected."""
        server = self.server
        if server is not None:
            def halt():
                server.stop()
                server.io_loop.stop()
            server.io_loop.add_callback(halt)
        if self._thread is not None:
            self._thread.join(10)
            self._thread = None
        self.close()

    def close(self) -> None:
        self.controls.close()
        self.hub.close()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


def monitor(folder=".", *, port: int = 5006, bind: str = "127.0.0.1", token: str | None = None, params=None,
            model: str = "su", open_browser: bool = True, echo=print) -> None:
    """Serve the live view of the runs below ``folder`` until Ctrl-C (`Monitor`'s arguments); prints the view
    URL and the control URL (the one that may pause, resume and abort runs) with ``echo``."""
    mon = Monitor(folder, port=port, bind=bind, token=token, params=params, model=model)
    view, control = mon.urls
    kept = _keep_control_url(control, port)
    echo(f"rdea-lab monitor: following the runs below {Path(folder).resolve()}")
    echo(f"  view:    {view}")
    echo(f"  control: {control}   (pause/resume/abort; keep it to yourself"
         + (f"; also in {kept}, readable by you only)" if kept else ")"))
    echo("  a closed page changes nothing for a run; Ctrl-C stops the monitor, not the runs")
    if open_browser:
        import webbrowser

        threading.Timer(0.5, webbrowser.open, args=(control,)).start()
    try:
        mon.serve_forever()
    finally:
        if kept is not None:
            kept.unlink(missing_ok=True)


def _keep_control_url(url: str, port: int) -> Path | None:
    """The control URL in ``$XDG_STATE_HOME/rdea-lab/monitor-<port>.url`` (``~/.local/state`` by default),
    mode 0600 in a 0700 folder, for as long as the monitor serves; None where it cannot be written."""
    import os

    base = Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state") / "rdea-lab"
    path = base / f"monitor-{port}.url"
    try:
        base.mkdir(parents=True, exist_ok=True, mode=0o700)
        path.unlink(missing_ok=True)  # a file of an earlier monitor (its mode unknown) is replaced, not reused
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(url + "\n")
    except OSError:
        return None
    return path


__all__ = ["MODELS", "Monitor", "monitor"]
