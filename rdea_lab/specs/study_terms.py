"""The vocabulary of design studies (`rdea_lab.specs.study`): the variables a study may vary, the
metrics it may ask for, and the small frozen records a study is made of (variables, objectives,
constraints, a bias curve)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: variable -> (dimension, display unit, lower bound it must stay above (SI), upper sanity bound (SI))
VARIABLES = {
    "L1": ("length", "mm", 0.0, 10.0), "L1e": ("length", "mm", 0.0, 10.0), "L2": ("length", "mm", 0.0, 100.0),
    "L2e": ("length", "mm", 0.0, 100.0), "Lp1": ("length", "mm", -1e-300, 100.0),
    "Lp2": ("length", "mm", -1e-300, 100.0), "L3": ("length", "um", 0.0, 1e-2),
    "stiffness": ("stiffness", "N/m", -1e-300, 1e7), "preload": ("force", "N", -1e-300, 1e3),
    "mass": ("mass", "g", 0.0, 100.0), "prestretch": ("dimensionless", "", 1.0, 3.0),
    "voltage": ("voltage", "kV", -1e-300, 1e5), "C10": ("pressure", "kPa", 0.0, 1e9),
    "C20": ("pressure", "kPa", -1e9, 1e9), "C30": ("pressure", "kPa", -1e9, 1e9),
    "eps_r": ("dimensionless", "", 1.0, 100.0),
}
MEMBRANE = ("L1", "L1e", "L2", "L2e", "Lp1", "Lp2", "L3")
MATERIAL = ("C10", "C20", "C30", "eps_r")
BIAS_VARIABLES = {"none": (), "mass": ("mass", "prestretch"), "spring": ("stiffness", "preload", "prestretch"),
                  "curve": ()}
SAMPLINGS = ("sobol", "lhs", "grid")
#: the models a study solves over designs (`rdea_lab.physics.designs.DESIGN_MODELS`, which a test keeps equal)
DESIGN_MODELS = ("su", "1r", "3r", "cr")
#: metric -> (unit SI, display unit, description); `rdea_lab.design.evaluate` computes them
METRICS = {
    "stroke": ("m", "mm", "lengthening from the 0 V equilibrium with the bias to the one at the voltage"),
    "strain": ("1", "", "stroke / rest length"),
    "blocking_force": ("N", "N", "force lost at the rest length when the voltage is applied"),
    "work": ("J", "mJ", "work done on the bias over the stroke"),
    "energy_density": ("J/m^3", "kJ/m^3", "work per volume of elastomer"),
    "specific_energy": ("J/kg", "J/kg", "work per mass of elastomer (needs density)"),
    "field": ("V/m", "V/um", "nominal field V lambda1 lambda2 / L3 at the voltage"),
    "stress": ("Pa", "kPa", "largest axial stress of the two operating points"),
    "rest_stretch": ("1", "", "stretch of the 0 V equilibrium"),
    "on_stretch": ("1", "", "stretch of the equilibrium at the voltage"),
    "rest_force": ("N", "N", "force at the 0 V equilibrium"),
    "capacitance": ("F", "nF", "capacitance at the 0 V equilibrium"),
    "outer_radius": ("m", "mm", "outer radius of the roll (appendix of the paper)"),
    "volume": ("m^3", "mm^3", "elastomer volume 2 L1 L2 L3"),
    "mass": ("kg", "g", "elastomer mass (needs density)"),
    "preload": ("N", "N", "spring bias: its pull at the roll's rest length (a prestretch sets it)"),
    "bias_mass": ("kg", "g", "mass bias: its mass (a prestretch sets it)"),
    "peak_force": ("N", "N", "largest force over the protocol"),
    "force_range": ("N", "N", "largest minus smallest force over the protocol"),
    "hysteresis": ("J", "mJ", "net mechanical work done on the roll over the protocol, integral of F dx (the "
                   "energy dissipated where it ends as it began and at 0 V)"),
    "peak_field": ("V/m", "V/um", "largest nominal field over the protocol"),
    "peak_capacitance": ("F", "nF", "largest capacitance over the protocol"),
    "limit_field": ("V/m", "V/um", "the protocol's field estimate |v| sqrt(stretch) / L3 at its worst sample "
                    "(what its max_field limits)"),
}
PROTOCOL_METRICS = ("peak_force", "force_range", "hysteresis", "peak_field", "peak_capacitance", "limit_field")
DENSITY_METRICS = ("specific_energy", "mass")
_KEYS = ("name", "description", "model", "params", "specimen", "variables", "sampling", "voltage", "bias",
         "objectives", "constraints", "tolerances", "sensitivity", "optimize", "protocol", "chunk", "density")


@dataclass(frozen=True)
class Variable:
    """A design variable: SI bounds, the grid's levels, a log scale."""

    name: str
    low: float
    high: float
    levels: int = 5
    log: bool = False

    @property
    def unit(self) -> str:
        return VARIABLES[self.name][1]

    def from_unit(self, u):
        """Values at unit-cube coordinates ``u`` in [0, 1]."""
        u = np.asarray(u, float)
        if self.log:
            return np.exp(np.log(self.low) + u * (np.log(self.high) - np.log(self.low)))
        return self.low + u * (self.high - self.low)

    def to_unit(self, x):
        x = np.asarray(x, float)
        if self.log:
            return (np.log(x) - np.log(self.low)) / (np.log(self.high) - np.log(self.low))
        return (x - self.low) / (self.high - self.low)


@dataclass(frozen=True)
class Goal:
    """An objective: the metric and its sense (+1 maximize, -1 minimize)."""

    metric: str
    sense: int

    @property
    def label(self) -> str:
        return f"{'max' if self.sense > 0 else 'min'} {self.metric}"


@dataclass(frozen=True)
class Bound:
    """A constraint ``low <= metric <= high`` [SI] (either side may be open)."""

    metric: str
    low: float = -math.inf
    high: float = math.inf


@dataclass(frozen=True)
class CurveBias:
    """A user's bias curve: force [N] against the roll's extension ``(lambda1 - 1) L1`` [m]."""

    extension: np.ndarray
    force_values: np.ndarray
    kind: str = "curve"

    def force(self, stretch, L1):
        return np.interp((np.asarray(stretch, float) - 1.0) * L1, self.extension, self.force_values)


__all__ = ["BIAS_VARIABLES", "DENSITY_METRICS", "DESIGN_MODELS", "MATERIAL", "MEMBRANE", "METRICS", "PROTOCOL_METRICS",
           "SAMPLINGS", "VARIABLES", "Bound", "CurveBias", "Goal", "Variable"]
