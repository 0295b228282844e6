"""A slow, obviously-right sequential reference for history-aware (path) equilibria.

Used by ``test_hysteresis.py`` to check ``solve(..., path=True)``. It knows
nothing of the package's solvers: all it uses is the free enthalpy density
``g(y)`` of the 1R and 3R models (``one_ring.enthalpy``, ``three_ring.enthalpy``,
energy only) and, for the end of the 3R admissible range, the closed-form
inverse of the hoop stretch (``three_ring.xi_at_hoop_stretch``).

The rule it implements (an overdamped quasi-static path): the samples are a
time series; at each sample the state is the local minimum of ``g`` at the
sample's (stretch, voltage) that a walk downhill from the previous state's
coordinate reaches (from the unloaded roll for the first sample). Per sample,
in a Python loop:

1. direction: downhill from ``y_prev``, by the sign of a finite-difference
   ``dg/dy`` (at the 3R boundary ``r_i = 0`` of a roll with ``Ri = 0``, where
   ``dg/dy = 0`` at every voltage, the boundary is kept while it is a local
   minimum, i.e. while ``v**2 < h(0+)``, see below);
2. walk: steps growing geometrically (x2) from a tiny step up to a fine cap
   (1e-4 of the admissible range) until ``g`` rises; the last three points
   bracket a local minimum (if the walk reaches ``r_i = 0`` still going
   down, the boundary is the minimum);
3. refine: ``scipy.optimize.minimize_scalar(method='bounded')`` on ``g`` in
   the bracket (energy only: about ``sqrt(eps)`` of the scale), then polish
   by ``brentq`` on the finite-difference ``dg/dy`` in a small interval
   around it where that derivative goes from - to + (the minimum
   condition); the polished point must be within 1e-5 of the scale of the
   energy minimum, or the reference raises. It is good to about 1e-11
   relative where the minimum is deep; ``RefPath.y_err`` estimates, per
   sample, what energy-only arithmetic can fix (up to ~1e-8, more next to a
   fold, where g'' vanishes; see :meth:`Reference.resolution`).

Where the stretch changes between samples, the coordinate (lambda2 for 1R,
``xi = r_i / Ro`` for 3R) is what carries over.

Snap-through. ``g = psi - v**2 c`` with ``psi = g(v=0)`` and
``c = (g(0) - g(V_REF)) / V_REF**2`` (two enthalpy evaluations; ``c`` is the
capacitive part with its load factor, so ``v**2`` multiplies it exactly).
An interior equilibrium satisfies ``v**2 = h(y) = psi'(y) / c'(y)`` and is
stable where ``h`` increases with ``y`` (``c' > 0``). So the new state is
continuously connected to the previous one exactly when ``h`` increases
monotonically on the interval between them; where it does not, the walk
crossed a fold: the first extremum of ``h`` met walking from ``y_prev``
(a maximum when walking up, a minimum when walking down) is the fold, and
``sqrt(h)`` there is the fold voltage at that sample's stretch. ``h`` is
checked by finite differences (``psi'``/``c'``, fourth-order stencils of
1e-3 of the local scale) on a grid between the two states (spacing at most
``FINE`` of the admissible range, at least 16 intervals), a
non-monotonicity counting only above ``H_TOL`` relative (the largest
wrong-way excursion is recorded per sample, so the tests can check the
margin on both sides); the extremum is refined by bounded minimization of
the same ``h``. A move shorter than ``MOVE_TOL`` of the scale is rounding
noise of the minimization and crosses no fold. At the 3R boundary
``r_i = 0`` (``Ri = 0``) the fold of a subcritical pitchfork is
``h(0+) = psi''(0) / c''(0)`` (see :meth:`Reference.h_boundary`).

Stress: ``sigma1 = lambda1 dg/dlambda1`` at fixed coordinate (the total
derivative at a stationary point, ERRATA), by finite differences. This is
the stress at the given stretch, signed: where it is negative the roll
would push (the package reports such samples as slack).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from rdea_lab.physics.models import one_ring, three_ring

#: Admissible range: hoop stretch up to HOOP_CAP times the uniaxial value lambda1**-0.5.
HOOP_CAP = 10.0
#: Voltage of the second enthalpy evaluation that gives the capacitive part c [V].
V_REF = 1000.0
#: Relative wrong-way excursion of h above which the path crossed a fold.
H_TOL = 1e-6
#: Moves shorter than this (relative to the coordinate's scale) are rounding noise of the
#: minimization, not a path: no fold can be resolved inside them.
MOVE_TOL = 1e-9
#: Largest walk step and h-grid spacing, as a fraction of the admissible range.
FINE = 1e-4
OK, SNAPPED = 0, 4


@dataclass
class RefPath:
    """The reference's answer for a series of samples (all arrays per sample)."""

    y: np.ndarray                 # coordinate: lambda2 (1R) or xi = r_i / Ro (3R)
    status: np.ndarray            # 0, or 4 where the state jumped across a fold since the previous sample
    critical_voltage: np.ndarray  # the crossed fold's voltage at 4, NaN elsewhere [V]
    sigma1: np.ndarray            # lambda1 dg/dlambda1 at the given stretch [Pa] (negative: would push)
    lambda2b: np.ndarray          # hoop stretch of the active ring [-]
    r_i: np.ndarray               # deformed inner radius [m]
    violation: np.ndarray         # largest wrong-way excursion of h between y_prev and y, relative
    y_err: np.ndarray             # resolution of y: error of dg/dy over g'' (0 at the boundary r_i = 0)
    sigma1_err: np.ndarray        # what y_err moves sigma1 by [Pa]
    lambda2b_err: np.ndarray      # what y_err moves lambda2b by
    end: float                    # coordinate after the last sample (to continue a path)


