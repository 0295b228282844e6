"""The built-in rig emulator: a specimen with its own "true" physics behind
instrument effects, served over the command set of ``docs/rig-protocol.md``.

`EmulatedRig` is the pure part (setpoints in, measured samples out);
`RigServer` puts it behind a TCP socket. The truth (model, material,
tolerances, instrument effects) is a `rdea_lab.specs.truth.TruthSpec`.

The server enforces its own limits (``LIM:*`` and ``ARM``), whatever a
client checked; it binds loopback unless it has a token.

Quick start (the whole library: see `rdea_lab`)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")
"""

from .controller import FAULTS, RigController, RigError
from .instruments import FirstOrderLag, lcr_bridge, load_cell, tau_of_bandwidth
from .rig import CHANNELS, COLUMNS, EmulatedRig, RunConfig, limit_violation
from .server import RigServer, is_loopback
from .truth import true_geometry

__all__ = [
    "CHANNELS", "COLUMNS", "FAULTS", "EmulatedRig", "FirstOrderLag", "RigController", "RigError", "RigServer",
    "RunConfig", "is_loopback", "lcr_bridge", "limit_violation", "load_cell", "tau_of_bandwidth", "true_geometry",
]
