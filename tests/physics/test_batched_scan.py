"""The batched certified scan (`kernels._scan_block`, what `branch_roots` runs) against the one-sample scan
(`kernels._one`, what the step kernel runs), sample by sample.

Both take the same steps (the shared `_next_node`, `_verdict`, `_fallen`, `_newton`), the batched one for a
block of samples at once with the terms of every sample at a node in one vectorized loop; without fastmath
the vectorized arithmetic is the scalar one lane by lane, so the roots, the certificates and the start
loads ``h0`` must agree to the bit. The problems are the ones `solve` hands to `branch_roots` on the random
hard-case families (folds, snaps, pitchforks, small and hollow micro-cores; ramp rule and paths), on the
bench scene and on solid rolls; the reference `_one` is itself checked against the numpy solver
(test_kernels) and that against brute force (test_random_cases).
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from rdea_lab.physics import kernels
from rdea_lab.physics.models import continuum, one_ring, solve, three_ring

from physics_cases import RIZZELLO, core, on_threads
from test_random_cases import cases


@pytest.fixture(autouse=True)
def _threads_whatever_the_load(monkeypatch):
    """The threaded variants run from their sample counts on, as on an idle machine (`on_threads`)."""
    on_threads(monkeypatch, True)

MODULES = {"1r": one_ring, "3r": three_ring, "cr": continuum}
#: Cases of each seeded family (a prefix; all of them under ``-m slow``).
N_CASES = 3  # (5 until the default suite neared 4 min in CI)


@numba.njit(cache=False, error_model="numpy")
def _scalar_roots(code, l1, y0, y_max, K, xi0, x0, R, Q, C10, C20, C30, offsets, whole, rtol, max_iter, n_scan,
                  pitchfork, y, ok, h0):
    """`_roots_loop` as it was: `_h_start` and `_one` sample by sample."""
    for i in range(l1.size):
        Ri = (xi0[i], x0[i], R[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) if code == 4 else R
        h0[i] = kernels._h_start(code, y0[i], l1[i], Ri, Q, C10, C20, C30, pitchfork)
        y[i], ok[i] = kernels._one(code, l1[i], y0[i], y_max[i], K[i], h0[i], Ri, Q, C10, C20, C30, offsets,
                                   whole, rtol, max_iter, n_scan, pitchfork)


def assert_batched_equals_scalar(problem, whole, what):
    n = problem.K.size
    args = kernels._roots_args(problem, whole)
    out = [(np.empty(n), np.zeros(n, np.int8), np.empty(n)) for _ in range(2)]
    kernels._roots[0](*args, *out[0])
    _scalar_roots(*args, *out[1])
    (y, ok, h0), (y1, ok1, h01) = out
    bad = np.flatnonzero((ok != ok1) | ((y != y1) & ~(np.isnan(y) & np.isnan(y1))))
    assert bad.size == 0, (f"{what}: {bad.size} of {n} samples differ, first {bad[0]}: y {y[bad[0]]!r} != "
                           f"{y1[bad[0]]!r}, certified {ok[bad[0]]} != {ok1[bad[0]]}")
    assert np.array_equal(h0, h01, equal_nan=True), what
    return ok


class _Recorder:
    """`kernels.branch_roots` that also records what it was called with."""

    def __init__(self, monkeypatch):
        self.calls = []
        original = kernels.branch_roots

        def record(problem, *, whole, start=None, **kw):
            self.calls.append((problem, whole))
            return original(problem, whole=whole, start=start, **kw)

        monkeypatch.setattr(kernels, "branch_roots", record)


def _family_problems(model, family, n_cases, monkeypatch):
    rec = _Recorder(monkeypatch)
    for case in cases(family, n_cases):
        if model == "cr" and case.geom.Ri == 0.0:
            continue
        vmax = float(np.max(case.voltage))
        v = np.r_[case.voltage, 3.0 * vmax]
        solve(model, case.geom, case.mat, np.full(v.size, case.stretch), v, kernel="numba")
        up = np.linspace(0.0, vmax, 30)
        solve(model, case.geom, case.mat, np.full(60, case.stretch), np.r_[up, up[::-1]], path=True, kernel="numba")
        lam = np.linspace(1.0, max(case.stretch, 1.01), 40)
        solve(model, case.geom, case.mat, lam, 0.8 * vmax, path=True, kernel="numba")
    return rec.calls


def _check_families(model, family, n_cases, monkeypatch):
    calls = _family_problems(model, family, n_cases, monkeypatch)
    assert calls, "the solves reached the kernel"
    outcomes = np.zeros(3, int)  # certificates 0, 1, 2 seen
    for k, (problem, whole) in enumerate(calls):
        ok = assert_batched_equals_scalar(problem, whole, f"{model} {family} call {k} whole={whole}")
        outcomes += np.bincount(ok, minlength=3)
    return calls, outcomes


@pytest.mark.parametrize("model, family", [("1r", "general"), ("3r", "general"), ("cr", "general"),
                                           ("1r", "small core"), ("3r", "small core"),
                                           ("3r", "hollow micro-core"), ("cr", "hollow micro-core")])
def test_batched_scan_equals_one_sample_scan_on_the_families(model, family, monkeypatch):
    calls, outcomes = _check_families(model, family, N_CASES, monkeypatch)
    assert {w for _, w in calls} == {False, True}  # both scans
    # samples certified, and (but on CR's micro-cores, which have no fold) samples left to the reference
    assert outcomes[1] > 0 and (outcomes[0] > 0 or (model, family) == ("cr", "hollow micro-core")), outcomes


@pytest.mark.slow
@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_batched_scan_equals_one_sample_scan_on_all_cases(model, monkeypatch):
    """The test above on 200 cases of each family (minutes)."""
    for family in ("general", "small core", "hollow micro-core"):
        if model == "cr" and family == "small core":
            continue  # solid rolls: CR is SU there
        _check_families(model, family, 200, monkeypatch)


@pytest.mark.parametrize("roll", ["hollow", "active", "passive"])
@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_batched_scan_equals_one_sample_scan_on_the_bench_scene(model, roll):
    """The bench scene (lambda1 U[1, 1.75], v U[0, 3.5 kV] and to 7 kV, past pull-in), solid rolls too,
    in blocks of every fill (a partial last block, single samples)."""
    if model == "cr" and roll != "hollow":
        return  # CR of a solid roll is SU: no free coordinate, no kernel
    rng = np.random.default_rng(7)
    for n in (1, 3, kernels.BLOCK + 5, 3000):
        l1, v = rng.uniform(1.0, 1.75, n), rng.uniform(0.0, 7000.0, n)
        problem = MODULES[model].problem(core(roll), RIZZELLO, l1, v)
        for whole in (False, True):
            assert_batched_equals_scalar(problem, whole, f"{model} {roll} n={n} whole={whole}")
