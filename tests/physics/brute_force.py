"""A slow, straightforward reference for the rising-ramp rule of the 1R and 3R models.

For one roll, material and stretch the 1R and 3R models have one free
coordinate ``y`` (1R: the hoop stretch ``lambda2``; 3R: ``xi = r_i / Ro``)
and their equilibria are the stationary points of the free enthalpy density

    g(y) = psi(y) - v**2 c(y)

(``c`` here per volt squared, so ``h = dpsi/dc`` is the voltage squared at
which ``y`` is an equilibrium). The state a quasi-static voltage ramp reaches
from the unloaded roll ``y0`` is the first local minimum of ``g`` met walking
from ``y0``; the ramp snapped through on the way iff ``h`` is not monotone on
``[y0, y*]``.

This module finds both by brute force: ``g`` on a dense graded grid (about
2e5 points, one numpy expression over the grid), the first grid minimum,
a bounded Brent refinement on ``g`` (polished by the root of the reference's own
closed-form ``dg/dy``), and the monotonicity of ``h`` from finite
differences of ``psi`` and ``c``. It shares nothing with the package's
solver (no analytic derivatives, no branch following).

Why ``g - g(y0)`` and not the package's ``enthalpy`` directly: ``enthalpy``
returns ``g`` in double precision, with an absolute rounding of about
``eps * psi(y0)``. The 3R roll with ``Ri = 0`` and a small core has its
whole structure near ``y0`` (the opening of the hole) at energy differences
of ``eta_a W ~ (Rie/Ro)**2 C10``, far below that rounding at a stretch above
1 (``Rie/Ro = 1e-6``: 1e-7 Pa against 1e-11 Pa of a 1e5 Pa energy, and the
fold structure of ``h`` is lost entirely). So the reference evaluates the
difference ``g(y) - g(y0)`` in closed form without cancellation (below,
from the kinematics of the three_ring docstring and ERRATA) and checks it
against the package's ``enthalpy`` at every tenth grid point, to the
enthalpy's rounding: the reference and the package solve the same model, or
the reference raises :class:`ReferenceModelMismatch`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from rdea_lab.physics.models import one_ring, three_ring

EPS = np.finfo(float).eps
#: End of the admissible range: the active ring's hoop stretch at this multiple
#: of the uniaxial value ``stretch**-0.5``.
HOOP_FACTOR = 10.0
#: Grid points in ``y`` (before de-duplication).
N_GRID = 200_000
#: Rounding allowance of one evaluated energy difference, relative to the size of
#: its terms: a few tens of roundings, generous for an expression of ~20 operations.
NOISE = 64.0 * EPS
#: Probe voltage [V] that separates the electrical part of the package's enthalpy:
#: large enough that ``v**2 c`` swamps ``psi``, so ``c`` comes out to rounding.
V_PROBE = 1e6
#: Relative width in ``c - c(y0)`` of the secant windows that estimate ``h``.
WINDOW = 1e-6
#: Comparison tolerance on the free coordinate, as a fraction of the admissible range.
Y_TOL = 1e-6

OK, LIMIT_POINT, SNAPPED, OUTSIDE_RANGE = 0, 1, 4, 6


class ReferenceModelMismatch(AssertionError):
    """The reference's closed-form ``g - g(y0)`` disagrees with the package's ``enthalpy``."""


@dataclass(frozen=True)
class RisingState:
    """What a voltage ramp from 0 V reaches at one stretch and voltage, by brute force.

    ``y`` is the free coordinate (1R: ``lambda2``; 3R: ``r_i / Ro``); ``tol``
    how far a solver's ``y`` may be from it (``Y_TOL`` of the range, or the
    width over which ``g`` is flat to rounding, ``2 band``, if larger). ``fold`` is a fold
    on ``[y0, y]`` when ``found``, anywhere in range otherwise;
    ``fold_voltage`` [V] the first fold's voltage (NaN without one);
    ``max_voltage`` [V] the largest voltage with an equilibrium in range,
    ``sqrt(max h)``. Where no state is found: if that largest ``h`` is a
    fold's (nothing beyond the fold reaches its load again) it is the pull-in
    voltage and ``expected`` is LIMIT_POINT; if it is ``h`` at the range end
    the branch leaves the range, ``expected`` is OUTSIDE_RANGE and it is the
    range's voltage (``fold`` may still be True: a fold crossed, then ``h``
    climbing past it to the range end). ``expected`` is the
    status a solver should report. ``ambiguous`` names a reason the sample
    sits too close to a boundary between outcomes to decide (or is empty).
    """

    model: str
    stretch: float
    voltage: float
    y0: float
    y_end: float
    found: bool
    y: float
    tol: float
    snapped: bool
    fold: bool
    fold_voltage: float
    max_voltage: float
    fold_margin: float
    expected: int
    ambiguous: str
    r_i: float
    band: float = 0.0

    @property
    def span(self) -> float:
        return self.y_end - self.y0


# ------------------------------------------------------------------ the model, cancellation-free
def _yeoh_increment_slope(C, x0, l20, dl2):
    """``d/d l2`` of :func:`_yeoh_increment` [Pa], also without cancellation:
    ``dx/dl2 = 2 (l2**2 - l20**2) (l2**2 + l20**2) / l2**3``, times ``dW/dI1``."""
    C10, C20, C30 = C
    l2 = l20 + dl2
    x = x0 + (dl2 * (l2 + l20) / l2) ** 2
    return (C10 + x * (2.0 * C20 + 3.0 * C30 * x)) * 2.0 * dl2 * (l2 + l20) * (l2 * l2 + l20 * l20) / l2**3


def _yeoh_increment(C, x0, l20, dl2):
    """``W(l1, l20 + dl2) - W(l1, l20)`` [Pa] for a ring uniaxial at ``l20 = l1**-0.5``.

    ``x = I1 - 3 = l1**2 + l2**2 + l1**-2 l2**-2 - 3``; with ``l20**2 = 1/l1``,
    ``x - x0 = (l2**2 - l20**2)**2 / l2**2`` exactly (no cancellation), and
    ``W(x0 + dx) - W(x0) = dx (C10 + C20 (2 x0 + dx) + C30 (3 x0**2 + 3 x0 dx + dx**2))``.
    """
    C10, C20, C30 = C
    l2 = l20 + dl2
    dx = (dl2 * (l2 + l20) / l2) ** 2
    return dx * (C10 + C20 * (2.0 * x0 + dx) + C30 * (3.0 * x0 * x0 + 3.0 * x0 * dx + dx * dx))


class Landscape:
    """``psi - psi(y0)`` and ``c - c(y0)`` of one model at one stretch, on a dense grid.

    Parameters
    ----------
    model : str
        ``"1r"`` or ``"3r"``.
    geom : RollGeometry
    material : object with ``C10, C20, C30`` [Pa] and ``eps_r``.
    stretch : float
        Axial stretch [-], >= 1.
    n : int
        Grid size.
    """

    def __init__(self, model, geom, material, stretch, n=N_GRID):
        self.model = model
        self.geom = geom
        self.material = material
        self.l1 = l1 = float(stretch)
        self.l20 = l1**-0.5
        a = np.log(l1)
        self.x0 = np.expm1(2.0 * a) + 2.0 * np.expm1(-a)  # l1**2 + 2/l1 - 3
        self.C = (float(material.C10), float(material.C20), float(material.C30))
        if model == "1r":
            self.y0 = self.l20
            self.y_end = HOOP_FACTOR * self.l20
            core = None
        elif model == "3r":
            Ro = geom.Ro
            self.rho = np.array([geom.Ri, geom.Rie, geom.Roe, Ro]) / Ro
            self.y0 = self.rho[0] / np.sqrt(l1)
            self.y_end = self.range_end_3r()
            # rings (inner boundary, outer boundary, volume fraction), empty rings left out
            area = 1.0 - self.rho[0] ** 2
            self.rings = [(k, k + 1, (self.rho[k + 1] ** 2 - self.rho[k] ** 2) / area) for k in range(3)
                          if self.rho[k + 1] > self.rho[k] or k == 1]
            core = self.rho[1]
        else:
            raise ValueError(f"brute force knows 1r and 3r, not {model!r}")
        self.span = self.y_end - self.y0
        # kappa l1**2 l20**2 = c(y0): the electrical factor, from the package's enthalpy
        psi0, c0 = self._package_parts(np.array([self.y0]))
        self.psi0, self.c0 = float(psi0[0]), float(c0[0])
        self.kappa = self.c0 / (l1 * l1 * self.l20 * self.l20)
        self.y = self._grid(n, core)
        self.dpsi, self.dc = self.increments(self.y)
        self._check_against_package()
        self._windows()

    # -- kinematics -------------------------------------------------------------------------
    def range_end_3r(self):
        """``xi`` at which ``lambda2b = HOOP_FACTOR / sqrt(l1)`` (closed form)."""
        l1 = self.l1
        rho_i, rho_ie, rho_oe = self.rho[:3]
        total = HOOP_FACTOR / np.sqrt(l1) * (rho_ie + rho_oe)  # r_ie + r_oe
        r_ie = 0.5 * (total - (rho_oe**2 - rho_ie**2) / (l1 * total))
        return float(np.sqrt(r_ie * r_ie - (rho_ie**2 - rho_i**2) / l1))

    def increments(self, y):
        """``(psi(y) - psi(y0), c(y) - c(y0))`` [Pa, Pa/V^2], evaluated without cancellation."""
        y = np.asarray(y, float)
        l1, l20 = self.l1, self.l20
        if self.model == "1r":
            dl2 = y - self.y0
            return _yeoh_increment(self.C, self.x0, l20, dl2), self.kappa * l1 * l1 * dl2 * (2.0 * l20 + dl2)
        # r_k**2 = xi**2 + (rho_k**2 - rho_i**2) / l1; at y0 every r_k = rho_k / sqrt(l1)
        s = (y - self.y0) * (y + self.y0)
        r0 = self.rho / np.sqrt(l1)
        dr = [y - self.y0]
        for k in (1, 2, 3):
            r = np.sqrt(y * y + (self.rho[k] ** 2 - self.rho[0] ** 2) / l1)
            dr.append(s / (r + r0[k]))
        dpsi = 0.0
        dc = None
        for inner, outer, eta in self.rings:
            dl2 = (dr[inner] + dr[outer]) / (self.rho[inner] + self.rho[outer])
            dpsi = dpsi + eta * _yeoh_increment(self.C, self.x0, l20, dl2)
            if inner == 1:
                dc = self.kappa * l1 * l1 * dl2 * (2.0 * l20 + dl2)
        return dpsi, dc

    def slope(self, v, y):
        """``dg/dy`` [Pa per unit of y] in closed form (the reference's own; only to polish a minimum)."""
        y = np.asarray(y, float)
        l1, l20 = self.l1, self.l20
        if self.model == "1r":
            dl2 = y - self.y0
            return (_yeoh_increment_slope(self.C, self.x0, l20, dl2)
                    - v * v * self.kappa * l1 * l1 * 2.0 * (l20 + dl2))
        s = (y - self.y0) * (y + self.y0)
        r0 = self.rho / np.sqrt(l1)
        dr, rate = [y - self.y0], [np.ones_like(y)]
        for k in (1, 2, 3):
            r = np.sqrt(y * y + (self.rho[k] ** 2 - self.rho[0] ** 2) / l1)
            dr.append(s / (r + r0[k]))
            rate.append(y / r)
        out = 0.0
        for inner, outer, eta in self.rings:
            S = self.rho[inner] + self.rho[outer]
            dl2 = (dr[inner] + dr[outer]) / S
            d = (rate[inner] + rate[outer]) / S
            out = out + eta * _yeoh_increment_slope(self.C, self.x0, l20, dl2) * d
            if inner == 1:
                out = out - v * v * self.kappa * l1 * l1 * 2.0 * (l20 + dl2) * d
        return out

    def _package_parts(self, y):
        """``(psi, c)`` from the package's energy-only enthalpy: psi at 0 V, c by the probe voltage."""
        if self.model == "1r":
            def energy(v):
                return one_ring.enthalpy(self.geom, self.material, self.l1, v, y)
        else:
            def energy(v):
                return three_ring.enthalpy(self.geom, self.material, self.l1, v, y * self.geom.Ro)
        psi = np.asarray(energy(0.0), float)
        return psi, (psi - np.asarray(energy(V_PROBE), float)) / V_PROBE**2

    def _rounding_scale(self, y):
        """Size of the terms the package sums for psi [Pa]: its rounding is NOISE times this.

        The terms of ``I1 - 3 = (l1**2 - 1) + (l2**2 - 1) + ((l1 l2)**-2 - 1)`` (at stretch 1 and a hoop
        strain ``e`` they are ``~2e`` and the sum ``~4e**2``): a bound on the rounding of any form of
        ``psi`` (`yeoh.energy`'s keeps ``I1 - 3`` to a few ulps of itself, well inside it).
        """
        a = abs(np.log(self.l1))
        C10, C20, C30 = (abs(c) for c in self.C)

        def ring(l2):
            b = np.log(l2)
            x = np.abs(np.expm1(2.0 * a)) + np.abs(np.expm1(2.0 * b)) + np.abs(np.expm1(-2.0 * (a + b)))
            return x * (C10 + x * (C20 + x * C30))

        if self.model == "1r":
            return ring(np.asarray(y, float))
        out = 0.0
        s = (y - self.y0) * (y + self.y0)
        r0 = self.rho / np.sqrt(self.l1)
        dr = [y - self.y0] + [s / (np.sqrt(y * y + (self.rho[k] ** 2 - self.rho[0] ** 2) / self.l1) + r0[k])
                              for k in (1, 2, 3)]
        for inner, outer, eta in self.rings:
            out = out + eta * ring(self.l20 + (dr[inner] + dr[outer]) / (self.rho[inner] + self.rho[outer]))
        return out

    def _check_against_package(self):
        idx = np.unique(np.r_[np.arange(0, self.y.size, 10), self.y.size - 1])
        psi, c = self._package_parts(self.y[idx])
        scale = self._rounding_scale(self.y[idx]) + float(self._rounding_scale(np.array([self.y0]))[0])
        bad_psi = np.abs((psi - self.psi0) - self.dpsi[idx]) > 4.0 * NOISE * (scale + np.abs(psi) + abs(self.psi0))
        bad_c = np.abs((c - self.c0) - self.dc[idx]) > 4.0 * NOISE * (np.abs(c) + abs(self.c0)
                                                                      + (np.abs(psi) + abs(self.psi0)) / V_PROBE**2)
        if np.any(bad_psi | bad_c):
            i = idx[np.flatnonzero(bad_psi | bad_c)[0]]
            raise ReferenceModelMismatch(
                f"{self.model} at stretch {self.l1}: the reference's g - g(y0) disagrees with the package's "
                f"enthalpy at y = {self.y[i]:.6g} (psi {psi[idx == i][0] - self.psi0:.6g} vs {self.dpsi[i]:.6g} Pa, "
                f"c {c[idx == i][0] - self.c0:.6g} vs {self.dc[i]:.6g} Pa/V^2)")

    # -- grid and h ----------------------------------------------------------------------------
    def _grid(self, n, core):
        span = self.span
        parts = [np.linspace(0.0, span, n // 2), span * np.logspace(-8, 0, n // 4)]
        if core is not None:
            parts.append(core * np.logspace(-6, 0, n // 4))  # the core scale Rie/Ro
        else:
            parts.append(span * np.logspace(-4, 0, n // 4))
        off = np.unique(np.concatenate(parts))
        off = off[(off >= 0.0) & (off <= span)]
        y = self.y0 + off
        y[-1] = self.y_end
        return np.unique(y)

    def _windows(self):
        """Secant estimates of ``h = dpsi/dc`` and their rounding, and the first significant fall of h."""
        dpsi, dc, y = self.dpsi, self.dc, self.y
        n = y.size
        cm = np.maximum.accumulate(dc)
        i = np.arange(n)
        j = np.maximum(np.searchsorted(cm, dc + WINDOW * np.abs(dc), side="left"), i + 1)
        keep = j < n
        i, j = i[keep], j[keep]
        dC = dc[j] - dc[i]
        keep = dC > 0
        i, j, dC = i[keep], j[keep], dC[keep]
        h = (dpsi[j] - dpsi[i]) / dC
        err = NOISE * (np.abs(dpsi[i]) + np.abs(dpsi[j]) + np.abs(h) * (np.abs(dc[i]) + np.abs(dc[j]))) / dC
        self.h, self.h_err = h, err
        self.h_y = 0.5 * (y[i] + y[j])
        self.h_top = y[j]  # windows are a prefix of [y0, y] iff h_top <= y
        # a fall of h beyond the rounding of both ends: some earlier window, even at
        # its lowest, lies above this one at its highest
        lower = np.maximum.accumulate(h - err)
        fall = lower[:-1] - (h[1:] + err[1:])
        hit = np.flatnonzero(fall > 0.0)
        if hit.size:
            d = int(hit[0]) + 1
            k = int(np.argmax(h[:d] - err[:d]))
            self.fold_index = d
            self.fold_h = float(h[k])
            self.fold_y = float(self.h_y[k])
            # how far h falls below the fold before it recovers (for the diagnosis of weak folds)
            after = np.flatnonzero(h[d:] - err[d:] > self.fold_h)
            stop = d + (int(after[0]) if after.size else h.size - d)
            self.fold_margin = float(np.max(fall[d - 1:stop - 1]) / abs(h[k]))
        else:
            self.fold_index = None
            self.fold_h = self.fold_y = self.fold_margin = np.nan
        # h at the range end: linear extrapolation of the last two windows
        ya, yb = self.h_y[-2], self.h_y[-1]
        self.h_end = float(h[-1] + (h[-1] - h[-2]) * (self.y_end - yb) / (yb - ya))
        precise = err <= 1e-6 * np.abs(h)  # windows whose h is good to 1e-6 (all but rounding-bound ones)
        self.h_inner_max = float(np.max(h[precise])) if precise.any() else -np.inf  # largest h inside the range

    # -- the state ------------------------------------------------------------------------------
    def g(self, v, y):
        dpsi, dc = self.increments(y)
        return dpsi - v * v * dc

    def rising_state(self, voltage) -> RisingState:
        v = float(voltage)
        K = v * v
        g = self.dpsi - K * self.dc
        tau = NOISE * (np.abs(self.dpsi) + K * np.abs(self.dc))
        running = np.minimum.accumulate(g)
        rise = g[1:] - running[:-1] > 2.0 * np.maximum(tau[1:], NOISE * np.abs(running[:-1]))
        span = self.span
        fold_v = np.sqrt(self.fold_h) if self.fold_index is not None else np.nan
        if not rise.any():
            # no state in range: a pull-in where the largest h in range is a fold's (nothing
            # beyond it reaches that load again), else the branch leaves through the range end
            fold = self.fold_index is not None
            h_max = max(self.h_inner_max, self.h_end)
            pull_in = fold and self.h_inner_max > self.h_end
            ambiguous = ""
            if abs(K - h_max) <= 1e-6 * h_max:
                ambiguous = "voltage within 1e-6 of the largest with a state in range"
            if fold and abs(K - self.fold_h) <= 1e-6 * self.fold_h:
                ambiguous = "voltage within 1e-6 of the fold's"
            if fold and abs(self.h_inner_max - self.h_end) <= 1e-6 * h_max:
                ambiguous = "h at the range end within 1e-6 of the largest fold's"
            return RisingState(self.model, self.l1, v, self.y0, self.y_end, False, np.nan, Y_TOL * span, False,
                               fold, fold_v, np.sqrt(h_max), self.fold_margin,
                               LIMIT_POINT if pull_in else OUTSIDE_RANGE, ambiguous, np.nan)
        i_up = int(np.flatnonzero(rise)[0]) + 1
        im = int(np.argmin(g[:i_up]))
        flat = g <= g[im] + 2.0 * np.maximum(tau, NOISE * abs(g[im]))
        left = im
        while left > 0 and flat[left - 1]:
            left -= 1
        right = im
        while right < i_up and flat[right + 1]:
            right += 1
        a = self.y[max(left - 1, 0)]
        b = self.y[min(right + 1, self.y.size - 1)]
        y_star = self._refine(v, a, b)
        tol, band = self._tolerance(v, a, b, y_star)
        snapped = self.fold_index is not None and self.h_top[self.fold_index] <= y_star
        ambiguous = ""
        if self.fold_index is not None and abs(K - self.fold_h) <= 1e-6 * self.fold_h:
            ambiguous = "voltage within 1e-6 of the fold's"
        if self.y_end - y_star <= 2.0 * tol:
            ambiguous = "state at the range end"
        r_i = y_star * self.geom.Ro if self.model == "3r" else np.nan
        return RisingState(self.model, self.l1, v, self.y0, self.y_end, True, y_star, tol, bool(snapped),
                           bool(snapped), fold_v if snapped else np.nan, np.sqrt(max(self.h_inner_max, self.h_end)),
                           self.fold_margin,
                           SNAPPED if snapped else OK, ambiguous, r_i, band)

    def _refine(self, v, a, b):
        """Bounded Brent on ``g`` inside the grid bracket ``[a, b]``."""
        span = self.span

        def f(t):
            return float(self.g(v, np.array([t]))[0])

        res = minimize_scalar(f, bounds=(a, b), method="bounded",
                              options={"xatol": 1e-13 * span, "maxiter": 1000})
        y_star = float(res.x)
        if a == self.y0 and f(self.y0) <= res.fun:
            return self.y0  # the minimum is the boundary point y0 (the pitchfork's r_i = 0)
        # Brent on g stops at ~sqrt(eps) of y (g is flat there to rounding); polish with
        # the root of dg/dy inside the bracket, where it changes sign
        def d(t):
            return float(self.slope(v, np.array([t]))[0])

        lo, hi = a, b
        for _ in range(60):
            if d(lo) < 0.0:
                break
            lo = 0.5 * (lo + y_star)
        for _ in range(60):
            if d(hi) > 0.0:
                break
            hi = 0.5 * (hi + y_star)
        if d(lo) < 0.0 < d(hi):
            y_star = brentq(d, lo, hi, xtol=1e-15 * span, rtol=4 * EPS, maxiter=500)
        return y_star

    def _tolerance(self, v, a, b, y_star):
        """``Y_TOL`` of the range, or twice the width where g is flat to rounding around ``y*``."""
        t = np.linspace(a, b, 4001)
        dpsi, dc = self.increments(t)
        g = dpsi - v * v * dc
        gs = float(self.g(v, np.array([y_star]))[0])
        tau = 2.0 * NOISE * (np.abs(dpsi) + v * v * np.abs(dc)) + 2.0 * NOISE * abs(gs)
        flat = np.flatnonzero(g <= gs + tau)
        band = (np.max(np.abs(t[flat] - y_star)) if flat.size else 0.0) + (b - a) / 4000
        return max(Y_TOL * self.span, 2.0 * band), band


def landscape(model, geom, material, stretch, n=N_GRID) -> Landscape:
    return Landscape(model, geom, material, stretch, n)


def rising_state(model, geom, material, stretch, voltage, n=N_GRID) -> RisingState:
    """The state a voltage ramp from 0 V reaches at ``(stretch, voltage)``, by brute force."""
    return Landscape(model, geom, material, stretch, n).rising_state(voltage)


def rising_states(model, geom, material, stretch, voltages, n=N_GRID) -> list[RisingState]:
    """:func:`rising_state` for several voltages at one stretch (one grid for all)."""
    land = Landscape(model, geom, material, stretch, n)
    return [land.rising_state(v) for v in np.atleast_1d(voltages)]
