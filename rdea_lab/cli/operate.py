"""``rdea-lab pause|resume|abort RUN``: operate a run in progress from another terminal; and the question a
first Ctrl-C asks in ``rdea-lab run``."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

import click

from ..api import _cli as api
from .errors import EXIT_HELP

def _ask(action: str, run: str, reason: str, wait: float) -> None:
    state = api.request(run, action, reason, by=f"rdea-lab {action}", wait=wait)
    if state.get("refused"):
        raise api.ControlError(run, f"the run refused to {action}: {state['refused']}")
    if wait <= 0:
        click.echo(f"{run}: {action} asked")
        return
    said = state.get("state", "?") + (f" ({state['reason']})" if state.get("reason") else "")
    click.echo(f"{run}: {action} acted on; the run is {said}, {state.get('samples', '?')} samples")


_RUN = click.argument("run", type=click.Path())
_WAIT = click.option("--wait", type=click.FloatRange(0, 600), default=10.0, show_default=True,
                     help="Seconds to wait for the run to act on it (0: ask and return).")
_EPILOG = EXIT_HELP + " 2 also when no run is going at RUN, or it refused."


@click.command(epilog=_EPILOG)
@_RUN
@click.option("--reason", default="", help="Why (recorded in the dataset with the pause).")
@_WAIT
def pause(run, reason, wait):
    """Pause a run in progress: the voltage to 0 at its protocol's ramp rate, the stretch held.

    The run keeps measuring while paused (its samples flagged ``paused`` in the dataset, with the reason);
    ``rdea-lab resume RUN`` goes back to the plan where it left it; ``rdea-lab abort RUN`` ends it, every
    sample kept. RUN is the run's dataset as ``rdea-lab run --out`` names it (or its journal folder,
    RUN.part); the run must be going.

    \b
    Example:
      rdea-lab pause datasets/long.nc --reason "look at the electrode"
    """
    _ask("pause", run, reason, wait)


@click.command(epilog=_EPILOG)
@_RUN
@click.option("--reason", default="", help="Why (recorded in the run's state).")
@_WAIT
def resume(run, reason, wait):
    """Resume a paused run: back to the plan's setpoints at the pause, then on with the plan.

    Refused while a suspender still holds the run (its condition has not cleared) or the rig's interlock is
    open. RUN is the run's dataset (or its journal folder, RUN.part).

    \b
    Example:
      rdea-lab resume datasets/long.nc
    """
    _ask("resume", run, reason, wait)


@click.command(epilog=_EPILOG)
@_RUN
@click.option("--reason", default="", help="Why (the dataset's status_reason).")
@_WAIT
def abort(run, reason, wait):
    """End a run in progress now: voltage off, status aborted, every sample kept.

    RUN is the run's dataset (or its journal folder, RUN.part).

    \b
    Example:
      rdea-lab abort datasets/long.nc --reason "electrode torn"
    """
    _ask("abort", run, reason, wait)


class AskOnCtrlC:
    """What a first Ctrl-C does in ``rdea-lab run`` on a terminal: pause the run and ask "resume or abort?".

    The answer is read from the terminal (``r`` resume, ``a`` abort); a second Ctrl-C while the question is
    open interrupts the run at once, voltage off, as a Ctrl-C always did. Called from the signal handler:
    it only asks the run to pause (`RunControl.pause`) and starts the reader; it never blocks.
    """

    def __init__(self, control, stream=None, echo=None):
        self.control = control
        self.stream = stream if stream is not None else sys.stdin
        self.echo = echo or (lambda text: click.echo(text, err=True))
        self.open = False
        self._lock = threading.Lock()

    def __call__(self) -> bool:
        with self._lock:
            if self.open:
                return False  # the second Ctrl-C: interrupt
            self.open = True
        request = self.control.pause("paused at the terminal (Ctrl-C)", by="Ctrl-C")
        self.echo("\nrdea-lab: pausing (voltage ramping to 0, stretch held). Type r + Enter to resume, a + Enter "
                  "to abort (every sample kept); Ctrl-C again interrupts at once.")
        threading.Thread(target=self._answer, daemon=True, name="rdea-lab ctrl-c question").start()
        threading.Thread(target=self._refused, args=(request,), daemon=True, name="rdea-lab ctrl-c pause").start()
        return True

    def _refused(self, request, wait: float = 5.0) -> None:
        """A pause the run refused (its plan driven to the end, a rig that will not): the Ctrl-C interrupts
        after all, as it did before it asked: the signal again, with the question open."""
        end = time.monotonic() + wait
        while time.monotonic() < end:
            done = self.control.outcome(request)
            if done is not None:
                if done.get("refused"):
                    self.echo(f"rdea-lab: the run did not pause ({done['refused']}): interrupting it")
                    os.kill(os.getpid(), signal.SIGINT)
                return
            time.sleep(0.02)

    def _answer(self) -> None:
        while True:
            line = self.stream.readline()
            if not line:  # the terminal closed: the run stays paused; Ctrl-C or rdea-lab resume/abort decide
                return
            word = line.strip().lower()
            if word in ("r", "resume"):
                self.control.resume("resumed at the terminal", by="Ctrl-C")
                self.echo("rdea-lab: resuming")
                break
            if word in ("a", "abort"):
                self.control.abort("aborted at the terminal after Ctrl-C", by="Ctrl-C")
                self.echo("rdea-lab: aborting")
                break
            self.echo("rdea-lab: r to resume, a to abort (Ctrl-C interrupts)")
        with self._lock:
            self.open = False
