"""Small pieces of the application layer that belong to no lower layer."""

from __future__ import annotations

from ..physics.geometry import geometry_from_card
from ..protocols import first_violation
from ..specs import SpecError, as_specimen

__all__ = ["check_plan", "geometry"]


def geometry(specimen):
    """The `RollGeometry` (or `StripGeometry`) of a card or a card's path.

    Parameters
    ----------
    specimen : SpecimenCard or path
        A card, or the path of a card file (a packaged one by its name, ``"specimen2"``).

    Returns
    -------
    RollGeometry or StripGeometry
        A roll's ring radii ``Ri, Rie, Roe, Ro`` [m], lengths ``L1, L1e`` [m] and membrane thickness
        ``L3`` [m]: as the card gives them, or from its unwound membrane by the Appendix of [1]
        (eqs. (45)-(58), as corrected in ``paper/ERRATA.md``); a strip card's strip.

    Raises
    ------
    SpecError
        The card cannot be read, or describes no possible roll (naming the card).

    References
    ----------
    [1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello, "Modeling and experimental
        validation of thin, tightly rolled dielectric elastomer actuators", Smart Mater. Struct. 31 (2022)
        015008 (2021 online), doi:10.1088/1361-665X/ac34be.
    """
    card = as_specimen(specimen)
    try:
        return geometry_from_card(card)
    except ValueError as exc:
        raise SpecError(str(specimen) if isinstance(specimen, str) else card.id, "<document>", str(exc)) from None


def check_plan(plan, L3=None) -> None:
    """Raise the first limit violation of ``plan`` (a `LimitError`), with the field checked if ``L3`` [m] is given."""
    first_violation(plan, L3=L3)
