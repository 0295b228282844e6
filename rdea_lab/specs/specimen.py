"""Specimen cards: the geometry of one rolled DEA, as YAML with units.

Two geometry forms, exactly one per card:

``membrane``
    the unwound membrane dimensions of Table 1 in [1] (``L1, L2, L3, L1e,
    Lp1, L2e`` and optionally ``Ri``, the spiral's starting radius, 0 by
    default as in Eq. (52) of [1]); the physics layer computes the radii
    (appendix of [1]);
``radii``
    the radii of the three rings ``Ri <= Rie < Roe <= Ro`` (Fig. 3b of [1])
    with ``L1``, ``L1e`` and ``L3`` at the top level, as for the three cores
    of Section 3.4 of [1].

All lengths are stored as SI floats [m].

[1] J. Prechtl et al., Smart Mater. Struct. (2021),
    doi:10.1088/1361-665X/ac34be.
"""

from __future__ import annotations

import os
from typing import Any

from pydantic import Field, field_validator, model_validator

from .base import Identifier, SpecModel
from .errors import SpecError, show
from .units import format_quantity, quantity

#: Specimen lengths: above 1 um and up to 10 m, thicknesses from 100 nm to 10 mm (anything outside is a
#: unit mistake, and a value near 0 would divide by almost zero in the geometry).
#: The smallest nonzero length and thickness a card (or a design study varying its membrane) accepts [m].
SMALLEST_LENGTH, SMALLEST_THICKNESS = 1e-6, 1e-7
Length = quantity("length", "mm", gt=0.0, tiny=SMALLEST_LENGTH, le=10.0)
Thickness = quantity("length", "um", gt=0.0, tiny=SMALLEST_THICKNESS, le=1e-2)
Radius = quantity("length", "mm", ge=0.0, tiny=1e-9, le=10.0)

#: unit each length is written with
_UNITS = {"L3": "um"}
KINDS = ("roll", "strip")
#: relative slack for sums compared with a length (0.1 + 0.2 > 0.3 in floats)
_ROUNDING = 1e-12


def _mm(value: float, key: str = "") -> str:
    return format_quantity(value, _UNITS.get(key, "mm"))


class Membrane(SpecModel):
    """Unwound membrane dimensions (Table 1 of [1]).

    Attributes
    ----------
    L1 : float
        Length along the actuation direction [m].
    L2 : float
        Length along the rolling direction, before rolling [m].
    L3 : float
        Thickness of one membrane [m].
    L1e : float
        Electrode length along the actuation direction [m].
    Lp1 : float
        Electrode-free length at the start of rolling [m].
    L2e : float
        Electrode length along the rolling direction [m].
    Ri : float
        Starting radius of the spiral [m]; 0 as in Eq. (52) of [1].
    """

    L1: Length
    L2: Length
    L3: Thickness
    L1e: Length
    Lp1: Length
    L2e: Length
    Ri: Radius = 0.0

    @model_validator(mode="after")
    def _consistent(self) -> "Membrane":
        if self.L1e > self.L1:
            raise SpecError("", "L1e", f"L1e = {_mm(self.L1e)} is longer than L1 = {_mm(self.L1)}; need L1e <= L1")
        if self.Lp1 + self.L2e > self.L2 * (1.0 + _ROUNDING):
            raise SpecError(
                "", "L2e",
                f"Lp1 + L2e = {_mm(self.Lp1)} + {_mm(self.L2e)} is longer than L2 = {_mm(self.L2)}; "
                "need Lp1 + L2e <= L2 (the outer passive length L2 - Lp1 - L2e must be >= 0)",
            )
        return self

    @property
    def Lp2(self) -> float:
        """Electrode-free length at the end of rolling, ``L2 - Lp1 - L2e`` [m].

        Never negative: when ``Lp1 + L2e`` equals ``L2`` in decimal, float
        rounding of the sum can leave -1e-17 m, returned as 0.
        """
        return max(0.0, self.L2 - self.Lp1 - self.L2e)


