"""Truth files: the "true" specimen and instruments behind the rig emulator.

The emulator (`rdea_lab.emulator`) answers like a real rig: a roll whose
physics is beyond the models a user calibrates (a chosen model, a material
with branches of either viscoelastic law, radii off by a manufacturing
tolerance, and `Effects` no model has: passive electrode-free ends in series,
clamp compliance, Mullins softening, fringe capacitance; their physics in
`rdea_lab.emulator.roll`) seen through imperfect instruments. A truth file
says all of it, in YAML with units (``truth/paper2021.yaml`` argues each
magnitude)::

    name: paper2021-emulator
    model: cr                       # the true physics: su | 1r | 3r | cr
    yeoh: {C10: 242 kPa, C20: -69 kPa, C30: 47 kPa}
    eps_r: 2.8
    viscoelastic:
      law: finite_strain
      branches: [{mu: 2757 kPa, eta: 28.67 kPa s}, {mu: 200 kPa, eta: 300 kPa s}]
      eta_v0: 0 kPa s
    radii_factors: {Rie: 1.02, Roe: 0.985, Ro: 1.01}   # true radius = nominal x factor
    effects:                        # each off when left out
      passive_ends: true            # L1 - L1e without electrode, in series
      passive_stiffness: 1.0        # factor on their Yeoh coefficients
      clamp_compliance: 20 um/N     # clamps and load cell in series
      mullins: {max_softening: 0.05, energy_scale: 30 kPa}   # Ogden-Roxburgh
      fringe_capacitance: true      # Palmer's edge correction
    instrument:
      force_noise: 4 mN             # load-cell noise, standard deviation
      force_offset: 8 mN            # load-cell offset
      force_drift: 0.5 mN/min       # drift of the offset (default 0)
      actuator_lag: 4 ms            # first-order tracking lag of the linear actuator
      amplifier_bandwidth: 300 Hz   # first-order bandwidth of the HV amplifier
      parasitic_capacitance: 25 pF  # LCR parasitics, added to the true capacitance
      capacitance_noise: 0.5 pF
      breakdown_field: 100 V/um     # dielectric breakdown above this field estimate
      current_noise: 20 nA          # amplifier current monitor noise (default 20 nA)
      leakage_resistance: 100 Gohm  # through the film, electrode to electrode (default 100 Gohm)
    seed: 2021

The material part (``yeoh``, ``eps_r``, ``viscoelastic``) is a parameter set
(`rdea_lab.specs.params`) with the same checks; `TruthSpec.material` holds it.
Radii factors default to 1 (``Ri`` may be given too); whether the factored
radii stay ordered depends on the specimen card, so that is checked where the
two meet (`rdea_lab.emulator.true_geometry`).
"""

from __future__ import annotations

import json
import numbers
import os
from typing import Annotated, Any

import yaml
from pydantic import AfterValidator, BeforeValidator

from .base import Identifier, SpecModel
from .errors import SpecError, seed_problem, show
from .params import ParameterSet, _Viscoelastic, _Yeoh, dump_params, params_from_mapping
from .names import MODEL_CHOICES, MODELS  # noqa: F401  (MODEL_CHOICES re-exported)
from .units import format_quantity, quantity

#: Open interval a radius factor must lie in: a tolerance, not another roll.
FACTOR_RANGE = (0.5, 1.5)
_MATERIAL_KEYS = ("name", "description", "source", "yeoh", "eps_r", "viscoelastic")

Force = quantity("force", "mN", ge=0.0)
Time = quantity("time", "ms", ge=0.0)
Frequency = quantity("frequency", "Hz", gt=0.0)
Capacitance = quantity("capacitance", "pF", ge=0.0)
Field = quantity("electric_field", "V/um", gt=0.0)
Number = quantity("dimensionless", "")
Compliance = quantity("compliance", "um/N", ge=0.0, le=100e-6)
ForceRate = quantity("force_rate", "mN/min")
Energy = quantity("pressure", "kPa", gt=0.0)  # an energy density, J/m^3 = Pa
#: Current-monitor noise [A]: 0 (ideal) to 1 mA (more is not a monitor of a nF roll's uA currents).
CurrentNoise = quantity("current", "nA", ge=0.0, le=1e-3)
#: Leakage resistance [ohm]: 1 Mohm (a damaged film) to 1e18 ohm (none to speak of).
Resistance = quantity("resistance", "Gohm", ge=1e6, le=1e18)
#: Defaults of the current monitor, argued in `Instrument`.
CURRENT_NOISE, LEAKAGE_RESISTANCE = 20e-9, 100e9


