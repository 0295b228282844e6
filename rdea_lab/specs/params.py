"""Material parameter sets: Yeoh coefficients, permittivity, viscoelastic branches.

YAML form (quantities with units)::

    name: paper2021-table3
    yeoh: {C10: 242 kPa, C20: -69 kPa, C30: 47 kPa}
    eps_r: 2.8
    viscoelastic: {branches: [{k: 8271 kPa, eta: 86 kPa s}], eta_v0: 0 kPa s}

`viscoelastic` is optional (no branches, ``eta_v0 = 0``); so are each of its
keys. ``law: linear`` (the default) is eq. (44) of [1], each branch a spring
``k`` and a damper ``eta``; ``law: finite_strain`` makes each branch a
neo-Hookean spring of shear modulus ``mu`` in series with a Newtonian dashpot
of shear viscosity ``eta`` (:mod:`rdea_lab.physics.viscoelastic`; at small
strain eq. (44) with ``k = 3 mu`` and ``eta = 3 eta``)::

    viscoelastic: {law: finite_strain, branches: [{mu: 2757 kPa, eta: 28.7 kPa s}]}
 The Python model is flat and SI: ``ParameterSet.C10`` [Pa], ...
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any, Literal

from pydantic import model_validator

from .base import Identifier, SpecModel
from .errors import SpecError
from .units import _dimension_of, format_quantity, parse_quantity, quantity

Pressure = quantity("pressure", "kPa")
Viscosity = quantity("viscosity", "kPa s")
Number = quantity("dimensionless", "")


def _kpa(value: float) -> str:
    return format_quantity(value, "kPa")


def _kpas(value: float) -> str:
    return format_quantity(value, "kPa s")


def yeoh_slope_nonpositive_at(C10: float, C20: float, C30: float) -> float | None:
    """Smallest ``x = I1 - 3 >= 0`` where the Yeoh slope stops being positive.

    The slope is ``dW/dI1 = C10 + 2 C20 x + 3 C30 x^2``; its first root on
    ``x >= 0`` is found in closed form (no sampling).

    Parameters
    ----------
    C10, C20, C30 : float
        Yeoh coefficients [Pa].

    Returns
    -------
    float or None
        ``x`` [-] where ``dW/dI1 <= 0`` first holds (0 if ``C10 <= 0``), or
        None if the slope stays positive for every ``x >= 0``.

    Notes
    -----
    The roots of ``3 C30 x^2 + 2 C20 x + C10`` are
    ``(-C20 +- sqrt(C20^2 - 3 C10 C30)) / (3 C30)``; the smaller non-negative
    one is written as ``C10 / (-C20 + sqrt(C20^2 - 3 C10 C30))`` (product of
    the roots), which has no cancellation for ``C20 < 0`` and also covers
    ``C30 = 0`` (``x = C10 / (-2 C20)``); for ``C30 < 0`` there is always one
    positive root (for ``C20 > 0`` taken as ``(C20 + sqrt(...)) / (-3 C30)``).
    """
    if C10 <= 0.0:
        return 0.0
    if C30 >= 0.0 and C20 >= 0.0:
        return None  # every term is non-negative and C10 > 0
    # sqrt(C20^2 - 3 C10 C30) without squaring C20 (no under/overflow)
    t = math.sqrt(3.0 * C10) * math.sqrt(abs(C30))
    if C30 < 0.0:
        root = math.hypot(C20, t)
        if C20 > 0.0:  # -C20 + root would cancel; use the other form of the root
            return (C20 + root) / (-3.0 * C30)
    else:  # C20 < 0
        if -C20 < t:
            return None  # C30 > 0 and the parabola's minimum stays above 0
        root = math.sqrt(-C20 - t) * math.sqrt(-C20 + t)
    return C10 / (-C20 + root)


def _branch_problems(k: float, eta: float, prefix: str, name: str = "k") -> list[tuple[str, str]]:
    problems = []
    if not math.isfinite(k) or k <= 0.0:
        what = "stiffness" if name == "k" else "shear modulus"
        problems.append((f"{prefix}{name}", f"{name} = {_kpa(k)} must be a finite {what} > 0 kPa"))
    if not math.isfinite(eta) or eta <= 0.0:
        problems.append((f"{prefix}eta", f"eta = {_kpas(eta)} must be a finite viscosity > 0 kPa s"))
    return problems


def material_problems(
    C10: float,
    C20: float,
    C30: float,
    eps_r: float,
    ks: Sequence[float] = (),
    etas: Sequence[float] = (),
    eta_v0: float = 0.0,
) -> list[tuple[str, str]]:
    """Every non-physical value in a material parameter set.

    Parameters
    ----------
    C10, C20, C30 : float
        Yeoh coefficients [Pa].
    eps_r : float
        Relative permittivity [-].
    ks : sequence of float
        Spring stiffness of each Maxwell branch [Pa].
    etas : sequence of float
        Damping of each Maxwell branch [Pa s].
    eta_v0 : float
        Parallel damping [Pa s].

    Returns
    -------
    list of (str, str)
        ``(field, message)`` per problem, in the order of the YAML form;
        fields like ``yeoh.C10``, ``eps_r``, ``viscoelastic.branches[0].eta``.
        Empty if the set is physical.

    Notes
    -----
    Rules: all finite; ``C10 > 0``; ``C30 >= 0``; the Yeoh slope
    ``dW/dI1 = C10 + 2 C20 x + 3 C30 x^2 > 0`` for every ``x = I1 - 3 >= 0``
    (see `yeoh_slope_nonpositive_at`), i.e. ``C20 > -sqrt(3 C10 C30)``
    (``C20 >= 0`` if ``C30 = 0``); ``eps_r >= 1``; ``k > 0``, ``eta > 0``,
    ``eta_v0 >= 0``.
    """
    problems: list[tuple[str, str]] = []
    yeoh = {"C10": C10, "C20": C20, "C30": C30}
    finite = {name: math.isfinite(value) for name, value in yeoh.items()}
    for name, value in yeoh.items():
        if not finite[name]:
            problems.append((f"yeoh.{name}", f"{name} = {value} must be a finite number"))
    if finite["C10"] and C10 <= 0.0:
        problems.append(("yeoh.C10", f"C10 = {_kpa(C10)} must be > 0 kPa (the small-strain shear modulus is 2 C10)"))
    if all(finite.values()) and C10 > 0.0 and C30 >= 0.0:
        x = yeoh_slope_nonpositive_at(C10, C20, C30)
        if x is not None:
            limit = format_quantity(-math.sqrt(3.0 * C10) * math.sqrt(C30), "kPa", digits=4)
            bound = "C20 >= 0 kPa" if C30 == 0.0 else f"C20 > -sqrt(3 C10 C30) = {limit}"
            problems.append((
                "yeoh.C20",
                f"C20 = {_kpa(C20)} is too negative for C10 = {_kpa(C10)}, C30 = {_kpa(C30)}: "
                f"the Yeoh slope dW/dI1 = C10 + 2 C20 x + 3 C30 x^2 turns non-positive at x = I1 - 3 = {x:.4g}, "
                f"so the energy stops increasing with stretch; need {bound}",
            ))
    if finite["C30"] and C30 < 0.0:
        problems.append((
            "yeoh.C30",
            f"C30 = {_kpa(C30)} must be >= 0 kPa: with C30 < 0 the Yeoh slope dW/dI1 = "
            "C10 + 2 C20 (I1 - 3) + 3 C30 (I1 - 3)^2 turns negative at large stretch",
        ))
    if not (math.isfinite(eps_r) and eps_r >= 1.0):
        problems.append(("eps_r", f"eps_r = {eps_r} must be a finite number >= 1 "
                                  "(a relative permittivity below 1 is not a dielectric)"))
    if len(ks) != len(etas):
        problems.append(("viscoelastic.branches", f"got {len(ks)} stiffnesses k and {len(etas)} dampings eta"))
    for i, (k, eta) in enumerate(zip(ks, etas)):
        problems += _branch_problems(k, eta, f"viscoelastic.branches[{i}].")
    if not (math.isfinite(eta_v0) and eta_v0 >= 0.0):
        problems.append(("viscoelastic.eta_v0", f"eta_v0 = {_kpas(eta_v0)} must be a finite viscosity >= 0 kPa s"))
    return problems


#: The viscoelastic laws (:mod:`rdea_lab.physics.viscoelastic`), and the name of each one's spring modulus.
LAWS = ("linear", "finite_strain")
MODULUS = {"linear": "k", "finite_strain": "mu"}


class ViscoBranch(SpecModel):
    """One Maxwell branch: a spring in series with a damper `eta` [Pa s].

    The spring is `k` [Pa] under the linear law (eq. (43)-(44) in [1]; Table 3
    calls them ``k_v1`` and ``eta_v1``) or a neo-Hookean spring of shear modulus
    `mu` [Pa] under the finite-strain law; a branch has exactly one of them.
    """

    k: Pressure | None = None
    mu: Pressure | None = None
    eta: Viscosity

    @model_validator(mode="after")
    def _physical(self) -> "ViscoBranch":
        if (self.k is None) == (self.mu is None):
            raise SpecError("", "k", "give the spring as k (law linear) or mu (law finite_strain), exactly one")
        for field, message in _branch_problems(self.modulus, self.eta, "", MODULUS[self.law]):
            raise SpecError("", field, message)
        return self

    @classmethod
    def of(cls, law: str, modulus: float, eta: float) -> "ViscoBranch":
        """A branch of ``law`` with spring modulus ``modulus`` (k or mu) [Pa] and damper ``eta`` [Pa s]."""
        return cls(**{MODULUS[law]: modulus, "eta": eta})

    def as_law(self, law: str) -> "ViscoBranch":
        """The same branch at small strain in `law`: ``k = 3 mu``, ``eta(44) = 3 eta`` (same relaxation time)."""
        if law == self.law:
            return self
        f = 1.0 / 3.0 if law == "finite_strain" else 3.0
        return ViscoBranch.of(law, self.modulus * f, self.eta * f)

    @property
    def law(self) -> str:
        """The law the branch's spring belongs to."""
        return "linear" if self.k is not None else "finite_strain"

    @property
    def modulus(self) -> float:
        """Spring modulus [Pa]: ``k`` or ``mu``."""
        return self.k if self.k is not None else self.mu

    @property
    def tau(self) -> float:
        """Relaxation time ``eta / k`` (or ``eta / mu``) [s]."""
        return self.eta / self.modulus


