"""The compiled kernels (`rdea_lab.physics.kernels`) against the numpy reference they stand in for.

The reference is the package's own numpy solver (``kernel="numpy"``), itself
checked against brute force (test_random_cases) and fsolve; the kernels must
give its statuses exactly and its numbers to 1e-12 relative (of each field's
largest magnitude over the call: a root refined by the same Newton iteration
from the same bracket agrees to rounding, 1e-15 measured; 1e-12 leaves room
for the order of a quadrature sum). Cases: the seeded random families of
test_random_cases (voltages put just below and above folds, small cores,
pitchforks, hollow micro-cores), hypothesis-drawn rolls and materials, NaN and edge inputs, and
paths that sweep the voltage across folds and back (hysteresis, snaps).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rdea_lab.physics import kernels
from rdea_lab.physics.geometry import RollGeometry
from rdea_lab.physics.models import solve
from rdea_lab.physics.result import SNAPPED

from physics_cases import RIZZELLO, TABLE3, core
from test_random_cases import cases

FIELDS = ("sigma1", "tension", "force", "lambda2a", "lambda2b", "lambda2c", "capacitance", "r_i",
          "critical_voltage", "range_voltage", "free_stretch")
RTOL = 1e-12
#: Cases of the seeded families per test (a prefix; more under ``-m slow``: test_kernels_many_cases).
N_CASES, N_PATHS = 6, 2  # (12, 3 until the default suite neared 4 min in CI; the slow test takes 200, 60)


def assert_same(a, b, what):
    assert np.array_equal(a.status, b.status), f"{what}: status {a.status} != {b.status}"
    for name in FIELDS:
        x, y = np.asarray(getattr(a, name), float), np.asarray(getattr(b, name), float)
        assert np.array_equal(np.isnan(x), np.isnan(y)), f"{what}: {name} NaN pattern differs"
        fin = np.isfinite(x)
        if fin.any():
            scale = np.max(np.abs(x[fin]))
            assert np.all(np.abs(x[fin] - y[fin]) <= RTOL * scale + 1e-300), (
                f"{what}: {name} differs by {np.max(np.abs(x[fin] - y[fin])) / max(scale, 1e-300):.2e} relative")
    if a.end is not None:
        la, lb = a.end.label, b.end.label
        assert (la is None) == (lb is None), f"{what}: end label {la} != {lb}"
        if la is not None:
            assert la[0] == lb[0] and np.allclose(la[1], lb[1], rtol=RTOL, equal_nan=True), f"{what}: {la} != {lb}"
        assert a.end.y == b.end.y or abs(a.end.y - b.end.y) <= RTOL * abs(a.end.y), f"{what}: end {a.end} {b.end}"


def both(model, geom, mat, l1, v, **kw):
    return (solve(model, geom, mat, l1, v, kernel="numpy", **kw), solve(model, geom, mat, l1, v, kernel="numba", **kw))


@pytest.mark.parametrize("model, family", [("1r", "general"), ("3r", "general"), ("cr", "general"),
                                           ("1r", "small core"), ("3r", "small core"),  # small cores are solid
                                           ("3r", "hollow micro-core"), ("cr", "hollow micro-core")])
def test_random_cases_ramp_rule_equal_reference(model, family):
    """The rising-ramp rule on the random families, folds and all (slack on and off)."""
    n_hard = 0
    # a micro-core's reference scans some 40 more nodes (graded toward its core): half as many cases
    for case in cases(family, N_CASES // 2 if family == "hollow micro-core" else N_CASES):
        if model == "cr" and case.geom.Ri == 0.0:
            continue
        v = np.r_[case.voltage, 3.0 * np.max(case.voltage)]  # and far past the folds
        for slack in (True, False):
            ref, fast = both(model, case.geom, case.mat, np.full(v.size, case.stretch), v, slack=slack)
            assert_same(ref, fast, f"{model} {case.name} slack={slack}")
            n_hard += int(np.count_nonzero(ref.status != 0))
    assert n_hard > 0  # the families reach folds, snaps and slack, not only the easy states


@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_random_cases_paths_across_folds_equal_reference(model):
    """Paths: the voltage up past each case's largest voltage and back, and a stretch ramp under it."""
    snapped = 0
    for case in cases("general", N_PATHS) + cases("small core", N_PATHS // 2) + cases("hollow micro-core", N_PATHS):
        if model == "cr" and case.geom.Ri == 0.0:
            continue
        vmax = float(np.max(case.voltage))
        up = np.linspace(0.0, vmax, 30)
        v = np.r_[up, up[::-1]]
        l1 = np.full(v.size, case.stretch)
        ref, fast = both(model, case.geom, case.mat, l1, v, path=True)
        assert_same(ref, fast, f"{model} {case.name} voltage loop")
        snapped += int(np.count_nonzero(ref.status == SNAPPED))
        lam = np.linspace(1.0, max(case.stretch, 1.01), 40)
        ref, fast = both(model, case.geom, case.mat, lam, np.full(lam.size, 0.8 * vmax), path=True)
        assert_same(ref, fast, f"{model} {case.name} stretch ramp")
        # a block continued from the previous one's end
        mid = lam.size // 2
        r1 = solve(model, case.geom, case.mat, lam[:mid], 0.8 * vmax, path=True, kernel="numpy")
        f1 = solve(model, case.geom, case.mat, lam[:mid], 0.8 * vmax, path=True, kernel="numba")
        assert_same(solve(model, case.geom, case.mat, lam[mid:], 0.8 * vmax, path=True, start=r1.end,
                          kernel="numpy"),
                    solve(model, case.geom, case.mat, lam[mid:], 0.8 * vmax, path=True, start=f1.end,
                          kernel="numba"), f"{model} {case.name} second block")
    assert snapped > 0  # some loops snap through: the fallback to the reference is exercised


@pytest.mark.slow
@pytest.mark.parametrize("model", ["1r", "3r"])
def test_kernels_many_cases(model, monkeypatch):
    """The two tests above on 200 and 60 cases of each family (minutes)."""
    import test_kernels as me

    monkeypatch.setattr(me, "N_CASES", 200)
    monkeypatch.setattr(me, "N_PATHS", 60)
    for family in ("general", "small core", "hollow micro-core"):
        test_random_cases_ramp_rule_equal_reference(model, family)
    test_random_cases_paths_across_folds_equal_reference(model)


@st.composite
def rolls(draw):
    Ro = draw(st.floats(0.5e-3, 3e-3))
    rho_i = draw(st.sampled_from([0.0, draw(st.floats(0.01, 0.9))]))
    rho_ie = rho_i + (1.0 - rho_i) * draw(st.floats(0.001, 0.5))
    rho_oe = rho_ie + (1.0 - rho_ie) * draw(st.floats(0.2, 1.0))
    L1 = draw(st.floats(10e-3, 80e-3))
    return RollGeometry(rho_i * Ro, rho_ie * Ro, min(rho_oe, 1.0) * Ro, Ro, L1=L1,
                        L1e=L1 * draw(st.floats(0.5, 1.0)), L3=draw(st.floats(20e-6, 80e-6)))


@st.composite
def materials(draw):
    C10 = draw(st.floats(20e3, 400e3))
    return SimpleNamespace(C10=C10, C20=C10 * draw(st.floats(-0.4, 0.1)), C30=C10 * draw(st.floats(0.0, 0.3)),
                           eps_r=draw(st.floats(2.0, 5.0)))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(geom=rolls(), mat=materials(), model=st.sampled_from(["su", "1r", "3r", "cr"]), seed=st.integers(0, 2**31),
       path=st.booleans())
def test_hypothesis_rolls_and_materials_equal_reference(geom, mat, model, seed, path):
    if model == "cr" and geom.Ri == 0.0:
        return
    rng = np.random.default_rng(seed)
    n = 64
    l1 = np.sort(rng.uniform(1.0, 2.0, n)) if path else rng.uniform(1.0, 2.0, n)
    v = rng.uniform(0.0, 6000.0, n)
    l1[rng.integers(0, n, 3)] = 1.0  # the unloaded stretch exactly
    ref, fast = both(model, geom, mat, l1, v, path=path)
    assert_same(ref, fast, f"{model} path={path}")


@pytest.mark.parametrize("model", ["su", "1r", "3r", "cr"])
def test_nan_and_edge_inputs_equal_reference(model):
    geom = core("hollow")
    l1 = np.array([1.0, np.nan, 1.2, 1.0 + 1e-12, 1.5, np.inf, 1.3])
    v = np.array([0.0, 1000.0, np.nan, 3000.0, 9000.0, 0.0, 2600.0])
    for path in (False, True):
        ref, fast = both(model, geom, RIZZELLO, l1, v, path=path)
        assert_same(ref, fast, f"{model} path={path}")


def test_specimen_like_solid_roll_3r_is_su_in_both():
    """Ri = 0 (the paper's specimens): the pitchfork start; 3R stays the SU state below the hole opening."""
    geom = core("active")
    l1 = np.linspace(1.0, 1.5, 101)
    for mat in (RIZZELLO, TABLE3):
        ref, fast = both("3r", geom, mat, l1, 2600.0, path=True)
        assert_same(ref, fast, "3r active core")


def test_su_state_writes_into_given_buffers_and_equals_the_formula():
    rng = np.random.default_rng(3)
    l1, v = rng.uniform(1.0, 2.0, 1000), rng.uniform(0.0, 3000.0, 1000)
    out = (np.empty(1000), np.empty(1000), np.empty(1000))
    got = kernels.su_state(l1, v, (242e3, -69e3, 47e3), 0.01, 2e-10, out=out)
    assert all(g is o for g, o in zip(got, out))
    # eq. (39) written out from the invariants, independently of su.basis
    I1 = l1**2 + 2.0 / l1
    W1 = 242e3 + 2 * -69e3 * (I1 - 3) + 3 * 47e3 * (I1 - 3) ** 2
    sigma = 2.0 * W1 * (l1**2 - 1.0 / l1) - 0.01 * l1 * v**2
    assert np.allclose(out[0], sigma, rtol=1e-9, atol=1e-9 * np.max(np.abs(sigma)))  # cancellation near l1 = 1
    assert np.array_equal(out[1], 1.0 / np.sqrt(l1)) and np.allclose(out[2], 2e-10 * l1, rtol=1e-15)


def test_kernel_choice_is_checked():
    with pytest.raises(ValueError, match="kernel 'gpu'; allowed: auto, numba, numpy"):
        solve("su", core("hollow"), RIZZELLO, 1.2, 0.0, kernel="gpu")


def _random_history(rng, n):
    """Uneven sampling (intervals over four decades), a stretch that walks, jumps and holds."""
    t = np.cumsum(10.0 ** rng.uniform(-5.0, -1.0, n))
    steps = rng.normal(0.0, 1e-3, n) + (rng.random(n) < 0.01) * rng.normal(0.0, 0.2, n)
    steps[rng.random(n) < 0.2] = 0.0  # holds
    return t, 1.0 + np.abs(np.cumsum(steps))


def _sequential(t, lam, tau, q0):
    """A slow straightforward reference: eq. (44)'s exact update, one sample at a time in Python."""
    q = np.empty((tau.size, t.size))
    for j, tj in enumerate(tau):
        q[j, 0] = x = q0[j]
        for n in range(t.size - 1):
            dt = t[n + 1] - t[n]
            x = x * np.exp(-dt / tj) + (lam[n + 1] - lam[n]) / dt * tj * -np.expm1(-dt / tj)
            q[j, n + 1] = x
    return q


@pytest.mark.parametrize("seed", range(6))
def test_linear_strains_compiled_equals_prefix_scan(seed):
    """Eq. (44)'s update in sequence (compiled, coefficients fused) against the numpy reference (the
    prefix scan) on random histories, branches from far stiffer than the sampling to far slower, to
    1e-12 of each branch's largest strain (the scan re-associates the products); and against the
    sequential reference in Python."""
    from rdea_lab.physics import viscoelastic

    rng = np.random.default_rng(seed)
    t, lam = _random_history(rng, 20_000)
    tau = 10.0 ** rng.uniform(-6.0, 4.0, 4)
    q0 = rng.normal(0.0, 0.05, tau.size)
    dt, slope = np.diff(t), np.diff(lam) / np.diff(t)
    q_ref, q_fast = np.empty((tau.size, t.size)), np.empty((tau.size, t.size))
    viscoelastic._linear_branches(dt, slope, tau, q0, q_ref, kernel="numpy")
    viscoelastic._linear_branches(dt, slope, tau, q0, q_fast, kernel="numba")
    scale = np.max(np.abs(q_ref), axis=1, keepdims=True)
    assert np.all(np.abs(q_fast - q_ref) <= 1e-12 * scale)
    m = 2000
    q_seq = _sequential(t[:m], lam[:m], tau, q0)
    assert np.all(np.abs(q_fast[:, :m] - q_seq) <= 1e-12 * np.max(np.abs(q_seq), axis=1, keepdims=True))
    with pytest.raises(ValueError, match="kernel 'x'"):
        viscoelastic._linear_branches(dt, slope, tau, q0, q_ref, kernel="x")


@pytest.mark.parametrize("sampling", ["uneven", "fixed rate"])
def test_history_takes_the_compiled_update(monkeypatch, sampling):
    """A `History` (evaluated for many parameter sets: the calibration's) takes the compiled update under
    ``auto`` however short, with the exponentials once per distinct interval (a fixed rate has a few: the
    time axis's rounding, and lost samples), and gives the numbers of the plain arrays' (the numpy prefix
    scan at this length); with ``RDEA_LAB_KERNELS=numpy`` it takes the scan."""
    from rdea_lab.physics import viscoelastic

    rng = np.random.default_rng(11)
    t, lam = _random_history(rng, 3000)
    if sampling == "fixed rate":
        t = np.delete(np.arange(3100) * 0.01, rng.choice(3100, 100, replace=False))
        assert np.unique(np.diff(t)).size < 30
    tau, q0 = np.array([1e-4, 0.05, 30.0]), np.array([0.0, 0.01, -0.02])
    calls = []
    real = kernels.linear_strains
    monkeypatch.setattr(kernels, "linear_strains", lambda *a: calls.append(1) or real(*a))
    plain = viscoelastic.branch_strains(t, lam, tau, q0)
    assert not calls  # 3000 samples once: numpy (loading numba would cost more than it saves)
    history = viscoelastic.History.of(t, lam)
    assert np.array_equal(history.lengths[history.length_index], np.diff(t))
    q = viscoelastic.branch_strains(history, None, tau, q0)
    assert calls
    assert np.all(np.abs(q - plain) <= 1e-12 * np.max(np.abs(plain), axis=1, keepdims=True))
    monkeypatch.setenv("RDEA_LAB_KERNELS", "numpy")
    calls.clear()
    assert np.array_equal(viscoelastic.branch_strains(history, None, tau, q0), plain)
    assert not calls


def test_kernels_turned_off_load_no_numba():
    """``RDEA_LAB_KERNELS=numpy`` turns the compiled kernels off before numba is loaded: a calibration's
    `History` (``auto`` at any length) runs the numpy scan in a process that never imports numba."""
    import os
    import subprocess
    import sys

    code = ("import sys\nimport numpy as np\nfrom rdea_lab.physics import viscoelastic\n"
            "h = viscoelastic.History.of(np.arange(50) * 0.01, 1 + 0.001 * np.arange(50))\n"
            "viscoelastic.branch_strains(h, None, np.array([0.1]), np.array([0.0]))\n"
            "print('numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "RDEA_LAB_KERNELS": "numpy"},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize("M", range(1, 8))
def test_the_linear_update_takes_each_branch_alone(M):
    """`kernels.linear_strains` runs up to three branches' updates side by side (`_linear`): each branch's
    strains are those it has updated alone, to the last bit, whatever its neighbours (every grouping of
    1 to 7 branches), and the sequential reference's to 1e-12."""
    rng = np.random.default_rng(M)
    t, lam = _random_history(rng, 3000)
    tau = 10.0 ** rng.uniform(-4.0, 3.0, M)
    q0 = rng.normal(0.0, 0.05, M)
    lengths, index = np.unique(np.diff(t), return_inverse=True)
    slope = np.diff(lam) / np.diff(t)
    q = np.empty((M, t.size))
    kernels.linear_strains(lengths, index, slope, tau, q0, q)
    for j in range(M):
        alone = np.empty((1, t.size))
        kernels.linear_strains(lengths, index, slope, tau[j:j + 1], q0[j:j + 1], alone)
        assert np.array_equal(q[j], alone[0]), j
    q_seq = _sequential(t[:1000], lam[:1000], tau, q0)
    assert np.all(np.abs(q[:, :1000] - q_seq) <= 1e-12 * np.max(np.abs(q_seq), axis=1, keepdims=True))
