"""The true roll of the emulated rig: physics a real roll has and no model of rdea-lab has.

The models of `rdea_lab.physics` (SU, 1R, 3R, continuum) all take the roll as
one uniform body between rigid clamps (Assumption 3 of [1]). A truth file's
``effects`` (`rdea_lab.specs.truth.Effects`) switch on what a real roll on a
real rig adds, so that a calibrated model can be wrong, as on a real rig:

- **passive ends** (``passive_ends``): the electrode covers ``L1e`` of the
  roll's length ``L1``; the ends ``L1 - L1e`` carry no field. They are their
  own zone in series with the electroded one: the same cross-section and
  force, lengths adding, ``lambda_a L1e + lambda_p (L1 - L1e) = Lambda_r L1``.
  The electroded zone follows the truth's model with the electrode over its
  whole length (``alpha_e1 = 1`` on ``L1e``); the passive ends are uniaxial
  (SU at 0 V, exact at 0 V for every model) with the Yeoh coefficients times
  ``passive_stiffness``. The models smear the electrode instead (``alpha_e1 =
  L1e / L1`` times the Maxwell stress over the whole length). At 0 V the two
  agree exactly (same film); under voltage the softened active zone stretches
  more than the roll and the passive ends less.
- **clamp compliance** (``clamp_compliance`` c [m/N]): clamps and load cell in
  series: ``Lambda L1 = Lambda_r L1 + c F``, with ``Lambda`` the actuator's
  (encoder's) stretch and ``Lambda_r`` the roll's own mean stretch.
- **viscoelasticity**: the truth's branches and damper (either law of
  `rdea_lab.physics.viscoelastic`) span the roll, in parallel with the series
  elastic chain: their overstress follows ``Lambda_r`` (the rheology of this
  truth; each zone's own overstress is not tracked, as `compose` does not
  track a slack roll's).
- **Mullins softening** (``mullins``): Ogden and Roxburgh's (1999)
  pseudo-elastic factor on the elastic chain's force, ``eta = 1 - s erf((W_max
  - W) / m)``, ``W`` the Yeoh energy density at ``Lambda_r`` and ``W_max`` its
  maximum so far in the run (1 on the virgin loading, below 1 on unloading and
  reloading below the previous maximum; each run starts virgin).
- **slack**: where the total force would be compressive the roll buckles and
  carries 0 (as in every model).
- **fringe capacitance** (``fringe_capacitance``): the field leaking past the
  electrodes' edges along the roll's two ends, Palmer's (1937) correction for
  a parallel-plate capacitor of side ``a`` and gap ``d``: ``C = C_plate (1 +
  (d / (pi a)) (1 + ln(2 pi a / d)))``, with ``a = lambda_a L1e`` and ``d =
  L3 / (lambda_a lambda_2b)`` (the other two edges, at the start and end of the
  winding, are ``a / L2e`` shorter: left out).

The zones' stretches are solved per block by a vectorized secant iteration on
``lambda_a``, sample by sample, to ``1e-13`` in stretch: each sample's residual
is monotone in its own ``lambda_a``; the branches couple the samples in time
only through the clamp term ``c F`` (the overstress follows ``Lambda_r``), which
the iteration passes on from one sweep to the next (5-13 sweeps per block at the
shipped 20 um/N, 20-30 at the largest compliance a truth accepts, 100 um/N).
Each sweep is one solve of the active zone's model over the block (continuing
the previous block's path) and one of the passive ends. A block that does not
converge raises RuntimeError; the emulated rig then aborts the run with that
reason (voltage off, the samples before it kept). With every effect off
`TrueRoll` is `rdea_lab.twin.simulate.TwinStream` (the same numbers).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.special import erf

from ..physics import viscoelastic
from ..physics.models import solve
from ..physics.result import is_valid
from ..physics.yeoh import energy_of
from ..twin.simulate import compose, slack_status, viscous

#: Convergence of the zone split, in stretch [-].
STRETCH_TOL = 1e-13
#: Most secant iterations per block (more is a bug: RuntimeError).
MAX_ITER = 100


def palmer_factor(a, d):
    """Palmer's (1937) fringe factor ``1 + (d / (pi a)) (1 + ln(2 pi a / d))`` for a plate side `a`, gap `d` [m]."""
    a = np.asarray(a, float)
    d = np.asarray(d, float)
    return 1.0 + d / (np.pi * a) * (1.0 + np.log(2.0 * np.pi * a / d))


