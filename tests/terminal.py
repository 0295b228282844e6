"""Processes as if started at an interactive terminal, for the tests that send them Ctrl-C or SIGTERM.

A suite started in the background (``&`` in a non-interactive shell, some CI runners) inherits SIGINT ignored,
and Python then leaves it ignored: a process would not see Ctrl-C at all, which is the shell's doing, not the
program's (an ignored signal stays ignored, `rdea_lab.signals`). A signal mask is inherited too: a blocked
SIGTERM never arrives.
"""

import contextlib
import os
import signal

SIGNALS = {signal.SIGINT, signal.SIGTERM}


def as_at_a_terminal():
    """``preexec_fn`` of a child the test signals: SIGINT at its default (Python's KeyboardInterrupt once it
    starts), neither signal blocked."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)


def in_a_group_of_its_own():
    """`as_at_a_terminal`, in a process group of its own (the terminal's foreground group: Ctrl-C reaches every
    process in it, a study's workers too)."""
    os.setpgrp()
    as_at_a_terminal()


@contextlib.contextmanager
def this_process_at_a_terminal():
    """This process (main thread) for the block as `as_at_a_terminal` leaves a child: SIGINT caught by Python's
    handler, neither signal blocked; both put back after."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    mask = signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        signal.signal(signal.SIGINT, previous)
