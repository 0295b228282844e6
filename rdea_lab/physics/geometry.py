"""Roll geometry: the three concentric rings of the 3R model and their radii.

The radii follow from the unwound membrane by the Appendix of [1]
(eqs. (45)-(58)), with the corrections listed in ``paper/ERRATA.md``:
(46) integrates the arc length (the norm, not its square) and (57)-(58) put
the square root over the whole volume balance.

References
----------
.. [1] Prechtl et al., Smart Mater. Struct. (2021), doi:10.1088/1361-665X/ac34be
"""

from __future__ import annotations

import os

from dataclasses import dataclass

import numpy as np

from .constants import EPS0


def spiral_length(r0, d, theta):
    """Arc length of an Archimedean spiral ``r = r0 + d theta / (2 pi)``.

    Parameters
    ----------
    r0 : array_like
        Starting radius [m].
    d : array_like
        Separation between adjacent turns [m].
    theta : array_like
        Accumulated turning angle [rad].

    Returns
    -------
    numpy.ndarray
        Arc length from angle 0 to ``theta`` [m].

    Notes
    -----
    Eq. (46) in [1], corrected in ERRATA (the integrand is the speed
    ``sqrt(b**2 + r**2)``, ``b = d / 2 pi``, not its square). Closed form:
    ``(F(r) - F(r0)) / (2 b)`` with ``F(u) = u sqrt(u**2 + b**2) + b**2 asinh(u / b)``.
    """
    r0, d, theta = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (r0, d, theta)))
    b = d / (2.0 * np.pi)
    r = r0 + b * theta

    def antiderivative(u):
        return u * np.hypot(u, b) + b**2 * np.arcsinh(u / b)

    return (antiderivative(r) - antiderivative(r0)) / (2.0 * b)


def spiral_angle(r0, d, length, *, rtol=1e-15, max_iter=50):
    """Turning angle at which an Archimedean spiral reaches a given arc length.

    Parameters
    ----------
    r0 : array_like
        Starting radius [m].
    d : array_like
        Separation between adjacent turns [m].
    length : array_like
        Arc length [m], >= 0.

    Returns
    -------
    numpy.ndarray
        Turning angle [rad].

    Notes
    -----
    Eq. (47) in [1], solved by Newton's method on the monotone
    :func:`spiral_length` (its derivative is the speed ``sqrt(b**2 + r**2)``),
    started from the area estimate ``r**2 = r0**2 + 2 b length``.
    """
    r0, d, length = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (r0, d, length)))
    b = d / (2.0 * np.pi)
    theta = (np.sqrt(r0**2 + 2.0 * b * length) - r0) / b
    for _ in range(max_iter):
        step = (spiral_length(r0, d, theta) - length) / np.hypot(b, r0 + b * theta)
        theta = theta - step
        if np.all(np.abs(step) <= rtol * np.maximum(np.abs(theta), 1.0)):
            break
    return theta


