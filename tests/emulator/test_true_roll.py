"""The emulator's true roll (rdea_lab.emulator.roll): each effect against what it must satisfy.

References independent of the zone solver: the model twin where an effect is
off or cannot act, a scalar brentq on the series balance per sample, the
Ogden-Roxburgh and Palmer formulas written out here.
"""

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from rdea_lab.emulator import true_geometry
from rdea_lab.emulator.roll import TrueRoll
from rdea_lab.physics.models import solve
from rdea_lab.specs.truth import Effects, Mullins
from rdea_lab.twin.simulate import TwinStream

RATE = 100.0


def history(n=801, top=1.5, volts=2600.0):
    """Up to `top` and back, with the voltage on in the middle half."""
    t = np.arange(n) / RATE
    x = 1.0 + (top - 1.0) * np.sin(np.pi * t / t[-1]) ** 2
    v = np.where((t > 0.25 * t[-1]) & (t < 0.75 * t[-1]), volts, 0.0)
    return t, x, v


def with_effects(truth, model=None, branches=True, **effects):
    material = truth.material if branches else truth.material.model_copy(update={"branches": (), "eta_v0": 0.0})
    return truth.model_copy(update={"effects": Effects(**effects), "material": material,
                                    "model": model or truth.model})


def blocks(obj, t, x, v, size=300):
    outs = [obj.step(t[i:i + size], x[i:i + size], v[i:i + size]) for i in range(0, t.size, size)]
    return {k: np.concatenate([o[k] for o in outs]) for k in ("force", "capacitance", "lambda_a", "lambda_p",
                                                            "roll_stretch")}


@pytest.fixture(scope="module")
def geom(card, truth):
    return true_geometry(card, truth)


def test_without_effects_it_is_the_twin(truth, geom):
    plain = with_effects(truth)
    t, x, v = history()
    roll = blocks(TrueRoll(geom, plain), t, x, v)
    twin = TwinStream(geom, plain.material, plain.model)
    outs = [twin.step(t[i:i + 300], x[i:i + 300], v[i:i + 300]) for i in range(0, t.size, 300)]
    ref = {k: np.concatenate([o[k] for o in outs]) for k in ("force", "capacitance")}
    np.testing.assert_array_equal(roll["force"], ref["force"])
    np.testing.assert_array_equal(roll["capacitance"], ref["capacitance"])


