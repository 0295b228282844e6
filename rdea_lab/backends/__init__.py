"""Backends: executors of plans behind one interface (the twin, the rig driver).

Every executor speaks `Backend`: ``start(plan)``, ``read_block()``,
``abort(reason)`` (voltage off first), ``close()``. The run engine
(`rdea_lab.runs.execute`) checks a plan's limits before ``start``, for every
backend; `RigBackend` also sends them to the rig, which checks them again.

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

from .base import Backend, BackendFailure, PauseRefused, RunInterrupted
from .twin import TwinBackend

__all__ = ["Backend", "BackendFailure", "PauseRefused", "RunInterrupted", "TwinBackend"]
