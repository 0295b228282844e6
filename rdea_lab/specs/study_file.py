"""The checks of a design-study file (`rdea_lab.specs.study`), one validator per key of `_StudyFile`,
run in the file's order: each names the file, the field and what is allowed."""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from .errors import SpecError, show
from .params import load_params
from .protocol import load_protocol
from .specimen import SMALLEST_LENGTH, SMALLEST_THICKNESS, load_specimen
from .study_terms import (BIAS_VARIABLES, DENSITY_METRICS, DESIGN_MODELS, MEMBRANE, METRICS, PROTOCOL_METRICS,
                          SAMPLINGS, VARIABLES, Bound, CurveBias, Goal, Variable, _KEYS)
from .target import BIAS_KINDS, bias_from_mapping
from .units import _dimension_of, format_quantity, parse_quantity

def _mapping(value, source, where):
    if not isinstance(value, Mapping):
        raise SpecError(source, where, f"expected a mapping, got {show(value)}")
    return {str(k): v for k, v in value.items()}


def _int(value, source, where, low=1, high=10**7):
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise SpecError(source, where, f"{show(value)}; give a whole number from {low} to {high}")
    return value


def _variable(name, value, source) -> Variable:
    where = f"variables.{name}"
    if name not in VARIABLES:
        raise SpecError(source, where, f"unknown variable; allowed: {', '.join(VARIABLES)}")
    dim, unit, floor, ceiling = VARIABLES[name]
    opts = {}
    if isinstance(value, Mapping):
        opts = _mapping(value, source, where)
        unknown = set(opts) - {"range", "levels", "scale"}
        if unknown:
            raise SpecError(source, f"{where}.{sorted(unknown)[0]}", "unknown key; allowed: range, levels, scale")
        if "range" not in opts:
            raise SpecError(source, f"{where}.range", "missing; give [low, high] with units")
        value = opts["range"]
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise SpecError(source, where, f"{show(value)}; give a range [low, high] with units, e.g. "
                        f"[{'1' if not unit else '20 ' + unit}, {'2' if not unit else '60 ' + unit}]")
    low, high = (parse_quantity(v, dim, source=source, field=f"{where}[{i}]", example_unit=unit or None)
                 for i, v in enumerate(value))
    shown = f"[{format_quantity(low, unit)}, {format_quantity(high, unit)}]"
    if low > high:
        raise SpecError(source, where, f"inverted bounds {shown}; give [low, high] with low < high")
    if low == high:
        raise SpecError(source, where, f"empty range {shown}; give low < high (a fixed value belongs in the "
                        "specimen, params or study, not in variables)")
    if not low > floor or not high <= ceiling:
        raise SpecError(source, where, f"{shown} leaves the physical range ({format_quantity(max(floor, 0.0), unit)}"
                        f" exclusive to {format_quantity(ceiling, unit)}); check the units")
    if name in MEMBRANE:  # a membrane length the designs' cards carry: the card's own smallest (L3 = 1e-200 m
        # would divide by L3**2 = 0 in the electrical factor)
        tiny = SMALLEST_THICKNESS if name == "L3" else SMALLEST_LENGTH
        for i, x in enumerate((low, high)):
            if 0.0 < abs(x) < tiny:
                raise SpecError(source, f"{where}[{i}]", f"{format_quantity(x, unit)} is smaller than any real "
                                f"{name} ({format_quantity(tiny, unit)} at least, as in a specimen card); "
                                "check the unit")
    levels = _int(opts.get("levels", 5), source, f"{where}.levels", 2, 1000)
    scale = opts.get("scale", "linear")
    if scale not in ("linear", "log"):
        raise SpecError(source, f"{where}.scale", f"{show(scale)}; allowed: linear, log")
    if scale == "log" and not low > 0:
        raise SpecError(source, f"{where}.scale", "log needs a positive range")
    return Variable(name, low, high, levels, scale == "log")


def _goal(i, value, source) -> Goal:
    where = f"objectives[{i}]"
    value = _mapping(value, source, where)
    if len(value) != 1 or next(iter(value)) not in ("maximize", "minimize"):
        raise SpecError(source, where, f"{show(value)}; give {{maximize: METRIC}} or {{minimize: METRIC}}")
    sense, metric = next(iter(value.items()))
    if metric not in METRICS:
        raise SpecError(source, f"{where}.{sense}", f"unknown metric {show(metric)}; allowed: {', '.join(METRICS)}")
    return Goal(metric, 1 if sense == "maximize" else -1)


