"""The fast whole-call paths of `solve` against the generic numpy reference.

The reference is `models._common.solve_model` with the model's numpy `evaluate`
(equilibria, then the slack roll's free state by `free_state`, then `finish`),
the path every model took before the fused ones; it is itself checked against
closed forms and brute force (test_models, test_random_cases). The fused SU
call (`kernels.su_solve`: the tension, status, convergence and slack samples in
one compiled pass, block by block; `kernels.su_fields` and `su_free`: the fields
and the slack rolls' free states when first read) must give its statuses
exactly and its numbers to 1e-12 of each field's largest magnitude
(test_kernels' `assert_same`), on random rolls, materials and inputs that reach
slack (near 1 and far beyond the free-stretch search's end), overflow, NaN and
infinite samples, broadcast shapes and paths.
"""

from __future__ import annotations

import numpy as np
import pytest

from rdea_lab.physics.models import solve, su
from rdea_lab.physics.models._common import FREE_STRETCH_MAX, solve_model
from rdea_lab.physics.result import BAD_INPUT, OVERFLOW, SLACK

from physics_cases import RIZZELLO, TABLE3, THREADS, core, on_threads
from test_kernels import assert_same

pytest.importorskip("numba")


def reference(geom, mat, l1, v, **kw):
    with np.errstate(over="ignore", invalid="ignore"):  # the overflowing samples (OVERFLOW)
        return solve_model("su", su.evaluate, geom, mat, l1, v, kernel="numpy", **kw)


def random_family(seed, n=3000):
    """A random roll and material and ``n`` (stretch, voltage) samples: most in the working range, some
    just above 1, some slack at voltages that push the free state past `FREE_STRETCH_MAX`, and NaN,
    infinite and overflowing samples."""
    rng = np.random.default_rng(seed)
    Ro = rng.uniform(0.5e-3, 3e-3)
    rho_i = 0.0 if rng.random() < 0.5 else rng.uniform(0.01, 0.9)
    rho_ie = rho_i + (1.0 - rho_i) * rng.uniform(0.001, 0.5)
    rho_oe = rho_ie + (1.0 - rho_ie) * rng.uniform(0.2, 1.0)
    L1 = rng.uniform(10e-3, 80e-3)
    geom = core((rho_i * Ro, rho_ie * Ro, min(rho_oe, 1.0) * Ro, Ro), L1=L1, L1e=L1 * rng.uniform(0.5, 1.0),
                L3=rng.uniform(20e-6, 80e-6))
    C10 = rng.uniform(20e3, 400e3)
    # every other family softens for good (C30 = 0, C20 < 0): its stretched rolls have no free state
    C30 = 0.0 if seed % 2 else C10 * rng.uniform(0.0, 0.3)
    mat = type(TABLE3)(C10=C10, C20=C10 * rng.uniform(-0.4, 0.1 if C30 else -0.1), C30=C30,
                       eps_r=rng.uniform(2.0, 5.0))
    l1 = np.where(rng.random(n) < 0.2, 1.0 + 10.0 ** rng.uniform(-14, -2, n), rng.uniform(1.0, 2.5, n))
    v = rng.uniform(0.0, 6000.0, n) * np.where(rng.random(n) < 0.05, 50.0, 1.0)
    k = rng.choice(n, 12, replace=False)
    l1[k[:3]], v[k[3:5]], l1[k[5]] = np.nan, np.inf, np.inf
    l1[k[6:8]], v[k[8]] = 1e120, 1e200  # the stress overflows; a slack roll that cannot be represented
    return geom, mat, l1, v


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("slack", [True, False])
def test_su_fused_pass_equals_reference_on_random_families(seed, slack):
    geom, mat, l1, v = random_family(seed)
    ref = reference(geom, mat, l1, v, slack=slack)
    assert_same(ref, solve("su", geom, mat, l1, v, slack=slack, kernel="numba"), f"seed {seed}")
    with np.errstate(over="ignore", invalid="ignore"):
        assert_same(ref, solve("su", geom, mat, l1, v, slack=slack, kernel="numpy"), f"seed {seed} numpy")
    # the families reach what the fused pass handles apart from the plain state
    assert np.any(ref.status == BAD_INPUT) and np.any(ref.status == OVERFLOW)
    if slack:
        assert np.any((ref.status == SLACK) & (ref.free_stretch < FREE_STRETCH_MAX))
        assert np.any((ref.status == SLACK) & np.isnan(ref.free_stretch)) or mat.C30 > 0.0


