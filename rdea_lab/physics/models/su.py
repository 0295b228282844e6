"""Strongly uniaxial (SU) model: eqs. (39)-(41) of [1], closed form."""

from __future__ import annotations

import threading

import numpy as np

from .. import yeoh
from ..result import (BAD_INPUT, OK, OVERFLOW, SLACK, ModelResult, PathEnd, broadcast_inputs, check_inputs, deferred,
                      nan_field, read_only)
from .._backend import AUTO_MIN_SAMPLES, compiled
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


def residual_pass(kernel="auto"):
    """A calibration run's scaled force errors in one compiled pass, or None where the compiled kernels are
    off or numba is missing (the caller then composes them in numpy).

    The pass (`rdea_lab.physics.kernels`) takes the same operations in the same order as
    :func:`stress_from_basis`, then `rdea_lab.twin.compose` under eq. (44)'s linear law, the force clipped
    at 0 (a slack roll), less the measured force, times ``scale``: the two agree to the last bit. It is a
    callable ``f(basis, geom, material, visco, history, stretch, force, scale, out)``: ``basis`` of
    :func:`stress_basis`, ``visco`` the twin's ``(k, eta, eta_v0, law)`` (the law linear, every ``eta / k``
    positive), ``history`` the run's `~rdea_lab.physics.viscoelastic.History` (finite, two samples or
    more); it writes ``out``. ``work``, optional: the pass's scratch, a C-contiguous float array of shape
    (branches, samples) that a caller evaluating many sets of one branch count reuses (its content does
    not matter: the pass overwrites it before reading it); else a new one per call.
    """
    fast = compiled(kernel, AUTO_MIN_SAMPLES)
    if fast is None:
        return None

    def run(basis, geom, material, visco, history, stretch, force, scale, out, work=None):
        b, x, lv2 = basis
        k, eta, eta_v0, _ = visco
        if work is None or work.shape != (k.size, stretch.size):
            work = np.empty((k.size, stretch.size))
        fast._su_linear_residual(b, x, lv2, yeoh_coefficients(material), kappa(geom, material), k, eta,
                                 history.lengths, history.length_index, history.slope, eta_v0, history.rate,
                                 float(geom.area), stretch, force, scale, work, out)
    return run


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
        l1, v, shape = broadcast_inputs(stretch, voltage)
        fast = compiled(kernel, l1.size)
        if fast is not None:  # the compiled pass checks the inputs itself
            return _solve_compiled(fast, geom, material, C, l1, v, shape, path, start, slack)
        prepared = check_inputs(l1, v, shape)
    return solve_model("su", evaluate, geom, material, stretch, voltage, path=path, start=start, slack=slack,
                       kernel=kernel, prepared=prepared)


def _solve_compiled(fast, geom, material, C, l1, v, shape, path, start, slack) -> ModelResult:
    """`solve` by the compiled kernels: the same result as `solve_model`'s (the tests hold them to 1e-12
    and identical statuses).

    One compiled pass (`rdea_lab.physics.kernels.su_solve`) computes what every caller needs: the status,
    the convergence and the tension (and checks the inputs). The other fields are computed when first read
    (`_Fields`): every field at the given stretch in one compiled pass (the stress, force, stretches,
    capacitance and radius: one read of the tension and stretch for all, where two passes cost 10-20 %
    more to a caller that reads every field, 30 % less to one that reads the stress alone), then the slack
    rolls' free states and the fields there. A caller that reads the stress alone pays for no free state.
    The result holds no reference to the caller's arrays beyond ``stretch`` and ``voltage``, so a later
    change to those changes no field computed later. Every array the result computes (the tension, status,
    convergence and fields) is read-only, nor can a view of one be made writeable: the fields are rows of one
    block (`su_solve`), and the later ones are computed from the earlier. (``stretch`` and ``voltage`` are
    read-only views of the caller's arrays; nothing is computed from them later.)"""
    end = check_start("su", path, start)
    kap = float(kappa(geom, material))
    l1c, vc = np.ascontiguousarray(l1), np.ascontiguousarray(v)
    area = float(geom.area)
    block, work, status, converged, idx, v_slack, low = fast.su_solve(l1c, vc, C, kap, area, slack, _CODES)
    if low:
        check_inputs(l1, v, shape)  # raises `StretchBelowOneError`, with the first such sample
    if path:  # SU has no coordinate: a path ends where it started only when it had no sample to solve
        none = end is not None and status.size and not (status != BAD_INPUT).any()
        end = PathEnd("su", *(end if none else (None, None)))
    status.flags.writeable = converged.flags.writeable = False
    # the slack samples' voltages (``v_slack``: copies, a few samples) for their free states
    derive = _Fields(fast, shape, block, work, idx, v_slack, C, kap, area, float(geom.C0(material.eps_r)),
                     float(geom.Ri), bool(slack))
    nan = nan_field(shape)  # SU has no fold and no range end
    return deferred({"model": "su", "stretch": read_only(l1.reshape(shape)), "voltage": read_only(v.reshape(shape)),
                     "status": status.reshape(shape), "tension": block[0].reshape(shape),
                     "converged": converged.reshape(shape), "critical_voltage": nan, "range_voltage": nan,
                     "end": end}, derive)


_CODES = (OK, SLACK, BAD_INPUT, OVERFLOW)


class _Fields:
    """The fields of a compiled SU solve that are computed when first read (see `_solve_compiled`), into
    the rows of the solve's block (`rdea_lab.physics.kernels.su_solve`), from its tension and state stretch
    and the slack samples' indices and voltages, in two passes (`rdea_lab.physics.kernels.su_fields`): every
    field at the state stretch (the stress and force are then final), then the free states and the fields
    at them (the state stretch, written in place, becomes the free stretch). Each is computed once, under a
    lock: threads that read a field first at once get the same arrays. A call gives every field of the pass
    (`deferred`)."""

    _PASSES = ({"sigma1": 2, "force": 3},
               {"lambda2a": 4, "lambda2b": 4, "lambda2c": 4, "capacitance": 5, "r_i": 6, "free_stretch": 1})
    _PASS = {name: k for k, names in enumerate(_PASSES) for name in names}

    def __init__(self, fast, shape, block, work, idx, v_slack, C, kap, area, C0, Ri, slack):
        self.fast, self.shape, self.block, self.work = fast, shape, block, work
        self.args = (idx, v_slack, C, kap, FREE_STRETCH_MAX, slack, area, C0, Ri)
        self.done = [None, None]
        self.lock = threading.Lock()

    def __call__(self, name):
        k = self._PASS[name]
        with self.lock:
            for j in range(k + 1):  # the free states' pass after the first
                if self.done[j] is None:
                    self._compute(j)
        return self.done[k]

    def _compute(self, k):
        self.fast.su_fields(self.work, *self.args, k)
        views = {}  # one view per row: the three rings' fields are one array
        self.done[k] = {key: views.setdefault(row, self.block[row].reshape(self.shape))
                        for key, row in self._PASSES[k].items()}
