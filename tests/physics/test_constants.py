"""The constants written out in rdea_lab.physics.constants against scipy's CODATA table."""

import pytest

from rdea_lab.physics.constants import EPS0


def test_eps0_is_codatas_vacuum_permittivity():
    scipy_constants = pytest.importorskip("scipy.constants")
    # CODATA 2018 -> 2022 moved epsilon_0 by 6.8e-10 relative (8.8541878128 -> 8.8541878188 pF/m) with a
    # standard uncertainty of 1.6e-10: 1e-9 allows a scipy one revision apart and catches a wrong digit among
    # the first nine.
    assert EPS0 == pytest.approx(scipy_constants.epsilon_0, rel=1e-9)
    value, unit, _ = scipy_constants.physical_constants["vacuum electric permittivity"]
    assert unit == "F m^-1" and EPS0 == pytest.approx(value, rel=1e-9)


def test_eps0_is_the_papers_rounded_value():
    # Table 1 of [1] rounds it to 8.85 pF/m.
    assert round(EPS0 * 1e12, 2) == 8.85
