"""Ctrl-C and SIGTERM as exceptions raised where they can be handled, and held where they cannot.

One class for the two places that need it: the run engine (while a run starts and acquires) and the CLI's
edge (a command's start-up and end). A signal raises its exception at once, unless

- the caller is closing (a dataset being written, the process about to exit): then it is recorded
  (`pending`) and the caller says so once it is done;
- it comes while Python runs code whose exceptions nobody can receive (a weakref or garbage-collector
  callback, a ``__del__``, a ctypes callback from compiled code such as llvmlite's while numba loads a
  kernel): Python would print "Exception ignored ..." and drop it, and the signal would be lost. Such an
  exception reaches `sys.unraisablehook`; the hook drops it silently and delivers the signal again 50 ms
  later instead.

A signal the caller ignores (SIG_IGN) stays ignored; handlers are installed from the main thread only.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

#: Seconds after which a signal whose exception was dropped (see above) is delivered again.
RETRY = 0.05


def signal_name(signum: int) -> str:
    """How a message names the signal: ``Ctrl-C`` or ``signal SIGTERM``."""
    return "Ctrl-C" if signum == signal.SIGINT else f"signal {signal.Signals(signum).name}"


@contextlib.contextmanager
def deferred():
    """SIGINT and SIGTERM recorded, not raised, while the block runs (a step that must not be cut in two: a
    journal being created, a cluster starting), then handed to the handler in place before it, as if they had
    come just after. Main thread only; an ignored or default handler is left alone."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got, previous = [], {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(sig)
        if callable(handler):  # Python's, the CLI's or the engine's
            previous[sig] = signal.signal(sig, lambda signum, frame: got.append(signum))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if got:
        previous[got[0]](got[0], None)


class Signals:
    """SIGINT and SIGTERM raise ``error(name)`` until `closing` is set; then they are recorded in `pending`.

    ``once``: the first signal also sets `closing` (the engine: after the first, the run is closing).
    ``first``: called for a SIGINT (never a SIGTERM) before anything else; when it returns True the signal
    was taken (the engine: a Ctrl-C that pauses the run and asks what next) and nothing is raised.
    """

    def __init__(self, error=KeyboardInterrupt, *, once=False, first=None):
        self.error = error
        self.once = once
        self.first = first
        self.closing = False
        self.pending = ""
        self._previous = {}
        self._hook = None

    def install(self) -> "Signals":
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous = signal.getsignal(sig)
                if previous is not signal.SIG_IGN:
                    self._previous[sig] = previous
                    signal.signal(sig, self._handle)
            if self._previous:
                self._hook = sys.unraisablehook
                sys.unraisablehook = self._unraisable
        return self

    def restore(self) -> None:
        for sig, previous in self._previous.items():
            signal.signal(sig, previous)
        self._previous = {}
        if self._hook is not None:
            sys.unraisablehook, self._hook = self._hook, None

    __enter__ = install

    def __exit__(self, *exc):
        self.restore()
        return False

    def hold(self) -> None:
        """The process is about to exit: block both signals for good (the interpreter's finalization puts the
        default handlers back, and a signal then would kill it with -2 or -15); one already pending is late."""
        wanted = {signal.SIGINT, signal.SIGTERM}
        self.closing = True
        try:
            signal.pthread_sigmask(signal.SIG_BLOCK, wanted)
            waiting = signal.sigpending() & wanted
        except (AttributeError, OSError):  # no POSIX signal masks here
            return
        if waiting and not self.pending:
            self.pending = signal_name(signal.SIGINT if signal.SIGINT in waiting else signal.SIGTERM)

    def _handle(self, signum, frame):
        if self.closing:
            self.pending = self.pending or signal_name(signum)
            return
        if self.first is not None and signum == signal.SIGINT and self.first():
            return
        if self.once:
            self.closing = True
        error = self.error(signal_name(signum))
        error.signum = signum
        raise error

    def _unraisable(self, unraisable) -> None:
        """Our exception, raised where Python drops it: say nothing, deliver the signal again shortly."""
        signum = getattr(unraisable.exc_value, "signum", None)
        if signum is None or not isinstance(unraisable.exc_value, self.error):
            (self._hook or sys.__unraisablehook__)(unraisable)
            return
        if self.once:
            self.closing = False
        timer = threading.Timer(RETRY, os.kill, (os.getpid(), signum))
        timer.daemon = True
        timer.start()
