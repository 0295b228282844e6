"""A relaxation spectrum: Maxwell branches on a fixed grid of time scales, moduli by regularized linear least squares.

For the SU strip (and every model at 0 V: uniaxial kinematics) the predicted
force is linear in the Yeoh coefficients and, at fixed relaxation times, in
the branch moduli: the quasi-static stress is ``b W'(x)`` with ``W'`` linear in
``C10, C20, C30`` (:func:`rdea_lab.physics.models.su.stress_basis`), and each
branch's internal strain depends on its ``tau_j`` alone (eq. (44): ``q_j``;
finite strain: ``du/dt = d ln(lambda1)/dt - f(u)/tau``), its stress being the
modulus times a function of that strain
(:func:`rdea_lab.physics.viscoelastic.stress_of`). The fit is then

    minimize  sum_i r_i(x)**2 + lam ndata sum_j ((D2 m)_j / m_ref)**2
    over      x = (C10, C20, C30, m_1 .. m_M, eta_v0),  C10 > 0, C30 >= 0, m_j >= 0, eta_v0 >= 0,

with ``r`` the calibration's weighted, peak-normalized residuals
(:func:`~rdea_lab.calibration.objective.residuals`), ``D2`` the second
differences of the moduli over ``ln tau`` (the grid is uniform in it),
``m_ref`` the small-strain modulus of the data (:func:`~rdea_lab.calibration.fit.initial_guess`'s
C10) and ``lam`` (dimensionless, relative to the mean squared residual) chosen
by leave-one-run-out cross-validation (`choose_strength`). Where the solution
breaks the Yeoh admissibility ``C20 > -sqrt(3 C10 C30)`` (not linear), the
same objective is minimized under that constraint (SLSQP). Where the twin
predicts a compressive force it clips it to 0 (slack) and the residual there
does not depend on the parameters: an active set of the samples in tension
is iterated (`_System`), so the fit minimizes the objective of the twin itself.

The grid (`tau_grid`): from ``TAU_MIN_SAMPLES`` times the shortest median
sample interval of the runs (faster branches are elastic springs or a damper
to the data) to ``beyond`` decades (default 1) past the longest run's
duration, ``per_decade`` time scales per decade (default 2), log-spaced, both
ends included. Why past the data: a grid that stops at the longest run
asserts that the material has all but relaxed a few of those durations later
(every branch's ``exp(-t/tau)`` is gone), which nothing in the data says;
the data cannot tell a branch slower than themselves from the elastic spring,
and the smoothness penalty (whose null space is linear in ``ln tau``) then
carries the spectrum's trend on past them instead of ending it. (The VHB
holds benchmark shows both rules; this default was chosen after seeing that
a grid ending at the data predicts the unseen rest of a hold worse than a
force that stops relaxing.) Branches whose modulus
ends below `MIN_MODULUS` (100 Pa, in practice 0) are left out of the parameter set (the record lists
the whole grid).
"""

from __future__ import annotations

import math
import time as _time
import types

import numpy as np
from scipy.optimize import lsq_linear, minimize

from ..physics import viscoelastic
from ..physics.models import su
from ..specs import ParameterSet, SpecError, ViscoBranch
from .objective import goodness, predict_force, residual_scale, residuals

#: The grid's shortest time scale, in sample intervals.
TAU_MIN_SAMPLES = 10
#: Time scales per decade of the grid by default.
PER_DECADE = 2
#: Decades of the grid beyond the longest run by default (see the module docstring).
BEYOND = 1.0
#: Moduli [Pa] below this (the fit bounds' lowest modulus) leave their branch out of the parameter set.
MIN_MODULUS = 1e2
#: Regularization strengths ``lam`` tried by the cross-validation (one per decade).
STRENGTHS = tuple(10.0 ** k for k in range(-9, 3))
_YEOH = ("C10", "C20", "C30")
#: Most active-set passes of a solve (the samples the twin predicts slack; see `_System`).
_SLACK_ITERATIONS = 8


