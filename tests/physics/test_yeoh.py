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
    lambda1 = 1 + e the energy is 3 C10 e^2 (higher orders are e^3 ~ 1e-36 relative).
    e = l1 - 1 is exact in floating point (Sterbenz). I1 - 3 is a sum of three
    expm1 terms of size ~2e that cancel to 3e^2: rounding bounds the relative error by
    3 * eps * 2e / (3 e^2) = 2 eps / e = 4.4e-4 at e = 1e-12; the naive
    l1^2 + l2^2 + ... - 3 would have no correct digit at all."""
    l1 = 1.0 + 1e-12
    e = l1 - 1.0
    psi = yeoh.energy(l1, l1**-0.5, (242e3, -69e3, 47e3))
    assert psi == pytest.approx(3 * 242e3 * e**2, rel=4.4e-4, abs=0)


def test_arrays_broadcast():
    l1 = np.linspace(1, 2, 5)[:, None]
    l2 = np.linspace(0.7, 1.0, 3)[None, :]
    assert yeoh.energy(l1, l2, (1.0, 0.0, 0.0)).shape == (5, 3)
