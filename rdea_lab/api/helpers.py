"""Small pieces of the application layer that belong to no lower layer."""

from __future__ import annotations

from ..physics.geometry import geometry_from_card
from ..protocols import first_violation
from ..specs import SpecError, as_specimen

__all__ = ["check_plan", "geometry"]


def geometry(specimen):
    """The `RollGeometry` (or `StripGeometry`) of a card or a card's path.

    Raises
    ------
    SpecError
        The card describes no possible roll (naming the card).
    """
    card = as_specimen(specimen)
    try:
        return geometry_from_card(card)
    except ValueError as exc:
        raise SpecError(str(specimen) if isinstance(specimen, str) else card.id, "<document>", str(exc)) from None


def check_plan(plan, L3=None) -> None:
    """Raise the first limit violation of ``plan`` (a `LimitError`), with the field checked if ``L3`` [m] is given."""
    first_violation(plan, L3=L3)