def test_su_fused_pass_on_the_bench_scene_and_shapes():
    """Specimen-like material, stretch 1-1.5 at 2.6 kV (about 3 % slack), as 1-D, 2-D and broadcast inputs."""
    geom = core("hollow")
    rng = np.random.default_rng(1)
    l1 = rng.uniform(1.0, 1.5, (40, 50))
    ref = reference(geom, TABLE3, l1, 2600.0)
    fast = solve("su", geom, TABLE3, l1, 2600.0, kernel="numba")
    assert fast.sigma1.shape == (40, 50) and np.any(ref.status == SLACK)
    assert_same(ref, fast, "2-D, scalar voltage")
    assert_same(reference(geom, RIZZELLO, l1[:, :1], np.linspace(0, 4e3, 7)),
                solve("su", geom, RIZZELLO, l1[:, :1], np.linspace(0, 4e3, 7), kernel="numba"), "broadcast")
    assert_same(reference(geom, RIZZELLO, 1.2, 1000.0), solve("su", geom, RIZZELLO, 1.2, 1000.0, kernel="numba"),
                "scalars")


def test_su_fused_pass_paths_and_their_ends():
    geom = core("active")
    lam = np.linspace(1.0, 1.4, 60)
    ref = reference(geom, TABLE3, lam, 2600.0, path=True)
    fast = solve("su", geom, TABLE3, lam, 2600.0, path=True, kernel="numba")
    assert_same(ref, fast, "path")
    assert fast.end == ref.end
    nan = np.full(3, np.nan)  # a block without a solvable sample carries the previous end on
    assert (solve("su", geom, TABLE3, nan, 1.0, path=True, start=fast.end, kernel="numba").end
            == reference(geom, TABLE3, nan, 1.0, path=True, start=ref.end).end)
    with pytest.raises(ValueError, match="start"):
        solve("su", geom, TABLE3, lam, 1.0, start=fast.end, kernel="numba")
    with pytest.raises(ValueError, match="start"):
        solve("su", geom, TABLE3, lam, 1.0, path=True, start=solve("1r", geom, TABLE3, lam, 1.0, path=True).end,
              kernel="numba")


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_inputs_are_not_copied_nor_changed(kernel):
    """The result's stretch and voltage are the caller's float arrays (no copy), and a bad sample,
    which the solvers see as the unloaded state, leaves the caller's array as it was."""
    geom = core("hollow")
    l1 = np.linspace(1.0, 1.5, 20000)
    v = np.full(l1.size, 2000.0)
    res = solve("su", geom, TABLE3, l1, v, kernel=kernel)
    assert np.shares_memory(res.stretch, l1) and np.shares_memory(res.voltage, v)
    l1[5] = np.nan
    res = solve("1r", geom, TABLE3, l1, v, kernel=kernel)
    assert np.isnan(l1[5]) and np.isnan(res.stretch[5]) and res.status[5] == BAD_INPUT
    assert not np.shares_memory(res.tension, res.sigma1)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(8, 72))
def test_su_fused_pass_equals_reference_on_many_random_families(seed):
    """The full set of families (the default suite runs the first 8, above)."""
    geom, mat, l1, v = random_family(seed)
    for slack in (True, False):
        assert_same(reference(geom, mat, l1, v, slack=slack),
                    solve("su", geom, mat, l1, v, slack=slack, kernel="numba"), f"seed {seed} slack {slack}")


