"""Independent checks of the fsolve 3R baseline (rdea_lab/reports/baseline_3r_fsolve.py).

The fast solver in rdea_lab.physics has its own tests; these only establish
that the baseline is a trustworthy reference.  The closed forms below (Yeoh
energy, 1R model, radii) are written out again here on purpose instead of
being imported from the baseline.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.constants import epsilon_0
from scipy.optimize import brentq

_PATH = Path(__file__).resolve().parents[1] / "rdea_lab" / "reports" / "baseline_3r_fsolve.py"
_spec = importlib.util.spec_from_file_location("baseline_3r_fsolve", _PATH)
baseline = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(baseline)

MAT = dict(L3=48e-6, alpha_e1=1.0, C10=241e3, C20=-33.2e3, C30=20.1e3, eps_r=2.8)
GEOMS = {
    "hollow": dict(Ri=0.86e-3, Rie=0.88e-3, Roe=1.76e-3, Ro=1.8e-3),
    "active": dict(Ri=0.0, Rie=0.088e-3, Roe=1.76e-3, Ro=1.8e-3),
    "passive": dict(Ri=0.0, Rie=0.81e-3, Roe=1.76e-3, Ro=1.8e-3),
}
ONLY_B = dict(Ri=0.5e-3, Rie=0.5e-3, Roe=1.8e-3, Ro=1.8e-3)  # rings a and c vanish
L1 = np.array([1.0, 1.25, 1.5, 1.75])


def yeoh(l1, l2):
    J = l1**2 + l2**2 + l1**-2 * l2**-2 - 3.0
    return MAT["C10"] * J + MAT["C20"] * J**2 + MAT["C30"] * J**3


def radii(geo, l1, l2a, l2b, l2c):
    """Deformed radii chained from the inside using only definitions (1)-(3) and
    incompressibility (5) of ring a, plus the circumferential stretches of rings b, c.

    r_i, r_ie from ring a (both stretches); r_oe from lambda2b given r_ie;
    r_o from lambda2c given r_oe.  Volume conservation of b and c therefore
    holds only if the contact constraints (8)-(9) hold.
    """
    Ri, Rie, Roe, Ro = geo["Ri"], geo["Rie"], geo["Roe"], geo["Ro"]
    l3a = 1.0 / (l1 * l2a)
    r_ie = 0.5 * ((Rie + Ri) * l2a + (Rie - Ri) * l3a)
    r_i = 0.5 * ((Rie + Ri) * l2a - (Rie - Ri) * l3a)
    r_oe = (Roe + Rie) * l2b - r_ie
    r_o = (Ro + Roe) * l2c - r_oe
    return r_i, r_ie, r_oe, r_o


@pytest.mark.parametrize("name", list(GEOMS))
def test_zero_voltage_is_uniaxial(name):
    geo = GEOMS[name]
    v = np.zeros_like(L1)
    # a deliberately wrong start, so that fsolve has to do some work
    bad = np.column_stack([np.zeros_like(L1), 1.06 * L1**-0.5, 0.95 * L1**-0.5,
                           1.03 * L1**-0.5, np.full_like(L1, 1e6), np.full_like(L1, -1e6)])
    # Uniaxial closed form: sigma1 = l1 d/dl1 psi_m(l1, l1^-1/2), by central
    # difference with h = 1e-5.  Truncation error h^2/6 |f'''| <~ 1e-10 * 1e7 Pa
    # / 6 ~ 2e-4 Pa; round-off ~ 1e-16 * psi / h ~ 1e-16 * 5e5 Pa / 1e-5 = 5e-6 Pa.
    # Tolerance 1e-2 Pa (4e-8 C10) is well above both and far below any
    # modelling difference (the Maxwell stress at 1 kV is ~1e4 Pa).
    h = 1e-5
    sigma_uni = L1 * (yeoh(L1 + h, (L1 + h) ** -0.5) - yeoh(L1 - h, (L1 - h) ** -0.5)) / (2 * h)
    for guess in ("1r", "su", bad):
        sol = baseline.solve_3r_fsolve(L1, v, **geo, **MAT, guess=guess)
        assert sol["converged"].all()
        for key in ("lambda2a", "lambda2b", "lambda2c"):
            np.testing.assert_allclose(sol[key], L1**-0.5, rtol=0, atol=1e-9)
        np.testing.assert_allclose(sol["sigma1"], sigma_uni, rtol=0, atol=1e-2)


def _one_ring_1r(l1, v, eta_b=1.0):
    """1R model (33) solved independently: returns (sigma1, lambda2)."""
    eps = epsilon_0 * MAT["eps_r"]
    C10, C20, C30 = MAT["C10"], MAT["C20"], MAT["C30"]

    def dJ(l1, l2):
        J = l1**2 + l2**2 + l1**-2 * l2**-2 - 3.0
        return C10 + 2 * C20 * J + 3 * C30 * J**2

    def maxwell(l2):
        return MAT["alpha_e1"] * eta_b * eps * (l1 * l2 * v / MAT["L3"]) ** 2

    def f(l2):
        return l2 * dJ(l1, l2) * (2 * l2 - 2 * l1**-2 * l2**-3) - maxwell(l2)

    l2 = brentq(f, l1**-0.5, 10 * l1**-0.5, xtol=1e-15, rtol=1e-15)
    sigma1 = l1 * dJ(l1, l2) * (2 * l1 - 2 * l1**-3 * l2**-2) - maxwell(l2)
    return sigma1, l2


@pytest.mark.parametrize("guess", ["1r", "su"])
def test_single_ring_equals_1r_model(guess):
    v = np.full_like(L1, 3000.0)
    sol = baseline.solve_3r_fsolve(L1, v, **ONLY_B, **MAT, guess=guess)
    ref = np.array([_one_ring_1r(l1, 3000.0) for l1 in L1])
    assert sol["converged"].all()
    assert np.isnan(sol["lambda2a"]).all() and np.isnan(sol["lambda2c"]).all()
    np.testing.assert_allclose(sol["lambda2b"], ref[:, 1], rtol=1e-8)
    np.testing.assert_allclose(sol["sigma1"], ref[:, 0], rtol=1e-8)
    # and the voltage really matters: l2b is well away from uniaxial
    assert np.all(sol["lambda2b"] - L1**-0.5 > 1e-2)


def _solutions():
    l1 = np.tile(L1, 3)
    v = np.repeat([0.0, 2000.0, 3500.0], L1.size)
    for name, geo in GEOMS.items():
        for guess in ("1r", "su"):
            yield name, geo, l1, baseline.solve_3r_fsolve(l1, v, **geo, **MAT, guess=guess)


def test_contact_constraints_hold():
    for name, geo, l1, sol in _solutions():
        assert sol["converged"].all(), name
        Ri, Rie, Roe, Ro = geo["Ri"], geo["Rie"], geo["Roe"], geo["Ro"]
        l2a, l2b, l2c = sol["lambda2a"], sol["lambda2b"], sol["lambda2c"]
        # r_ie seen from ring a and from ring b, eq. (1)-(2) with (5)-(6)
        r_ie_a = 0.5 * ((Rie + Ri) * l2a + (Rie - Ri) / (l1 * l2a))
        r_ie_b = 0.5 * ((Roe + Rie) * l2b - (Roe - Rie) / (l1 * l2b))
        # r_oe seen from ring b and from ring c, eq. (2)-(3) with (6)-(7)
        r_oe_b = 0.5 * ((Roe + Rie) * l2b + (Roe - Rie) / (l1 * l2b))
        r_oe_c = 0.5 * ((Ro + Roe) * l2c - (Ro - Roe) / (l1 * l2c))
        np.testing.assert_allclose(r_ie_a, r_ie_b, rtol=0, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(r_oe_b, r_oe_c, rtol=0, atol=1e-12, err_msg=name)


def test_ring_volumes_conserved():
    for name, geo, l1, sol in _solutions():
        Ri, Rie, Roe, Ro = geo["Ri"], geo["Rie"], geo["Roe"], geo["Ro"]
        r_i, r_ie, r_oe, r_o = radii(geo, l1, sol["lambda2a"], sol["lambda2b"], sol["lambda2c"])
        for deformed, undeformed in [
            ((r_ie**2 - r_i**2) * l1, Rie**2 - Ri**2),
            ((r_oe**2 - r_ie**2) * l1, Roe**2 - Rie**2),
            ((r_o**2 - r_oe**2) * l1, Ro**2 - Roe**2),
            ((r_o**2 - r_i**2) * l1, Ro**2 - Ri**2),
        ]:
            np.testing.assert_allclose(deformed, undeformed, rtol=1e-10, atol=0, err_msg=name)


def test_hollow_core_guess_independent():
    # Ri > 0: no r_i = 0 fold, and both starts reach the same equilibrium
    l1 = np.tile(L1, 2)
    v = np.repeat([2000.0, 3500.0], L1.size)
    a = baseline.solve_3r_fsolve(l1, v, **GEOMS["hollow"], **MAT, guess="1r")
    b = baseline.solve_3r_fsolve(l1, v, **GEOMS["hollow"], **MAT, guess="su")
    for key in ("sigma1", "lambda2a", "lambda2b", "lambda2c"):
        np.testing.assert_allclose(a[key], b[key], rtol=1e-9, err_msg=key)


def test_solid_core_uniaxial_state_is_always_stationary():
    # ERRATA: with Ri = 0 the all-uniaxial state solves (27) at any voltage;
    # started there, the baseline stays there.  (Whether it is the energy
    # minimum is NOT checked by the baseline.)
    v = np.full_like(L1, 3500.0)
    for name in ("active", "passive"):
        sol = baseline.solve_3r_fsolve(L1, v, **GEOMS[name], **MAT, guess="su")
        assert sol["converged"].all()
        for key in ("lambda2a", "lambda2b", "lambda2c"):
            np.testing.assert_allclose(sol[key], L1**-0.5, rtol=0, atol=1e-12)


def test_force_and_capacitance_helpers():
    F = baseline.force_from_sigma1(np.array([1e5]), np.array([1.5]), 0.0, 1.8e-3)
    assert F[0] == pytest.approx(1e5 * math.pi * (1.8e-3) ** 2 / 1.5, rel=1e-15)
    C = baseline.capacitance_3r(np.array([1.5]), np.array([1.5**-0.5]), 2e-9)
    assert C[0] == pytest.approx(2e-9 * 1.5, rel=1e-14)  # reduces to (41) when uniaxial


def test_bad_inputs():
    with pytest.raises(ValueError):
        baseline.solve_3r_fsolve(L1, L1[:2], **GEOMS["hollow"], **MAT)
    with pytest.raises(ValueError):
        baseline.solve_3r_fsolve(L1, 0 * L1, **GEOMS["hollow"], **MAT, guess=np.zeros((2, 6)))