def radii_from_membrane(L2, L3, Lp1, L2e, Ri=0.0, *, check=True):
    """Radii of the three rings from the unwound membrane (Appendix of [1]).

    Parameters
    ----------
    L2 : float or array_like
        Membrane length in the rolling direction [m].
    L3 : float or array_like
        Thickness of one membrane [m]; the rolled stack is two membranes.
    Lp1 : float or array_like
        Electrode-free length at the start of rolling [m].
    L2e : float or array_like
        Electrode length in the rolling direction [m].
    Ri : float or array_like, optional
        Inner radius of the roll [m]; eq. (52) sets it to 0.
    check : bool, optional
        Raise a ValueError for a membrane that rolls into no roll (no fully
        active region, ``Lp1 + L2e > L2``). With ``check=False`` such entries
        are NaN instead (a design study's arrays of membranes).

    Returns
    -------
    dict
        ``Ri, Rie, Roe, Ro`` [m] and the intermediate lengths ``theta_p1``
        [rad], ``L_pa``, ``L_fa``, ``L_p2`` [m]: floats for scalar inputs,
        arrays of the inputs' broadcast shape otherwise.

    Notes
    -----
    Eqs. (48)-(58) in [1]; (57) and (58) as corrected in ERRATA, and (53)
    generalised to ``Ri > 0``: ``pi (Rie**2 - Ri**2) = L3 (2 Lp1 + L_pa)``.
    By construction ``pi (Ro**2 - Ri**2) = 2 L2 L3``: the rolled volume equals
    the flat one.
    """
    L2, L3, Lp1, L2e, Ri = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (L2, L3, Lp1, L2e, Ri)))
    d = 2.0 * L3
    theta_p1 = spiral_angle(Ri, d, Lp1)
    L_pa = spiral_length(Ri, d, theta_p1 + 2.0 * np.pi) - Lp1
    L_fa = L2e - L_pa
    L_p2 = L2 - Lp1 - L2e
    bad = ~(L_fa > 0) | ~(L_p2 >= 0)
    if check and np.any(bad):
        i = np.flatnonzero(bad.ravel())[0]
        fa, p2 = L_fa.ravel()[i], L_p2.ravel()[i]
        where = f" (entry {i} of {bad.size})" if bad.ndim else ""
        if not fa > 0:
            raise ValueError(
                f"the electrode length L2e = {L2e.ravel()[i]:g} m is shorter than the partially "
                f"active first turn ({L_pa.ravel()[i]:g} m): no fully active region; that turn's length comes "
                f"from the thickness L3 = {L3.ravel()[i]:g} m and Lp1 = {Lp1.ravel()[i]:g} m, so check their "
                f"units as well as L2e's{where}"
            )
        raise ValueError(f"Lp1 + L2e = {Lp1.ravel()[i] + L2e.ravel()[i]:g} m exceeds L2 = {L2.ravel()[i]:g} m"
                         f"{where} (by {-p2:g} m)")
    with np.errstate(invalid="ignore"):
        Rie = np.sqrt(L3 * (2.0 * Lp1 + L_pa) / np.pi + Ri**2)
        Roe = np.sqrt(L3 * (2.0 * L_fa + L_pa) / np.pi + Rie**2)
        Ro = np.sqrt(2.0 * L3 * L_p2 / np.pi + Roe**2)
    out = {"Ri": Ri, "Rie": Rie, "Roe": Roe, "Ro": Ro, "theta_p1": theta_p1, "L_pa": L_pa, "L_fa": L_fa,
           "L_p2": L_p2}
    out = {k: np.where(bad, np.nan, v) for k, v in out.items()}
    if bad.ndim == 0:
        return {k: float(v) for k, v in out.items()}
    return out