class Radii(SpecModel):
    """Radii of the three rings a (passive), b (active), c (passive) [m].

    Requires ``0 <= Ri <= Rie < Roe <= Ro``: ring b must have a positive
    thickness, rings a and c may vanish.
    """

    Ri: Radius
    Rie: Length
    Roe: Length
    Ro: Length

    @model_validator(mode="after")
    def _ordered(self) -> "Radii":
        if self.Rie < self.Ri:
            raise SpecError("", "Rie", f"Rie = {_mm(self.Rie)} is smaller than Ri = {_mm(self.Ri)}; need Ri <= Rie")
        if self.Roe <= self.Rie:
            raise SpecError(
                "", "Roe",
                f"Roe = {_mm(self.Roe)} is not larger than Rie = {_mm(self.Rie)}; need Rie < Roe "
                "(the active ring b must have a positive thickness)",
            )
        if self.Ro < self.Roe:
            raise SpecError("", "Ro", f"Ro = {_mm(self.Ro)} is smaller than Roe = {_mm(self.Roe)}; need Roe <= Ro")
        return self


_TOP = ("L1", "L1e", "L3")
_STRIP = ("length", "width", "thickness")


class Electrode(SpecModel):
    """The electrode of a strip: where the voltage is applied (centred on the strip).

    Attributes
    ----------
    length : float
        Along the stretch direction [m].
    width : float
        Across it [m].
    """

    length: Length
    width: Length


class SpecimenCard(SpecModel):
    """One specimen: an id and its geometry, in one of two forms.

    Attributes
    ----------
    id : str
        Letters, digits, ``-``, ``_``, ``.`` (e.g. ``specimen-2``).
    kind : str
        ``"roll"`` (the only kind so far).
    membrane : Membrane or None
        Unwound membrane form.
    radii : Radii or None
        Ring radii form; then ``L1``, ``L1e``, ``L3`` are top-level keys.
    description, source : str or None
        Free text; `source` says where the numbers come from.
    """

    id: Identifier
    kind: str
    description: str | None = None
    source: str | None = None
    membrane: Membrane | None = None
    radii: Radii | None = None
    radii_L1: Length | None = Field(None, alias="L1")
    radii_L1e: Length | None = Field(None, alias="L1e")
    radii_L3: Thickness | None = Field(None, alias="L3")
    length: Length | None = None
    width: Length | None = None
    thickness: Length | None = None
    electrode: Electrode | None = None

    @field_validator("kind", mode="before")
    @classmethod
    def _known_kind(cls, value: Any) -> Any:
        if value not in KINDS:
            raise SpecError("", "", f"kind {show(value)} is not supported; allowed: {', '.join(KINDS)}")
        return value

    @model_validator(mode="after")
    def _one_geometry(self) -> "SpecimenCard":
        strip = {k: getattr(self, k) for k in (*_STRIP, "electrode")}
        if self.kind == "strip":
            return self._strip_geometry(strip)
        for key, value in strip.items():
            if value is not None:
                raise SpecError("", key, f"'{key}' belongs to a strip card (kind: strip); a roll has "
                                         "'membrane' or 'radii'")
        top = {"L1": self.radii_L1, "L1e": self.radii_L1e, "L3": self.radii_L3}
        if self.membrane is not None and self.radii is not None:
            raise SpecError("", "radii", "give the geometry either as 'membrane' or as 'radii', not both")
        if self.membrane is None and self.radii is None:
            raise SpecError(
                "", "membrane",
                "missing geometry; give 'membrane' (L1, L2, L3, L1e, Lp1, L2e) "
                "or 'radii' (Ri, Rie, Roe, Ro) with top-level L1, L1e, L3",
            )
        if self.membrane is not None:
            for key, value in top.items():
                if value is not None:
                    raise SpecError(
                        "", key, f"a top-level {key} belongs to the 'radii' form; "
                        f"with 'membrane', give {key} inside membrane",
                    )
            return self
        for key, value in top.items():
            if value is None:
                raise SpecError(
                    "", key, f"missing required key '{key}' (the 'radii' form needs L1, L1e and L3 at the top level)"
                )
        if self.radii_L1e > self.radii_L1:
            raise SpecError(
                "", "L1e", f"L1e = {_mm(self.radii_L1e)} is longer than L1 = {_mm(self.radii_L1)}; need L1e <= L1"
            )
        ring = self.radii.Roe - self.radii.Rie
        if not self.radii_L3 < ring:
            raise SpecError(
                "", "L3",
                f"L3 = {_mm(self.radii_L3, 'L3')} is not smaller than the active ring's thickness "
                f"Roe - Rie = {format_quantity(ring, 'mm', digits=4)}; "
                "a layer must be thinner than the ring it is rolled into",
            )
        return self

    def _strip_geometry(self, strip) -> "SpecimenCard":
        for key, value in {"membrane": self.membrane, "radii": self.radii, "L1": self.radii_L1,
                           "L1e": self.radii_L1e, "L3": self.radii_L3}.items():
            if value is not None:
                raise SpecError("", key, f"'{key}' belongs to a roll card; a strip has length, width, "
                                         "thickness (and optionally electrode)")
        for key in _STRIP:
            if strip[key] is None:
                raise SpecError("", key, f"missing required key '{key}' (a strip needs length, width and thickness)")
        e = self.electrode
        if e is not None:
            if e.length > self.length * (1 + _ROUNDING):
                raise SpecError("", "electrode.length",
                                f"{_mm(e.length)} is longer than the strip ({_mm(self.length)})")
            if e.width > self.width * (1 + _ROUNDING):
                raise SpecError("", "electrode.width", f"{_mm(e.width)} is wider than the strip ({_mm(self.width)})")
        return self

    @property
    def form(self) -> str:
        """``"membrane"``, ``"radii"`` or ``"strip"``: which geometry form the card uses."""
        if self.kind == "strip":
            return "strip"
        return "membrane" if self.membrane is not None else "radii"

    @property
    def L1(self) -> float:
        """Length along the actuation direction [m]."""
        if self.kind == "strip":
            return self.length
        return self.membrane.L1 if self.membrane is not None else self.radii_L1

    @property
    def L1e(self) -> float:
        """Electrode length along the actuation direction [m] (0 for a strip without electrode)."""
        if self.kind == "strip":
            return self.electrode.length if self.electrode is not None else 0.0
        return self.membrane.L1e if self.membrane is not None else self.radii_L1e

    @property
    def L3(self) -> float:
        """Thickness of one membrane (of the strip) [m]."""
        if self.kind == "strip":
            return self.thickness
        return self.membrane.L3 if self.membrane is not None else self.radii_L3

    spec_kind = "specimens"

    def _form(self) -> dict:
        """The YAML form: the card's geometry form with lengths in mm (thicknesses in um)."""
        data: dict[str, Any] = {"id": self.id, "kind": self.kind}
        for key in ("description", "source"):
            if getattr(self, key) is not None:
                data[key] = getattr(self, key)
        if self.kind == "strip":
            data.update({k: _mm(getattr(self, k)) for k in _STRIP})
            if self.electrode is not None:
                data["electrode"] = {k: _mm(getattr(self.electrode, k)) for k in ("length", "width")}
        elif self.membrane is not None:
            data["membrane"] = {k: _mm(getattr(self.membrane, k), k) for k in Membrane.model_fields}
        else:
            data["radii"] = {k: _mm(getattr(self.radii, k), k) for k in Radii.model_fields}
            data.update({k: _mm(getattr(self, k), k) for k in _TOP})
        return data


