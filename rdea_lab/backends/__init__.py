"""Backends: executors of plans behind one interface (the twin, the rig driver).

Every executor speaks `Backend`: ``start(plan)``, ``read_block()``,
``abort(reason)`` (voltage off first), ``close()``. The run engine
(`rdea_lab.runs.execute`) checks a plan's limits before ``start``, for every
backend; `RigBackend` also sends them to the rig, which checks them again.

Quick start (the whole library: see `rdea_lab`)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")
"""

from .base import Backend, BackendFailure, RunInterrupted
from .twin import TwinBackend

__all__ = ["Backend", "BackendFailure", "RunInterrupted", "TwinBackend"]
