"""The inverse twin: the voltage that makes the twin's force follow a target along a stretch history.

Along a given stretch history the viscoelastic overstress (eq. (44) of [1], or
its finite-strain form) depends on the stretch alone, not on the voltage, so
the force the quasi-static model must supply at each sample is known before
any voltage is: ``sigma_rev = F lambda1 / A - sigma_irr`` (eqs. (43), (16)).
What is left is a per-sample inversion of the quasi-static stress in ``v**2``:

- SU: ``sigma_rev = b W'(x) - kappa lambda1 v**2`` (eq. (39)) is affine in
  ``v**2``: closed form. SU has no fold; the stress falls without bound with
  ``v**2`` and only the voltage limit (the protocol's, and its field limit)
  ends the reachable range.
- 1R, 3R, CR: the stress falls monotonically with ``v**2`` along the branch a
  voltage ramp from 0 V follows, up to the fold (pull-in, status
  ``LIMIT_POINT``, or ``SNAPPED`` where the roll jumps to another branch, e.g. the
  hole of a passive core opening) where that branch ends. A vectorized bisection in ``v**2``
  over ``[0, min(limit, fold)**2]`` on all samples at once (no loop over
  samples); a sample whose target needs more than the fold or the limit is
  unreachable (the twin would snap through or the rig refuse), and is reported,
  not clipped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..physics import viscoelastic
from ..physics.models import solve, su
from ..physics.result import LIMIT_POINT, OK, SLACK, SNAPPED
from .simulate import as_geometry, compose, viscous
from ..specs import as_params

#: Bisection steps in v**2 for the models without a closed form: 2**-60 of the
#: bracket is below a double's resolution of any voltage up to the limit.
BISECTION_STEPS = 60


@dataclass(frozen=True)
class InverseResult:
    """The voltage for a force target, per sample.

    Attributes
    ----------
    voltage : numpy.ndarray
        Planned voltage [V], >= 0; 0 where there is no target (NaN force); NaN where the target is
        out of reach.
    reachable : numpy.ndarray of bool
        The target is reachable (True where there is no target).
    force_max, force_min : numpy.ndarray
        The twin's force at 0 V and at the highest usable voltage [N]: the reachable range at each
        sample with a target (force falls as the voltage rises); NaN where there is no target.
    voltage_max : numpy.ndarray
        The highest usable voltage [V]: the limit given, or the fold's voltage where it is lower.
    fold : numpy.ndarray of bool
        The fold (pull-in) lies below the limit at that sample, so it sets ``voltage_max``.
    """

    voltage: np.ndarray
    reachable: np.ndarray
    force_max: np.ndarray
    force_min: np.ndarray
    voltage_max: np.ndarray
    fold: np.ndarray


class RequiredStress(NamedTuple):
    """What :func:`required_stress` returns (a tuple too, in this order).

    Attributes
    ----------
    sigma_rev : numpy.ndarray, shape (n,)
        The quasi-static (reversible) axial stress the force history needs [Pa].
    sigma_irr : numpy.ndarray, shape (n,)
        The viscoelastic overstress along the stretch history [Pa].
    """

    sigma_rev: np.ndarray
    sigma_irr: np.ndarray


def required_stress(geom, params, t, stretch, force) -> RequiredStress:
    """The quasi-static stress a force history needs, and the overstress along its stretch history.

    Parameters
    ----------
    geom : RollGeometry or StripGeometry
    params : ParameterSet
    t : numpy.ndarray, shape (n,)
        Sample times [s], strictly increasing.
    stretch : numpy.ndarray, shape (n,)
        Axial stretch [-].
    force : numpy.ndarray, shape (n,)
        Force [N].

    Returns
    -------
    RequiredStress
        ``sigma_rev = F lambda1 / A - sigma_irr`` [Pa] (eqs. (43), (16) of [1]) and ``sigma_irr`` [Pa]
        (eq. (44) of [1], or its finite-strain form); the branches start relaxed at ``t[0]``, as in `simulate`.
    """
    k, eta, eta_v0, law = viscous(params)
    sigma_irr, _ = viscoelastic.overstress_step(t, stretch, k, eta, eta_v0, law=law)
    return RequiredStress(force * stretch / geom.area - sigma_irr, sigma_irr)


def _force(geom, params, t, stretch, tension):
    """The twin's force [N] for a quasi-static stress along the history: `compose`, the one composition."""
    return compose(geom, viscous(params), t, stretch, tension)[2]


