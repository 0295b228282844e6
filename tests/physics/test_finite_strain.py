"""The finite-strain viscoelastic law (neo-Hookean spring mu in series with a Newtonian dashpot eta).

Every reference is independent of the code under test: eq. (44) (the linear law, exact for
piecewise-linear stretch, tested in test_viscoelastic.py) for the small-strain limit;
``scipy.integrate.solve_ivp`` (Radau) on the branch ODE written out here from the module's
derivation, ``du/dt = d(ln lambda1)/dt - f(u)/tau``, ``f(u) = (exp(2u) - exp(-u))/3``; the
closed-form relaxation of a hold by ``scipy.integrate.quad``; the energy balance of the
spring ``W_e = mu/2 (lambda_e**2 + 2/lambda_e - 3)``; and the parameter bounds of the
branch stress derived in the docstrings below.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

from rdea_lab.physics.viscoelastic import branch_strains, dissipation_rate, overstress, overstress_step, stress_of
from rdea_lab.specs import ParameterSet, SpecError, ViscoBranch, dump_params, load_params, params_from_mapping, \
    params_from_yaml
from rdea_lab.twin import simulate
from rdea_lab.twin.simulate import as_geometry

ROOT = Path(__file__).resolve().parents[2]
FS = "finite_strain"


def f_ref(u):
    """f(u) = (exp(2u) - exp(-u)) / 3 with expm1: no cancellation near u = 0 (the reference's own)."""
    return (np.expm1(2.0 * u) - np.expm1(-u)) / 3.0


def sigma_ref(mu, u):
    """Branch true stress mu (lambda_e**2 - 1/lambda_e), lambda_e = exp(u) [Pa]."""
    return 3.0 * mu * f_ref(u)


def u_reference(t, lam, tau, u0=0.0, rtol=1e-12, atol=1e-300):
    """solve_ivp (Radau, exact Jacobian) interval by interval, the stretch linear on each one."""
    u = [float(u0)]
    for i in range(1, t.size):
        a, b, l0 = t[i - 1], t[i], lam[i - 1]
        s = (lam[i] - l0) / (b - a)

        def rhs(tt, y, s=s, a=a, l0=l0):
            return [s / (l0 + s * (tt - a)) - f_ref(y[0]) / tau]

        def jac(tt, y):
            return [[-(2.0 * np.exp(2.0 * y[0]) + np.exp(-y[0])) / (3.0 * tau)]]

        sol = solve_ivp(rhs, (a, b), [u[-1]], method="Radau", jac=jac, rtol=rtol, atol=atol)
        assert sol.success, sol.message
        u.append(sol.y[0, -1])
    return np.array(u)


# ------------------------------------------------------------------ 1. small-strain limit
def _sine(eps, law, k=3e5, eta44=6e4):
    """A sine of amplitude eps about stretch 1 (period 1 s, tau = 0.2 s, 2001 samples)."""
    t = np.linspace(0.0, 2.0, 2001)
    lam = 1.0 + eps * np.sin(2 * np.pi * t)
    if law == "linear":
        return overstress(t, lam, [k], [eta44])
    return overstress(t, lam, [k / 3], [eta44 / 3], law=FS)


def test_small_strain_limit_is_eq_44_with_k_3mu_and_eta_3eta():
    """Reference: eq. (44) (law linear, k, eta_44), exact for piecewise-linear stretch.

    The laws agree to first order and differ at second order (f(u) = u + u**2/2 + ...,
    ln lambda1 = eps - eps**2/2 + ...), so |delta sigma| / (k eps) is proportional to eps: it
    halves when eps halves (to O(eps) ~ 1e-4 relative, and the finite-strain integrator's
    error, ~1e-9 of the peak, is 1e-5 of the difference at eps = 5e-5: 10 % is ample).
    At eps = 1e-4 the second-order term is ~eps/2 of the stress: relative difference below
    1e-3 (5x the expected ~1e-4 ... 2e-4), and in strain units (|delta sigma| / k ~ eps**2) below 1e-6.
    """
    k = 3e5
    d = {}
    for eps in (1e-4, 5e-5):
        lin, fs = _sine(eps, "linear", k), _sine(eps, FS, k)
        d[eps] = np.max(np.abs(fs - lin)) / (k * eps)
        assert np.max(np.abs(fs - lin)) / np.max(np.abs(lin)) < 1e-3
        assert np.max(np.abs(fs - lin)) / k < 1e-6
    assert d[1e-4] / d[5e-5] == pytest.approx(2.0, rel=0.1)
    assert d[5e-5] > 0  # the laws are not identical: the test sees the second-order term


def test_small_strain_ramp_hold_matches_eq_44():
    """Ramp-hold to stretch 1 + 1e-4: the same limit on a history with a hold (relaxation).

    Reference and tolerances as for the sine: difference below 1e-6 in strain units and 1e-3
    relative to the peak overstress."""
    k, eta44, eps = 3e5, 6e4, 1e-4
    t = np.linspace(0.0, 2.0, 401)
    lam = 1.0 + eps * np.minimum(t / 0.5, 1.0)
    lin = overstress(t, lam, [k], [eta44])
    fs = overstress(t, lam, [k / 3], [eta44 / 3], law=FS)
    assert np.max(np.abs(fs - lin)) / np.max(np.abs(lin)) < 1e-3
    assert np.max(np.abs(fs - lin)) / k < 1e-6


# ------------------------------------------------------------------ 2. against solve_ivp and the hold's integral
RATIOS = [1e-4, 1e-2, 1.0, 1e2, 1e4]


def _history(name):
    """(t, stretch): 20 intervals of 1 s (step and ramp), or 16 (one period of a sine)."""
    if name == "step":  # to stretch 2 in one sample, then held
        t = np.arange(21.0)
        return t, np.where(t > 0, 2.0, 1.0)
    if name == "ramp":  # constant rate to stretch 3
        t = np.arange(21.0)
        return t, 1.0 + 0.1 * t
    t = np.arange(17.0)
    return t, 1.0 + 0.5 * (1.0 - np.cos(2 * np.pi * t / 16.0))


def _past_bounds(lam):
    """Bounds of u from the history alone: max/min over j <= i of ln(lambda_i / lambda_j).

    du/dt = r - f(u)/tau with u f(u) >= 0: while u > 0 it grows at most like ln lambda1
    (the elastic solution, no flow), while u < 0 it falls at most like it, and it starts
    at 0 (relaxed): so min(0, .) <= u_i <= max(0, .). For a monotone loading this is
    0 (fully relaxed) <= u <= ln(lambda1 / lambda1(0)) (elastic). With stretch linear between
    samples, ln lambda1 is monotone on each interval, so its extremes lie at samples."""
    ell = np.log(lam)
    hi = np.array([max(0.0, ell[i] - ell[: i + 1].min()) for i in range(ell.size)])
    lo = np.array([min(0.0, ell[i] - ell[: i + 1].max()) for i in range(ell.size)])
    return lo, hi


#: Radau takes seconds on the stiff sines (tau/dt <= 1e-2): those two run in the slow step.
RADAU_CASES = [pytest.param(ratio, name, marks=[pytest.mark.slow] if name == "sine" and ratio < 1 else [])
               for ratio in RATIOS for name in ("step", "ramp", "sine")]


@pytest.mark.parametrize(("ratio", "name"), RADAU_CASES)
def test_matches_radau_reference_for_every_tau_over_dt(name, ratio):
    """Reference: solve_ivp Radau at rtol 1e-12 on the same piecewise-linear stretch (f by expm1:
    no cancellation near u = 0; atol 1e-12 of an a-priori bound of |u|,
    min(ln-range, tau max|d ln lambda/dt|), since the solution passes through 0).

    Tolerance 1e-8 of the peak branch stress: the kernel's own accuracy is ~1e-9 on these
    harsh histories (a rate jump at every sample, tau/dt from 1e-4 to 1e4); the reference's
    error is ~1e-11 (it changes by less than that from rtol 1e-11 to 1e-12).
    Stability: finite and inside the bounds of `_past_bounds` (elastic / fully relaxed), to rounding."""
    t, lam = _history(name)
    mu, tau = 1e5, ratio * 1.0
    u = branch_strains(t, lam, [tau], law=FS)[0]
    scale = min(np.log(lam.max()), tau * np.max(np.abs(np.diff(np.log(lam)))))
    ref = u_reference(t, lam, tau, atol=1e-12 * scale)
    s_ref = sigma_ref(mu, ref)
    s = stress_of(FS, [mu], u[None, :])[0]
    peak = np.max(np.abs(s_ref))
    assert np.all(np.isfinite(u))
    assert np.max(np.abs(s - s_ref)) <= 1e-8 * peak
    lo, hi = _past_bounds(lam)
    assert np.all(u <= hi + 1e-12) and np.all(u >= lo - 1e-12)


def _hold_time(x, x0, tau):
    """Time for the hold to bring u from exp(x0) down to exp(x): tau * integral du / f(u),
    in x = ln u (a smooth integrand, e^x / f(e^x) -> 1 as x -> -inf); quad to 1e-12 relative
    (tighter meets its roundoff floor), a relative error of u of 1e-12 * t / tau at most."""
    val, _ = quad(lambda y: math.exp(y) / f_ref(math.exp(y)), x, x0, epsabs=0.0, epsrel=1e-12, limit=200)
    return tau * val


@pytest.mark.parametrize("ratio", RATIOS)
def test_relaxation_at_a_hold_is_the_separable_integral(ratio):
    """Stretch held at 2 from u0 = ln 2 (the spring carrying it all): du/dt = -f(u)/tau, so
    t = tau * integral_u^u0 dv / f(v) (scipy quad, solved for u by brentq to 1e-14 in ln u).

    Where the integral says u < 1e-10 (stress below 3e-10 mu, 1e-10 of the peak 3.5 mu) only
    |sigma| <= 1e-8 of the peak is asked. Tolerance 1e-8 of the peak as for the Radau test."""
    mu, tau = 1e5, ratio * 1.0
    t = np.arange(21.0)
    u0 = math.log(2.0)
    u = branch_strains(t, np.full(t.size, 2.0), [tau], q0=[u0], law=FS)[0]
    x0, x_min = math.log(u0), math.log(1e-10)
    t_min = _hold_time(x_min, x0, tau)
    expected = np.zeros(t.size)
    for i, ti in enumerate(t):
        if ti == 0.0:
            expected[i] = u0
        elif ti < t_min:
            expected[i] = math.exp(brentq(lambda x: _hold_time(x, x0, tau) - ti, x_min, x0, xtol=1e-14, rtol=1e-14))
    peak = sigma_ref(mu, u0)
    assert np.all(np.isfinite(u)) and np.all(u >= 0) and np.all(np.diff(u) <= 0)
    assert np.max(np.abs(stress_of(FS, [mu], u[None, :])[0] - sigma_ref(mu, expected))) <= 1e-8 * peak


# ------------------------------------------------------------------ 3. dissipation
def _random_history(seed, tau, per_tau=1000, knots=30):
    """Piecewise-linear stretch through random values in [1, 4] at random knots (0.2 to 2 tau apart),
    the knots on a sample grid of tau / per_tau."""
    rng = np.random.default_rng(seed)
    gaps = rng.integers(int(0.2 * per_tau), 2 * per_tau, knots)
    at = np.concatenate([[0], np.cumsum(gaps)])
    values = np.concatenate([[1.0], rng.uniform(1.0, 4.0, knots)])
    n = np.arange(at[-1] + 1)
    return n * (tau / per_tau), np.interp(n, at, values)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dissipation_is_never_negative_and_balances_the_energy(seed):
    """Work sigma d(ln lambda1) (trapezoid) minus the change of W_e(u) is the dissipation.

    Its increment on each step must be >= -|delta sigma| |delta ln lambda1| / 2: the gap between
    the trapezoid and either rectangle rule, which bounds the trapezoid's error wherever sigma is
    monotone over the step (on a step of constant stretch rate u' = 0 only where u'' = r' < 0, so
    at most one interior maximum: there the error is of second order, far below the bound);
    plus 1e-12 of W_e for the rounding of the energy difference. A wrong-sign flow rule would
    give -sigma**2 dt / (3 eta) per step, orders of magnitude beyond it.
    The total equals the integral of `dissipation_rate` (trapezoid as well): two second-order
    quadratures of one integral with kappa dt <= 10.75 / 1000 (kappa = f'(u) / tau, u <= ln 4),
    each off by ~(kappa dt)**2 / 12 ~ 1e-5 relative: 1e-4."""
    mu, eta = 1e5, 1e5
    tau = eta / mu
    t, lam = _random_history(seed, tau)
    u = branch_strains(t, lam, [tau], law=FS)[0]
    assert np.all(np.isfinite(u))
    sigma = stress_of(FS, [mu], u[None, :])[0]
    np.testing.assert_allclose(sigma, sigma_ref(mu, u), rtol=1e-12, atol=1e-12 * mu)  # the stress formula
    ell = np.log(lam)
    d_ell = np.diff(ell)
    work = 0.5 * (sigma[1:] + sigma[:-1]) * d_ell
    W_e = 0.5 * mu * (np.exp(2 * u) + 2 * np.exp(-u) - 3)
    dD = work - np.diff(W_e)
    bound = 0.5 * np.abs(np.diff(sigma)) * np.abs(d_ell) + 1e-12 * np.maximum(W_e[1:], W_e[:-1])
    assert np.all(dD >= -bound), np.min(dD + bound)
    rate = dissipation_rate(FS, [mu], [eta], u[None, :])[0]
    assert np.all(rate >= 0)
    np.testing.assert_allclose(rate, sigma**2 / (3 * eta), rtol=1e-12)  # sigma d(ln xi)/dt with the flow rule
    total = np.sum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))
    assert dD.sum() == pytest.approx(total, rel=1e-4)
    # the flow direction: d(ln xi) = d(ln lambda1) - du has the sign of sigma wherever sigma keeps a sign
    d_xi = d_ell - np.diff(u)
    same = (np.sign(sigma[1:]) == np.sign(sigma[:-1])) & (np.abs(d_xi) > 1e-13 * (np.abs(ell[1:]) + 1))
    assert same.sum() > 0.9 * d_xi.size
    assert np.all(np.sign(d_xi[same]) == np.sign(sigma[1:][same]))