def _bound(metric, value, source) -> Bound:
    where = f"constraints.{metric}"
    if metric not in METRICS:
        raise SpecError(source, where, f"unknown metric; allowed: {', '.join(METRICS)}")
    value = _mapping(value, source, where)
    unknown = set(value) - {"min", "max"}
    if unknown or not value:
        raise SpecError(source, where, f"{show(value)}; give {{min: ...}}, {{max: ...}} or both, with units")
    si, _, _ = METRICS[metric]
    dim = _dimension_of(si)
    ex = METRICS[metric][1] or None
    sides = {k: parse_quantity(v, dim, source=source, field=f"{where}.{k}", example_unit=ex) for k, v in value.items()}
    low, high = sides.get("min", -math.inf), sides.get("max", math.inf)
    if low >= high:
        raise SpecError(source, where, f"min {low:g} >= max {high:g}: no value meets it")
    return Bound(metric, low, high)


def _resolve(folder: Path, rel, source, key, loader):
    if not isinstance(rel, str):
        raise SpecError(source, key, f"{show(rel)}; give a file path relative to the study")
    path = folder / rel
    if not path.is_file():
        raise SpecError(source, key, f"{show(rel)} not found (relative to {folder})")
    return loader(path), str(path)


def _bias(value, source):
    if value is None or value == "none":
        value = {"kind": "none"}
    value = _mapping(value, source, "bias")
    if value.get("kind") == "curve":
        unknown = set(value) - {"kind", "extension", "force", "units"}
        if unknown:
            raise SpecError(source, f"bias.{sorted(unknown)[0]}", "unknown key; allowed: extension, force, units")
        units = _mapping(value.get("units", {}), source, "bias.units")
        if set(units) - {"extension", "force"}:
            raise SpecError(source, f"bias.units.{sorted(set(units) - {'extension', 'force'})[0]}",
                            "unknown key; allowed: extension, force")
        cols = {}
        for key, dim in (("extension", "length"), ("force", "force")):
            raw = value.get(key)
            if not isinstance(raw, (list, tuple)) or len(raw) < 2:
                raise SpecError(source, f"bias.{key}", f"{show(raw)}; give a list of at least two values")
            unit = units.get(key)
            cols[key] = np.array([parse_quantity(f"{v} {unit}" if unit and not isinstance(v, str) else v, dim,
                                                 source=source, field=f"bias.{key}[{i}]")
                                  for i, v in enumerate(raw)])
        if cols["extension"].size != cols["force"].size:
            raise SpecError(source, "bias.force", f"{cols['force'].size} values for {cols['extension'].size} "
                            "extensions; give one force per extension")
        if np.any(np.diff(cols["extension"]) <= 0):
            raise SpecError(source, "bias.extension", "must increase strictly")
        return CurveBias(cols["extension"], cols["force"])
    if value.get("kind") not in (*BIAS_KINDS, "curve"):
        raise SpecError(source, "bias.kind", f"{show(value.get('kind'))}; allowed: {', '.join(BIAS_KINDS)}, curve")
    try:
        return bias_from_mapping(value, "bias")
    except SpecError as err:
        raise err.with_source(source) from None


#: a key the file does not give (``key:`` with nothing after it is given, as None)
_MISSING = object()


def _given(value) -> bool:
    return value is not _MISSING


