"""Quantities with units (``"48 um"``, ``"2.6 kV"``, ``"86 kPa s"``) to SI floats
and back, and the pydantic field types that use them.

A quantity in a spec file is a string: a number, then a unit that pint
understands. Only dimensionless quantities may be bare numbers.
"""

from __future__ import annotations

import math
import numbers
import re
import threading
from decimal import Decimal
from typing import Annotated, Any

from pydantic import AfterValidator, BeforeValidator

from .base import units_required
from .errors import SpecError, show


class _LazyRegistry:
    """Stands for pint's `UnitRegistry`, built on the first attribute asked of it.

    Importing pint and building its registry take 0.3-0.5 s (pint also imports dask
    and scipy when they are installed), which every ``rdea-lab --help`` paid at import.
    ``ureg.parse_units(...)``, ``ureg.Quantity(...)`` work as on the registry itself;
    `unit_registry` returns the registry.
    """

    __slots__ = ("_registry", "_lock")

    def __init__(self):
        self._registry = None
        self._lock = threading.Lock()  # one registry even if two threads ask first at once

    def get(self):
        if self._registry is None:
            with self._lock:
                if self._registry is None:
                    import pint

                    self._registry = pint.UnitRegistry()
        return self._registry

    def __getattr__(self, name: str):
        return getattr(self.get(), name)

    def __repr__(self) -> str:
        return "<rdea-lab's unit registry (" + ("built" if self._registry is not None else "not built yet") + ")>"


#: The one unit registry of rdea-lab (pint's, built on first use).
ureg = _LazyRegistry()


def unit_registry():
    """The one `pint.UnitRegistry` of rdea-lab (built on the first call)."""
    return ureg.get()

# dimension -> (SI unit the float is expressed in, name, example)
_DIMENSIONS: dict[str, tuple[str, str, str]] = {
    "length": ("m", "length", "34 mm"),
    "pressure": ("Pa", "pressure", "242 kPa"),
    "viscosity": ("Pa*s", "viscosity", "86 kPa s"),
    "voltage": ("V", "voltage", "2600 V"),
    "frequency": ("Hz", "frequency", "0.1 Hz"),
    "time": ("s", "time", "10 s"),
    "dimensionless": ("dimensionless", "dimensionless number", "2.8"),
    "force": ("N", "force", "1.5 N"),
    "capacitance": ("F", "capacitance", "100 pF"),
    "electric_field": ("V/m", "electric field", "50 V/um"),
    "compliance": ("m/N", "compliance", "20 um/N"),
    "force_rate": ("N/s", "force rate", "0.5 mN/min"),
    "stiffness": ("N/m", "stiffness", "200 N/m"),
    "mass": ("kg", "mass", "100 g"),
    "current": ("A", "current", "20 nA"),
    "resistance": ("ohm", "resistance", "100 Gohm"),
    "energy": ("J", "energy", "5 mJ"),
    "specific_energy": ("J/kg", "specific energy", "2 J/kg"),
    "volume": ("m^3", "volume", "300 mm^3"),
    "density": ("kg/m^3", "density", "1100 kg/m^3"),
    "voltage_rate": ("V/s", "voltage rate", "1 kV/s"),
    "temperature": ("K", "temperature", "60 degC"),
}
_NOTES = {"viscosity": " (pressure times time)", "electric_field": " (voltage per length)",
          "compliance": " (length per force)", "force_rate": " (force per time)",
          "stiffness": " (force per length)", "specific_energy": " (energy per mass)",
          "density": " (mass per volume)", "voltage_rate": " (voltage per time)"}
DIMENSIONS = tuple(_DIMENSIONS)

_NUMBER = re.compile(
    r"\s*([+-]?(?:(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?|(?:nan|inf(?:inity)?)(?![a-z])))\s*(.*?)\s*$",
    re.IGNORECASE,
)


#: A unit is names (letters, µ, Ω, °) joined by spaces, ``*`` or ``/``, each with an optional one-digit
#: exponent (``m^2``, ``s**-1``), optionally ``1/`` first: never an expression with numbers in it, which
#: pint would evaluate (``kV*10**10**10`` does not finish).
_UNIT_NAME = r"(?:[A-Za-zµμΩ°_]+|%)(?:(?:\^|\*\*)-?\d)?"
_UNIT = re.compile(rf"(?:1\s*/\s*)?{_UNIT_NAME}(?:\s*[*/ ·⋅]\s*{_UNIT_NAME})*")


