"""The built-in rig emulator: a specimen with its own "true" physics behind
instrument effects, served over the command set of ``docs/rig-protocol.md``.

`EmulatedRig` is the pure part (setpoints in, measured samples out);
`RigServer` puts it behind a TCP socket. The truth (model, material,
tolerances, instrument effects) is a `rdea_lab.specs.truth.TruthSpec`.

The server enforces its own limits (``LIM:*`` and ``ARM``), whatever a
client checked; it binds loopback unless it has a token.

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

from .conditions import Fault
from .controller import FAULTS, RigController, RigError
from .instruments import FirstOrderLag, lcr_bridge, load_cell, tau_of_bandwidth
from .rig import CHANNELS, COLUMNS, EmulatedRig, RunConfig, limit_violation
from .server import RigServer, is_loopback
from .truth import true_geometry

__all__ = [
    "CHANNELS", "COLUMNS", "FAULTS", "EmulatedRig", "Fault", "FirstOrderLag", "RigController", "RigError", "RigServer",
    "RunConfig", "is_loopback", "lcr_bridge", "limit_violation", "load_cell", "tau_of_bandwidth", "true_geometry",
]