def tau_grid(runs, per_decade: float = PER_DECADE, beyond: float = BEYOND) -> np.ndarray:
    """Relaxation times [s] of a spectrum for ``runs`` (the module's rule).

    Parameters
    ----------
    runs : sequence of RunData
    per_decade : float
        Time scales per decade [-], > 0.
    beyond : float
        Decades [-] past the longest run's duration the grid reaches, >= 0.

    Returns
    -------
    numpy.ndarray
        Log-spaced from ``TAU_MIN_SAMPLES`` times the shortest median sample interval [s] to the longest
        run's duration [s] times ``10**beyond``, both included.

    Raises
    ------
    SpecError
        ``per_decade`` not a positive number, ``beyond`` not a number >= 0.
    """
    if not (isinstance(per_decade, (int, float)) and math.isfinite(per_decade) and per_decade > 0):
        raise SpecError("arguments", "per_decade", f"{per_decade!r}; allowed: a number of time scales > 0")
    if not (isinstance(beyond, (int, float)) and math.isfinite(beyond) and beyond >= 0):
        raise SpecError("arguments", "beyond", f"{beyond!r}; allowed: a number of decades >= 0")
    lo = TAU_MIN_SAMPLES * min(float(np.median(np.diff(r.t))) for r in runs)
    hi = max(float(r.t[-1] - r.t[0]) for r in runs) * 10.0 ** beyond
    hi = max(hi, 10 * lo)
    n = int(math.ceil(per_decade * math.log10(hi / lo) - 1e-9)) + 1
    return np.geomspace(lo, hi, n)


def design(run, taus, law: str, eps_r: float):
    """``(A, f0)``: the run's force [N] is ``A @ x + f0`` for ``x = (C10, C20, C30, m_1 .. m_M, eta_v0)``
    [Pa, Pa s].

    The columns come from the twin's own functions with unit parameters (SU stress of
    :func:`rdea_lab.physics.models.su.stress_from_basis`, the branches' of
    :func:`rdea_lab.physics.viscoelastic.stress_basis`, the damper's rate of the run's `History`);
    ``f0`` is the electrostatic part at the run's voltage. Force is stress times ``area / stretch``
    (eq. (16)), before the slack clip.
    """
    basis, geom = run.su_basis(), run.geom
    to_force = geom.area / run.stretch

    def yeoh(c10, c20, c30):
        return su.stress_from_basis(basis, geom, types.SimpleNamespace(C10=c10, C20=c20, C30=c30, eps_r=eps_r))

    s0 = yeoh(0.0, 0.0, 0.0)
    cols = [yeoh(*np.eye(3)[i]) - s0 for i in range(3)]
    taus = np.asarray(taus, float)
    if taus.size:
        cols += list(viscoelastic.stress_basis(run.visco_history(), taus, law))
    cols.append(run.visco_history().rate)
    return np.column_stack(cols) * to_force[:, None], s0 * to_force


def _second_differences(M: int) -> np.ndarray:
    return np.diff(np.eye(M), 2, axis=0) if M >= 3 else np.zeros((0, M))