def _in_factor_range(value: float) -> float:
    lo, hi = FACTOR_RANGE
    if not lo < value < hi:
        raise SpecError("", "", f"radius factor {value:g} is outside ({lo:g}, {hi:g}); a factor is a "
                                "manufacturing tolerance (true radius = nominal x factor), not another roll")
    return value


Factor = Annotated[Number, AfterValidator(_in_factor_range)]


def _model_name(value: Any) -> str:
    if not isinstance(value, str) or value.lower() not in MODELS:
        raise SpecError("", "", f"model {show(value)} is not one of {', '.join(MODELS)}")
    return value.lower()


ModelName = Annotated[str, BeforeValidator(_model_name)]


def _seed(value: Any) -> int:
    value = int(value) if isinstance(value, numbers.Integral) and not isinstance(value, bool) else value
    problem = seed_problem(value)
    if problem:
        raise SpecError("", "", problem)
    return value


Seed = Annotated[int, BeforeValidator(_seed)]


class RadiiFactors(SpecModel):
    """Manufacturing tolerance: true radius = nominal radius x factor, each in (0.5, 1.5)."""

    Ri: Factor = 1.0
    Rie: Factor = 1.0
    Roe: Factor = 1.0
    Ro: Factor = 1.0


#: Passive ends' stiffness factor: the same film give or take its electrode layers, not another material.
PASSIVE_STIFFNESS_RANGE = (0.5, 5.0)
#: Largest clamp compliance [m/N]: 1e4 N/m is already a soft clamp (a 10 N load cell is 5e4-1e5 N/m).
MAX_CLAMP_COMPLIANCE = 100e-6


def _stiffness_factor(value: float) -> float:
    lo, hi = PASSIVE_STIFFNESS_RANGE
    if not lo <= value <= hi:
        raise SpecError("", "", f"factor {value:g} is outside [{lo:g}, {hi:g}]: the passive ends are the same "
                                "film as the electroded zone, give or take its electrodes")
    return value


def _softening(value: float) -> float:
    if not 0.0 < value < 1.0:
        raise SpecError("", "", f"max_softening {value:g} is not in (0, 1): it is the fraction of the "
                                "stress lost at most on reloading (1/r of Ogden and Roxburgh)")
    return value


class Mullins(SpecModel):
    """Ogden-Roxburgh pseudo-elastic softening of the quasi-static force.

    ``F = eta F_virgin`` with ``eta = 1 - max_softening erf((W_max - W) / energy_scale)``,
    ``W`` the Yeoh energy density at the roll's stretch and ``W_max`` the
    largest so far in the run: 1 on the virgin (first) loading, lower on
    unloading and reloading below the previous maximum.

    Attributes
    ----------
    max_softening : float
        ``1/r`` of Ogden and Roxburgh (1999), in (0, 1).
    energy_scale : float
        ``m`` [J/m^3 = Pa], > 0.
    """

    max_softening: Annotated[Number, AfterValidator(_softening)]
    energy_scale: Energy


class Effects(SpecModel):
    """Physics of a real roll that no model of `rdea_lab.physics` has (each off by default).

    Attributes
    ----------
    passive_ends : bool
        The electrode-free ends ``L1 - L1e`` are their own zone in series with
        the electroded zone ``L1e`` (no Maxwell stress there; Assumption 3 of
        [1] smears the electrode over ``L1`` with ``alpha_e1`` instead).
    passive_stiffness : float
        Factor on the Yeoh coefficients of the passive ends, in [0.5, 5] (1: the same film).
    clamp_compliance : float
        Compliance of clamps and load cell in series with the roll [m/N], 0 (rigid) to
        100 um/N (1e4 N/m: a soft clamp; softer is another spring, not a clamp).
    mullins : Mullins or None
        First-cycle softening (None: none).
    fringe_capacitance : bool
        Palmer's (1937) edge correction on the electrodes' capacitance.
    """

    passive_ends: bool = False
    passive_stiffness: Annotated[Number, AfterValidator(_stiffness_factor)] = 1.0
    clamp_compliance: Compliance = 0.0
    mullins: Mullins | None = None
    fringe_capacitance: bool = False