class _StudyFile(BaseModel):
    """The study file's form. Each key's check runs in this order and sees the keys before it
    (``info.data``: only those that passed); `Study._from_form` reports the first problem. A check that
    needs a key which failed is skipped: that key's problem comes first. A plain pydantic model, not a
    `SpecModel`: its validators read the file's name and folder from pydantic's validation context, which
    `SpecModel`'s own ``__init__`` would drop."""

    model_config = ConfigDict(frozen=True, extra="forbid", validate_default=True, arbitrary_types_allowed=True)

    name: Any = None
    description: Any = None
    model: Any = "su"
    params: Any = None
    specimen: Any = None
    variables: Any = None
    sampling: Any = Field(default_factory=dict)
    voltage: Any = _MISSING
    bias: Any = None
    objectives: Any = None
    constraints: Any = Field(default_factory=dict)
    density: Any = _MISSING
    protocol: Any = _MISSING
    tolerances: Any = Field(default_factory=dict)
    sensitivity: Any = Field(default_factory=dict)
    optimize: Any = _MISSING
    chunk: Any = 256

    @model_validator(mode="before")
    @classmethod
    def _keys(cls, data: Any, info: ValidationInfo) -> dict:
        source = info.context["source"]
        data = {str(k): v for k, v in data.items()}
        unknown = sorted(set(data) - set(_KEYS))
        if unknown:
            raise SpecError(source, unknown[0], f"unknown key; allowed: {', '.join(_KEYS)}")
        for key in ("name", "params", "specimen", "variables", "objectives"):
            if key not in data:
                raise SpecError(source, key, "missing")
        return data

    @field_validator("name")
    @classmethod
    def _name(cls, name, info: ValidationInfo):
        if not isinstance(name, str) or not name.replace("-", "").replace("_", "").replace(".", "").isalnum():
            raise SpecError(info.context["source"], "name", f"{show(name)}; give letters, digits, '-', '_' or '.'")
        return name

    @field_validator("model")
    @classmethod
    def _model(cls, model, info: ValidationInfo):
        if model not in DESIGN_MODELS:
            raise SpecError(info.context["source"], "model", f"{show(model)}; allowed: {', '.join(DESIGN_MODELS)}")
        return model

    @field_validator("params")
    @classmethod
    def _params(cls, rel, info: ValidationInfo):
        return _resolve(info.context["folder"], rel, info.context["source"], "params", load_params)[0]

    @field_validator("specimen")
    @classmethod
    def _specimen(cls, rel, info: ValidationInfo):
        source = info.context["source"]
        card, _ = _resolve(info.context["folder"], rel, source, "specimen", load_specimen)
        if getattr(card, "membrane", None) is None:
            raise SpecError(source, "specimen", "the card gives no membrane; a study varies the unwound membrane "
                            "(give a card with membrane: L1, L2, L3, L1e, Lp1, L2e)")
        return card

    @field_validator("variables")
    @classmethod
    def _variables(cls, value, info: ValidationInfo):
        """The variables and the mapping they came from (its ``levels`` are checked against the sampling)."""
        source = info.context["source"]
        variables = _mapping(value, source, "variables")
        if not variables:
            raise SpecError(source, "variables", "empty; give at least one, e.g. L1: [20 mm, 60 mm]")
        var = tuple(_variable(k, v, source) for k, v in variables.items())
        names = {v.name for v in var}
        if names & {"C10", "C20", "C30"} and info.data.get("model", "su") == "1r":
            raise SpecError(source, "variables", f"{sorted(names & {'C10', 'C20', 'C30'})[0]}: the 1R branch "
                            "solver takes one material; vary Yeoh coefficients with model: su, 3r or cr")
        if {"L2", "L2e", "Lp1", "Lp2"} <= names:
            raise SpecError(source, "variables", "L2, L2e, Lp1 and Lp2: L2 = Lp1 + L2e + Lp2; vary three of them")
        return var, variables

    @field_validator("sampling")
    @classmethod
    def _sampling(cls, value, info: ValidationInfo):
        """``(method, n, seed)``."""
        source = info.context["source"]
        sampling = _mapping(value, source, "sampling")
        extra = set(sampling) - {"method", "n", "seed"}
        if extra:
            raise SpecError(source, f"sampling.{sorted(extra)[0]}", "unknown key; allowed: method, n, seed")
        method = sampling.get("method", "sobol")
        if method not in SAMPLINGS:
            raise SpecError(source, "sampling.method", f"{show(method)}; allowed: {', '.join(SAMPLINGS)}")
        if method == "grid":
            if "n" in sampling:
                raise SpecError(source, "sampling.n", "a grid's size is the product of its variables' levels; "
                                "give levels per variable instead")
            if "variables" not in info.data:
                return method, 0, 0
            n = int(np.prod([v.levels for v in info.data["variables"][0]]))
            if n > 10**7:
                raise SpecError(source, "variables", f"a grid of {n} designs; at most 1e7")
        else:
            n = _int(sampling.get("n", 256), source, "sampling.n", 2)
        return method, n, _int(sampling.get("seed", 0), source, "sampling.seed", 0, 2**32 - 1)

    @field_validator("voltage")
    @classmethod
    def _voltage(cls, value, info: ValidationInfo):
        source = info.context["source"]
        if _given(value):
            voltage = parse_quantity(value, "voltage", source=source, field="voltage", example_unit="kV")
            if not 0 <= voltage <= 1e5:
                raise SpecError(source, "voltage", f"{format_quantity(voltage, 'kV')}; give 0 to 100 kV")
            return voltage
        if "voltage" not in _names(info):
            raise SpecError(source, "voltage", "missing; give the operating voltage, e.g. 2.6 kV (or vary it)")
        return 0.0

    @field_validator("bias")
    @classmethod
    def _bias(cls, value, info: ValidationInfo):
        source = info.context["source"]
        bias = _bias(value, source)
        kind, names = bias.kind, _names(info)
        for v in info.data.get("variables", ((), {}))[0]:
            if v.name in ("stiffness", "preload", "mass", "prestretch") and v.name not in BIAS_VARIABLES[kind]:
                raise SpecError(source, f"variables.{v.name}", f"not a variable of a {kind} bias; allowed with it: "
                                f"{', '.join(BIAS_VARIABLES[kind]) or 'none'}")
        if "prestretch" in names and names & {"preload", "mass"}:
            raise SpecError(source, "variables.prestretch", "sets the preload (or mass) itself; vary one of them")
        return bias

    @field_validator("objectives")
    @classmethod
    def _objectives(cls, objectives, info: ValidationInfo):
        source = info.context["source"]
        if not isinstance(objectives, (list, tuple)) or not objectives:
            raise SpecError(source, "objectives", "give a list, e.g. [{maximize: stroke}]")
        return tuple(_goal(i, g, source) for i, g in enumerate(objectives))

    @field_validator("constraints")
    @classmethod
    def _constraints(cls, value, info: ValidationInfo):
        source = info.context["source"]
        return tuple(_bound(k, v, source) for k, v in _mapping(value, source, "constraints").items())

    @field_validator("density")
    @classmethod
    def _density(cls, value, info: ValidationInfo):
        if not _given(value):
            return None
        source = info.context["source"]
        density = parse_quantity(value, "density", source=source, field="density", example_unit="kg/m^3")
        if not 10.0 <= density <= 1e5:
            raise SpecError(source, "density", f"{density:g} kg/m^3; give 10 to 1e5 kg/m^3, e.g. 1100 kg/m^3")
        return density

    @field_validator("protocol")
    @classmethod
    def _protocol(cls, rel, info: ValidationInfo):
        """``(protocol, path)``, both None without one; then what the objectives and constraints need."""
        source = info.context["source"]
        protocol = protocol_path = None
        if _given(rel):
            protocol, protocol_path = _resolve(info.context["folder"], rel, source, "protocol", load_protocol)
        if not {"objectives", "constraints", "density", "bias"} <= set(info.data):
            return protocol, protocol_path
        density, kind = info.data["density"], info.data["bias"].kind
        for what, metric in [("objectives", g.metric) for g in info.data["objectives"]] \
                + [("constraints", b.metric) for b in info.data["constraints"]]:
            if metric in PROTOCOL_METRICS and protocol is None:
                raise SpecError(source, what, f"{metric} is a protocol's metric; give a protocol to run")
            if metric in DENSITY_METRICS and density is None:
                raise SpecError(source, what, f"{metric} needs the elastomer's density, e.g. density: 1100 kg/m^3")
            if kind == "none" and metric in ("work", "energy_density", "specific_energy"):
                raise SpecError(source, what, f"{metric}: with no bias nothing is done work on; give a bias")
        return protocol, protocol_path

    @field_validator("tolerances")
    @classmethod
    def _tolerances(cls, value, info: ValidationInfo):
        """``(radii, samples, seed)``: the Monte Carlo spread of the radii."""
        source = info.context["source"]
        tol = _mapping(value, source, "tolerances")
        extra = set(tol) - {"radii", "samples", "seed"}
        if extra:
            raise SpecError(source, f"tolerances.{sorted(extra)[0]}", "unknown key; allowed: radii, samples, seed")
        radii_tol = parse_quantity(tol.get("radii", 0), "dimensionless", source=source, field="tolerances.radii")
        if not 0 <= radii_tol <= 0.2:
            raise SpecError(source, "tolerances.radii", f"{radii_tol:g}; give a relative spread from 0 to 20 %")
        mc = _int(tol.get("samples", 32 if radii_tol > 0 else 0), source, "tolerances.samples", 0, 10000)
        if radii_tol > 0 and mc < 2:
            raise SpecError(source, "tolerances.samples", "give at least 2 Monte Carlo samples")
        return radii_tol, mc, _int(tol.get("seed", 0), source, "tolerances.seed", 0, 2**32 - 1)

    @field_validator("sensitivity")
    @classmethod
    def _sensitivity(cls, value, info: ValidationInfo):
        """``(n, the mapping)``: its seed is checked after every other key (`Study._from_form`), as it always was."""
        source = info.context["source"]
        sens = _mapping(value, source, "sensitivity")
        extra = set(sens) - {"n", "seed"}
        if extra:
            raise SpecError(source, f"sensitivity.{sorted(extra)[0]}", "unknown key; allowed: n, seed")
        sens_n = _int(sens.get("n", 0), source, "sensitivity.n", 0, 2**20) if sens else 0
        if sens_n and (sens_n & (sens_n - 1)):
            raise SpecError(source, "sensitivity.n", f"{sens_n}; Saltelli's sampling needs a power of 2, e.g. 128")
        return sens_n, sens

    @field_validator("optimize")
    @classmethod
    def _optimize(cls, value, info: ValidationInfo):
        if not _given(value):
            return None
        source = info.context["source"]
        opt = _mapping(value, source, "optimize")
        extra = set(opt) - {"objective", "starts", "max_iter"}
        if extra:
            raise SpecError(source, f"optimize.{sorted(extra)[0]}", "unknown key; allowed: objective, starts, "
                            "max_iter")
        goals = info.data.get("objectives", ())
        metric = opt.get("objective", goals[0].metric if goals else None)
        if metric not in [g.metric for g in goals]:
            raise SpecError(source, "optimize.objective", f"{show(metric)}; allowed: one of the objectives "
                            f"({', '.join(g.metric for g in goals)})")
        return {"objective": metric, "starts": _int(opt.get("starts", 4), source, "optimize.starts", 1, 64),
                "max_iter": _int(opt.get("max_iter", 25), source, "optimize.max_iter", 1, 10000)}

    @field_validator("chunk")
    @classmethod
    def _chunk(cls, value, info: ValidationInfo):
        return _int(value, info.context["source"], "chunk", 1, 10**6)

    @model_validator(mode="after")
    def _last(self, info: ValidationInfo) -> "_StudyFile":
        """A grid's levels only with a grid, and Yeoh ranges that stay physical."""
        source = info.context["source"]
        (var, variables), method = self.variables, self.sampling[0]
        if method != "grid":
            for v in var:
                if isinstance(variables[v.name], Mapping) and "levels" in variables[v.name]:
                    raise SpecError(source, f"variables.{v.name}.levels", f"a grid's; sampling is {method} (n designs)")
        _check_material(var, self.params, source)
        return self


