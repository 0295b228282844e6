"""Where a study's tasks run: a dask.distributed cluster (local or a lab's), or in-process.

`connect` gives a `distributed.Client`: to ``address`` (``tcp://HOST:PORT``,
or the ``DASK_SCHEDULER_ADDRESS`` environment variable), or to a new
`LocalCluster` on this machine (one single-threaded worker process per core,
bound to loopback, its dashboard on a free loopback port). ``synchronous``
runs every task in this process, one after the other (dask's synchronous
scheduler): for debugging and for the reference a test compares against.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import time

from ..signals import deferred
from ..specs.errors import UserError

#: seconds a scheduler has to answer
CONNECT_TIMEOUT = 3.0
_ADDRESS = re.compile(r"^(tcp|tls|ucx|inproc)://[^\s/:]+(:\d{1,5})?$")


class SchedulerError(UserError):
    """The scheduler address is malformed or nothing answers there (exit status 2)."""


class StudyAborted(RuntimeError):
    """The cluster lost the study's work: a worker died while it ran a task (killed, out of memory), or the
    data every task shares went with the workers that held it. The CLI: exit status 3, one line."""


def scheduler_address(given: str | None) -> str | None:
    """The address to connect to: ``given``, else ``DASK_SCHEDULER_ADDRESS``, else None (a local cluster)."""
    address = given or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if address is None:
        return None
    where = "--scheduler" if given else "DASK_SCHEDULER_ADDRESS"
    if address.startswith("synchronous") or not _ADDRESS.match(address):
        raise SchedulerError(f"{where}: {address!r} is not a scheduler address; give tcp://HOST:PORT "
                             "(e.g. tcp://10.0.0.5:8786)")
    return address


#: The loggers of dask.distributed and what it runs on, silenced while a client or cluster shuts down.
DASK_LOGGERS = ("distributed", "tornado", "asyncio", "bokeh")


def silence_dask() -> None:
    """No dask log record reaches stderr from now on: a client or cluster torn down early (Ctrl-C, an
    error) makes the scheduler report, at CRITICAL, every result it can no longer send (hundreds of lines
    of tracebacks after the one line that says what happened)."""
    import logging

    for name in list(logging.root.manager.loggerDict):
        if name.split(".")[0] in DASK_LOGGERS:
            logging.getLogger(name).disabled = True
    for name in DASK_LOGGERS:
        logging.getLogger(name).disabled = True


@contextlib.contextmanager
def connect(address: str | None = None, *, workers: int | None = None, quiet: bool = False):
    """A `distributed.Client` for the block: to ``address`` or to a new local cluster of ``workers``
    single-threaded processes (default: one per core). Prints where the dashboard is. A block that ends
    in an exception (Ctrl-C included) closes the client and the cluster with dask's logging silenced."""
    import logging

    from distributed import Client, LocalCluster

    for name in ("distributed", "distributed.worker", "distributed.scheduler", "distributed.nanny",
                 "bokeh", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL)  # what went wrong reaches the user as one exception
    given = address
    address = scheduler_address(address)
    if address is not None and workers:
        raise SchedulerError(f"workers: for a local cluster; the scheduler "
                             f"{'given' if given else 'of DASK_SCHEDULER_ADDRESS'} ({address}) has its own workers")
    if address is not None:
        t0 = time.monotonic()
        client = _client(Client, address)
        with client:
            if not quiet:
                n = len(client.scheduler_info().get("workers", {}))
                _say(f"dask: scheduler {address} ({n} workers, connected in {time.monotonic() - t0:.1f} s), "
                     f"dashboard {client.dashboard_link}")
            with _silenced_on_error():
                yield client
        return
    n = workers or os.cpu_count() or 1
    # dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, so glibc hands every freed buffer back to
    # the system: a task's tens of MB of numpy temporaries then fault in again page by page, and more than
    # half a worker's CPU went to the kernel (benchmarks/bench_design.py: 1e4 designs 34 s on 2 workers with
    # it, 13-14 s without). Our workers keep glibc's own threshold.
    import dask

    spawn = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    spawn.pop("MALLOC_TRIM_THRESHOLD_", None)
    # Ctrl-C reaches the terminal's whole process group, our workers with it: they leave it to this process,
    # which closes the cluster (each worker's own KeyboardInterrupt was a 30-line traceback)
    preload = [*dask.config.get("distributed.worker.preload", []), __name__]
    from distributed.deploy.spec import SpecCluster

    earlier = set(SpecCluster._instances)
    with contextlib.ExitStack() as stack:
        cluster = None
        try:
            with deferred():  # a signal as the cluster starts is taken once it has (and can be closed)
                # a worker that dies while it runs a task ends the study (StudyAborted), not the tasks' retries
                stack.enter_context(dask.config.set({"distributed.nanny.pre-spawn-environ": spawn,
                                                     "distributed.worker.preload": preload,
                                                     "distributed.worker.multiprocessing-method": "forkserver",
                                                     "distributed.scheduler.allowed-failures": 0}))
                _start_forkserver()
                cluster = stack.enter_context(LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                                           host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                                           silence_logs=logging.CRITICAL))
                client = stack.enter_context(Client(cluster, set_as_default=False))
        except BaseException:  # Ctrl-C as the cluster started, or it did not start
            silence_dask()
            for unstarted in set(SpecCluster._instances) - earlier - {cluster}:
                # dask's exit handler fails on it (a traceback after our line); its processes end with ours
                SpecCluster._instances.discard(unstarted)
            raise
        if not quiet:
            _say(f"dask: local cluster, {n} worker{'s' if n > 1 else ''}, dashboard {client.dashboard_link}")
        with _silenced_on_error():
            yield client


