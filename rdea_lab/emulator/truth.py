"""The true roll of an emulated rig: a specimen card's geometry with the truth's tolerances."""

from __future__ import annotations

from ..physics.geometry import RollGeometry, geometry_from_card
from ..specs import SpecError
from ..specs.units import format_quantity

_ORDER = ("Ri", "Rie", "Roe", "Ro")


def _mm(value: float) -> str:
    return format_quantity(value, "mm", digits=6)


def true_geometry(card, truth, *, source: str | None = None) -> RollGeometry:
    """The geometry the emulated roll really has: nominal radii x `truth.radii_factors`.

    Parameters
    ----------
    card : SpecimenCard
        The nominal specimen (membrane or radii form).
    truth : TruthSpec
    source : str, optional
        Where `truth` came from (its file), for error messages.

    Returns
    -------
    RollGeometry
        Radii ``Ri, Rie, Roe, Ro`` scaled by their factors; ``L1``, ``L1e``
        and ``L3`` as on the card.

    Raises
    ------
    SpecError
        Field ``radii_factors.<name>``: the factored radii are no longer
        ordered ``0 <= Ri <= Rie < Roe <= Ro``, or the active ring is no
        thicker than one layer ``L3``.
    """
    source = source or f"truth {truth.name}"
    if getattr(card, "kind", "roll") != "roll":
        raise SpecError(source, "kind", f"the emulator emulates a roll; {card.id} is a {card.kind} "
                                        "(use the twin, or import measured strip data)")
    nominal = geometry_from_card(card)
    f = truth.radii_factors
    r = {k: getattr(nominal, k) * getattr(f, k) for k in _ORDER}

    def fail(key: str, other: str, relation: str) -> SpecError:
        return SpecError(
            source, f"radii_factors.{key}",
            f"with {card.id}, {key} x {getattr(f, key):g} = {_mm(r[key])} is {relation} "
            f"{other} x {getattr(f, other):g} = {_mm(r[other])}; the factored radii must keep "
            "Ri <= Rie < Roe <= Ro",
        )

    if r["Rie"] < r["Ri"]:
        raise fail("Rie", "Ri", "smaller than")
    if not r["Roe"] > r["Rie"]:
        raise fail("Roe", "Rie", "not larger than")
    if r["Ro"] < r["Roe"]:
        raise fail("Ro", "Roe", "smaller than")
    if not r["Roe"] - r["Rie"] > nominal.L3:
        raise SpecError(
            source, "radii_factors.Roe",
            f"with {card.id}, the factored active ring Roe - Rie = {_mm(r['Roe'] - r['Rie'])} is not thicker "
            f"than one layer L3 = {format_quantity(nominal.L3, 'um', digits=6)}",
        )
    try:
        return RollGeometry(r["Ri"], r["Rie"], r["Roe"], r["Ro"], nominal.L1, nominal.L1e, nominal.L3)
    except ValueError as exc:  # e.g. a vanishing passive core
        raise SpecError(source, "radii_factors", f"with {card.id}: {exc}") from None
