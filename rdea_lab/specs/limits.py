"""Safety limits: the `Limits` of a protocol (or a target), and their check on setpoint or
stretch/voltage arrays, before anything moves.

One implementation of the check for a protocol's plan (`rdea_lab.protocols.check_plan`, which
passes the segment each sample belongs to) and for a bare history given to the
twin with a protocol (`rdea_lab.twin.predict`). The rig server keeps its own,
independent check (it is the stand-in for separate hardware).
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from pydantic import AfterValidator

from .base import SpecModel
from .errors import SpecError
from .names import MAX_STRETCH
from .units import format_quantity, quantity

#: Ceilings of the safety limits: a limit above them is no limit of a rolled DEA on a bench rig but a unit
#: mistake (``max_force: 1e308 N``). High-voltage amplifiers for DEAs reach 10-30 kV; the paper's roll pulls a
#: few newtons, and a 1 kN load cell is far beyond such a rig; no elastomer holds 1000 V/um (VHB breaks
#: near 100-400 V/um); stretch at most `MAX_STRETCH`.
LIMIT_CEILINGS = {"max_voltage": 30e3, "max_stretch": MAX_STRETCH, "max_force": 1e3, "max_field": 1000e6}


def _ceiling(name: str, unit: str, why: str):
    top = LIMIT_CEILINGS[name]

    def check(value: float) -> float:
        if not value <= top:
            bottom = "1 <=" if name == "max_stretch" else f"0 {unit} <"
            shown = f"{value:g}" if name == "max_stretch" else format_quantity(value, unit, digits=6)
            raise SpecError("", "", f"{shown} is above any real limit ({why}); allowed: {bottom} {name} <= "
                            f"{f'{top:g}' if name == 'max_stretch' else format_quantity(top, unit)}")
        return value

    return AfterValidator(check)


class Limits(SpecModel):
    """Safety limits of a protocol (SI), each at most its `LIMIT_CEILINGS` value.

    Read from a file as the ``limits:`` mapping of a protocol or a target (quantities with units,
    ``{max_voltage: 3 kV, max_field: 80 V/um}``; the limits not given keep their defaults).

    Attributes
    ----------
    max_voltage : float
        Largest allowed ``|voltage|`` [V]; 3 kV by default.
    max_stretch : float
        Largest allowed stretch [-]; 2.0 by default.
    max_force : float
        Largest allowed ``|force|`` [N], enforced while running; 50 N by default.
    max_field : float
        Largest allowed field estimate ``|v| sqrt(stretch) / L3`` [V/m]; 80 V/um by default.
    """

    max_voltage: Annotated[quantity("voltage", "kV", gt=0.0),
                           _ceiling("max_voltage", "kV", "DEA amplifiers reach 10-30 kV")] = 3e3
    max_stretch: Annotated[quantity("dimensionless", "", ge=1.0),
                           _ceiling("max_stretch", "", "no elastomer is drawn 20-fold")] = 2.0
    max_force: Annotated[quantity("force", "N", gt=0.0),
                         _ceiling("max_force", "N", "a rolled DEA pulls a few newtons; 1 kN is beyond the rig")] = 50.0
    max_field: Annotated[quantity("electric_field", "V/um", gt=0.0),
                         _ceiling("max_field", "V/um", "elastomers break down near 100-400 V/um")] = 80e6

    @classmethod
    def from_options(cls, values: dict, source: str = "command line") -> "Limits":
        """Limits from option texts (``{"max_voltage": "3 kV", ...}``); a bad one is a `SpecError` naming
        the option (``--max-voltage``).

        Parameters
        ----------
        values : dict
            Limit name -> text with its unit (or a number in SI).
        source : str
            Where the options came from, for the message.

        Returns
        -------
        Limits

        Raises
        ------
        SpecError
            A limit that is not a quantity of its kind, not above 0 (stretch: below 1), or above its
            `LIMIT_CEILINGS` value; the field is the option (``--max-voltage``).
        """
        try:
            return cls(**values)
        except SpecError as err:
            raise SpecError(source, "--" + err.field.replace("_", "-"), err.message) from None

    def _form(self) -> dict:
        """The YAML form, each limit with its unit (``limits:`` of a protocol's file)."""
        return {
            "max_voltage": format_quantity(self.max_voltage, "kV"),
            "max_stretch": self.max_stretch,
            "max_force": format_quantity(self.max_force, "N"),
            "max_field": format_quantity(self.max_field, "V/um"),
        }


#: relative slack of the limit checks: rounding of a ramp or sine that ends
#: exactly on a limit (a stretch of 1 - 1e-16) is not a violation
SLACK = 1e-12


class LimitError(SpecError):
    """A setpoint or history beyond a safety limit, found before anything moved (exit status 2).

    ``str`` is one line, ``"{source}: {field}: {message}"``, e.g. ``protocols/x.yaml: voltage[1]: voltage
    3.2 kV at t = 4 s is above the limit max_voltage = 3 kV``.

    Parameters
    ----------
    source : str
        Where the setpoints come from: the protocol file (or ``"<limits>"`` for bare limits).
    field : str
        The channel and, for a plan, the segment holding the worst sample (``stretch[0]``,
        ``voltage[1]``); ``stretch`` or ``voltage`` for a bare history.
    message : str
        The worst value with its unit, its time [s], the limit and the span that exceeds it.
    """


def _seconds(t: float) -> str:
    return format_quantity(t, "s", digits=6)


def _shown(value: float, limit: float, fmt) -> str:
    """`value` with just enough digits to differ from `limit`."""
    for digits in (4, 6, 9, 12, 17):
        text = fmt(value, digits)
        if text != fmt(limit, digits):
            return text
    return text


def field_estimate(voltage, stretch, L3):
    """The field estimate ``|v| sqrt(stretch) / L3`` [V/m] a limit is checked against (the membrane thins
    as ``1 / sqrt(stretch)`` under uniaxial stretch)."""
    with np.errstate(invalid="ignore", over="ignore"):
        return np.abs(np.asarray(voltage, float)) * np.sqrt(np.maximum(np.asarray(stretch, float), 0.0)) / L3


class Violations:
    """Limit violations gathered over consecutive windows of one history (`limit_violations` in pieces).

    ``add`` each window in order; ``errors`` gives what `limit_violations` gives for the whole history:
    for every check and segment, the first and last exceeding sample, their count and the worst one (the
    first of equal worst ones), so a plan too long to hold is checked in windows with the same errors.

    Parameters
    ----------
    limits : Limits
    source : str
        Where the arrays come from (a protocol file), for the messages.
    L3 : float, optional
        Membrane thickness of the specimen [m]; without it no field check.
    """

    def __init__(self, limits: Limits, source: str, L3: float | None = None):
        if L3 is not None and not (math.isfinite(L3) and L3 > 0.0):
            raise ValueError(f"L3 must be a finite thickness > 0 m, got {L3!r}")
        self.limits, self.source, self.L3 = limits, source, L3
        #: (order, segment) -> [t_first, t_last, count, worst excess, worst sample's (t, x, v, E), channel]
        self._found: dict = {}

    def add(self, time, stretch, voltage, stretch_segment=None, voltage_segment=None) -> None:
        """Check one window: sample times [s], stretch [-], voltage [V] and, optionally, each sample's
        segment per channel (then the fields are ``stretch[i]``, ``voltage[i]``). NaN samples are not
        checked."""
        lim = self.limits
        t = np.asarray(time, float)
        x = np.asarray(stretch, float)
        v = np.broadcast_to(np.asarray(voltage, float), x.shape)
        ss = None if stretch_segment is None else np.asarray(stretch_segment)
        vs = None if voltage_segment is None else np.asarray(voltage_segment)
        with np.errstate(invalid="ignore"):
            av = np.abs(v)
            E = None if self.L3 is None else field_estimate(v, x, self.L3)
            self._report(0, x < 1.0 - SLACK, 1.0 - x, "stretch", ss, t, x, v, E)
            self._report(1, x > lim.max_stretch * (1.0 + SLACK), x - lim.max_stretch, "stretch", ss, t, x, v, E)
            self._report(2, av > lim.max_voltage * (1.0 + SLACK), av, "voltage", vs, t, x, v, E)
            if E is not None:
                self._report(3, E > lim.max_field * (1.0 + SLACK), E, "voltage", vs, t, x, v, E)

    def _report(self, order, mask, excess, channel, segment, t, x, v, E):
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            return
        groups = [idx] if segment is None else np.split(idx, np.flatnonzero(np.diff(segment[idx])) + 1)
        for group in groups:
            worst = int(group[np.argmax(excess[group])])
            key = (order, None if segment is None else int(segment[worst]))
            sample = (float(t[worst]), float(x[worst]), float(v[worst]), None if E is None else float(E[worst]))
            known = self._found.get(key)
            if known is None:
                self._found[key] = [float(t[group[0]]), float(t[group[-1]]), group.size, float(excess[worst]),
                                    sample, channel]
                continue
            known[1], known[2] = float(t[group[-1]]), known[2] + group.size
            if excess[worst] > known[3]:  # the first of equal worst ones stays
                known[3], known[4] = float(excess[worst]), sample

    def errors(self) -> list[LimitError]:
        """The violations found so far, one `LimitError` per check and segment, by the time each limit is
        first exceeded (as `limit_violations`)."""
        lim, L3 = self.limits, self.L3
        plain = lambda value, digits: f"{value:.{digits}g}"  # noqa: E731
        volts = lambda value, digits: format_quantity(value, "kV", digits=digits)  # noqa: E731
        field = lambda value, digits: format_quantity(value, "V/um", digits=digits)  # noqa: E731
        out = []
        for (order, segment), (t0, t1, count, _, (t, x, v, E), channel) in self._found.items():
            at = f"at t = {_seconds(t)}"
            if order == 0:
                message = f"stretch {_shown(x, 1.0, plain)} {at} is below 1; the roll must stay in tension"
            elif order == 1:
                message = (f"stretch {_shown(x, lim.max_stretch, plain)} {at} is above the limit "
                           f"max_stretch = {lim.max_stretch:g}")
            elif order == 2:
                message = (f"voltage {_shown(v, math.copysign(lim.max_voltage, v), volts)} {at} is "
                           f"{'above' if v > 0 else 'beyond (in magnitude)'} the limit "
                           f"max_voltage = {volts(lim.max_voltage, 4)}")
            else:
                message = (f"field estimate |v| sqrt(stretch) / L3 = {_shown(E, lim.max_field, field)} "
                           f"(voltage {volts(v, 4)}, stretch {x:.4g}, L3 = {format_quantity(L3, 'um', digits=4)}) "
                           f"{at} is above the limit max_field = {field(lim.max_field, 4)}")
            span = f" (exceeded from t = {_seconds(t0)} to {_seconds(t1)})" if count > 1 else ""
            name = channel if segment is None else f"{channel}[{segment}]"
            out.append((t0, order, LimitError(self.source, name, f"{message}{span}")))
        out.sort(key=lambda item: (item[0], item[1]))
        return [err for _, _, err in out]


def limit_violations(limits: Limits, source: str, time, stretch, voltage, L3: float | None = None,
                     stretch_segment=None, voltage_segment=None) -> list[LimitError]:
    """Every limit violation of stretch and voltage arrays, one `LimitError` per check and segment.

    Checks: stretch >= 1 (the roll must stay in tension), stretch <=
    ``max_stretch``, ``|voltage| <= max_voltage`` and, if `L3` is given, the
    field estimate ``E = |v| sqrt(stretch) / L3 <= max_field``. ``max_force``
    is enforced while running, not here.

    Parameters
    ----------
    limits : Limits
    source : str
        Where the arrays come from (a protocol file), for the messages.
    time, stretch, voltage : array_like, shape (n,)
        Sample times [s], stretch [-], voltage [V]. NaN samples are not checked.
    L3 : float, optional
        Membrane thickness of the specimen [m].
    stretch_segment, voltage_segment : array_like of int, optional
        Segment of each sample, per channel (a plan's); the error's field is then
        ``stretch[i]`` / ``voltage[i]``, else ``stretch`` / ``voltage``.

    Returns
    -------
    list of LimitError
        The message names the worst value, its time, the limit and, if more
        than one sample exceeds it, the span. Ordered by the time the limit is
        first exceeded. Empty if every sample is within the limits.
        (`Violations` gathers the same over windows of a long history.)
    """
    found = Violations(limits, source, L3)
    found.add(time, stretch, voltage, stretch_segment, voltage_segment)
    return found.errors()


def check_limits(limits: Limits, source: str, time, stretch, voltage, L3: float | None = None,
                 stretch_segment=None, voltage_segment=None) -> None:
    """Raise the first `LimitError` of `limit_violations`, if any."""
    problems = limit_violations(limits, source, time, stretch, voltage, L3, stretch_segment, voltage_segment)
    if problems:
        raise problems[0]
