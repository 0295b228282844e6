"""Small pieces of the application layer that belong to no lower layer."""

from __future__ import annotations

from ..backends.rig import RigRefused
from ..calibration.app import KINDS as CALIBRATION_KINDS
from ..physics.geometry import geometry_from_card
from ..physics.result import ModelNotApplicable, StretchBelowOneError
from ..protocols import first_violation
from ..reports.reproduce import ReproduceInputError
from ..reports.validation import ReportInputError
from ..specs import SpecError, UserError, as_specimen
from ..specs.importing import FORMATS as IMPORT_FORMATS
from ..specs.importing import KINDS as IMPORT_KINDS
from ..specs.importing import MIN_STRETCH as IMPORT_MIN_STRETCH

#: A user's mistakes: the CLI gives them exit status 2 and one line (all derive from `UserError`).
USER_ERRORS = (UserError,)
assert all(issubclass(e, UserError) for e in (SpecError, StretchBelowOneError, ModelNotApplicable, RigRefused,
                                              ReportInputError, ReproduceInputError))

__all__ = ["check_plan", "CALIBRATION_KINDS", "IMPORT_FORMATS", "IMPORT_KINDS", "IMPORT_MIN_STRETCH", "USER_ERRORS", "geometry"]


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
