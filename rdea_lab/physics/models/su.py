"""Strongly uniaxial (SU) model: eqs. (39)-(41) of [1], closed form."""

from __future__ import annotations

import numpy as np

from .. import yeoh
from ..result import BAD_INPUT, OK, OVERFLOW, SLACK, ModelResult, PathEnd, prepare_inputs, read_only
from .._backend import compiled
from ._common import FREE_STRETCH_MAX, Evaluation, check_start, kappa, solve_model, yeoh_coefficients


def enthalpy(geom, material, stretch, voltage):
    """Free enthalpy density ``g = psi_m(l1, l1**-0.5) - kappa l1 v**2`` [Pa].

    Parameters
    ----------
    geom : RollGeometry
    material : parameter set with ``C10, C20, C30`` [Pa] and ``eps_r`` [-]
    stretch : array_like
        Axial stretch [-].
    voltage : array_like
        Voltage [V].
    """
    l1 = np.asarray(stretch, float)
    return (yeoh.energy(l1, l1**-0.5, yeoh_coefficients(material))
            - kappa(geom, material) * l1 * np.asarray(voltage, float) ** 2)


def basis(stretch):
    """``(b, x)`` with the SU mechanical stress ``b W'(x)`` [Pa], eq. (39).

    ``x = I1 - 3 = lambda1**2 + 2 / lambda1 - 3 = d**2 (lambda1 + 2) / lambda1`` and ``b = 2 lambda1**2
    (1 - lambda1**-3) = 2 d (lambda1**2 + lambda1 + 1) / lambda1`` with ``d = lambda1 - 1`` (exact in
    floating point for lambda1 in [0.5, 2]): the factored forms keep every digit near lambda1 = 1, where
    the plain ones cancel, and cost no transcendental function (the compiled kernels compile this too).
    The stress is linear in the Yeoh coefficients through
    ``W'(x) = C10 + 2 C20 x + 3 C30 x**2``, which a calibration can exploit.
    """
    d = stretch - 1.0
    inv = 1.0 / stretch
    return 2.0 * d * (stretch * stretch + stretch + 1.0) * inv, d * d * (stretch + 2.0) * inv


def stress_basis(stretch, voltage):
    """``(b, x, lambda1 v**2)``: the SU stress is ``b W'(x) - kappa lambda1 v**2``, eq. (39).

    With ``W'(x) = C10 + 2 C20 x + 3 C30 x**2`` it is linear in the Yeoh
    coefficients and in ``kappa`` (:func:`stress_from_basis`), so a calibration
    that evaluates many parameter sets on one history computes this once.
    """
    stretch = np.asarray(stretch, float)
    b, x = basis(stretch)
    return b, x, stretch * np.asarray(voltage, float) ** 2


def stress_from_basis(stress_basis_, geom, material):
    """Axial SU stress [Pa] of eq. (39) from :func:`stress_basis` for a geometry and material."""
    b, x, lv2 = stress_basis_
    W1, _ = yeoh.slope(x, yeoh_coefficients(material))
    return b * W1 - kappa(geom, material) * lv2


def evaluate(geom, material, l1, v, *, path=False, start=None, origin=None, kernel="auto") -> Evaluation:
    """Closed-form SU state at clean 1-D inputs (no free coordinate: a path changes nothing)."""
    C = yeoh_coefficients(material)
    # per-sample Yeoh coefficients (a design study's material sweep) take the numpy form
    fast = compiled(kernel, l1.size) if all(isinstance(c, float) for c in C) else None
    C0 = geom.C0(material.eps_r)
    if fast is not None:
        sigma1, l2, capacitance = fast.su_state(l1, v, C, kappa(geom, material), C0)
    else:
        sigma1 = stress_from_basis(stress_basis(l1, v), geom, material)
        l2 = 1.0 / np.sqrt(l1)
        capacitance = C0 * l1
    n = l1.size
    fields = {"sigma1": sigma1, "lambda2a": l2, "lambda2b": l2, "lambda2c": l2,
              "capacitance": capacitance, "r_i": geom.Ri * l2}
    return Evaluation(np.full(n, OK, np.int8), None, None, fields, None)  # no fold, no range end