def _names(info: ValidationInfo) -> set[str]:
    """The names of the variables (none if they did not pass)."""
    return {v.name for v in info.data.get("variables", ((), {}))[0]}


#: largest I1 - 3 the equilibrium search reaches (stretch 2.5 in uniaxial tension)
_X_MAX = 2.5**2 + 2.0 / 2.5 - 3.0


def _check_material(var, params, source) -> None:
    """Yeoh coefficients as variables must give a rising energy (W' > 0) everywhere in their box: W' is
    linear in the coefficients, so the box's corners decide it (as `load_params` checks one set)."""
    ranges = {v.name: (v.low, v.high) for v in var if v.name in ("C10", "C20", "C30")}
    if not ranges:
        return
    x = np.linspace(0.0, _X_MAX, 200)
    for corner in itertools.product(*[ranges.get(k, (getattr(params, k),) * 2) for k in ("C10", "C20", "C30")]):
        c10, c20, c30 = corner
        slope = c10 + 2.0 * c20 * x + 3.0 * c30 * x**2
        if np.min(slope) <= 0:
            name = sorted(ranges)[0]
            raise SpecError(source, f"variables.{name}", f"at C10, C20, C30 = {c10:g}, {c20:g}, {c30:g} Pa the Yeoh "
                            f"slope W' turns non-positive (at I1 - 3 = {x[np.argmin(slope)]:.3g}): no physical "
                            "material; narrow the ranges")