class ParameterSet(SpecModel):
    """A material parameter set, in SI.

    Attributes
    ----------
    name : str
        Letters, digits, ``-``, ``_``, ``.``.
    C10, C20, C30 : float
        Yeoh coefficients [Pa].
    eps_r : float
        Relative permittivity [-].
    law : {"linear", "finite_strain"}
        Viscoelastic law of the branches (eq. (44) of [1], or its finite-strain form).
    branches : tuple of ViscoBranch
        Maxwell branches (M = len(branches)), each with the spring of `law`.
    eta_v0 : float
        Parallel damping [Pa s].
    description, source : str or None
        Free text; `source` says where the numbers come from.
    """

    _yaml_paths = {
        "C10": "yeoh.C10", "C20": "yeoh.C20", "C30": "yeoh.C30",
        "branches": "viscoelastic.branches", "eta_v0": "viscoelastic.eta_v0", "law": "viscoelastic.law",
    }

    name: Identifier
    C10: Pressure
    C20: Pressure
    C30: Pressure
    eps_r: Number
    law: Literal["linear", "finite_strain"] = "linear"
    branches: tuple[ViscoBranch, ...] = ()
    eta_v0: Viscosity = 0.0
    description: str | None = None
    source: str | None = None

    @model_validator(mode="after")
    def _physical(self) -> "ParameterSet":
        problems = material_problems(
            self.C10, self.C20, self.C30, self.eps_r,
            [b.modulus for b in self.branches], [b.eta for b in self.branches], self.eta_v0,
        )
        if problems:
            raise SpecError("", *problems[0])
        for i, b in enumerate(self.branches):
            if b.law != self.law:
                raise SpecError("", f"viscoelastic.branches[{i}].{MODULUS[b.law]}",
                                f"a {MODULUS[b.law]} spring under law {self.law}; the branches of law {self.law} "
                                f"give {MODULUS[self.law]} (and eta)")
        return self

    @property
    def M(self) -> int:
        """Number of Maxwell branches (viscoelastic model order)."""
        return len(self.branches)

    def replace(self, **changes: Any) -> "ParameterSet":
        """A new, validated set with some fields changed (SI numbers).

        Raises
        ------
        SpecError
            Unknown field, or the new set is not physical.
        """
        data = {name: getattr(self, name) for name in type(self).model_fields}
        data.update(changes)
        return type(self)(**data)

    spec_kind = "params"

    @classmethod
    def _from_form(cls, mapping: dict, source: str) -> "ParameterSet":
        """The set from its file's form (``yeoh``, ``viscoelastic`` sections; a ``calibration`` record is
        read by `rdea_lab.specs.record.CalibrationRecord.of_file`, not kept in the set)."""
        f = _ParamsFile.from_yaml_mapping(dict(mapping), source)
        try:
            return cls(
                name=f.name, description=f.description, source=f.source,
                C10=f.yeoh.C10, C20=f.yeoh.C20, C30=f.yeoh.C30, eps_r=f.eps_r,
                law=f.viscoelastic.law, branches=f.viscoelastic.branches, eta_v0=f.viscoelastic.eta_v0,
            )
        except SpecError as err:
            raise err.with_source(source) from None

    def _form(self) -> dict:
        """The YAML form, each quantity in one fixed unit (moduli in kPa, viscosities in kPa s); read back
        equal (to the last digit but one at worst)."""
        data: dict[str, Any] = {"name": self.name}
        for key in ("description", "source"):
            if getattr(self, key) is not None:
                data[key] = getattr(self, key)
        data["yeoh"] = {k: _fixed(getattr(self, k), "kPa") for k in ("C10", "C20", "C30")}
        data["eps_r"] = self.eps_r
        data["viscoelastic"] = {
            "law": self.law,
            "branches": [{MODULUS[self.law]: _fixed(b.modulus, "kPa"), "eta": _fixed(b.eta, "kPa s")}
                         for b in self.branches],
            "eta_v0": _fixed(self.eta_v0, "kPa s"),
        }
        return data