ALL_FIELDS = ("sigma1", "force", "tension", "lambda2a", "lambda2b", "lambda2c", "capacitance", "converged", "status",
              "r_i", "free_stretch", "critical_voltage", "range_voltage")


@pytest.mark.parametrize("seed", range(4))
def test_su_fields_computed_when_read_in_any_order(seed):
    """The compiled SU result computes most fields when first read (`su._Fields`): read in a random order,
    after the caller has overwritten its input arrays, each equals the reference's (computed before)."""
    geom, mat, l1, v = random_family(seed)
    ref = reference(geom, mat, l1, v)
    fast = solve("su", geom, mat, l1, v, kernel="numba")
    l1[:] = 1.3  # the caller reuses its arrays: no field computed later sees that
    v[:] = 0.0
    order = np.random.default_rng(seed).permutation(ALL_FIELDS)
    for name in order:
        x, y = getattr(ref, name), getattr(fast, name)
        assert x.shape == y.shape and x.dtype == y.dtype, name
        if x.dtype == bool or x.dtype == np.int8:
            assert np.array_equal(x, y), name
        else:
            assert np.array_equal(np.isnan(x), np.isnan(y)), name
            fin = np.isfinite(x)
            assert np.all(np.abs(x[fin] - y[fin]) <= 1e-12 * np.max(np.abs(x[fin]), initial=0.0)), name
    assert fast.lambda2a is fast.lambda2b is fast.lambda2c  # one array for the three rings, read-only
    for name in ("lambda2a", "status", "tension"):
        assert not getattr(fast, name).flags.writeable, name  # shared, or what later fields are computed from



def test_su_deferred_fields_cannot_be_changed_through_a_view():
    """The arrays the deferred fields are computed from (tension, status, the state stretch that becomes
    the free one) and the rings' shared array are not writeable themselves: a caller who asks a view of
    them to be writeable is refused, and every field read later equals the reference's."""
    geom = core("hollow")
    l1 = np.linspace(1.0, 1.5, 3000)
    ref = reference(geom, TABLE3, l1, 2600.0)
    assert np.any(ref.status == SLACK)
    fast = solve("su", geom, TABLE3, l1, 2600.0, kernel="numba")
    for name in ("tension", "status", "converged", "critical_voltage", "range_voltage"):  # before any deferred
        with pytest.raises(ValueError):
            getattr(fast, name).flags.writeable = True
        with pytest.raises(ValueError):
            getattr(fast, name)[...] = 0
    assert_same(ref, fast, "after the refused writes")  # every deferred field computed after them
    for name in ("lambda2a", "free_stretch"):
        with pytest.raises(ValueError):
            getattr(fast, name).flags.writeable = True
    assert_same(ref, fast, "after the refused writes")
    with pytest.raises(ValueError):  # the numpy path's NaN fields, one broadcast NaN, as well
        ref.critical_voltage.flags.writeable = True