class Instrument(SpecModel):
    """The rig's instrument effects, SI.

    Attributes
    ----------
    force_noise : float
        Load-cell noise, standard deviation [N], >= 0.
    force_offset : float
        Load-cell offset [N], >= 0.
    actuator_lag : float
        Time constant of the linear actuator's first-order tracking lag [s], >= 0.
    amplifier_bandwidth : float
        -3 dB bandwidth of the high-voltage amplifier, first order [Hz], > 0.
    parasitic_capacitance : float
        LCR bridge parasitics, added to the true capacitance [F], >= 0.
    capacitance_noise : float
        LCR bridge noise, standard deviation [F], >= 0.
    breakdown_field : float
        The membrane breaks down above this field estimate
        ``|v| sqrt(stretch) / L3`` [V/m], > 0.
    force_drift : float
        Drift of the load-cell offset [N/s] (0: none); the offset is
        ``force_offset + force_drift t`` with ``t`` from the run's start.
    current_noise : float
        Noise of the amplifier's current monitor, standard deviation per DAQ
        sample [A], 0 to 1 mA; 20 nA by default: a low-side shunt monitor
        (10 kohm, 16 bits over +-100 uA: 3 nA a bit, a few bits of noise),
        as self-sensing rigs use; an HV amplifier's own monitor is uA-class.
    leakage_resistance : float
        Resistance through the film, electrode to electrode [ohm], 1 Mohm to
        1e18 ohm; 100 Gohm by default: silicone's volume resistivity of about
        1e13 ohm m across 48 um over the 2 x 29 mm x 76 mm of electrode that
        faces film in a roll (specimen 2) gives 1.1e11 ohm.
    """

    force_noise: Force
    force_offset: Force
    actuator_lag: Time
    amplifier_bandwidth: Frequency
    parasitic_capacitance: Capacitance
    capacitance_noise: Capacitance
    breakdown_field: Field
    force_drift: ForceRate = 0.0
    current_noise: CurrentNoise = CURRENT_NOISE
    leakage_resistance: Resistance = LEAKAGE_RESISTANCE


