"""Strip specimens (issue 7): uniaxial tension at 0 V, the DE strip under voltage."""

import numpy as np
import pytest
from scipy.optimize import brentq

from rdea_lab.physics.constants import EPS0
from rdea_lab.physics.geometry import StripGeometry, geometry_from_card
import functools

from rdea_lab.physics.models import solve as _solve
from rdea_lab.physics.selection import select_model
from rdea_lab.specs import SpecError, dump_specimen, specimen_from_yaml
from rdea_lab.twin import simulate

from physics_cases import RIZZELLO

#: The strip's equations (its slack force is the twin's concern: carried_force).
solve = functools.partial(_solve, slack=False)

CARD = "{id: s1, kind: strip, length: 80 mm, width: 22 mm, thickness: 1 mm, electrode: {length: 80 mm, width: 22 mm}}"


def W1(x, m):
    return m.C10 + 2 * m.C20 * x + 3 * m.C30 * x**2


def test_card_round_trip_and_geometry():
    card = specimen_from_yaml(CARD)
    assert specimen_from_yaml(dump_specimen(card)) == card
    g = geometry_from_card(card)
    assert isinstance(g, StripGeometry) and g.area == pytest.approx(22e-6, rel=1e-12, abs=0)
    assert g.C0(2.8) == pytest.approx(EPS0 * 2.8 * 0.08 * 0.022 / 1e-3, rel=1e-12, abs=0)  # a parallel plate
    with pytest.raises(SpecError, match="thickness"):
        specimen_from_yaml("{id: s, kind: strip, length: 80 mm, width: 22 mm}")
    with pytest.raises(SpecError, match="electrode.width"):
        specimen_from_yaml("{id: s, kind: strip, length: 80 mm, width: 22 mm, thickness: 1 mm, "
                           "electrode: {length: 10 mm, width: 30 mm}}")