def voltage_for_force(specimen, params, t, stretch, force, model="su", *, max_voltage) -> InverseResult:
    """Voltage such that the twin's force follows `force` along the stretch history `stretch`.

    Parameters
    ----------
    specimen : SpecimenCard, RollGeometry or path
    params : ParameterSet or path
    t : array_like, shape (n,)
        Sample times [s], strictly increasing.
    stretch : array_like, shape (n,)
        Axial stretch [-], >= 1 (fixed for a blocking test, moving against a bias).
    force : array_like, shape (n,)
        Target force [N], > 0; NaN where there is no target (0 V is planned there, and the
        overstress history runs on).
    model : {"su", "1r", "3r", "cr"}
    max_voltage : float or array_like
        Highest voltage allowed at each sample [V] (a protocol's voltage and field limits).

    Returns
    -------
    InverseResult

    Notes
    -----
    Inverts eqs. (43), (44), (16) with (39) (SU) or the model's own
    equilibria: see the module docstring. Forward check: `simulate` on the
    returned voltage gives `force` (to rounding for SU, to the bisection's
    resolution otherwise) where the model's branch from 0 V is the one the
    time series follows.
    """
    geom = as_geometry(specimen)
    params = as_params(params)
    stretch = np.asarray(stretch, float)
    t = viscoelastic.check_time(t, stretch.shape)
    force = np.asarray(force, float)
    vmax = np.broadcast_to(np.asarray(max_voltage, float), stretch.shape)
    target = np.isfinite(force)
    need, sigma_irr = required_stress(geom, params, t, stretch, np.where(target, force, 0.0))
    umax = vmax**2
    if model == "su":
        mech = su.stress_from_basis(su.stress_basis(stretch, 0.0), geom, params)
        zero = np.zeros_like(stretch)
        slope = -su.stress_from_basis((zero, zero, stretch), geom, params)  # -d sigma_rev / d(v**2) = kappa l1
        u = (mech - need) / slope
        u = np.where((u < 0.0) & (u > -1e-12 * umax), 0.0, u)  # a target at the 0 V force, to rounding
        fmax, fmin = _force(geom, params, t, stretch, mech), _force(geom, params, t, stretch, mech - slope * umax)
        fold = np.zeros(stretch.shape, bool)
        ok = (u >= 0.0) & (u <= umax)
    else:
        u, ok, fmax, fmin, umax, fold = _bisect(model, geom, params, t, stretch, need, umax, target)
    reachable = ok | ~target
    fmax, fmin = np.where(target, fmax, np.nan), np.where(target, fmin, np.nan)
    voltage = np.where(target, np.where(ok, np.sqrt(np.where(ok, u, 0.0)), np.nan), 0.0)
    return InverseResult(voltage, reachable, fmax, fmin, np.sqrt(umax), fold)


def _bisect(model, geom, params, t, stretch, need, umax, target):
    """Vectorized bisection of ``sigma_rev(v**2) = need`` on ``[0, umax]`` (the fold caps the bracket),
    on the samples with a target only."""
    idx = np.flatnonzero(target)
    lam, want, cap = stretch[idx], need[idx], umax[idx]

    def tension(u):
        res = solve(model, geom, params, lam, np.sqrt(u), path=False)
        return res.tension, np.isin(res.status, (OK, SLACK)), res

    s0, valid0, _ = tension(np.zeros_like(cap))
    s1, valid1, res1 = tension(cap)
    crit = np.asarray(res1.critical_voltage, float)
    fold = np.isin(res1.status, (LIMIT_POINT, SNAPPED))  # the branch from 0 V ends below the limit
    # past the fold: the bracket ends at the fold's voltage (just below it, where the branch still exists)
    top = np.where(fold & np.isfinite(crit), np.minimum(cap, (crit * (1.0 - 1e-9)) ** 2), cap)
    s1, valid1, _ = tension(top)
    lo, hi = np.zeros_like(cap), top.copy()
    for _ in range(BISECTION_STEPS):  # over the bracket, on all samples at once
        mid = 0.5 * (lo + hi)
        tm, valid, _ = tension(mid)
        above = valid & (tm > want)  # still too much stress: more voltage
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)

    def full(values, fill):
        out = np.full(stretch.shape, fill, dtype=np.asarray(values).dtype)
        out[idx] = values
        return out

    u = full(0.5 * (lo + hi), 0.0)
    fmax = _force(geom, params, t, stretch, full(s0, np.nan))
    fmin = _force(geom, params, t, stretch, full(s1, np.nan))
    ok = full(valid0 & (s0 >= want) & (s1 <= want), False)
    return u, ok, fmax, fmin, full(top, 0.0) + np.where(target, 0.0, umax), full(fold & (top < cap), False)


__all__ = ["BISECTION_STEPS", "InverseResult", "RequiredStress", "required_stress", "voltage_for_force"]
