"""The twin's multi-array results are NamedTuples: `viscous`, `compose`, `required_stress` name their fields,
and still unpack as the tuples they were (callers in the emulator and design studies unpack them).

The values are checked against the parameter set and the paper's equations directly, not against the code.
"""

from pathlib import Path

import numpy as np
import pytest

from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.specs import load_params, load_specimen
from rdea_lab.twin import compose, viscous
from rdea_lab.twin.inverse import RequiredStress, required_stress
from rdea_lab.twin.simulate import Composition, Viscous

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def geom():
    return geometry_from_card(load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"))


@pytest.fixture(scope="module")
def table3():
    return load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")


def test_viscous_names_the_branches_of_the_set(table3):
    v = viscous(table3)
    assert isinstance(v, Viscous) and v._fields == ("modulus", "eta", "eta_v0", "law")
    assert list(v.modulus) == [b.k for b in table3.branches] and list(v.eta) == [b.eta for b in table3.branches]
    assert v.eta_v0 == table3.eta_v0 and v.law == table3.law == "linear"
    k, eta, eta_v0, law = v  # a tuple too, in this order
    assert k is v.modulus and law == "linear"


def test_compose_names_stress_overstress_force_and_state(geom, table3):
    t = np.linspace(0.0, 2.0, 201)
    stretch = 1.0 + 0.2 * np.sin(np.pi * t / 2.0)  # out and back: the overstress turns compressive
    sigma_rev = np.full(t.size, 10e3)  # [Pa]: below the unloading overstress (k tau rate, about 27 kPa)
    out = compose(geom, viscous(table3), t, stretch, sigma_rev)
    assert isinstance(out, Composition) and out._fields == ("sigma1", "sigma1_irr", "force", "state")
    taut = out.force > 0
    assert taut.any() and (~taut).any()
    # eq. (43): sigma1 = sigma_rev + sigma_irr where taut, 0 where slack; eq. (16): F = sigma1 A / lambda1
    np.testing.assert_array_equal(out.sigma1[taut], (sigma_rev + out.sigma1_irr)[taut])
    np.testing.assert_array_equal(out.sigma1[~taut], 0.0)
    np.testing.assert_allclose(out.force[taut], (out.sigma1 * geom.area / stretch)[taut], rtol=1e-15)
    sigma1, sigma1_irr, force, state = out  # a tuple too, in this order
    assert force is out.force and state is out.state is not None


def test_required_stress_splits_the_force_into_quasi_static_and_overstress(geom, table3):
    t = np.linspace(0.0, 1.0, 101)
    stretch = 1.0 + 0.3 * t
    force = np.full(t.size, 2.0)  # [N]
    need = required_stress(geom, table3, t, stretch, force)
    assert isinstance(need, RequiredStress) and need._fields == ("sigma_rev", "sigma_irr")
    # eqs. (43) and (16): sigma_rev + sigma_irr = F lambda1 / A (1e-12: one subtraction and addition of floats)
    np.testing.assert_allclose(need.sigma_rev + need.sigma_irr, force * stretch / geom.area, rtol=1e-12)
    assert need.sigma_irr[0] == 0.0 and np.all(need.sigma_irr[1:] > 0)  # relaxed at t[0], stretched after
    sigma_rev, sigma_irr = need
    assert sigma_rev is need.sigma_rev
