"""A plan checked against its limits for one specimen: what the engine runs, and nothing else.

The limits of a run (stretch, voltage, the field estimate with the specimen's L3) are checked once, in
preparation (`rdea_lab.runs.app.prepare_run`, and a campaign's `experiments`), by `checked_plan`. It
returns a `CheckedPlan`: the plan, the card and geometry it was checked for, and a fingerprint of what
the check read (setpoints, limits, card, L3). The engine (`rdea_lab.runs.engine.execute`) takes only a
`CheckedPlan` whose fingerprint still matches, so a plan that skipped the check, or was changed after it
(another plan put in its place, its arrays made writable and edited, other limits, another specimen),
is refused before the backend starts: nothing moves, nothing is written. The rig server checks again on
its side (``ARM``), independently.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..protocols import first_violation


class UncheckedPlan(RuntimeError):
    """The engine was given a plan that did not go through `checked_plan` (or was changed after it)."""


_NAMES = ("time", "stretch", "voltage")


def _digest(pieces) -> bytes:
    h = hashlib.sha256()
    for piece in pieces:
        h.update(np.ascontiguousarray(piece, dtype="<f8"))
    return h.digest()


def _held(plan) -> tuple:
    """The setpoint arrays a plan holds (the others are computed from its definition when read)."""
    return tuple(name for name in _NAMES if name in plan.held()) if hasattr(plan, "held") else _NAMES


def _fingerprint(plan, card, L3: float, held=None) -> str:
    """SHA-256 of what the limit check read: the setpoints, the limits, the card and its L3.

    A `~rdea_lab.protocols.Plan`'s setpoints are its definition (spec, rate, duration, samples: what any
    window is computed from) and the bytes of the arrays it holds; a long plan is never held for this.
    `held` (the arrays held when the plan was checked): an array held since is taken for the plan's only
    if it equals, bit for bit, what the definition computes.
    """
    h = hashlib.sha256()
    if hasattr(plan, "held"):
        h.update(plan.definition().encode())
        now = plan.held()
        for name in _NAMES:
            if name not in now:
                continue
            digest = _digest((now[name],))
            if held is not None and name not in held:  # read (and kept) since the check: must be the computed
                if digest != _digest(plan.rendered(name)):
                    h.update(b"edited since the check")
                continue
            h.update(name.encode() + digest)
    else:  # a plan-like object: its whole arrays
        for name in _NAMES:
            h.update(name.encode() + _digest((getattr(plan, name),)))
    dump = getattr(card, "model_dump_json", None)
    for text in (repr(plan.limits), repr(float(plan.sample_rate)), dump() if dump else repr(card), float(L3).hex()):
        h.update(text.encode())
        h.update(b"\0")
    return h.hexdigest()


@dataclass(frozen=True, eq=False)
class CheckedPlan:
    """A plan whose limits `checked_plan` checked for one specimen. Made only by `checked_plan`.

    Attributes
    ----------
    plan : Plan
        The expanded protocol (its arrays read-only).
    card : SpecimenCard
        The specimen it was checked for.
    geometry : RollGeometry or StripGeometry
        The card's geometry (its ``L3`` [m] gave the field estimate).
    fingerprint : str
        SHA-256 of the setpoints, limits, card and L3 at the time of the check.
    held : tuple of str
        The setpoint arrays the plan held then (a long plan holds none: its windows are computed).
    """

    plan: object
    card: object
    geometry: object
    fingerprint: str
    held: tuple = ()

    def intact(self) -> bool:
        """Whether the plan, the card and the geometry are still what was checked."""
        return _fingerprint(self.plan, self.card, self.geometry.L3, self.held) == self.fingerprint

    def is_for(self, card) -> bool:
        """Whether this plan was checked for ``card`` (the same specimen card) and is unchanged since."""
        return (self.card is card or self.card == card) and self.intact()


def checked_plan(plan, card, geometry) -> CheckedPlan:
    """Check a plan against its limits for a specimen: the one limit check of a run, before anything moves.

    Parameters
    ----------
    plan : Plan
    card : SpecimenCard
    geometry : RollGeometry or StripGeometry
        ``card``'s geometry; its membrane thickness ``L3`` [m] gives the field estimate.

    Returns
    -------
    CheckedPlan

    Raises
    ------
    LimitError
        The first limit the plan exceeds (stretch >= 1, ``max_stretch``, ``max_voltage``, ``max_field``;
        `rdea_lab.protocols.check_plan`).
    """
    first_violation(plan, L3=geometry.L3)
    return CheckedPlan(plan, card, geometry, _fingerprint(plan, card, geometry.L3), _held(plan))


def require_checked(checked, card):
    """The plan of ``checked`` if it went through `checked_plan` for ``card`` and is unchanged since.

    Parameters
    ----------
    checked : CheckedPlan
    card : SpecimenCard
        The specimen the run is for.

    Returns
    -------
    Plan

    Raises
    ------
    UncheckedPlan
        ``checked`` is not a `CheckedPlan` (a bare plan), or its plan, limits, card or geometry changed
        after the check, or it was checked for another specimen.
    """
    if not isinstance(checked, CheckedPlan):
        raise UncheckedPlan(f"the engine runs only a plan checked against its limits, not a "
                            f"{type(checked).__name__}: prepare the run (rdea_lab.prepare_run) or check it with "
                            "rdea_lab.runs.checked_plan(plan, card, geometry); nothing was started")
    if not (checked.card is card or checked.card == card):
        raise UncheckedPlan(f"the plan was checked for specimen {getattr(checked.card, 'id', '?')!r}, the run is "
                            f"on {getattr(card, 'id', '?')!r}: check it for this specimen; nothing was started")
    if not checked.intact():
        raise UncheckedPlan("the plan (its setpoints or limits), card or geometry changed after its limits were "
                            "checked: check it again; nothing was started")
    return checked.plan


__all__ = ["CheckedPlan", "UncheckedPlan", "checked_plan", "require_checked"]
