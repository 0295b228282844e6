"""Geometry: the Appendix of the paper (eqs. 45-58), checked against Table 2 and volume balance."""

import numpy as np
import pytest
from scipy.integrate import quad

from rdea_lab.physics.constants import EPS0
from rdea_lab.physics.geometry import (
    RollGeometry, geometry_from_card, radii_from_membrane, spiral_angle, spiral_length,
)
from rdea_lab.specs import load_specimen

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# Table 1 (L2, L2e) and Table 2 (Rie, Roe, Ro in mm) of the paper; L3 = 48 um, Lp1 = 10 mm.
TABLES = {
    1: (58e-3, 38e-3, (0.600, 1.206, 1.326)),
    2: (99e-3, 76e-3, (0.600, 1.615, 1.732)),
    3: (58e-3, 38e-3, (0.600, 1.206, 1.326)),
}


@pytest.mark.parametrize("n", sorted(TABLES))
def test_radii_reproduce_table2(n):
    """Table 2 within 0.5 %. We get +0.38 % to +0.44 % for every radius of every
    specimen: a systematic offset that ERRATA predicts (the paper's own numbers
    are rounded from a slightly different evaluation); it is reported, not tuned."""
    card = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / f"specimen{n}.yaml")
    g = geometry_from_card(card)
    assert g.Ri == 0.0
    got = np.array([g.Rie, g.Roe, g.Ro]) * 1e3
    offset = got / np.array(TABLES[n][2]) - 1.0
    assert np.all(np.abs(offset) < 0.005), offset
    assert np.all((offset > 0.0035) & (offset < 0.0045)), offset  # the offset we state


@pytest.mark.parametrize("n", sorted(TABLES))
def test_rolled_volume_equals_flat_volume(n):
    """pi (Ro^2 - Ri^2) L1 = 2 L1 L2 L3: the stack of two membranes keeps its volume."""
    L2, L2e, _ = TABLES[n]
    for Ri in (0.0, 0.3e-3):
        r = radii_from_membrane(L2, 48e-6, 10e-3, L2e, Ri=Ri)
        rolled = np.pi * (r["Ro"] ** 2 - r["Ri"] ** 2)
        assert rolled == pytest.approx(2 * L2 * 48e-6, rel=1e-9, abs=0)


def test_region_volumes_follow_eqs_53_to_55():
    """Each ring holds the membrane it was rolled from: (53), (54), (55)."""
    L2, L2e, L3, Lp1 = 99e-3, 76e-3, 48e-6, 10e-3
    r = radii_from_membrane(L2, L3, Lp1, L2e)
    assert np.pi * (r["Rie"] ** 2 - r["Ri"] ** 2) == pytest.approx(L3 * (2 * Lp1 + r["L_pa"]), rel=1e-12, abs=0)
    assert np.pi * (r["Roe"] ** 2 - r["Rie"] ** 2) == pytest.approx(L3 * (2 * r["L_fa"] + r["L_pa"]), rel=1e-12, abs=0)
    assert np.pi * (r["Ro"] ** 2 - r["Roe"] ** 2) == pytest.approx(2 * L3 * r["L_p2"], rel=1e-12, abs=0)
    assert r["L_pa"] + r["L_fa"] == pytest.approx(L2e, rel=1e-15, abs=0)


@pytest.mark.parametrize("r0, d, theta", [(0.0, 96e-6, 36.0), (0.5e-3, 96e-6, 12.0), (1e-3, 1e-6, 2 * np.pi)])
def test_spiral_length_is_the_integral_of_the_speed(r0, d, theta):
    """Eq. (46) as corrected: arc length = integral of |d/dtheta (r(theta) e_r)|, by quadrature."""
    b = d / (2 * np.pi)
    ref, _ = quad(lambda th: np.hypot(b, r0 + b * th), 0.0, theta, epsabs=0, epsrel=1e-13, limit=200)
    assert float(spiral_length(r0, d, theta)) == pytest.approx(ref, rel=1e-11, abs=0)


def test_spiral_angle_inverts_length():
    lengths = np.array([1e-6, 1e-3, 10e-3, 99e-3])
    theta = spiral_angle(0.0, 96e-6, lengths)
    assert np.allclose(spiral_length(0.0, 96e-6, theta), lengths, rtol=1e-13, atol=0)


def test_tight_spiral_turn_is_a_circle():
    """Far from the centre one turn is ~ 2 pi r: a limit independent of the closed form."""
    r0 = 1e-3
    assert float(spiral_length(r0, 1e-9, 2 * np.pi)) == pytest.approx(2 * np.pi * r0, rel=1e-5, abs=0)


def test_C0_and_fractions_by_hand():
    g = RollGeometry(0.0, 0.6e-3, 1.615e-3, 1.732e-3, L1=34e-3, L1e=29e-3, L3=48e-6)
    assert g.eta_a + g.eta_b + g.eta_c == pytest.approx(1.0, abs=1e-15)
    assert g.eta_b == pytest.approx((1.615**2 - 0.6**2) / 1.732**2, rel=1e-12, abs=0)
    hand = 8.8541878128e-12 * 2.8 * (29 / 34) * 34e-3 * np.pi * (1.615e-3**2 - 0.6e-3**2) / 48e-6**2
    assert g.C0(2.8) == pytest.approx(hand, rel=1e-9, abs=0)
    assert EPS0 == pytest.approx(8.85e-12, rel=1e-3, abs=0)  # Table 1 prints 8.85 pF/m


def test_electrode_shorter_than_one_turn_is_refused():
    with pytest.raises(ValueError, match="shorter than the partially active first turn"):
        radii_from_membrane(58e-3, 48e-6, 10e-3, 1e-3)


@pytest.mark.parametrize("radii", [(0.9e-3, 0.8e-3, 1.7e-3, 1.8e-3), (0.0, 1.0e-3, 1.0e-3, 1.8e-3),
                                   (0.0, 0.8e-3, 1.9e-3, 1.8e-3), (-1e-4, 0.8e-3, 1.7e-3, 1.8e-3)])
def test_unordered_radii_are_refused(radii):
    with pytest.raises(ValueError, match="radii must satisfy"):
        RollGeometry(*radii, L1=34e-3, L1e=34e-3, L3=48e-6)