class _System:
    """The weighted linear system of every run, with the twin's slack clip handled by an active set.

    Per run ``i`` the weighted residual is ``A_i z - b_i`` (``z = x * norm``, columns scaled to unit norm
    over all runs) where the model force is >= 0, and ``-s_i F_i`` where the twin clips a compressive
    force to 0 (slack): there it does not depend on ``z``. `solve` alternates a bounded linear least
    squares on the samples the last iterate predicts in tension with recomputing that set (at most
    `_SLACK_ITERATIONS` times), keeping the iterate of least penalized objective.
    """

    def __init__(self, runs, taus, law, eps_r, m_ref):
        self.taus, self.m_ref = np.asarray(taus, float), float(m_ref)
        self.counts = [r.n for r in runs]
        self.blocks = []
        for run, s in zip(runs, residual_scale(runs)):
            A, f0 = design(run, taus, law, eps_r)
            self.blocks.append((A * s[:, None], (run.force - f0) * s, f0 * s, run.force * s))
        self.norm = np.sqrt(sum(np.sum(A * A, axis=0) for A, _, _, _ in self.blocks))
        self.norm[self.norm == 0] = 1.0
        self.blocks = [(A / self.norm, b, g0, y) for A, b, g0, y in self.blocks]
        M = self.taus.size
        D = _second_differences(M)
        self.penalty = np.zeros((D.shape[0], 4 + M))
        self.penalty[:, 3:3 + M] = D / self.m_ref
        self.penalty /= self.norm  # in the scaled variables z = x * norm
        lo = np.r_[1e2, -np.inf, 0.0, np.zeros(M + 1)] * self.norm
        self.bounds = (lo, np.full(4 + M, np.inf))
        self._qr = {}

    def _reduced(self, i, mask):
        """``(R, c)`` with ``||A z - b||^2 = ||R z - c||^2 + const`` over the rows ``mask`` of run ``i`` (cached:
        the active set of a run seldom changes, and never where it carries force throughout, as in a hold)."""
        key = (i, np.packbits(mask).tobytes())
        if key not in self._qr:
            A, b = self.blocks[i][0][mask], self.blocks[i][1][mask]
            Q, R = np.linalg.qr(A)
            self._qr[key] = (R, Q.T @ b)
        return self._qr[key]

    def solve(self, lam, use=None):
        """Scaled solution ``z`` (``x = z / norm``) over the runs ``use`` (default all) at strength ``lam``."""
        use = list(range(len(self.blocks))) if use is None else list(use)
        n = sum(self.counts[i] for i in use)  # ndata of the runs fitted
        P = math.sqrt(lam * n) * self.penalty
        masks = {i: np.ones(self.counts[i], bool) for i in use}
        best, best_f = None, np.inf
        for _ in range(_SLACK_ITERATIONS):
            parts = [self._reduced(i, masks[i]) for i in use]
            R = np.vstack([p[0] for p in parts] + [P])
            c = np.concatenate([p[1] for p in parts] + [np.zeros(P.shape[0])])
            z = lsq_linear(R, c, bounds=self.bounds, method="bvls", tol=1e-12).x
            if not _admissible(z / self.norm):
                z = self._constrained(R, c, z)
            f = sum(self.error(z, i) for i in use) + float(np.sum((P @ z) ** 2))
            if f < best_f:
                best, best_f = z, f
            new = {i: self.blocks[i][0] @ z + self.blocks[i][2] >= 0.0 for i in use}
            if all(np.array_equal(new[i], masks[i]) for i in use):
                break
            masks = new
        return best

    def _constrained(self, R, c, z0):
        """The same least squares under the Yeoh admissibility ``C20 + sqrt(3 C10 C30) >= 0`` (SLSQP)."""
        norm = self.norm
        lo, hi = self.bounds

        def f(z):
            r = R @ z - c
            return float(r @ r), 2.0 * (R.T @ r)

        def g(z):
            x = z[:3] / norm[:3]
            return x[1] + math.sqrt(3.0 * max(x[0], 0.0) * max(x[2], 0.0)) - 1e-9 * abs(x[0])

        start = z0.copy()
        start[1] = max(z0[1], 0.0)  # C20 >= 0 is admissible
        res = minimize(f, start, jac=True, method="SLSQP", bounds=list(zip(lo, hi)),
                       constraints=[{"type": "ineq", "fun": g}], options={"ftol": 1e-14, "maxiter": 500})
        return res.x if _admissible(res.x / norm) else start

    def error(self, z, i) -> float:
        """Weighted sum of squared residuals of run ``i`` at ``z``, the slack clip included (as `residuals`)."""
        A, b, g0, y = self.blocks[i]
        p = A @ z
        r = np.where(p + g0 < 0.0, -y, p - b)
        return float(r @ r)


