"""Backends: executors of plans behind one interface, and the run engine."""

from .base import Backend
from .engine import BackendFailure, RunInterrupted, RunResult, execute
from .twin import TwinBackend

__all__ = ["Backend", "BackendFailure", "RunInterrupted", "RunResult", "TwinBackend", "execute"]