def mullins_factor(W, W_max, max_softening, energy_scale):
    """Ogden-Roxburgh softening ``1 - s erf((W_max - W) / m)`` [-] (W, W_max, m in J/m^3)."""
    return 1.0 - max_softening * erf((np.asarray(W_max) - np.asarray(W)) / energy_scale)


class TrueRoll:
    """The emulated roll, one block at a time (see the module docstring).

    Parameters
    ----------
    geom : RollGeometry
        The true geometry (`rdea_lab.emulator.true_geometry`).
    truth : TruthSpec
    """

    def __init__(self, geom, truth):
        self.geom = geom
        self.material = truth.material
        self.model = truth.model
        e = self.effects = truth.effects
        self.passive = bool(e.passive_ends) and geom.L1e < geom.L1
        self.Lp = geom.L1 - geom.L1e if self.passive else 0.0
        self.active_geom = dataclasses.replace(geom, L1=geom.L1e) if self.passive else geom
        self.passive_geom = dataclasses.replace(geom, L1=self.Lp, L1e=self.Lp) if self.passive else None
        f = e.passive_stiffness
        m = self.material
        self.passive_material = m.model_copy(update={"C10": m.C10 * f, "C20": m.C20 * f, "C30": m.C30 * f})
        self.compliance = float(e.clamp_compliance)
        self._visco = viscous(m)
        self._C = (m.C10, m.C20, m.C30)
        self._state = None  # viscoelastic state at the end of the previous block
        self._path = None  # the active zone's equilibrium at the end of the previous block
        self._W_max = 0.0  # largest energy density so far (Mullins)

    @property
    def uniform(self) -> bool:
        """True when the roll is one zone between rigid clamps (the models' picture)."""
        return not self.passive and self.compliance == 0.0

    def _passive_stretch(self, force):
        """Stretch of the passive ends carrying `force` [N] (1 where `force` <= 0)."""
        force = np.asarray(force, float)
        taut = force > 0.0
        lam = np.ones_like(force)
        if not taut.any():
            return lam
        target = force[taut]
        A, C10 = self.geom.area, self.passive_material.C10
        zero = np.zeros_like(target)

        def F(x):
            return solve("su", self.passive_geom, self.passive_material, x, zero).tension * A / x

        x0, r0 = np.ones_like(target), -target
        x1 = 1.0 + target / (6.0 * C10 * A)  # the small-strain (Young's modulus 6 C10) estimate
        r1 = F(x1) - target
        for _ in range(MAX_ITER):
            if np.max(np.abs(x1 - x0)) < STRETCH_TOL and np.all(np.abs(r1) <= 1e-9 * target):
                break
            with np.errstate(invalid="ignore", divide="ignore"):
                step = np.where(r1 != r0, r1 * (x1 - x0) / (r1 - r0), 0.0)
            x0, r0 = x1, r1
            x1 = np.maximum(x1 - step, 1.0)
            r1 = F(x1) - target
        else:
            # a force of a few nN (the roll just taut) is below what a stretch near 1 resolves in
            # double precision (one ulp of stretch is 6 C10 A eps, about 2e-14 N here): the secant
            # stalls at the rounding of F, not off the solution; accept that, and only that
            floor = 8.0 * np.finfo(float).eps * 6.0 * C10 * A * x1
            if np.max(np.abs(x1 - x0)) >= STRETCH_TOL or np.any(np.abs(r1) > 1e-9 * target + floor):
                raise RuntimeError("passive ends: the secant iteration did not converge")
        lam[taut] = x1
        return lam

    def _evaluate(self, t, Lam, v, la):
        """Everything of one trial split ``la`` (active-zone stretch) over a block."""
        res = solve(self.model, self.active_geom, self.material, la, v, path=True, start=self._path)
        A = self.geom.area
        if self.passive:
            Fa = res.tension * A / la
            lp = self._passive_stretch(Fa)
            Lr = (la * self.geom.L1e + lp * self.Lp) / self.geom.L1
            tension = Fa * Lr / A  # the chain's true stress at the roll's mean stretch
        else:
            lp, Lr, tension = la, la, res.tension
        mullins = self.effects.mullins
        W_max = self._W_max
        if mullins is not None:
            W = energy_of(Lr**2 + 2.0 / Lr - 3.0, self._C)
            W_max = np.maximum(self._W_max, np.maximum.accumulate(W))
            tension = tension * mullins_factor(W, W_max, mullins.max_softening, mullins.energy_scale)
        sigma, sigma_irr, force, state = compose(self.geom, self._visco, t, Lr, tension, self._state)
        residual = Lr + self.compliance * force / self.geom.L1 - Lam
        end = (res.end, state, float(np.max(W_max, initial=self._W_max)))
        return res, residual, {"end": end, "sigma": sigma, "sigma_irr": sigma_irr, "force": force, "tension": tension,
                               "lambda_a": la, "lambda_p": lp, "roll_stretch": Lr}

    def step(self, t, stretch, voltage) -> dict:
        """Force [N], capacitance [F], stresses [Pa], zone stretches [-] and status for one block.

        Parameters
        ----------
        t : numpy.ndarray
            Sample times [s], after the previous block's.
        stretch : numpy.ndarray
            The actuator's (encoder's) stretch ``Lambda`` [-], >= 1.
        voltage : numpy.ndarray
            Voltage [V].
        """
        Lam = np.asarray(stretch, float)
        v = np.broadcast_to(np.asarray(voltage, float), Lam.shape)
        t = viscoelastic.check_time(t, Lam.shape)
        if self._state is not None and not t[0] > self._state.t:
            raise ValueError(f"block starts at t = {float(t[0])!r}, not after the previous block's end")
        x0 = Lam.copy()
        res, r0, out = self._evaluate(t, Lam, v, x0)  # the uniform roll: all of it when there is no series element
        if not self.uniform:
            x1 = np.maximum(x0 - r0, 1.0)
            res, r1, out = self._evaluate(t, Lam, v, x1)
            for _ in range(MAX_ITER):
                # converged, or at stretch 1 with the clamps still too far: the roll cannot be
                # shorter than unstretched here (it would buckle), so the split stays there
                open_ = (np.abs(r1) >= STRETCH_TOL) & ~((x1 == 1.0) & (r1 > 0.0))
                if not open_.any():
                    break
                with np.errstate(invalid="ignore", divide="ignore"):  # no secant yet: slope 1 (a uniform roll's)
                    step = np.where((r1 != r0) & (x1 != x0), r1 * (x1 - x0) / (r1 - r0), r1)
                x0, r0 = x1, r1
                x1 = np.maximum(x1 - np.where(open_, step, 0.0), 1.0)
                res, r1, out = self._evaluate(t, Lam, v, x1)
            else:
                raise RuntimeError(f"true roll: the zone split did not converge (residual {np.max(np.abs(r1)):.3g})")
        self._path, self._state, self._W_max = out["end"]
        capacitance = res.capacitance
        if self.effects.fringe_capacitance:
            la = out["lambda_a"]
            capacitance = capacitance * palmer_factor(la * self.geom.L1e, self.geom.L3 / (la * res.lambda2b))
        status = slack_status(res.status, out["tension"] + out["sigma_irr"] < 0.0, out["force"])
        valid = is_valid(status)
        return {"force": out["force"], "capacitance": capacitance, "sigma1": out["sigma"],
                "sigma1_irr": out["sigma_irr"], "lambda2b": res.lambda2b, "model_status": status,
                "lambda_a": np.where(valid, out["lambda_a"], np.nan), "lambda_p": out["lambda_p"],
                "roll_stretch": out["roll_stretch"]}


__all__ = ["TrueRoll", "mullins_factor", "palmer_factor"]
