"""`branch.newton_start` (where the ramp rule's Newton iteration starts in its bracket) against the
interpolation it states: where the inverse ``y(h)`` is a cubic (the slopes at both nodes known) or a
quadratic (the slope at ``lo`` unknown, as at ``y0``), the start is the root itself to rounding; outside
the bracket it falls back to the midpoint; and the compiled form (`kernels._start`) gives the same bits.
"""

from __future__ import annotations

import numpy as np
import pytest

from rdea_lab.physics.branch import newton_start


def _bracket(rng, n, degree):
    """Rising inverses ``y(h) = y0 + a h + b h**2 (+ c h**3)`` (``dy/dh > 0`` on [0, 1]), brackets
    ``[y(h_lo), y(h_hi)]`` and loads ``K`` inside; returns ``(lo, hi, h_lo, h_hi, s_lo, s_hi, K, root)``."""
    a = rng.uniform(0.5, 2.0, n)
    b = rng.uniform(-0.2, 0.2, n)
    c = rng.uniform(-0.1, 0.1, n) if degree == 3 else np.zeros(n)

    def y(h):
        return 1.0 + h * (a + h * (b + h * c))

    def dy(h):
        return a + h * (2.0 * b + 3.0 * h * c)

    h_lo = rng.uniform(0.0, 0.5, n)
    h_hi = h_lo + rng.uniform(1e-3, 0.5, n)
    K = h_lo + rng.uniform(0.0, 1.0, n) * (h_hi - h_lo)
    s_lo = 1.0 / dy(h_lo) if degree == 3 else np.full(n, np.nan)
    return y(h_lo), y(h_hi), h_lo, h_hi, s_lo, 1.0 / dy(h_hi), K, y(K)


@pytest.mark.parametrize("degree", [3, 2])
def test_start_is_the_root_of_a_cubic_or_quadratic_inverse(degree):
    lo, hi, h_lo, h_hi, s_lo, s_hi, K, root = _bracket(np.random.default_rng(degree), 2000, degree)
    start = newton_start(lo, hi, h_lo, h_hi, s_lo, s_hi, K)
    assert np.all((start >= lo) & (start <= hi))
    assert np.allclose(start, root, rtol=0.0, atol=1e-13)


def test_outside_the_bracket_the_midpoint():
    # slopes that overshoot: the interpolant leaves [lo, hi]; and a load above h_hi
    lo, hi = np.array([1.0, 1.0, 1.0]), np.array([2.0, 2.0, 2.0])
    start = newton_start(lo, hi, np.zeros(3), np.ones(3), np.array([1e-3, np.nan, 1.0]), np.array([1e-3, 1e-3, 1.0]),
                         np.array([0.5, 0.5, 1.5]))
    assert np.array_equal(start, [1.5, 1.5, 1.5])


def test_compiled_start_same_bits():
    numba = pytest.importorskip("numba")
    from rdea_lab.physics import kernels

    @numba.njit(cache=False)
    def starts(lo, hi, h_lo, h_hi, s_lo, s_hi, K):
        out = np.empty(lo.size)
        for i in range(lo.size):
            out[i] = kernels._start(lo[i], hi[i], h_lo[i], h_hi[i], s_lo[i], s_hi[i], K[i])
        return out

    for degree in (3, 2):
        args = _bracket(np.random.default_rng(10 + degree), 500, degree)[:7]
        assert np.array_equal(starts(*args), newton_start(*args))