def test_zero_volts_is_plain_uniaxial_tension():
    """Incompressible uniaxial tension: true stress 2 (l^2 - 1/l) W'(I1), I1 = l^2 + 2/l;
    nominal force = true stress x area / l."""
    g = geometry_from_card(specimen_from_yaml(CARD))
    l = np.linspace(1, 3, 21)
    sigma = 2 * (l**2 - 1 / l) * W1(l**2 + 2 / l - 3, RIZZELLO)
    for model in ("su", "1r"):
        r = solve(model, g, RIZZELLO, l, 0.0)
        np.testing.assert_allclose(r.sigma1, sigma, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(r.force, sigma * g.area / l, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("v", [2e3, 10e3, 20e3])
def test_fully_covered_strip_under_voltage_is_the_classic_de_strip(v):
    """Stretch l1 held, sides free: l2 dpsi/dl2 = eps E^2 with E = l1 l2 v / t (eq. 33 with
    alpha = eta_b = 1), solved here by brentq; sigma1 = l1 dpsi/dl1 - eps E^2."""
    g = geometry_from_card(specimen_from_yaml(CARD))
    eps = EPS0 * 2.8
    for l1 in (1.0, 1.5, 2.5):
        def f(l2):
            x = l1**2 + l2**2 + (l1 * l2) ** -2 - 3
            return W1(x, RIZZELLO) * (2 * l2**2 - 2 * l1**-2 * l2**-2) - eps * (l1 * l2 * v / 1e-3) ** 2
        l2 = brentq(f, l1**-0.5, 4 * l1**-0.5, xtol=1e-15)
        x = l1**2 + l2**2 + (l1 * l2) ** -2 - 3
        sigma = W1(x, RIZZELLO) * (2 * l1**2 - 2 * l1**-2 * l2**-2) - eps * (l1 * l2 * v / 1e-3) ** 2
        r = solve("1r", g, RIZZELLO, l1, v)
        assert r.lambda2b == pytest.approx(l2, rel=1e-10, abs=0)
        assert r.sigma1 == pytest.approx(sigma, rel=1e-9, abs=1e-6)
        assert r.capacitance == pytest.approx(g.C0(2.8) * (l1 * l2) ** 2, rel=1e-10, abs=0)


def test_3r_is_refused_and_auto_picks_1r():
    g = geometry_from_card(specimen_from_yaml(CARD))
    from rdea_lab.physics.result import ModelNotApplicable
    with pytest.raises(ModelNotApplicable, match="a strip is the 1R model"):
        solve("3r", g, RIZZELLO, 1.2, 0.0)
    assert select_model(g, RIZZELLO, [1.0, 1.5], [0.0, 0.0]).model == "1r"


def test_twin_on_a_strip_without_electrode():
    card = specimen_from_yaml("{id: vhb, kind: strip, length: 80 mm, width: 22 mm, thickness: 1 mm}")
    t = np.linspace(0, 10, 101)
    lam = 1 + 0.05 * t
    ds = simulate(card, RIZZELLO, t, lam, 0.0, model="1r")
    assert np.all(ds["capacitance"].values == 0.0)  # no electrode, no capacitance
    sigma = 2 * (lam**2 - 1 / lam) * W1(lam**2 + 2 / lam - 3, RIZZELLO)
    np.testing.assert_allclose(ds["force"].values, sigma * 22e-6 / lam, rtol=1e-12, atol=1e-12)


def test_a_strip_and_a_roll_go_slack_instead_of_pushing():
    """Unloading faster than the material relaxes drives the viscoelastic stress below
    zero: a thin strip buckles and carries no force (what a tensile machine measures),
    and so does a roll (Assumption 1: a roll is only ever in tension; clamped shorter than
    it would be, it buckles): force 0, status slack, and the same where the model's
    tension itself is compressive."""
    from rdea_lab.physics.result import SLACK
    from rdea_lab.specs import ParameterSet, ViscoBranch
    from rdea_lab.twin import viscous
    from rdea_lab.physics import viscoelastic
    soft = ParameterSet(name="v", C10=20e3, C20=0.0, C30=0.0, eps_r=4.7,
                        branches=(ViscoBranch(k=50e3, eta=5e5),))
    t = np.linspace(0, 20, 2001)
    lam = 1 + 0.5 * (1 - np.abs(t - 10) / 10)  # up to 1.5 and back at 0.05 /s
    strip = simulate(specimen_from_yaml("{id: v, kind: strip, length: 80 mm, width: 22 mm, thickness: 1 mm}"),
                     soft, t, lam, 0.0, model="1r")
    geom = geometry_from_card(specimen_from_yaml(CARD))
    roll = simulate(geom, soft, t, lam, 0.0, model="1r")
    k, eta, eta_v0, _ = viscous(soft)
    for ds, g in ((strip, geometry_from_card(specimen_from_yaml(
            "{id: v, kind: strip, length: 80 mm, width: 22 mm, thickness: 1 mm}"))), (roll, geom)):
        # the model's stress, composed by hand: quasi-static (equations) + overstress (eq. 44)
        sigma = (solve("1r", g, soft, lam, 0.0).sigma1
                 + viscoelastic.overstress(t, lam, k, eta, eta_v0))
        pushes = sigma < 0
        assert 100 < pushes.sum() < 1500  # the model's stress does go compressive on the way back
        np.testing.assert_allclose(ds["force"].values, np.maximum(sigma * g.area / lam, 0.0), rtol=1e-12, atol=0)
        assert np.all(ds["model_status"].values[pushes] == SLACK) and np.all(ds["sigma1"].values[pushes] == 0)
        assert not np.any(ds["model_status"].values[~pushes] == SLACK)


def test_3r_on_a_strip_is_a_user_mistake_at_the_command_line(capsys, tmp_path):
    from pathlib import Path

    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    root = Path(__file__).resolve().parents[2] / "rdea_lab" / "data"
    card = str(root / "specimens" / "vhb4910_strip.yaml")
    for args in (["curve", "--specimen", card, "--params", str(root / "params" / "rizzello2020.yaml"), "--model", "3r"],
                 ["run", str(root / "protocols" / "tensile_ramp_sine_0V.yaml"), "--specimen", card, "--model", "3r",
                  "--quiet", "--out", str(tmp_path / "x.nc")]):
        rc = run_cli(cli, args)
        err = capsys.readouterr().err
        assert rc == 2 and "--model 1r" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.nc").exists() and not (tmp_path / "x.nc.part").exists()
