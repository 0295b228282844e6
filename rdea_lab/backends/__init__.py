"""Backends: executors of plans behind one interface (the twin, the rig driver)."""

from .base import Backend, BackendFailure, RunInterrupted
from .twin import TwinBackend

__all__ = ["Backend", "BackendFailure", "RunInterrupted", "TwinBackend"]