def test_dissipation_rate_is_non_negative_for_both_laws():
    """sigma**2 / eta (linear) and sigma**2 / (3 eta) (finite strain) over any strains, of either sign."""
    q = np.linspace(-2.0, 2.0, 401)[None, :]
    for law in ("linear", FS):
        rate = dissipation_rate(law, [1e5], [3e4], q)
        assert np.all(rate >= 0) and rate[0, 200] == 0.0


# ------------------------------------------------------------------ 4. blocks
@pytest.mark.parametrize("law", ["linear", FS])
def test_blocks_carrying_the_state_equal_the_whole_series(law):
    """A series cut into random blocks (state carried) gives the whole series' numbers: the
    interval between blocks is integrated as every other one. 1e-13 relative (rounding; the
    same arithmetic in another order at most), at 1e-13 of the peak near zero crossings."""
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(0.005, 0.02, 3000))
    lam = 1.0 + 1.5 * np.abs(np.sin(0.7 * t)) + 0.2 * np.sin(5.1 * t)
    k, eta, eta_v0 = [3e5, 4e4], [6e4, 4e5], 2e3
    whole = overstress(t, lam, k, eta, eta_v0, law=law)
    cuts = np.sort(rng.choice(np.arange(2, t.size - 1), 25, replace=False))
    state, parts = None, []
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, t.size]):
        s, state = overstress_step(t[a:b], lam[a:b], k, eta, eta_v0, state=state, law=law)
        parts.append(s)
    got = np.concatenate(parts)
    np.testing.assert_allclose(got, whole, rtol=1e-13, atol=1e-13 * np.abs(whole).max())