# ------------------------------------------------------------- YAML form
class _Yeoh(SpecModel):
    C10: Pressure
    C20: Pressure
    C30: Pressure


class _Viscoelastic(SpecModel):
    law: Literal["linear", "finite_strain"] = "linear"
    branches: tuple[ViscoBranch, ...] = ()
    eta_v0: Viscosity = 0.0


class _ParamsFile(SpecModel):
    name: Identifier
    description: str | None = None
    source: str | None = None
    yeoh: _Yeoh
    eps_r: Number
    viscoelastic: _Viscoelastic = _Viscoelastic()
    #: a calibration record (rdea-lab calibrate): kept in the file, not part of the set
    calibration: dict | None = None


def params_from_mapping(mapping: Any, source: str = "<mapping>") -> ParameterSet:
    """`ParameterSet.from_mapping`: a parameter set given as a mapping in the YAML form."""
    return ParameterSet.from_mapping(mapping, source)


def params_from_yaml(text: str, source: str = "<string>") -> ParameterSet:
    """`ParameterSet.from_yaml`: a parameter set given as YAML text (e.g. a dataset attr)."""
    return ParameterSet.from_yaml(text, source)


def load_params(path: str | os.PathLike) -> ParameterSet:
    """`ParameterSet.load`: read and validate a parameter set YAML file.

    Parameters
    ----------
    path : str or path-like
        The YAML file; a path that does not exist may name a packaged reference file
        (``"paper2021_table3"``, ``"paper2021_table3.yaml"`` or ``"params/paper2021_table3.yaml"``).

    Returns
    -------
    ParameterSet
        Frozen, in SI units.
        A calibration record is a parameter set too (its ``calibration`` section is not part of the
        set: `rdea_lab.specs.record.CalibrationRecord.of_file` reads it).

    Raises
    ------
    SpecError
        The file is missing, too large, not YAML, not a mapping, or a value is invalid; one line naming
        the file, the field and what is allowed.
    """
    return ParameterSet.load(path)


def _fixed(value: float, unit: str) -> str:
    """``value`` always in ``unit``: the shortest digits that read back exactly, else 17 significant
    digits (then within one unit in the last place: a decimal in kPa cannot hit every float in Pa)."""
    text = format_quantity(value, unit)
    if not text.endswith(" " + unit):  # format_quantity fell back to the SI unit
        factor = parse_quantity(f"1 {unit}", _dimension_of(unit), source="", field="")
        text = f"{value / factor:.17g} {unit}"
    return text


def dump_params(ps: ParameterSet) -> str:
    """`ParameterSet.dump`: a parameter set as YAML with units (moduli in kPa, viscosities in kPa s)."""
    return ps.dump()


__all__ = [
    "LAWS", "MODULUS", "ParameterSet", "ViscoBranch", "dump_params", "load_params", "material_problems",
    "params_from_mapping", "params_from_yaml", "yeoh_slope_nonpositive_at",
]