def _admissible(x) -> bool:
    from .methods import _yeoh_admissible

    return _yeoh_admissible(float(x[0]), float(x[1]), float(x[2]))


def choose_strength(system: _System, strengths=STRENGTHS):
    """``(lam, scores)``: the strength whose leave-one-run-out prediction error is least.

    Each run in turn is left out, the rest fitted at each strength, and the left-out run's weighted sum of
    squared residuals added up (every run counts equally, as in the fit). With a single run there is
    nothing to leave out: the smallest strength is taken.
    """
    k = len(system.blocks)
    if k < 2:
        return float(strengths[0]), {float(strengths[0]): float("nan")}
    scores = {}
    for lam in strengths:
        scores[float(lam)] = sum(system.error(system.solve(lam, [j for j in range(k) if j != i]), i)
                                 for i in range(k))
    best = min(scores, key=scores.get)
    return best, scores


def fit_spectrum(runs, start: ParameterSet, *, model="su", per_decade: float = PER_DECADE, beyond: float = BEYOND,
                 strength=None, taus=None):
    """Fit the Yeoh coefficients and a relaxation spectrum (the module's problem) to measured runs.

    Parameters
    ----------
    runs : list of RunData
    start : ParameterSet
        Its ``law`` and ``eps_r`` are kept; its C10 is the modulus scale ``m_ref`` of the smoothness
        penalty [Pa].
    model : str
        Quasi-static model; the force must be linear in the parameters: ``su``, or runs all at 0 V.
    per_decade : float
        Time scales per decade of the grid (`tau_grid`).
    beyond : float
        Decades of the grid past the longest run (`tau_grid`; default `BEYOND`, 1).
    strength : float, optional
        ``lam`` [-]; default: chosen by `choose_strength`.
    taus : array_like, optional
        The grid [s] (default `tau_grid`).

    Returns
    -------
    CalibrationResult
        Its ``params`` hold the branches of nonzero modulus (``eta = tau * modulus``); ``spectrum``
        says how it was chosen (grid, rule, strengths tried with their cross-validation scores).

    Raises
    ------
    SpecError
        A model and voltage where the force is not linear in the parameters.
    """
    from .fit import CalibrationResult, start_branches
    from .parameters import fit_parameters, values_of

    t0 = _time.monotonic()
    if not (model == "su" or all(r.zero_voltage for r in runs)):
        raise SpecError("arguments", "branches", f"spectrum with model {model} at a voltage: the force is then not "
                                                 "linear in the parameters; allowed: model su, or runs at 0 V")
    law, eps_r = start.law, start.eps_r
    grid = tau_grid(runs, per_decade, beyond) if taus is None else np.asarray(taus, float)
    system = _System(runs, grid, law, eps_r, start.C10)
    if strength is None:
        lam, scores = choose_strength(system)
        rule = "leave-one-run-out cross-validation over the strengths tried" if len(runs) > 1 else \
            "a single run: nothing to cross-validate, the smallest strength"
        if len(runs) > 1 and lam in (min(scores), max(scores)):
            rule += f" (at the edge of the strengths tried, {min(scores):.0e}-{max(scores):.0e})"
    else:
        lam, scores, rule = float(strength), {}, "given"
    x = system.solve(lam) / system.norm
    moduli, eta_v0 = x[3:-1], float(x[-1])
    keep = moduli >= MIN_MODULUS
    best = start.replace(C10=float(x[0]), C20=float(x[1]), C30=float(x[2]), eta_v0=eta_v0,
                         branches=tuple(ViscoBranch.of(law, float(m), float(m * tau))
                                        for m, tau in zip(moduli[keep], grid[keep])))
    r = residuals(runs, best, model)
    n = r.size
    chisqr = float(r @ r)
    free = set(_YEOH) | {"eta_v0"} | {name for name in values_of(best) if name.startswith(("k_v", "mu_v"))}
    parameters = fit_parameters(best, free)
    names = tuple(p.name for p in parameters if p.free)
    k = len(names)
    stderr, corr, covar = _covariance(system, x, keep, chisqr / max(n - k, 1), names)
    values = values_of(best)
    wall = _time.monotonic() - t0
    nsolves = len(runs) * len(scores) + 1
    message = (f"relaxation spectrum: {grid.size} time scales {grid[0]:.3g}-{grid[-1]:.3g} s, "
               f"{int(keep.sum())} with a modulus >= {MIN_MODULUS:g} Pa; strength {lam:.3g} ({rule})")
    spectrum = {"tau_s": [float(t) for t in grid], "modulus_Pa": [float(m) for m in moduli],
                "grid_rule": f"log-spaced, {per_decade:g} per decade, from {TAU_MIN_SAMPLES} x the shortest median "
                             f"sample interval to {beyond:g} decade(s) beyond the longest run's duration"
                             if taus is None else "given",
                "regularization": "Tikhonov on the second differences of the moduli over ln(tau), "
                                  "lam ndata sum((D2 m / m_ref)^2), moduli >= 0",
                "m_ref_Pa": float(start.C10), "strength": float(lam), "strength_rule": rule,
                "cv_scores": {f"{s:.0e}": float(v) for s, v in scores.items()}}
    stage = {"stage": 0, "label": f"spectrum, {grid.size} time scales", "branches": start_branches(best),
             "nfev": nsolves, "wall_time_s": float(wall), "objective": math.sqrt(chisqr / n), "restarts": 0,
             "converged": True, "kept": True, "message": message, "budget_reached": ""}
    return CalibrationResult(
        params=best, start=start, parameters=tuple(parameters), values=values, stderr=stderr, correlation=corr,
        covar=covar, free_names=names,
        at_bound=tuple(p.name for p in parameters if p.free and p.at_bound(values[p.name])), unmoved=(),
        unidentifiable=tuple(n_ for n_ in names if not stderr[n_] == stderr[n_] or stderr[n_] > 0.5 * abs(values[n_])),
        model=model, metric="rms", method="least-squares", objective=math.sqrt(chisqr / n), chisqr=chisqr,
        redchi=chisqr / max(n - k, 1), aic=float(n * np.log(chisqr / n) + 2 * k),
        bic=float(n * np.log(chisqr / n) + k * np.log(n)), ndata=n, nvarys=k, nfree=n - k, nfev=nsolves, nit=0,
        restarts=0, wall_time=float(wall), converged=True, message=message,
        runs=tuple(goodness(run, predict_force(run, best, model)) for run in runs),
        history=np.array([[nsolves, math.sqrt(chisqr / n), 0]], float), stages=(stage,),
        budgets={"max_evals": nsolves, "max_time_s": float(wall), "max_restarts": "not used by the spectrum",
                 "step": "not used by the spectrum", "tolerances": {"bvls": 1e-12},
                 "scope": "the spectrum makes linear solves (counted as evaluations), no budget applies"},
        run_data=tuple(runs), spectrum=spectrum)


def _covariance(system, x, keep, s2, names):
    """Standard errors [SI] from the data's exact Jacobian at fixed time scales (the penalty left out)."""
    cols = np.r_[np.ones(3, bool), keep, True]
    z = x * system.norm
    J = np.vstack([A[A @ z + g0 >= 0.0] for A, _, g0, _ in system.blocks])  # slack samples do not depend on x
    R = np.linalg.qr(J[:, cols] * system.norm[cols], mode="r")  # d r / d x = (d r / d z) norm
    cov = s2 * np.linalg.pinv(R.T @ R)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    return {n: float(v) for n, v in zip(names, sd)}, corr, cov


__all__ = ["BEYOND", "PER_DECADE", "STRENGTHS", "TAU_MIN_SAMPLES", "choose_strength", "design", "fit_spectrum",
           "tau_grid"]