class Reference:
    """Sequential path equilibria of one model on one geometry and material."""

    def __init__(self, model, geom, material):
        self.model = model.lower()
        if self.model not in ("1r", "3r"):
            raise ValueError(f"the reference knows 1r and 3r, not {model!r}")
        self.geom = geom
        self.material = material
        # 3R with Ri = 0: r_i = 0 is an admissible boundary and stationary at every voltage
        self.pitchfork = self.model == "3r" and geom.Ri == 0.0
        self._h0 = {}  # h(0+) per stretch

    # -- energy -------------------------------------------------------------------------
    def g(self, l1, v, y):
        y = np.asarray(y, float)
        if self.model == "1r":
            return one_ring.enthalpy(self.geom, self.material, l1, v, y)
        return three_ring.enthalpy(self.geom, self.material, l1, v, y * self.geom.Ro)

    def psi_c(self, l1, y):
        """Elastic part ``psi = g(0 V)`` and capacitive part ``c`` with ``g(v) = psi - v**2 c``."""
        g0 = self.g(l1, 0.0, y)
        return g0, (g0 - self.g(l1, V_REF, y)) / V_REF**2

    # -- coordinate ---------------------------------------------------------------------
    def unloaded(self, l1):
        if self.model == "1r":
            return l1**-0.5
        return (self.geom.Ri / self.geom.Ro) / np.sqrt(l1)

    def bounds(self, l1):
        if self.model == "1r":
            y0 = l1**-0.5
            return y0 / HOOP_CAP, HOOP_CAP * y0
        rings = three_ring._Rings(self.geom, l1)
        hi = float(three_ring.xi_at_hoop_stretch(HOOP_CAP / np.sqrt(l1), l1, *rings.bound_constants[1:]))
        return 0.0, hi

    def scale(self, l1, y):
        """Local length scale of the coordinate (sets finite-difference and first walk steps)."""
        floor = l1**-0.5 if self.model == "1r" else self.geom.Rie / self.geom.Ro
        return max(abs(float(y)), floor)

    # -- finite differences -------------------------------------------------------------
    @staticmethod
    def _d1(values, step):
        """Fourth-order central first derivative from values at -2, -1, +1, +2 steps."""
        return (values[0] - 8.0 * values[1] + 8.0 * values[2] - values[3]) / (12.0 * step)

    def _stencil(self, l1, y):
        hd = 1e-3 * self.scale(l1, y)
        return hd, y + hd * np.array([-2.0, -1.0, 1.0, 2.0])

    def dg(self, l1, v, y):
        hd, pts = self._stencil(l1, y)
        return self._d1(self.g(l1, v, pts), hd)

    def h(self, l1, y):
        """``h = psi'(y) / c'(y)`` [V^2] by finite differences, at one point or an array of points."""
        y = np.asarray(y, float)
        floor = l1**-0.5 if self.model == "1r" else self.geom.Rie / self.geom.Ro
        hd = 1e-3 * np.maximum(np.abs(y), floor)
        pts = y[..., None] + hd[..., None] * np.array([-2.0, -1.0, 1.0, 2.0])
        psi, c = self.psi_c(l1, pts)
        psi, c = np.moveaxis(psi, -1, 0), np.moveaxis(c, -1, 0)
        return self._d1(psi, hd) / self._d1(c, hd)

    def h_boundary(self, l1):
        """``h(0+) = lim psi'/c' = psi''(0) / c''(0)`` at the 3R boundary r_i = 0 (Ri = 0).

        There ``psi' = c' = 0``. The enthalpy's formulas are smooth through
        ``r_i = 0`` (every radius but r_i stays positive), so the second
        derivatives are taken by central fourth-order stencils on that smooth
        continuation, at steps d and 2d, extrapolated once (Richardson). As a
        check of that continuation, one-sided difference ratios
        ``(psi(d) - psi(0)) / (c(d) - c(0)) = h(0+) + a1 d + ...`` (r_i >= 0 only)
        extrapolated twice must agree to 1e-6.
        """
        if l1 in self._h0:
            return self._h0[l1]
        d = 1e-2 * self.scale(l1, 0.0)
        w = np.array([-1.0, 16.0, -30.0, 16.0, -1.0])

        def central(step):
            psi, c = self.psi_c(l1, step * np.array([-2.0, -1.0, 0.0, 1.0, 2.0]))
            return (w @ psi) / (w @ c)

        h0 = (16.0 * central(d) - central(2.0 * d)) / 15.0
        ds = d / np.array([1.0, 2.0, 4.0])
        psi, c = self.psi_c(l1, np.concatenate([[0.0], ds]))
        q = (psi[1:] - psi[0]) / (c[1:] - c[0])
        r1 = 2.0 * q[1:] - q[:-1]
        one_sided = (4.0 * r1[1] - r1[0]) / 3.0
        if not abs(one_sided - h0) <= 1e-6 * abs(h0):
            raise RuntimeError(f"reference: h(0+) {h0} (central) and {one_sided} (one-sided) disagree")
        self._h0[l1] = float(h0)
        return self._h0[l1]

    def stress(self, l1, v, y):
        """``sigma1 = lambda1 dg/dlambda1`` at fixed coordinate [Pa]."""
        step = 1e-3 * l1
        vals = self.g(l1 + step * np.array([-2.0, -1.0, 1.0, 2.0]), v, y)
        return float(l1 * self._d1(vals, step))

    def resolution(self, l1, v, y):
        """How well energy-only arithmetic fixes the minimum ``y``: ``error(dg/dy) / g''``.

        The rounding noise of g is measured, not assumed (psi and v**2 c nearly cancel in g, so it is
        about ten times eps |g|): the largest residual of a quadratic fit to g at 33 points 1e-9 of
        the scale apart. The stencil's error is then ``1.5 noise / hd`` (its weights sum to 18/12)
        plus its truncation, estimated by the difference to a sixth-order stencil. ``g''`` by
        differencing ``dg/dy``. A shallow minimum (a state close to a fold, or on the short branch
        of a narrow bistable window) is fixed only to that, whatever the solver.

        Returns ``(y_err, hd)``.
        """
        s = self.scale(l1, y)
        dy = 1e-9 * s * np.arange(-16.0, 17.0)
        g = self.g(l1, v, y + dy)
        noise = np.max(np.abs(g - np.polyval(np.polyfit(dy, g, 2), dy)))
        hd, _ = self._stencil(l1, y)
        g6 = self.g(l1, v, y + hd * np.array([-3.0, -2.0, -1.0, 1.0, 2.0, 3.0]))
        d6 = (-g6[0] + 9.0 * g6[1] - 45.0 * g6[2] + 45.0 * g6[3] - 9.0 * g6[4] + g6[5]) / (60.0 * hd)
        error = 1.5 * noise / hd + abs(self.dg(l1, v, y) - d6)
        gyy = (self.dg(l1, v, y + hd) - self.dg(l1, v, y - hd)) / (2.0 * hd)
        if not gyy > 0.0:
            raise RuntimeError(f"reference: state {y} is not a strict minimum (g'' = {gyy})")
        return error / gyy, hd

    def lambda2b(self, l1, y):
        """Hoop stretch of the active ring from volume conservation of each ring (eqs. 5-7)."""
        if self.model == "1r":
            return y
        Ri, Rie, Roe = self.geom.Ri, self.geom.Rie, self.geom.Roe
        r_i = y * self.geom.Ro
        r_ie = np.sqrt(r_i**2 + (Rie**2 - Ri**2) / l1)
        r_oe = np.sqrt(r_i**2 + (Roe**2 - Ri**2) / l1)
        return (r_ie + r_oe) / (Rie + Roe)

    def r_i(self, l1, y):
        if self.model == "3r":
            return y * self.geom.Ro
        Ri, Ro = self.geom.Ri, self.geom.Ro  # one hollow cylinder of mean hoop stretch lambda2
        return 0.5 * (y * (Ro + Ri) - (Ro - Ri) / (l1 * y))

    # -- one sample -----------------------------------------------------------------------
    def descend(self, l1, v, y_prev):
        """The local minimum of g at (l1, v) reached walking downhill from ``y_prev``."""
        lo, hi = self.bounds(l1)
        at_boundary = self.pitchfork and y_prev == 0.0
        s = self.scale(l1, y_prev)
        if at_boundary:
            if v * v <= self.h_boundary(l1):  # g''(0) = c''(0) (h(0+) - v**2) >= 0: stays
                return 0.0
            direction, step = 1.0, 1e-3 * s  # leave the flat top with a step g can resolve
        else:
            direction, step = (-1.0 if self.dg(l1, v, y_prev) > 0.0 else 1.0), 1e-6 * s
        bracket = self._walk(l1, v, y_prev, direction, step, lo, hi)
        if bracket is None:  # reached r_i = 0 still going down (Ri = 0): the boundary minimum
            return 0.0
        return self._refine(l1, v, *bracket)

    def _walk(self, l1, v, y_start, direction, step, lo, hi):
        max_step = FINE * (hi - lo)
        ys = np.array([y_start])
        gs = np.atleast_1d(self.g(l1, v, ys))
        while True:
            steps = np.minimum(step * 2.0 ** np.arange(1, 257), max_step)
            step = steps[-1]
            cand = ys[-1] + direction * np.cumsum(steps)
            end = hi if direction > 0 else lo
            past = direction * (cand - end) >= 0.0
            if np.any(past):
                cand = np.concatenate([cand[~past], [end]])
            ys = np.concatenate([ys, cand])
            gs = np.concatenate([gs, self.g(l1, v, cand)])
            rise = np.flatnonzero(gs[1:] > gs[:-1])
            if rise.size:
                i = rise[0] + 1  # g rose from point i-1 to point i
                a = ys[i - 2] if i >= 2 else y_start - (ys[1] - y_start)
                a, b = sorted((float(a), float(ys[i])))
                return max(a, lo), min(b, hi)
            if np.any(past):
                if end == lo and self.pitchfork and lo == 0.0:
                    return None
                raise RuntimeError(f"reference: no local minimum of g in [{lo}, {hi}] at stretch {l1}, "
                                   f"voltage {v} walking from {y_start} (direction {direction:+.0f})")

    def _refine(self, l1, v, a, b):
        s = self.scale(l1, 0.5 * (a + b))
        res = minimize_scalar(lambda y: float(self.g(l1, v, y)), bounds=(a, b), method="bounded",
                              options={"xatol": 1e-9 * s, "maxiter": 500})
        y_b = float(res.x)
        w = 1e-7 * s
        for _ in range(40):
            lo_, hi_ = y_b - w, y_b + w
            if self.dg(l1, v, lo_) < 0.0 < self.dg(l1, v, hi_):
                break
            w *= 2.0
        else:
            raise RuntimeError(f"reference: no sign change of dg/dy around the minimum {y_b} "
                               f"(stretch {l1}, voltage {v})")
        y = brentq(lambda yy: self.dg(l1, v, yy), lo_, hi_, xtol=1e-15 * s, rtol=4 * np.finfo(float).eps)
        if abs(y - y_b) > 1e-5 * s:
            raise RuntimeError(f"reference: energy minimum {y_b} and stationary point {y} disagree")
        return y

    def fold_between(self, l1, y_from, y_to):
        """``(fold voltage or None, violation)``: the fold crossed going from y_from to y_to."""
        if abs(y_to - y_from) <= MOVE_TOL * self.scale(l1, y_from):
            return None, 0.0
        direction = 1.0 if y_to > y_from else -1.0
        lo, hi = self.bounds(l1)
        n = int(min(max(16, np.ceil(abs(y_to - y_from) / (FINE * (hi - lo)))), 200_000))
        ys = np.linspace(y_from, y_to, n + 1)
        if self.pitchfork:
            ys = ys[ys != 0.0]  # h is 0/0 at the boundary itself: its limit h(0+) is taken below
        h = self.h(l1, ys)
        q = direction * h  # non-decreasing in walk order on a stable branch
        drop = np.maximum.accumulate(q) - q
        h_scale = np.max(np.abs(h))
        violation = float(np.max(drop) / h_scale)
        bad = np.flatnonzero(drop > H_TOL * h_scale)
        if bad.size == 0:
            return None, violation
        m = int(np.argmax(q[: bad[0] + 1]))  # node nearest the first extremum
        if m == 0 and self.pitchfork and y_from == 0.0:
            h_fold = max(self.h_boundary(l1), h[0])
        else:
            a, b = sorted((ys[max(m - 1, 0)], ys[min(m + 1, ys.size - 1)]))
            res = minimize_scalar(lambda y: -direction * self.h(l1, y), bounds=(a, b), method="bounded",
                                  options={"xatol": 1e-13 * self.scale(l1, a), "maxiter": 500})
            h_fold = -direction * res.fun
            if direction * h_fold < q[m] - 1e-9 * h_scale:
                raise RuntimeError("reference: refined fold below the grid's extremum")
        return float(np.sqrt(h_fold)), violation

    # -- a series ---------------------------------------------------------------------
    def path(self, stretch, voltage, start=None):
        """States along the series; ``start`` a previous RefPath's ``end`` (else the unloaded roll)."""
        l1s, vs = np.broadcast_arrays(np.asarray(stretch, float), np.asarray(voltage, float))
        l1s, vs = l1s.ravel(), vs.ravel()
        n = l1s.size
        out = {k: np.full(n, np.nan) for k in ("y", "cv", "sigma1", "l2b", "r_i", "violation", "y_err",
                                                "s_err", "l_err")}
        status = np.zeros(n, dtype=np.int8)
        y_prev = self.unloaded(l1s[0]) if start is None else float(start)
        for k in range(n):
            l1, v = float(l1s[k]), float(vs[k])
            y = self.descend(l1, v, y_prev)
            v_fold, violation = self.fold_between(l1, y_prev, y)
            if v_fold is not None:
                status[k] = SNAPPED
                out["cv"][k] = v_fold
            out["y"][k] = y
            out["violation"][k] = violation
            out["sigma1"][k] = self.stress(l1, v, y)
            out["l2b"][k] = self.lambda2b(l1, y)
            out["r_i"][k] = self.r_i(l1, y)
            if self.pitchfork and y == 0.0:  # the boundary is exact
                out["y_err"][k] = out["s_err"][k] = out["l_err"][k] = 0.0
            else:
                err, hd = self.resolution(l1, v, y)
                out["y_err"][k] = err
                out["s_err"][k] = err * abs(self.stress(l1, v, y + hd) - self.stress(l1, v, y - hd)) / (2 * hd)
                out["l_err"][k] = err * abs(self.lambda2b(l1, y + hd) - self.lambda2b(l1, y - hd)) / (2 * hd)
            y_prev = y
        return RefPath(out["y"], status, out["cv"], out["sigma1"], out["l2b"], out["r_i"],
                       out["violation"], out["y_err"], out["s_err"], out["l_err"], y_prev)

    def rising_rule(self, stretch, voltage):
        """Every sample on its own, walked from the unloaded roll (what a ramp from 0 V reaches)."""
        l1s, vs = np.broadcast_arrays(np.asarray(stretch, float), np.asarray(voltage, float))
        parts = [self.path([a], [b]) for a, b in zip(l1s.ravel(), vs.ravel())]
        fields = {name: np.concatenate([getattr(p, name) for p in parts])
                  for name in ("y", "status", "critical_voltage", "sigma1", "lambda2b", "r_i", "violation",
                               "y_err", "sigma1_err", "lambda2b_err")}
        return RefPath(**fields, end=parts[-1].end)
