"""Runs: the engine that drives a backend and streams its samples into the store, and campaigns."""

from .campaign import experiments, run_campaign
from .engine import RunResult, execute, run_attrs

__all__ = ["RunResult", "execute", "experiments", "run_attrs", "run_campaign"]