@pytest.mark.parametrize("law", ["linear", FS])
def test_nan_samples_are_skipped_in_blocks(law):
    """Documented: a sample without a finite stretch has no stress (NaN), and the branches carry on
    as if the stretch were linear between its finite neighbours: the numbers are those of the
    series without it (whole or in blocks; a block of NaN only leaves the state as it was)."""
    rng = np.random.default_rng(11)
    t = np.cumsum(rng.uniform(0.005, 0.02, 600))
    lam = 1.0 + 1.5 * np.abs(np.sin(0.7 * t))
    bad = np.zeros(t.size, bool)
    bad[[5, 99, 100, 101, 199, 200, 350]] = True  # inside blocks, at a block's end (99) and start (200)
    bad[300:320] = True  # a whole block
    lam_nan = np.where(bad, np.nan, lam)
    lam_nan[350] = np.inf
    k, eta, eta_v0 = [3e5], [6e4], 2e3
    ref = overstress(t[~bad], lam[~bad], k, eta, eta_v0, law=law)
    whole = overstress(t, lam_nan, k, eta, eta_v0, law=law)
    assert np.all(np.isnan(whole[bad])) and np.all(np.isfinite(whole[~bad]))
    np.testing.assert_allclose(whole[~bad], ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())
    state, parts = None, []
    for a, b in [(0, 100), (100, 200), (200, 300), (300, 320), (320, 600)]:
        s, new = overstress_step(t[a:b], lam_nan[a:b], k, eta, eta_v0, state=state, law=law)
        if a == 300:
            # no finite sample: the state is unchanged
            assert (new.t, new.stretch, new.q.tolist()) == (state.t, state.stretch, state.q.tolist())
        state = new
        parts.append(s)
    got = np.concatenate(parts)
    assert np.all(np.isnan(got[bad]))
    np.testing.assert_allclose(got[~bad], ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())