def test_su_deferred_block_computed_once_by_threads_reading_it_at_once():
    """Two threads that read a deferred field first at the same time get the same arrays, computed once
    (`su._Fields`' lock); the fields equal the reference's."""
    import threading
    import time

    geom = core("hollow")
    l1 = np.linspace(1.0, 1.5, 3000)
    ref = reference(geom, TABLE3, l1, 2600.0)
    fast = solve("su", geom, TABLE3, l1, 2600.0, kernel="numba")
    derive = fast._derive
    calls = []

    class Slow:  # the kernels module, its fields pass slowed down so that the two reads overlap
        def __getattr__(self, name):
            return getattr(derive_fast, name)

        def su_fields(self, *args):
            calls.append(args[-1])
            time.sleep(0.05)
            return derive_fast.su_fields(*args)

    derive_fast, derive.fast = derive.fast, Slow()
    got = {}

    def read(key, name):
        got[key] = getattr(fast, name)

    threads = [threading.Thread(target=read, args=(k, name)) for k, name in enumerate(("free_stretch", "r_i",
                                                                                           "sigma1", "force"))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(calls) == [0, 1]  # each block once
    assert got[0] is fast.free_stretch and got[1] is fast.r_i and got[2] is fast.sigma1 and got[3] is fast.force
    assert_same(ref, fast, "read by threads")

def test_su_deferred_result_pickles_copies_and_replaces_as_a_model_result():
    import copy
    import dataclasses
    import pickle

    from rdea_lab.physics.result import ModelResult

    geom = core("hollow")
    l1 = np.linspace(1.0, 1.5, 300)
    ref = reference(geom, TABLE3, l1, 2600.0)
    assert np.any(ref.status == SLACK)
    for make in (lambda r: pickle.loads(pickle.dumps(r)), copy.copy, copy.deepcopy,
                 lambda r: dataclasses.replace(r, model="su")):
        out = make(solve("su", geom, TABLE3, l1, 2600.0, kernel="numba"))
        assert isinstance(out, ModelResult)
        assert_same(ref, out, "copied")
        assert np.array_equal(out.converged, ref.converged)
    fast = solve("su", geom, TABLE3, l1, 2600.0, kernel="numba")
    assert not hasattr(fast, "sigma2") and "sigma1=" in repr(fast) and fast.summary() == ref.summary()
    assert [f.name for f in dataclasses.fields(fast)] == [f.name for f in dataclasses.fields(ref)]
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.sigma1 = None


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_su_stretch_below_one_is_the_callers_error(kernel):
    from rdea_lab.physics.result import StretchBelowOneError

    l1 = np.array([1.2, np.nan, 0.99, 0.5, 1.0])
    with pytest.raises(StretchBelowOneError, match=r"stretch 0\.99 at sample 2 is below 1 \(1 samples in all\)"):
        solve("su", core("hollow"), TABLE3, l1, np.array([0.0, 1.0, 1.0, np.inf, 1.0]), kernel=kernel)


@pytest.mark.parametrize("threads", THREADS)
@pytest.mark.parametrize("n", [0, 1, 4096, 2 * 4096 + 17, 32768 + 1234])
def test_su_solve_indexes_its_slack_samples_in_order_with_their_voltages(n, threads, monkeypatch):
    """`kernels.su_solve` finds its slack samples block by block (`SU_BLOCK`), on one thread or on numba's threads
    (from `SU_PARALLEL_MIN` samples): their indices are where the status is SLACK, in order, their voltages the
    caller's there (a copy), and the stretches below 1 are counted, for any count of samples (none, one, a
    whole block, blocks and a part); the slack samples crowd in one part of the scene, as a ramp's do."""
    from rdea_lab.physics import kernels
    from rdea_lab.physics.models._common import kappa
    from rdea_lab.physics.result import OK

    on_threads(monkeypatch, threads)
    ran = []  # which variant of the pass ran: 0 one thread, 1 numba's threads
    monkeypatch.setattr(kernels, "_su_pass", tuple((lambda *a, k=k, f=f: ran.append(k) or f(*a))
                                                   for k, f in enumerate(kernels._su_pass)))
    geom = core("hollow")
    rng = np.random.default_rng(n)
    l1, v = rng.uniform(1.0, 1.6, n), rng.uniform(0.0, 1000.0, n)
    v[n // 3: n // 2] = 3000.0  # slack here, where the stretch is low
    l1[::997] = 0.99
    C, kap = (TABLE3.C10, TABLE3.C20, TABLE3.C30), float(kappa(geom, TABLE3))
    _, _, status, _, idx, v_slack, low = kernels.su_solve(l1, v, C, kap, float(geom.area), True,
                                                          (OK, SLACK, BAD_INPUT, OVERFLOW))
    np.testing.assert_array_equal(idx, np.flatnonzero(status == SLACK))
    np.testing.assert_array_equal(v_slack, v[idx])
    assert not np.shares_memory(v_slack, v)
    assert low == np.count_nonzero(l1 < 1.0)
    assert ran == [int(threads and n >= kernels.SU_PARALLEL_MIN)]
    if n > 4096:
        assert 0 < idx.size < n and np.count_nonzero((idx >= n // 3) & (idx < n // 2)) > idx.size // 2


def _lanes_against_one_by_one(seeds):
    from rdea_lab.physics import kernels
    from rdea_lab.physics.models._common import kappa

    total = 0
    for seed in seeds:
        geom, mat, l1, v = random_family(seed, 5000)
        C, kap = (mat.C10, mat.C20, mat.C30), float(kappa(geom, mat))
        ok = np.isfinite(l1) & np.isfinite(v)
        l1, v = l1[ok], v[ok]
        block, _, _, _, idx, _, _ = kernels.su_solve(l1, v, C, kap, float(geom.area), True,
                                                 (0, SLACK, BAD_INPUT, OVERFLOW))
        tension = block[0]
        args = (l1[idx].copy(), v[idx].copy(), tension[idx].copy(), *C, kap, FREE_STRETCH_MAX)
        one, lanes = np.empty(idx.size), np.full(idx.size, -1.0)
        kernels._su_free_all(*args, one)
        half = idx.size // 2  # in two ranges: every sample in one
        kernels._su_free_lanes(*args, lanes, 0, half)
        kernels._su_free_lanes(*args, lanes, half, idx.size)
        assert np.array_equal(one, lanes, equal_nan=True), f"seed {seed}"
        total += idx.size
    return total



def test_su_compiled_free_states_equal_the_numpy_reference_bit_for_bit():
    """The compiled free-state step (`kernels._free_step`, which `free_stretch` and the SU lanes take) against
    the numpy reference `_common.free_state` (its bracketing, Illinois iteration and final check
    `free_check`) with the numpy SU model: the same trials in the same order, so the same free stretches to
    the last bit, NaN where there is none, on slack samples of random families."""
    from rdea_lab.physics import kernels
    from rdea_lab.physics.models._common import free_state, kappa

    total = none = 0
    for seed in range(6):
        geom, mat, l1, v = random_family(seed, 5000)
        C, kap = (mat.C10, mat.C20, mat.C30), float(kappa(geom, mat))
        ok = np.isfinite(l1) & np.isfinite(v)
        l1, v = l1[ok], v[ok]
        block, _, _, _, idx, _, _ = kernels.su_solve(l1, v, C, kap, float(geom.area), True,
                                                 (0, SLACK, BAD_INPUT, OVERFLOW))
        lam, vs, s1 = l1[idx].copy(), v[idx].copy(), block[0][idx].copy()
        with np.errstate(over="ignore", invalid="ignore"):
            ref, _, _ = free_state(su.evaluate, geom, mat, lam, vs, s1, kernel="numpy")
        lanes = np.empty(idx.size)
        kernels._su_free_lanes(lam, vs, s1, *C, kap, FREE_STRETCH_MAX, lanes, 0, idx.size)
        assert np.array_equal(ref, lanes, equal_nan=True), f"seed {seed}"
        total += idx.size
        none += np.count_nonzero(np.isnan(ref))
    assert total > 5000 and 100 < none < total - 1000  # both kinds of ending

def test_su_free_states_in_lockstep_equal_one_by_one():
    """`kernels._su_free_lanes` (several slack samples in lockstep) against `_su_free` sample by sample
    (which the tests above hold to the numpy reference): bit for bit, NaN where none is found."""
    assert _lanes_against_one_by_one(range(6)) > 5000


@pytest.mark.slow
def test_su_free_states_in_lockstep_equal_one_by_one_on_many_families():
    assert _lanes_against_one_by_one(range(6, 80)) > 50000