def specimen_from_mapping(mapping: Any, source: str = "<mapping>") -> SpecimenCard:
    """`SpecimenCard.from_mapping`: a card given as a mapping (as read from YAML)."""
    return SpecimenCard.from_mapping(mapping, source)


def specimen_from_yaml(text: str, source: str = "<string>") -> SpecimenCard:
    """`SpecimenCard.from_yaml`: a card given as YAML text (e.g. a dataset attr)."""
    return SpecimenCard.from_yaml(text, source)


def load_specimen(path: str | os.PathLike) -> SpecimenCard:
    """`SpecimenCard.load`: read and validate a specimen card YAML file.

    Parameters
    ----------
    path : str or path-like
        The YAML file; a path that does not exist may name a packaged reference file
        (``"specimen2"``, ``"specimen2.yaml"`` or ``"specimens/specimen2.yaml"``).

    Returns
    -------
    SpecimenCard
        Frozen, in SI units.

    Raises
    ------
    SpecError
        The file is missing, too large, not YAML, not a mapping, or a value is invalid; one line naming
        the file, the field and what is allowed.
    """
    return SpecimenCard.load(path)


def dump_specimen(card: SpecimenCard) -> str:
    """`SpecimenCard.dump`: a card as YAML with units; `load_specimen` reads it back equal."""
    return card.dump()


__all__ = [
    "KINDS", "Electrode", "Membrane", "Radii", "SpecimenCard", "dump_specimen", "load_specimen",
    "specimen_from_mapping", "specimen_from_yaml",
]