# ------------------------------------------------------------------ 5. parameter sets and the twin
TABLE3 = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
#: Table 3 converted by the small-strain map: mu = k / 3, eta = eta_44 / 3 (the same tau).
TABLE3_FS = TABLE3.replace(law=FS, branches=tuple(ViscoBranch(mu=b.k / 3, eta=b.eta / 3) for b in TABLE3.branches))
BASE = {"name": "x", "yeoh": {"C10": "242 kPa", "C20": "-69 kPa", "C30": "47 kPa"}, "eps_r": 2.8}


def test_finite_strain_set_round_trips_through_yaml():
    ps = TABLE3_FS.replace(branches=(ViscoBranch(mu=2757e3, eta=28.7e3), ViscoBranch(mu=1 / 3 * 1e5, eta=12345.678)),
                           eta_v0=1.5e3)
    text = dump_params(ps)
    assert "law: finite_strain" in text and "mu: 2757 kPa" in text and "k:" not in text
    back = params_from_yaml(text)
    assert back == ps and back.law == FS and back.branches[0].mu == 2757e3


def test_the_documented_yaml_form_reads_as_written():
    ps = params_from_mapping({**BASE, "viscoelastic": {"law": FS, "branches": [{"mu": "2757 kPa",
                                                                                   "eta": "28.7 kPa s"}]}})
    (b,) = ps.branches
    assert (ps.law, b.mu, b.k, b.law) == (FS, 2757e3, None, FS)
    assert b.modulus == 2757e3 and b.tau == pytest.approx(28.7 / 2757, rel=1e-15)
    assert ViscoBranch.of(FS, 1e5, 2e4) == ViscoBranch(mu=1e5, eta=2e4)
    assert ViscoBranch.of("linear", 1e5, 2e4) == ViscoBranch(k=1e5, eta=2e4)


