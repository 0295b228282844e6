"""The physics twin: a quasi-static model plus viscoelasticity over a time series.

- `predict` (history, params, model): the twin on a run's own stretch and
  voltage history (an xarray Dataset of a run, or arrays), as a Dataset on the
  same time coordinate; with ``protocol=`` the history is first checked against
  that protocol's limits.
- `simulate` (specimen, params, t, stretch, voltage, model): the same on bare arrays.
- `TwinStream`: block by block, carrying the viscoelastic state (the twin
  backend and the emulator use it).
- `TwinStep`: one sample per call, compiled, for a control loop.
- `compose`: the one composition of eqs. (43), (44) and (16) of [1].

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

from .curves import quasi_static_curves
from .predict import MIN_STRETCH, predict
from .simulate import TwinStream, as_geometry, compose, simulate, viscous
from .step import TwinStep

__all__ = ["MIN_STRETCH", "TwinStep", "TwinStream", "as_geometry", "compose", "predict", "quasi_static_curves",
           "simulate", "viscous"]