#: Where a bare number's likely unit is looked for [SI]: a rolled DEA's voltages (up to the 30 kV of the
#: limits' ceiling), forces, fields, frequencies and a pause's voltage ramp rates. A number that is
#: plausible in the field's display unit keeps it; '3000' for a voltage shown in kV is '3000 V' (or '3 kV'),
#: not '3000 kV'.
_PLAUSIBLE = {"voltage": (1.0, 30e3), "force": (1e-4, 1e3), "electric_field": (1e5, 1e9),
              "frequency": (1e-4, 1e5), "voltage_rate": (1.0, 1e5)}


def _bare_example(dimension: str, number: str, example_unit: str | None) -> str:
    """The example for a number given without a unit: in the first unit (the field's, the dimension's
    example's, SI) in which the number is plausible, and in the field's unit too."""
    if dimension not in _PLAUSIBLE:
        return _example(dimension, number, example_unit)
    low, high = _PLAUSIBLE[dimension]
    si_unit = _DIMENSIONS[dimension][0]
    shown_unit = example_unit or _DIMENSIONS[dimension][2].partition(" ")[2]
    for unit in dict.fromkeys(u for u in (shown_unit, _DIMENSIONS[dimension][2].partition(" ")[2], si_unit) if u):
        try:
            si = abs(float(number)) * float(ureg.Quantity(1.0, ureg.parse_units(unit)).to(si_unit).magnitude)
        except Exception:  # a number or unit the example cannot use: the plain example
            return _example(dimension, number, example_unit)
        if low <= si <= high:
            first = f"'{number} {unit}'"
            if unit == shown_unit:
                return first
            return f"{first} or '{format_quantity(math.copysign(si, float(number)), shown_unit)}'"
    return _example(dimension, number, example_unit)


def _example(dimension: str, number: str | None, example_unit: str | None) -> str:
    ex_number, _, ex_unit = _DIMENSIONS[dimension][2].partition(" ")
    unit = ex_unit if example_unit is None else example_unit
    return f"'{number or ex_number} {unit}'" if unit else f"'{number or ex_number}'"


