"""Protocols: waveform segments and named presets expanded into setpoint plans.

``load_plan("protocols/blocking_force.yaml")`` reads a protocol (see
`rdea_lab.specs.protocol`), expands its preset, samples both channels into
read-only arrays and returns a `Plan`; `check_plan` lists every limit
violation, `first_violation` raises the first.

``as_plan`` takes a plan, a ProtocolSpec or a path.

Quick start (the whole library: see `rdea_lab`)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")
"""

from .plan import Plan, as_plan, check_plan, expand, first_violation, load_plan
from .presets import BUILDERS, expand_preset
from .segments import describe, end_value, evaluate, render

__all__ = [
    "BUILDERS", "Plan", "as_plan", "check_plan", "describe", "end_value", "evaluate", "expand", "expand_preset",
    "first_violation", "load_plan", "render",
]