@dataclass(frozen=True)
class RollGeometry:
    """Undeformed geometry of a roll: ring radii and axial lengths, SI.

    Attributes
    ----------
    Ri, Rie, Roe, Ro : float
        Inner radius of ring a, a/b interface, b/c interface, outer radius [m].
    L1 : float
        Roll length along the axis [m].
    L1e : float
        Electrode length along the axis [m].
    L3 : float
        Single-membrane thickness [m].
    """

    Ri: float
    Rie: float
    Roe: float
    Ro: float
    L1: float
    L1e: float
    L3: float

    def __post_init__(self):
        # scalars (one roll) or arrays of one shape (a design study's rolls, broadcast against samples)
        Ri, Rie, Roe, Ro, L1, L1e, L3 = (np.asarray(getattr(self, k), float)
                                         for k in ("Ri", "Rie", "Roe", "Ro", "L1", "L1e", "L3"))
        order = (0.0 <= Ri) & (Ri <= Rie) & (Rie < Roe) & (Roe <= Ro)
        if not np.all(order):
            i = np.flatnonzero(~np.broadcast_to(order, np.broadcast(Ri, Rie, Roe, Ro).shape).ravel())[0]
            at = lambda a: float(np.broadcast_to(a, order.shape).ravel()[i])  # noqa: E731
            raise ValueError(
                "radii must satisfy 0 <= Ri <= Rie < Roe <= Ro, got "
                f"Ri={at(Ri):g}, Rie={at(Rie):g}, Roe={at(Roe):g}, Ro={at(Ro):g} m"
            )
        if np.any((Ri == 0.0) & (Rie < 1e-6 * Ro)):
            raise ValueError(
                f"Rie = {float(np.min(Rie)):g} m is below 1e-6 Ro with Ri = 0: as the passive core shrinks "
                "the 3R model tends to the SU model (the core forbids the hole to open), and "
                "Rie = 0 would drop that constraint; give Rie >= 1e-6 Ro or use the SU model"
            )
        if not (np.all(0.0 < L1e) and np.all(L1e <= L1)) or not np.all(L3 > 0.0):
            raise ValueError(f"need 0 < L1e <= L1 and L3 > 0, got L1e={np.min(L1e):g}, L1={np.min(L1):g}, "
                             f"L3={np.min(L3):g} m")

    @property
    def area(self) -> float:
        """Undeformed cross-section ``pi (Ro**2 - Ri**2)`` [m^2]."""
        return np.pi * (self.Ro**2 - self.Ri**2)

    @property
    def volume(self) -> float:
        """Material volume ``Omega`` [m^3], eq. (15)."""
        return self.area * self.L1

    def _fraction(self, inner, outer):
        return (outer**2 - inner**2) / (self.Ro**2 - self.Ri**2)

    @property
    def eta_a(self) -> float:
        """Volume fraction of the inner passive ring a, eq. (10)."""
        return self._fraction(self.Ri, self.Rie)

    @property
    def eta_b(self) -> float:
        """Volume fraction of the active ring b, eq. (11)."""
        return self._fraction(self.Rie, self.Roe)

    @property
    def eta_c(self) -> float:
        """Volume fraction of the outer passive ring c, eq. (12)."""
        return self._fraction(self.Roe, self.Ro)

    @property
    def alpha_e1(self) -> float:
        """Electrode coverage along the axis ``L1e / L1``, eq. (13)."""
        return self.L1e / self.L1

    @staticmethod
    def carried_force(force):
        """The force the roll carries [N]: a roll clamped shorter than its free length
        buckles instead of pushing (Assumption 1 of [1]: it is only ever in tension),
        so a compressive model force reads 0 (slack)."""
        return np.maximum(force, 0.0)

    def C0(self, eps_r: float) -> float:
        """Capacitance of the undeformed roll [F], eq. (29).

        ``C0 = eps0 eps_r alpha_e1 L1 pi (Roe**2 - Rie**2) / L3**2``.
        """
        return EPS0 * eps_r * self.alpha_e1 * self.L1 * np.pi * (self.Roe**2 - self.Rie**2) / self.L3**2

    def as_dict(self, eps_r: float | None = None) -> dict:
        """Radii, volume fractions, alpha_e1 and (with ``eps_r``) C0, SI."""
        out = {
            "Ri": self.Ri, "Rie": self.Rie, "Roe": self.Roe, "Ro": self.Ro,
            "L1": self.L1, "L1e": self.L1e, "L3": self.L3,
            "eta_a": self.eta_a, "eta_b": self.eta_b, "eta_c": self.eta_c,
            "alpha_e1": self.alpha_e1,
        }
        if eps_r is not None:
            out["eps_r"] = float(eps_r)
            out["C0"] = self.C0(eps_r)
        return {k: float(v) for k, v in out.items()}