def parse_quantity(
    value: Any,
    dimension: str,
    *,
    source: str,
    field: str,
    example_unit: str | None = None,
) -> float:
    """Parse a quantity with a unit to its SI magnitude.

    Parameters
    ----------
    value : str or number
        ``"48 um"``, ``"48 µm"``, ``"-69 kPa"``, ``"86 kPa s"``, ``"1e-3 m"``.
        A bare number is accepted only for ``dimension="dimensionless"``.
    dimension : str
        One of `DIMENSIONS`: ``length`` [m], ``pressure`` [Pa], ``viscosity``
        [Pa s], ``voltage`` [V], ``frequency`` [Hz], ``time`` [s],
        ``dimensionless`` [-], ``force`` [N], ``capacitance`` [F],
        ``electric_field`` [V/m], ``compliance`` [m/N], ``force_rate`` [N/s],
        ``stiffness`` [N/m], ``mass`` [kg], ``current`` [A], ``resistance`` [ohm], ``energy`` [J],
        ``specific_energy`` [J/kg], ``volume`` [m^3], ``density`` [kg/m^3], ``voltage_rate`` [V/s],
        ``temperature`` [K] (``60 degC`` is 333.15 K: an offset unit, converted as such).
    source, field : str
        Where the value came from, for the error message.
    example_unit : str, optional
        Unit used in the "e.g." of error messages (``"um"`` for a thickness).

    Returns
    -------
    float
        The magnitude in the SI unit of `dimension`.

    Raises
    ------
    SpecError
        No unit (for a dimensional quantity), unknown unit, wrong dimension,
        angle units (``rad/s``, ``rpm``: ambiguous by 2 pi), NaN or infinity,
        booleans, anything that is not a number or a string.
    """
    if dimension not in _DIMENSIONS:
        raise ValueError(f"unknown dimension {dimension!r}; allowed: {', '.join(DIMENSIONS)}")
    si_unit, name, _ = _DIMENSIONS[dimension]

    def fail(message: str) -> SpecError:
        return SpecError(source, field, message)

    if isinstance(value, bool) or value is None or not isinstance(value, (str, numbers.Real)):
        what = "no value given" if value is None else f"{show(value)} is not a quantity"
        raise fail(f"{what}; give a {name}, e.g. {_example(dimension, None, example_unit)}")
    if isinstance(value, numbers.Real):
        if not math.isfinite(value):
            raise fail(f"{value} is not a finite number; give a finite {name}")
        if dimension != "dimensionless":
            raise fail(
                f"'{value}' has no unit; give a {name}, e.g. {_bare_example(dimension, str(value), example_unit)}"
            )
        return float(value)

    match = _NUMBER.match(value)
    if match is None:
        raise fail(
            f"{show(value)} is not a number followed by a unit; "
            f"give a {name}, e.g. {_example(dimension, None, example_unit)}"
        )
    number, unit_text = match.groups()
    if not math.isfinite(float(number)):
        raise fail(f"{show(value)} is not a finite number; give a finite {name}")
    if not unit_text and dimension != "dimensionless":
        raise fail(f"{show(value)} has no unit; give a {name}, e.g. {_bare_example(dimension, number, example_unit)}")
    if unit_text and (len(unit_text) > 40 or not _UNIT.fullmatch(unit_text)):
        raise fail(
            f"{show(value)}: {show(unit_text)} is not a unit (names such as kV, V/um, kPa s; no arithmetic); "
            f"give a {name}, e.g. {_example(dimension, number, example_unit)}"
        )
    try:  # pint's parser raises many types (tokenize, ZeroDivision, Pint...)
        units = ureg.parse_units(unit_text) if unit_text else ureg.dimensionless
    except Exception:
        raise fail(
            f"{show(value)} has an unknown unit {show(unit_text)}; "
            f"give a {name}, e.g. {_example(dimension, number, example_unit)}"
        ) from None
    quantity = ureg.Quantity(float(number), units)
    if quantity.dimensionality != ureg.parse_units(si_unit).dimensionality:
        wanted = "a plain number" if dimension == "dimensionless" else f"it with a {name} unit"
        raise fail(
            f"{show(value)} is not a {name}{_NOTES.get(dimension, '')}; give {wanted}, "
            f"e.g. {_example(dimension, number, example_unit)}"
        )
    if "radian" in str(quantity.to_root_units().units):
        unit_hint = "a plain number" if dimension == "dimensionless" else f"a {name} in {si_unit}"
        raise fail(f"{show(value)} uses an angle unit (ambiguous by 2 pi); give {unit_hint}")
    if dimension == "temperature":
        return _kelvin(value, float(number), units, fail)
    si = _to_si(number, units, si_unit)
    if not math.isfinite(si):
        raise fail(f"{show(value)} is not a finite number; give a finite {name}")
    return si


def _kelvin(value: str, number: float, units: Any, fail) -> float:
    """A temperature in kelvin. degC and degF are offset units (0 degC is 273.15 K): converted as pint converts
    a temperature, never by a factor; a temperature difference (``delta_degC``) is not a temperature."""
    if "delta" in str(units):
        raise fail(f"{show(value)} is a temperature difference; give a temperature, e.g. '60 degC' or '333 K'")
    kelvin = float(ureg.Quantity(number, units).to("K").magnitude)
    if not (math.isfinite(kelvin) and kelvin >= 0.0):
        raise fail(f"{show(value)} is below absolute zero; give a temperature, e.g. '60 degC' or '333 K'")
    return kelvin


def _to_si(number: str, units: Any, si_unit: str) -> float:
    """``number`` (decimal text) in ``units`` -> SI float.

    For decimal prefixes (mm, um, kPa, pF) the scaling is done in decimal
    arithmetic, so '1.8 mm' gives 0.0018 (the float nearest to 1.8e-3), not
    0.0018000000000000002."""
    factor = float(ureg.Quantity(1.0, units).to(si_unit).magnitude)
    if factor >= 1.0 and factor == round(factor):
        return float(Decimal(number) * int(factor))
    if 0.0 < factor < 1.0:
        inverse = round(1.0 / factor)
        if abs(1.0 / factor - inverse) <= 1e-9 * inverse:
            return float(Decimal(number) / inverse)
    return float(number) * factor