def solve(geom, material, stretch, voltage, *, path=False, start=None, slack=True,
          kernel="auto") -> ModelResult:
    """Axial stress, force and capacitance of the SU model.

    Parameters
    ----------
    geom : RollGeometry
        Undeformed roll geometry.
    material : parameter set
        ``C10, C20, C30`` [Pa], ``eps_r`` [-].
    stretch : array_like
        Axial stretch ``lambda1`` [-], >= 1.
    voltage : array_like
        Voltage [V].
    path, start, slack
        See :func:`rdea_lab.physics.models.solve`; SU has no free coordinate,
        so its state has no memory of the path.

    Returns
    -------
    ModelResult

    Notes
    -----
    Eq. (39) in [1]: ``sigma1 = lambda1 d psi_m(lambda1, lambda1**-0.5) /
    d lambda1 - 0.5 alpha_e1 eta_b eps E**2`` with ``E = sqrt(lambda1) v / L3``;
    capacitance eq. (41), ``C = C0 lambda1``. With
    ``I1 - 3 = x = e**(2a) + 2 e**(-a) - 3``, ``a = ln lambda1``, the
    mechanical part is ``2 lambda1**2 W'(x) (1 - lambda1**-3)``. There is no
    free coordinate at fixed stretch, hence no limit point. Where the stress
    would be negative the roll is slack (force 0) in its free state, the
    stretch where eq. (39) vanishes.
    """
    C = yeoh_coefficients(material)
    prepared = None
    if all(isinstance(c, float) for c in C) and np.ndim(geom.Ri) == 0 and np.ndim(material.eps_r) == 0:
        prepared = prepare_inputs(stretch, voltage)
        fast = compiled(kernel, prepared[0].size)
        if fast is not None:
            return _solve_compiled(fast, geom, material, C, *prepared, path, start, slack)
    return solve_model("su", evaluate, geom, material, stretch, voltage, path=path, start=start, slack=slack,
                       kernel=kernel, prepared=prepared)


def _solve_compiled(fast, geom, material, C, l1, v, bad, shape, raw, path, start, slack) -> ModelResult:
    """`solve` in one compiled pass (`rdea_lab.physics.kernels.su_solve`): the same result as
    `solve_model`'s (the tests hold them to 1e-12 and identical statuses)."""
    end = check_start("su", path, start)
    if path:  # SU has no coordinate: a path ends where it started only when it had no sample to solve
        end = PathEnd("su", *(end if (end is not None and bad.size and bad.all()) else (None, None)))
    fields, status, ok = fast.su_solve(np.ascontiguousarray(l1), np.ascontiguousarray(v), bad, C,
                                       float(kappa(geom, material)), float(geom.C0(material.eps_r)),
                                       float(geom.Ri), float(geom.area), slack, FREE_STRETCH_MAX,
                                       (OK, SLACK, BAD_INPUT, OVERFLOW))
    sigma, tension, force, l2, cap, r_i, free = (f.reshape(shape) for f in fields)
    nan = np.broadcast_to(np.nan, shape)  # SU has no fold and no range end
    l2 = read_only(l2)  # one array for the three rings: read-only, so no write to one changes another
    return ModelResult(model="su", stretch=read_only(raw[0].reshape(shape)), voltage=read_only(raw[1].reshape(shape)),
                       sigma1=sigma, force=force, lambda2a=l2, lambda2b=l2, lambda2c=l2, capacitance=cap,
                       converged=ok.reshape(shape), status=status.reshape(shape), critical_voltage=nan,
                       r_i=r_i, tension=tension, range_voltage=nan, free_stretch=free, end=end)
