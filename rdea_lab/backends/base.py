"""One small interface for every executor of a plan: the twin, the emulated rig, the real rig."""

from __future__ import annotations

from typing import Protocol, runtime_checkable


class BackendFailure(Exception):
    """The backend reports the run cannot go on (lost connection, breakdown, server abort)."""


class PauseRefused(RuntimeError):
    """The backend refused to pause or resume the run (the rig's message: not paused, the door interlock open,
    a rig that cannot pause); the run goes on as it was."""


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM during a run. A KeyboardInterrupt, not an Exception: no ``except Exception`` on
    the way (a driver's, pyvisa's) can take it for a lost connection."""


@runtime_checkable
class Backend(Protocol):
    """An executor of a :class:`~rdea_lab.protocols.Plan`.

    The engine calls ``start(plan)`` once, then ``read_block()`` until it
    returns None (the plan is done), and ``close()`` at the end. On any abort
    path (a limit, Ctrl-C, a lost connection, an error) it calls
    ``abort(reason)`` first, which must turn the voltage off before anything
    else. A block is a dict of equal-length arrays keyed by the schema's
    variable names (``time``, ``stretch``, ``position``, ``voltage``,
    ``force``, ``capacitance``, ``stretch_setpoint``, ``voltage_setpoint``,
    plus the backend's ``extra_variables``).
    """

    name: str
    extra_variables: tuple

    def attrs(self) -> dict:
        """Provenance for the dataset attributes (strings and numbers, no None)."""

    def start(self, plan) -> None:
        """Check the plan against the backend's own limits and begin."""

    def read_block(self) -> dict | None:
        """The next block of samples, or None when the plan is done."""

    def abort(self, reason: str) -> None:
        """Voltage to zero, motion stopped; safe to call more than once."""

    def close(self) -> None:
        """Release resources."""