def test_default_law_is_linear():
    ps = params_from_mapping({**BASE, "viscoelastic": {"branches": [{"k": "8271 kPa", "eta": "86 kPa s"}]}})
    assert ps.law == "linear" and ps.branches[0].k == 8271e3
    assert params_from_mapping(BASE).law == "linear"
    assert ParameterSet(name="y", C10=1e5, C20=0, C30=0, eps_r=3).law == "linear"


@pytest.mark.parametrize("visco, field, match", [
    ({"law": FS, "branches": [{"k": "8271 kPa", "eta": "86 kPa s"}]}, "viscoelastic.branches[0].k",
     "a k spring under law finite_strain"),
    ({"law": "linear", "branches": [{"mu": "2757 kPa", "eta": "86 kPa s"}]}, "viscoelastic.branches[0].mu",
     "a mu spring under law linear"),
    ({"branches": [{"mu": "2757 kPa", "eta": "86 kPa s"}]}, "viscoelastic.branches[0].mu",
     "a mu spring under law linear"),
    ({"law": FS, "branches": [{"mu": "-1 kPa", "eta": "86 kPa s"}]}, "viscoelastic.branches[0].mu",
     "mu = -1 kPa must be a finite shear modulus > 0 kPa"),
    ({"law": "plastic"}, "viscoelastic.law", "plastic"),
])
def test_refusals_name_the_field(visco, field, match):
    with pytest.raises(SpecError, match=match) as err:
        params_from_mapping({**BASE, "viscoelastic": visco}, "card.yaml")
    assert err.value.field == field and err.value.source == "card.yaml"