def test_passive_ends_at_0V_are_the_uniform_roll(truth, geom):
    # the same film with and without electrode: at 0 V the zones stretch alike
    t, x, _ = history()
    zero = np.zeros_like(t)
    split = blocks(TrueRoll(geom, with_effects(truth, passive_ends=True)), t, x, zero)
    uniform = blocks(TrueRoll(geom, with_effects(truth)), t, x, zero)
    np.testing.assert_allclose(split["force"], uniform["force"], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(split["lambda_a"], x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(split["lambda_p"], x, rtol=0, atol=1e-12)


@pytest.mark.parametrize("model", ["su", "cr"])
def test_passive_ends_under_voltage_balance_force_and_length(truth, geom, model):
    tr = with_effects(truth, model=model, branches=False, passive_ends=True, passive_stiffness=1.3)
    t, x, v = history(n=201)
    out = blocks(TrueRoll(geom, tr), t, x, v, size=64)
    La, Lp, A = geom.L1e, geom.L1 - geom.L1e, geom.area
    active = dataclasses.replace(geom, L1=geom.L1e)
    passive = dataclasses.replace(geom, L1=Lp, L1e=Lp)
    stiff = tr.material.model_copy(update={k: 1.3 * getattr(tr.material, k) for k in ("C10", "C20", "C30")})

    def f_active(la, volts):
        return float(solve(model, active, tr.material, la, volts).tension[()] * A / la)

    def f_passive(lp):
        return float(solve("su", passive, stiff, lp, 0.0).tension[()] * A / lp)

    checked = 0
    for k in range(0, t.size, 10):
        if v[k] == 0.0 or x[k] < 1.05:
            continue

        def residual(la):  # length left for the passive ends, minus what their force needs
            lp = (x[k] * geom.L1 - la * La) / Lp
            return f_active(la, v[k]) - f_passive(max(lp, 1.0))

        la = brentq(residual, 1.0, x[k] * geom.L1 / La - 1e-9, xtol=1e-15, rtol=1e-15)
        assert out["lambda_a"][k] == pytest.approx(la, rel=1e-11)
        assert out["force"][k] == pytest.approx(f_active(la, v[k]), rel=1e-10)
        assert out["lambda_a"][k] > x[k] > out["lambda_p"][k]  # the softened zone takes more of the stretch
        checked += 1
    assert checked >= 5


def test_clamp_compliance_shortens_the_roll_by_c_F(truth, geom):
    c = 1e-4  # m/N: five times the shipped value (the largest a truth accepts), well above rounding
    tr = with_effects(truth, branches=False, clamp_compliance=c)
    t, x, v = history(n=201)
    out = blocks(TrueRoll(geom, tr), t, x, v, size=64)
    F, Lr = out["force"], out["roll_stretch"]
    np.testing.assert_allclose(Lr + c * F / geom.L1, x, rtol=0, atol=2e-13)
    model = solve(tr.model, geom, tr.material, Lr, v).tension * geom.area / Lr
    np.testing.assert_allclose(F, np.maximum(model, 0.0), rtol=1e-10, atol=1e-12)
    assert np.all(Lr <= x) and (x - Lr).max() > 1e-3


def test_mullins_softens_only_below_the_previous_maximum(truth, geom):
    s, m = 0.05, 30e3
    tr = with_effects(truth, branches=False, mullins=Mullins(max_softening=s, energy_scale=m))
    t, x, _ = history(n=401)
    zero = np.zeros_like(t)
    soft = blocks(TrueRoll(geom, tr), t, x, zero, size=128)
    virgin = solve(tr.model, geom, tr.material, x, zero).tension * geom.area / x
    C10, C20, C30 = tr.material.C10, tr.material.C20, tr.material.C30
    I = x**2 + 2.0 / x - 3.0
    W = C10 * I + C20 * I**2 + C30 * I**3
    W_max = np.maximum.accumulate(W)
    eta = np.array([1.0 - s * math.erf((a - b) / m) for a, b in zip(W_max, W)])
    np.testing.assert_allclose(soft["force"], eta * virgin, rtol=1e-12, atol=1e-14)
    loading = np.arange(t.size) <= np.argmax(x)
    np.testing.assert_allclose(soft["force"][loading], virgin[loading], rtol=1e-13, atol=1e-14)  # virgin path
    assert (soft["force"][~loading] < virgin[~loading] * (1 - 0.01)).sum() > 0.5 * (~loading).sum() - 20


def test_fringe_capacitance_is_palmers_correction(truth, geom):
    tr_on = with_effects(truth, fringe_capacitance=True)
    t, x, _ = history(n=101)
    zero = np.zeros_like(t)
    on = blocks(TrueRoll(geom, tr_on), t, x, zero)
    res = solve(tr_on.model, geom, tr_on.material, x, zero)
    a, d = x * geom.L1e, geom.L3 / (x * res.lambda2b)
    palmer = 1.0 + d / (math.pi * a) * (1.0 + np.log(2.0 * math.pi * a / d))
    np.testing.assert_allclose(on["capacitance"], res.capacitance * palmer, rtol=1e-13)
    assert 1.003 < palmer[0] < 1.01  # 48 um film, 29 mm electrodes: half a per cent


def test_all_effects_give_the_same_numbers_in_any_blocks(truth, geom):
    t, x, v = history(n=601)
    a = blocks(TrueRoll(geom, truth), t, x, v, size=600)
    b = blocks(TrueRoll(geom, truth), t, x, v, size=97)
    np.testing.assert_allclose(a["force"], b["force"], rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(a["capacitance"], b["capacitance"], rtol=1e-10)


def test_the_softest_clamp_with_branches_is_the_twin_at_the_roll_stretch(truth, geom):
    # the largest compliance a truth accepts, with the shipped finite-strain branches: the force is
    # the twin's on the roll's own stretch history, and the clamps take up the rest
    c = 100e-6
    tr = with_effects(truth, clamp_compliance=c)
    t, x, v = history(n=601)
    out = blocks(TrueRoll(geom, tr), t, x, v, size=300)
    np.testing.assert_allclose(out["roll_stretch"] + c * out["force"] / geom.L1, x, rtol=0, atol=2e-13)
    twin = TwinStream(geom, tr.material, tr.model)
    ref = np.concatenate([twin.step(t[i:i + 300], out["roll_stretch"][i:i + 300], v[i:i + 300])["force"]
                          for i in range(0, t.size, 300)])
    np.testing.assert_allclose(out["force"], ref, rtol=1e-9, atol=1e-11)


def test_a_block_without_solution_aborts_the_run_with_voltage_off(card, truth, monkeypatch):
    import rdea_lab.emulator.roll as roll
    from rdea_lab.emulator import EmulatedRig, RunConfig

    n = 5000  # three blocks: the first solves, the second cannot
    x = 1.0 + 0.3 * np.sin(np.linspace(0.0, np.pi, n)) ** 2
    v = np.full(n, 1500.0)
    rig = EmulatedRig(card, truth, np.random.default_rng(1),
                      RunConfig(rate=RATE, stretch_setpoint=x, voltage_setpoint=v, L1=0.034, L3=48e-6))
    first = rig.produce(100)
    monkeypatch.setattr(roll, "MAX_ITER", 0)
    rows = rig.produce(n)
    assert rig.state == "aborted" and "no solution" in rig.reason and "did not converge" in rig.reason
    from rdea_lab.emulator.rig import BLOCK
    assert first.shape[0] + rows.shape[0] == BLOCK  # the solved block kept, nothing after it
    assert rig._amplifier.y == 0.0  # voltage off


def test_a_roll_just_taut_under_voltage_is_solved(truth, geom):
    # At 1 kHz the first samples of a stretch leaving 1 under voltage carry forces of a few nN:
    # below what a stretch near 1 resolves in double precision (6 C10 A eps, about 2e-14 N), so
    # the passive ends' secant stalls at rounding. It must give that state, not abort the run
    # (before the fix: "passive ends: the secant iteration did not converge" at t = 0 s).
    rate = 1000.0
    t = np.arange(2001) / rate
    x = 1.0 + 0.25 * (1.0 - np.cos(2.0 * np.pi * 0.1 * t))
    v = 1300.0 * (1.0 - np.cos(2.0 * np.pi * t))
    roll = TrueRoll(geom, truth)
    out = [roll.step(t[i:i + 1000], x[i:i + 1000], v[i:i + 1000]) for i in (0, 1000)]
    force = np.concatenate([o["force"] for o in out])
    assert np.all(np.isfinite(force)) and force.max() > 0.1
