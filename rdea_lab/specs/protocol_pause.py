"""How a run pauses: a protocol's optional ``pause:`` mapping (`Pause`), in SI.

::

    pause: {ramp_rate: 1 kV/s, hold_stretch: 1.05, stretch_rate: 0.05 /s}

Every key is optional. A pause takes the voltage to 0 at ``ramp_rate``, holds the stretch where it
was or, once the voltage is 0, takes it to ``hold_stretch`` at ``stretch_rate``; a resume goes back
the same way (`rdea_lab.protocols.pause` drives it). ``hold_stretch`` is checked against the
protocol's ``limits.max_stretch`` where the protocol is read (`ProtocolSpec`).
"""

from __future__ import annotations

import math
import numbers
from typing import Annotated, Any

from pydantic import AfterValidator, BeforeValidator

from .base import SpecModel, units_required
from .errors import SpecError, show
from .units import _NUMBER, format_quantity, parse_quantity, quantity

#: Voltage ramp rate of a pause when the protocol declares none [V/s]: 2.6 kV (the paper's largest voltage)
#: is off in 2.6 s.
DEFAULT_RAMP_RATE = 1000.0
#: Stretch rate to and from a declared ``hold_stretch`` when the protocol gives none [1/s].
DEFAULT_STRETCH_RATE = 0.05


def _stretch_rate(value: Any) -> float:
    """A stretch rate [1/s] from ``"0.05 /s"`` (also ``"0.05 1/s"``, ``"5 %/s"``); from Python a number is
    1/s."""
    example = "give a stretch rate, e.g. '0.05 /s'"
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and not units_required():
        if not math.isfinite(value):
            raise SpecError("", "", f"{value} is not a finite number; {example}")
        return float(value)
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        raise SpecError("", "", f"'{value}' has no unit; give a stretch rate, e.g. '{value} /s'")
    match = _NUMBER.match(value) if isinstance(value, str) else None
    if match is not None and match.group(2).startswith("/"):  # '0.05 /s' reads as 0.05 per second
        value = f"{match.group(1)} 1{match.group(2)}"
    try:
        return parse_quantity(value, "frequency", source="", field="")
    except SpecError:
        raise SpecError("", "", f"{show(value)} is not a stretch rate; {example} (stretch per second)") from None


def _positive_rate(value: float) -> float:
    if not value > 0.0:
        raise SpecError("", "", f"must be > 0 /s, got {_rate_text(value)}")
    return value


def _at_least_one(value: float) -> float:
    if not value >= 1.0:
        raise SpecError("", "", f"stretch {value:g} is below 1; the roll must stay in tension; allowed: "
                        "1 <= hold_stretch <= limits.max_stretch")
    return value


def _rate_text(value: float) -> str:
    """A stretch rate [1/s] as ``"0.05 /s"`` (reads back equal)."""
    return format_quantity(value, "1/s").replace(" 1/s", " /s")


class Pause(SpecModel):
    """How a run pauses and resumes (SI): the protocol's ``pause:`` mapping.

    Attributes
    ----------
    ramp_rate : float
        Voltage ramp to 0 and back [V/s], finite and > 0; `DEFAULT_RAMP_RATE` (1 kV/s) if not given.
    hold_stretch : float or None
        The stretch held while paused [-], ``1 <= hold_stretch <= limits.max_stretch``; None (not given)
        holds the stretch the plan had when the pause began.
    stretch_rate : float
        Stretch rate to and from `hold_stretch` [1/s], > 0; `DEFAULT_STRETCH_RATE` (0.05 /s) if not given.
    """

    ramp_rate: quantity("voltage_rate", "kV/s", gt=0.0) = DEFAULT_RAMP_RATE
    hold_stretch: Annotated[quantity("dimensionless", ""), AfterValidator(_at_least_one)] | None = None
    stretch_rate: Annotated[float, BeforeValidator(_stretch_rate), AfterValidator(_positive_rate)] = \
        DEFAULT_STRETCH_RATE

    def _form(self) -> dict:
        """The YAML form (``pause:`` of a protocol's file): both rates, and the hold stretch if given."""
        out: dict[str, Any] = {"ramp_rate": format_quantity(self.ramp_rate, "kV/s")}
        if self.hold_stretch is not None:
            out["hold_stretch"] = float(self.hold_stretch)
        out["stretch_rate"] = _rate_text(self.stretch_rate)
        return out


__all__ = ["DEFAULT_RAMP_RATE", "DEFAULT_STRETCH_RATE", "Pause"]