def test_simulate_records_the_law():
    t = np.linspace(0, 4, 81)
    lam = 1 + 0.25 * (1 - np.cos(2 * np.pi * 0.25 * t))
    for ps in (TABLE3, TABLE3_FS):
        ds = simulate(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml", ps, t, lam, 0.0)
        assert ds.attrs["viscoelastic_law"] == ps.law
        p = params_from_yaml(ds.attrs["parameters"], "parameters")  # YAML, as runs write it (issue 14)
        assert p.law == ps.law
        assert [(b.modulus, b.eta) for b in p.branches] == [(b.modulus, b.eta) for b in ps.branches]


CASES = [("specimen2.yaml", m) for m in ("su", "1r", "3r", "cr")] + [("vhb4910_strip.yaml", m) for m in ("su", "1r")]


def _run(card, model, ps, t, lam):
    voltage = np.where(t > 2.0, 2600.0, 0.0) if card == "specimen2.yaml" else 0.0
    return simulate(ROOT / "rdea_lab" / "data" / "specimens" / card, ps, t, lam, voltage, model=model)


@pytest.mark.parametrize("card, model", CASES)
def test_every_model_runs_with_either_law_and_vanishing_branches_agree(card, model):
    """Finite forces with either law; and the limits where a branch carries no stress, against
    the twin without branches (independent of either law), to a bound derived from the ODEs:

    * eta -> 0 (tau -> 0): |f(u)| cannot exceed tau R (R = max |d ln lambda1/dt| = max |s| / lambda1
      over the intervals: above it du/dt < 0), so |sigma| <= 3 mu tau R = 3 eta R; linear likewise
      |sigma| <= eta max|lambda1'|. eta = 10 Pa s: a branch stress ~1e-4 of the elastic one, at
      tau/dt ~ 7e-5 (inside the integrator's documented range).
    * mu, k -> 0: |u| <= ln(Lambda), Lambda = max/min stretch (see `_past_bounds`), so
      |sigma| <= mu (Lambda**2 - 1/Lambda); linear |sigma| <= k (max - min stretch).

    The force is sigma A / lambda1, clipped at 0 where slack (a clip never increases a
    difference), so |F - F_none| <= bound * A / lambda1, with the specimen's cross-section A.
    At eta -> 0 the linear bound is reached (sigma = eta lambda1' at the fastest sample): 1e-9
    relative and a few ulp of the force are all the slack."""
    t = np.linspace(0, 6, 61)
    lam = 1 + 0.25 * (1 - np.cos(2 * np.pi * t / 3.0))
    area = as_geometry(ROOT / "rdea_lab" / "data" / "specimens" / card).area
    for ps in (TABLE3, TABLE3_FS):
        assert np.all(np.isfinite(_run(card, model, ps, t, lam)["force"].values))
    none = _run(card, model, TABLE3.replace(branches=()), t, lam)["force"].values
    rate = np.abs(np.diff(lam) / np.diff(t)).max()
    R = np.max(np.abs(np.diff(lam) / np.diff(t)) / np.minimum(lam[1:], lam[:-1]))
    Lam = lam.max() / lam.min()
    eta, mod = 10.0, 1e-3  # [Pa s], [Pa]
    limits = [
        (ViscoBranch(k=8e6, eta=eta), eta * rate), (ViscoBranch(mu=8e6 / 3, eta=eta), 3 * eta * R),
        (ViscoBranch(k=mod, eta=8e4), mod * (lam.max() - lam.min())),
        (ViscoBranch(mu=mod, eta=8e4), mod * (Lam**2 - 1 / Lam)),
    ]
    for branch, bound in limits:
        ps = TABLE3.replace(law=branch.law, branches=(branch,))
        ds = _run(card, model, ps, t, lam)
        assert np.all(np.abs(ds["sigma1_irr"].values) <= bound * (1 + 1e-9)), branch
        # + 1e-14 of the force: the rounding of two forces ~1 N apart by a difference of ~1e-9 N (a few ulp)
        slack = 1e-14 * np.abs(none).max()
        assert np.all(np.abs(ds["force"].values - none) <= bound * area / lam * (1 + 1e-9) + slack), branch