@dataclass(frozen=True)
class StripGeometry:
    """A flat strip in uniaxial tension (a membrane before it is rolled, as in ref. [36] of [1]).

    It offers the interface of :class:`RollGeometry` that the SU and 1R models
    use, so those models apply unchanged: the 1R model is "formally identical to
    the one for strip-shaped DE membranes" (Section 3.2 of [1]), its sides free
    of traction; at 0 V it is plain uniaxial tension. The electrode covers
    ``electrode_length x electrode_width``; the voltage acts across the
    thickness. There are no rings: the 3R model does not apply.

    Attributes
    ----------
    length, width, thickness : float
        Undeformed dimensions [m].
    electrode_length, electrode_width : float
        Electrode dimensions [m] (0: no electrode).
    """

    length: float
    width: float
    thickness: float
    electrode_length: float = 0.0
    electrode_width: float = 0.0
    kind = "strip"
    # no rings: radii are undefined
    Ri = Rie = Roe = Ro = float("nan")

    def __post_init__(self):
        if not (self.length > 0 and self.width > 0 and self.thickness > 0):
            raise ValueError(f"a strip needs length, width, thickness > 0, got {self.length:g}, {self.width:g}, "
                             f"{self.thickness:g} m")
        if not (0 <= self.electrode_length <= self.length and 0 <= self.electrode_width <= self.width):
            raise ValueError("the electrode must fit on the strip")

    L1 = property(lambda self: self.length, doc="Length along the stretch [m].")
    L1e = property(lambda self: self.electrode_length, doc="Electrode length along the stretch [m].")
    L3 = property(lambda self: self.thickness, doc="Thickness the voltage acts across [m].")

    @property
    def area(self) -> float:
        """Undeformed cross-section ``width x thickness`` [m^2]."""
        return self.width * self.thickness

    @property
    def volume(self) -> float:
        return self.area * self.length

    @property
    def eta_b(self) -> float:
        """Active fraction across the width (with ``alpha_e1`` along the length)."""
        return self.electrode_width / self.width

    eta_a = property(lambda self: 0.0)
    eta_c = property(lambda self: 1.0 - self.electrode_width / self.width)

    @property
    def alpha_e1(self) -> float:
        return self.electrode_length / self.length

    @staticmethod
    def carried_force(force):
        """The force the strip can carry [N]: a thin membrane buckles (goes slack)
        instead of carrying compression, so a compressive model force reads 0."""
        return np.maximum(force, 0.0)

    def C0(self, eps_r: float) -> float:
        """Capacitance of the undeformed strip ``eps0 eps_r A_e / thickness`` [F]."""
        return EPS0 * eps_r * self.electrode_length * self.electrode_width / self.thickness

    def as_dict(self, eps_r: float | None = None) -> dict:
        out = {"length": self.length, "width": self.width, "thickness": self.thickness,
               "electrode_length": self.electrode_length, "electrode_width": self.electrode_width,
               "area": self.area, "alpha_e1": self.alpha_e1, "eta_b": self.eta_b}
        if eps_r is not None:
            out["eps_r"] = float(eps_r)
            out["C0"] = self.C0(eps_r)
        return {k: float(v) for k, v in out.items()}


def geometry_from_card(card) -> RollGeometry | StripGeometry:
    """Build the :class:`RollGeometry` of a specimen card.

    Parameters
    ----------
    card : rdea_lab.specs.specimen.SpecimenCard
        A roll card with either ``membrane`` (unwound dimensions, radii by the
        Appendix of [1]) or ``radii`` given directly, or a strip card
        (:class:`StripGeometry`).
    """
    if isinstance(card, (str, os.PathLike)):
        raise TypeError(f"geometry_from_card takes a SpecimenCard, not the path {str(card)!r}: physics reads no "
                        "files; use rdea_lab.geometry(path) or rdea_lab.load_specimen(path)")
    if getattr(card, "kind", "roll") == "strip":
        e = card.electrode
        return StripGeometry(card.length, card.width, card.thickness, e.length if e else 0.0, e.width if e else 0.0)
    if card.membrane is not None:
        m = card.membrane
        r = radii_from_membrane(m.L2, m.L3, m.Lp1, m.L2e, Ri=m.Ri)
        return RollGeometry(r["Ri"], r["Rie"], r["Roe"], r["Ro"], m.L1, m.L1e, m.L3)
    r = card.radii
    return RollGeometry(r.Ri, r.Rie, r.Roe, r.Ro, card.L1, card.L1e, card.L3)
