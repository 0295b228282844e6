"""Protocols: waveform segments and named presets expanded into setpoint plans.

``load_plan("protocols/blocking_force.yaml")`` reads a protocol (see
`rdea_lab.specs.protocol`), expands its preset, samples both channels into
read-only arrays and returns a `Plan`; `check_plan` lists every limit
violation, `first_violation` raises the first.

``as_plan`` takes a plan, a ProtocolSpec or a path.

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

from .plan import Plan, as_plan, check_plan, expand, first_violation, load_plan
from .presets import BUILDERS, expand_preset
from .segments import describe, end_value, evaluate, render

__all__ = [
    "BUILDERS", "Plan", "as_plan", "check_plan", "describe", "end_value", "evaluate", "expand", "expand_preset",
    "first_violation", "load_plan", "render",
]
