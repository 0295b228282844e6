"""Yeoh energy (22): analytic derivatives against finite differences (property tests)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rdea_lab.physics import yeoh

stretch = st.floats(0.4, 3.0)
coeff = st.tuples(st.floats(1e4, 1e6), st.floats(-1e5, 1e5), st.floats(0.0, 1e5))


def central(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


@settings(max_examples=200, deadline=None)
@given(stretch, stretch, coeff)
def test_gradient_matches_finite_differences(l1, l2, C):
    """Central differences with h = 1e-6 have truncation error ~ h^2 |psi'''| and rounding
    ~ eps |psi| / h; both stay below 1e-6 of the energy scale C10 + |C20| + C30 here."""
    h = 1e-6
    p1, p2 = yeoh.gradient(l1, l2, C)
    scale = sum(abs(c) for c in C) * max(1.0, yeoh.energy(l1, l2, (1, 1, 1)))
    assert p1 == pytest.approx(central(lambda x: yeoh.energy(x, l2, C), l1, h), abs=1e-6 * scale)
    assert p2 == pytest.approx(central(lambda x: yeoh.energy(l1, x, C), l2, h), abs=1e-6 * scale)


@settings(max_examples=200, deadline=None)
@given(stretch, stretch, coeff)
def test_hessian_matches_finite_differences_of_gradient(l1, l2, C):
    h = 1e-6
    p11, p12, p22 = yeoh.hessian(l1, l2, C)
    scale = sum(abs(c) for c in C) * max(1.0, yeoh.energy(l1, l2, (1, 1, 1)))
    assert p11 == pytest.approx(central(lambda x: yeoh.gradient(x, l2, C)[0], l1, h), abs=1e-5 * scale)
    assert p12 == pytest.approx(central(lambda x: yeoh.gradient(l1, x, C)[0], l2, h), abs=1e-5 * scale)
    assert p22 == pytest.approx(central(lambda x: yeoh.gradient(l1, x, C)[1], l2, h), abs=1e-5 * scale)


@settings(max_examples=100, deadline=None)
@given(stretch, stretch, coeff)
def test_solver_kernel_agrees_with_gradient_and_hessian(l1, l2, C):
    """The algebraic hot-path kernel and the log-accurate functions compute the same thing."""
    p2, p22 = yeoh.d_psi_d_l2(l1, l2, C)
    scale = sum(abs(c) for c in C) * max(1.0, yeoh.energy(l1, l2, (1, 1, 1)))
    assert p2 == pytest.approx(yeoh.gradient(l1, l2, C)[1], abs=1e-10 * scale)
    assert p22 == pytest.approx(yeoh.hessian(l1, l2, C)[2], abs=1e-10 * scale)


def test_energy_is_zero_and_stationary_at_rest():
    C = (242e3, -69e3, 47e3)
    assert yeoh.energy(1.0, 1.0, C) == 0.0
    assert yeoh.gradient(1.0, 1.0, C) == (0.0, 0.0)


def test_small_strain_modulus_is_six_C10():
    """Uniaxial tension of an incompressible solid: Young's modulus 3 mu = 6 C10, so at
    lambda1 = 1 + e the energy is 3 C10 e^2 (1 + O(e)). e = l1 - 1 is exact in floating point
    (Sterbenz). The invariant is formed as a sum of two terms that are never negative
    (`yeoh._invariant_terms`), so it keeps its relative accuracy: the bound is the O(e) of the expansion
    (1e-12) and the C20 term (x C20 / C10 ~ 1e-24), well inside 1e-10; the naive
    l1^2 + l2^2 + ... - 3 would have no correct digit at all (and a sum of expm1 terms of size ~2e about
    4e-4)."""
    l1 = 1.0 + 1e-12
    e = l1 - 1.0
    psi = yeoh.energy(l1, l1**-0.5, (242e3, -69e3, 47e3))
    assert psi == pytest.approx(3 * 242e3 * e**2, rel=1e-10, abs=0)


def _exact_invariants(l1, l2):
    """``(I1 - 3, dI1/dl1, dI1/dl2)`` of two floats in exact rational arithmetic."""
    from fractions import Fraction

    a, b = Fraction(float(l1)), Fraction(float(l2))
    return a * a + b * b + 1 / (a * b) ** 2 - 3, 2 * a * (1 - 1 / (a**4 * b**2)), 2 * b * (1 - 1 / (a**2 * b**4))


def _pairs(rng, n=150):
    """Stretch pairs: independent near 1 (strains 0.3 down to 1e-13), uniaxial, ``l1 l2`` near 1, wide
    (``l1`` to 100, ``l2`` up to ten times its uniaxial value), ``l2`` below 0.5 with ``l1`` near 1, and ``l2``
    at the two sides of `yeoh._invariant_terms`' switch (``|l2 - 1| = 0.5``)."""
    out = []
    for scale in (3e-1, 1e-2, 1e-5, 1e-9, 1e-13):
        a = 1.0 + rng.uniform(-scale, scale, n)
        out.append(("independent", a, 1.0 + rng.uniform(-scale, scale, n)))
        out.append(("uniaxial", a, a**-0.5))
        out.append(("l1 l2 near 1", a, (1.0 / a) * (1.0 + rng.uniform(-1e-3, 1e-3, n) * scale)))
    a = 10.0 ** rng.uniform(0.0, 2.0, n)
    out.append(("wide", a, a**-0.5 * 10.0 ** rng.uniform(0.0, 1.0, n)))
    out.append(("l2 below 0.5", 1.0 + rng.uniform(-1e-3, 1e-3, n), rng.uniform(0.01, 0.5, n)))
    at = np.array([0.5, 1.5])
    edge = np.concatenate([at, np.nextafter(at, 0.0), np.nextafter(at, 2.0)])
    out.append(("at the switch", 1.0 + rng.uniform(-0.3, 0.3, edge.size), edge))
    return out


def test_invariant_keeps_its_digits_against_exact_arithmetic():
    """Against exact rational arithmetic on the same floats: ``I1 - 3`` to 8 ulps of itself however small the
    strain (its two terms are never negative; the logarithmic form it replaced was off by up to 1e13 of
    them near stretch 1), and ``dI1/dl1``, ``dI1/dl2`` to 4 ulps of the sum they are formed from
    (``2 l1 (S + 1) / S**2`` times ``s = (l1 - 1) + l1 r``, ``r = l1 l2 - 1`` itself a sum, or ``P - 1`` where
    ``l2`` is outside [0.5, 1.5]; ``dI1/dl2`` likewise): where ``l1**2 l2`` is near 1 the input's last bit
    decides ``dI1/dl1``, in any form, so the error is bounded by the size of the terms, not of their sum."""
    from fractions import Fraction

    eps = np.finfo(float).eps
    for kind, l1, l2 in _pairs(np.random.default_rng(11)):
        got = yeoh._invariant_terms(l1, l2)
        for i in range(l1.size):
            a, b = Fraction(float(l1[i])), Fraction(float(l2[i]))
            exact = _exact_invariants(a, b)
            err = [abs(Fraction(float(got[k][i])) - exact[k]) for k in range(3)]
            assert err[0] <= 8 * eps * abs(exact[0]), (kind, "x", l1[i], l2[i], float(err[0] / abs(exact[0])) / eps)
            p, q, r, P = abs(a - 1), abs(b - 1), abs(a * b - 1), a * b
            r_terms = p + a * q if q <= Fraction(1, 2) else P  # what the rounding of r is relative to
            for k, lam, own, side in ((1, a, p, a * P), (2, b, q, b * P)):
                terms = 2 * lam * (side + 1) / side**2 * (own + lam * r + lam * r_terms)
                assert err[k] <= 4 * eps * terms, (kind, k, l1[i], l2[i], float(err[k] / terms) / eps)


def test_invariant_of_a_nan_or_infinite_stretch_is_not_finite():
    with np.errstate(all="ignore"):
        for l1, l2 in ((np.nan, 1.0), (1.2, np.nan), (np.inf, 1.0), (1.2, 0.0)):
            assert not np.all(np.isfinite(yeoh._invariant_terms(np.array([l1]), np.array([l2])))), (l1, l2)


def test_arrays_broadcast():
    l1 = np.linspace(1, 2, 5)[:, None]
    l2 = np.linspace(0.7, 1.0, 3)[None, :]
    assert yeoh.energy(l1, l2, (1.0, 0.0, 0.0)).shape == (5, 3)