def _start_forkserver() -> None:
    """multiprocessing's fork server, with dask's preloads, started here with SIGINT ignored (if it is not
    running yet): an ignored signal stays ignored through exec, so the server and every worker it forks
    ignore Ctrl-C from their first instruction (a worker spawned from dask's threads had Python's handler,
    and a traceback for a Ctrl-C while it started). This process ignores SIGINT only while it forks the
    server (milliseconds: a Ctrl-C then is lost; press it again)."""
    import signal
    import threading
    from multiprocessing import forkserver

    from distributed.utils import get_mp_context

    get_mp_context()  # sets the fork server's preloads (distributed, numpy, ...)
    if threading.current_thread() is not threading.main_thread():
        forkserver.ensure_running()
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def _silenced_on_error():
    """The block; if it ends in an exception, dask's logging silenced before the client and cluster close,
    and the work the cluster lost (`lost_work`) raised as `StudyAborted`."""
    try:
        yield
    except BaseException as exc:
        silence_dask()
        lost = lost_work(exc)
        if lost:
            raise StudyAborted(lost) from None
        raise


def lost_work(exc: BaseException) -> str:
    """What the cluster lost, if ``exc`` says it lost work (a worker died running a task; a task cancelled
    because its shared data went with its workers), else ``""``."""
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    if isinstance(exc, KilledWorker):
        return (f"design: a dask worker died while it ran task {exc.task!r} (killed, or out of memory); the "
                "study stopped, nothing written")
    if isinstance(exc, FutureCancelledError):
        return (f"design: task {exc.key!r} was cancelled ({exc.reason.rstrip('.')}): the dask workers that held "
                "the study's shared data were lost (killed, or out of memory); the study stopped, nothing written")
    return ""


def dask_setup(worker) -> None:
    """In each worker process of our local cluster (a dask preload): SIGINT ignored, the client's process
    stops the cluster."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _client(Client, address):
    """A client to ``address`` within a hard deadline: something that accepts the connection but is no
    scheduler (a web server, the dashboard's port) can stall dask's handshake past its own timeout, and a
    stranger's reply can make it fail in any way; each is the user's address, not our bug."""
    import threading

    box = {}

    def attempt():
        try:
            box["client"] = Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except BaseException as exc:  # noqa: BLE001 (reported below, in one line)
            box["error"] = exc

    thread = threading.Thread(target=attempt, name="rdea-dask-connect", daemon=True)
    thread.start()
    thread.join(CONNECT_TIMEOUT + 2.0)
    if thread.is_alive() or "client" not in box:
        exc = box.get("error")
        _quiet_half_open_clients()
        why = "no reply" if exc is None else type(exc).__name__
        raise SchedulerError(f"scheduler {address}: no answer within {CONNECT_TIMEOUT:g} s ({why}); is a dask "
                             "scheduler running there and reachable (its port, not the dashboard's)?")
    return box["client"]


def _quiet_half_open_clients() -> None:
    """A client whose handshake failed tries to close itself when collected and reports its own timeout as
    an unraisable exception (a traceback after our one line): that one is dropped, any other shown."""
    previous = sys.unraisablehook

    def hook(unraisable):
        if getattr(getattr(unraisable, "object", None), "__qualname__", "") != "Client.__del__":
            previous(unraisable)

    sys.unraisablehook = hook


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


class Progress:
    """A one-line progress bar on stderr (redrawn in place on a terminal, a line per 10 % otherwise)."""

    def __init__(self, total: int, label: str, enabled: bool = True):
        self.total, self.label, self.enabled = total, label, enabled
        self.done = 0
        self.t0 = time.monotonic()
        self._tty = sys.stderr.isatty()
        self._shown = -1

    def update(self, k: int = 1) -> None:
        self.done += k
        if not self.enabled:
            return
        frac = self.done / max(self.total, 1)
        if not self._tty and int(frac * 10) == self._shown and self.done < self.total:
            return
        self._shown = int(frac * 10)
        bar = "#" * int(30 * frac)
        line = (f"{self.label} [{bar:<30}] {self.done}/{self.total} tasks, "
                f"{time.monotonic() - self.t0:.1f} s")
        print(("\r" if self._tty else "") + line, end="" if self._tty and self.done < self.total else "\n",
              file=sys.stderr, flush=True)
