"""The calibration objective's residuals of one run in one compiled pass (numba; imported only where it is there).

What `rdea_lab.calibration.objective.residuals` computes for a run whose quasi-static stress is SU's
basis (`rdea_lab.physics.models.su.stress_from_basis`) under eq. (44)'s linear law:
``((max((b W'(x) - kappa lambda1 v**2 + sum_j k_j q_j + eta_v0 rate) A / lambda1, 0)) - F) * scale``,
the same operations in the same order as the numpy composition (`rdea_lab.twin.compose`,
`rdea_lab.physics.viscoelastic.overstress_step`), so the two agree to the last bit; the branch strains
``q`` come from the compiled update a `~rdea_lab.physics.viscoelastic.History` takes
(`rdea_lab.physics.kernels.linear_strains`'s loop, relaxed at the first sample). One compiled call per
run instead of a dozen numpy temporaries and calls: the objective is evaluated thousands of times per fit.
"""

from __future__ import annotations

import numba
import numpy as np

from ..physics.kernels import _linear, _slope_inline


@numba.njit(cache=True, error_model="numpy")
def su_linear_residual(b, x, lv2, C, kap, k, eta, lengths, index, slope, eta_v0, rate, area, stretch, force,
                       scale, q, out):
    """``out[i]``: the scaled force error at sample i (module docstring); ``eta_v0 == 0``: no damper term.

    ``lengths``, ``index``, ``slope``, ``rate``: the run's `History` (its distinct interval lengths, each
    interval's, the stretch slopes and rates); ``q``: scratch of shape (M, n) for the branch strains.
    """
    M = k.size
    n = b.size
    if M:
        _linear(lengths, index, slope, eta / k, np.zeros(M), q)
    # in passes without branches inside (the compiler vectorizes them), in the numpy composition's order:
    # q[0] becomes the overstress k_1 q_1 + ... + k_M q_M (+ eta_v0 rate); out the reversible stress
    for i in range(n):
        W1, _ = _slope_inline(x[i], C)
        out[i] = b[i] * W1 - kap * lv2[i]
    if M:
        k0 = k[0]
        for i in range(n):
            q[0, i] = k0 * q[0, i]
        for j in range(1, M):
            kj = k[j]
            for i in range(n):
                q[0, i] += kj * q[j, i]
        if eta_v0 != 0.0:
            for i in range(n):
                q[0, i] += eta_v0 * rate[i]
        for i in range(n):
            out[i] = out[i] + q[0, i]
    elif eta_v0 != 0.0:
        for i in range(n):
            out[i] = out[i] + (0.0 + eta_v0 * rate[i])
    else:
        for i in range(n):
            out[i] = out[i] + 0.0
    for i in range(n):
        f = out[i] * area / stretch[i]
        f = 0.0 if f < 0.0 else f  # np.maximum(f, 0.0): slack; NaN stays NaN
        out[i] = (f - force[i]) * scale[i]