def _dimension_of(unit: str) -> str:
    dim = ureg.parse_units(unit or "dimensionless").dimensionality
    for dimension, (si_unit, _, _) in _DIMENSIONS.items():
        if ureg.parse_units(si_unit).dimensionality == dim:
            return dimension
    raise ValueError(f"unit {unit!r} matches none of {', '.join(DIMENSIONS)}")


def format_quantity(value: float, unit: str, digits: int | None = None) -> str:
    """Write an SI value with `unit`, e.g. ``(242000.0, "kPa") -> "242 kPa"``.

    Uses the shortest of 6, 9, 12, 15 or 17 significant digits that parses
    back to exactly `value`, so ``parse_quantity(format_quantity(x, u))``
    round-trips; falls back to the SI unit if no digit count does.

    Parameters
    ----------
    value : float
        Magnitude in the SI unit of `unit`'s dimension.
    unit : str
        Unit to write (``"mm"``, ``"um"``, ``"kPa"``, ``"kPa s"``); ``""``
        for a dimensionless number.
    digits : int, optional
        Fixed number of significant digits (for messages); the result then
        need not round-trip.
    """
    dimension = _dimension_of(unit)
    si_unit = _DIMENSIONS[dimension][0]
    value = float(value)

    def text(x: float, u: str, n: int) -> str:
        number = f"{x:.{n}g}"
        return f"{number} {u}" if u and u != "dimensionless" else number

    if not math.isfinite(value):
        return text(value, unit, 6)
    x = float(ureg.Quantity(value, si_unit).to(unit or "dimensionless").magnitude)
    if digits is not None:
        return text(x, unit, digits)
    for n in (6, 9, 12, 15, 17):
        candidate = text(x, unit, n)
        if parse_quantity(candidate, dimension, source="", field="") == value:
            return candidate
    return text(value, si_unit, 17)


# ------------------------------------------------------- pydantic field types
def _number_or_quantity(dimension: str, example_unit: str | None):
    def validate(value: Any) -> float:
        if isinstance(value, numbers.Real) and not isinstance(value, bool) and not units_required():
            value = float(value)  # Python caller: a number is already SI
            if not math.isfinite(value):
                raise SpecError("", "", f"{value} is not a finite number")
            return value
        return parse_quantity(value, dimension, source="", field="", example_unit=example_unit)

    return validate


def _bound(unit: str, gt: float | None, ge: float | None, le: float | None = None, tiny: float | None = None):
    def check(value: float) -> float:
        if gt is not None and not value > gt:
            raise SpecError("", "", f"must be > {format_quantity(gt, unit)}, got {format_quantity(value, unit)}")
        if ge is not None and not value >= ge:
            raise SpecError("", "", f"must be >= {format_quantity(ge, unit)}, got {format_quantity(value, unit)}")
        if tiny is not None and 0.0 < abs(value) < tiny:
            raise SpecError("", "", f"{format_quantity(value, unit)} is smaller than any real one "
                            f"({format_quantity(tiny, unit)} at least); check the unit")
        if le is not None and not value <= le:
            raise SpecError("", "", f"must be <= {format_quantity(le, unit)}, got {format_quantity(value, unit)}; "
                            "check the unit")
        return value

    return check


def quantity(dimension: str, unit: str, *, gt: float | None = None, ge: float | None = None,
             le: float | None = None, tiny: float | None = None):
    """A pydantic field type: an SI float parsed from a quantity with a unit.

    Parameters
    ----------
    dimension : str
        One of `DIMENSIONS`.
    unit : str
        Display unit for messages and for writing back (``"mm"``).
    gt, ge : float, optional
        Lower bounds [SI], checked with a message that names the bound.
    le : float, optional
        Upper bound [SI] (a value past it is a unit mistake).
    tiny : float, optional
        Nonzero values smaller in magnitude than this [SI] are refused (a unit mistake, and a
        division by almost zero downstream).

    Notes
    -----
    From YAML (`units_required`) a dimensional value must carry a unit; from
    Python, a bare number is taken as SI.
    """
    return Annotated[
        float,
        BeforeValidator(_number_or_quantity(dimension, unit or None)),
        AfterValidator(_bound(unit, gt, ge, le, tiny)),
    ]


__all__ = ["DIMENSIONS", "format_quantity", "parse_quantity", "quantity", "unit_registry", "ureg"]