class TruthSpec(SpecModel):
    """What the emulated rig really is (see the module docstring).

    Attributes
    ----------
    name : str
        Letters, digits, ``-``, ``_``, ``.``.
    model : str
        The true quasi-static physics, ``"su"``, ``"1r"``, ``"3r"`` or ``"cr"``.
    material : ParameterSet
        The true material (named like the truth).
    radii_factors : RadiiFactors
        True radius = nominal radius x factor.
    effects : Effects
        Physics beyond every model (passive ends, clamp compliance, Mullins, fringe capacitance).
    instrument : Instrument
    seed : int
        Seed of the emulator's noise, >= 0 (0 if not given).
    description, source : str or None
        Free text.
    """

    name: Identifier
    model: ModelName
    material: ParameterSet
    radii_factors: RadiiFactors = RadiiFactors()
    effects: Effects = Effects()
    instrument: Instrument
    seed: Seed = 0
    description: str | None = None
    source: str | None = None

    spec_kind = "truth"

    @classmethod
    def _from_form(cls, mapping: dict, source: str) -> "TruthSpec":
        """The truth from its file's form (the material's keys as in a parameter file)."""
        f = _TruthFile.from_yaml_mapping(dict(mapping), source)
        material = params_from_mapping({k: mapping[k] for k in _MATERIAL_KEYS if k in mapping}, source)
        try:
            return cls(name=f.name, description=f.description, source=f.source, model=f.model,
                             material=material, radii_factors=f.radii_factors, effects=f.effects,
                             instrument=f.instrument, seed=f.seed)
        except SpecError as err:
            raise err.with_source(source) from None

    def _form(self) -> dict:
        """The YAML form (quantities as strings with units)."""
        material = yaml.safe_load(dump_params(self.material))
        data: dict[str, Any] = {"name": self.name}
        for key in ("description", "source"):
            if getattr(self, key) is not None:
                data[key] = getattr(self, key)
        data["model"] = self.model
        data.update({k: material[k] for k in ("yeoh", "eps_r", "viscoelastic")})
        data["radii_factors"] = {k: getattr(self.radii_factors, k) for k in RadiiFactors.model_fields}
        e = self.effects
        data["effects"] = {"passive_ends": e.passive_ends, "passive_stiffness": e.passive_stiffness,
                           "clamp_compliance": format_quantity(e.clamp_compliance, "um/N"),
                           "fringe_capacitance": e.fringe_capacitance}
        if e.mullins is not None:  # omitted: none
            data["effects"]["mullins"] = {"max_softening": e.mullins.max_softening,
                                          "energy_scale": format_quantity(e.mullins.energy_scale, "kPa")}
        data["instrument"] = {k: format_quantity(getattr(self.instrument, k), unit)
                              for k, unit in _INSTRUMENT_UNITS.items()}
        # the current monitor's settings only where they differ from the defaults: the truth of a run
        # that does not record the current reads as it did before the current channel existed
        for key, unit, default in (("current_noise", "nA", CURRENT_NOISE), ("leakage_resistance", "Gohm",
                                                                             LEAKAGE_RESISTANCE)):
            if getattr(self.instrument, key) != default:
                data["instrument"][key] = format_quantity(getattr(self.instrument, key), unit)
        data["seed"] = self.seed
        return data


# ------------------------------------------------------------- YAML form
class _TruthFile(SpecModel):
    name: Identifier
    description: str | None = None
    source: str | None = None
    model: ModelName
    yeoh: _Yeoh
    eps_r: Number
    viscoelastic: _Viscoelastic = _Viscoelastic()
    radii_factors: RadiiFactors = RadiiFactors()
    effects: Effects = Effects()
    instrument: Instrument
    seed: Seed = 0


def truth_from_mapping(mapping: Any, source: str = "<mapping>") -> TruthSpec:
    """`TruthSpec.from_mapping`: a truth given as a mapping in the YAML form."""
    return TruthSpec.from_mapping(mapping, source)


def truth_from_yaml(text: str, source: str = "<string>") -> TruthSpec:
    """`TruthSpec.from_yaml`: a truth given as YAML text."""
    return TruthSpec.from_yaml(text, source)


def load_truth(path: str | os.PathLike) -> TruthSpec:
    """`TruthSpec.load`: read and validate a truth YAML file."""
    return TruthSpec.load(path)


_INSTRUMENT_UNITS = {
    "force_noise": "mN", "force_offset": "mN", "actuator_lag": "ms", "amplifier_bandwidth": "Hz",
    "parasitic_capacitance": "pF", "capacitance_noise": "pF", "breakdown_field": "V/um", "force_drift": "mN/min",
}


def truth_as_mapping(truth: TruthSpec) -> dict:
    """The YAML form of a truth (quantities as strings with units); `truth_from_mapping` reads it back equal."""
    return truth._form()


def dump_truth(truth: TruthSpec) -> str:
    """`TruthSpec.dump`: a truth as YAML with units; `load_truth` reads it back equal."""
    return truth.dump()


def truth_json(truth: TruthSpec) -> str:
    """The truth's YAML form as one line of ASCII JSON (for ``SYST:TRUTH?``)."""
    return json.dumps(truth_as_mapping(truth), separators=(",", ":"), ensure_ascii=True)


__all__ = [
    "FACTOR_RANGE", "Effects", "Instrument", "Mullins", "RadiiFactors", "TruthSpec", "dump_truth", "load_truth",
    "truth_as_mapping", "truth_from_mapping", "truth_from_yaml", "truth_json",
]
