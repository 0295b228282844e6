"""The compiled rising-ramp rule (`scan_kernel.follow_branch_at`) against the numpy reference `branch.follow_branch`.

The compiled rule replays `follow_branch` for one sample at a time in the same floating-point operations; a compiled
solve gives it the samples the certified kernel leaves (a fold, a snap, pull-in, the range's end). Here it runs on
every sample of a problem and on a subset (as a solve calls it: `follow_branch` of ``problem.subset(sel)``, scanned
at the parent's nodes), against the reference: states, critical and range loads to 1e-12 (relative) and statuses
identical; its blocks (`scan_kernel._branch_block`, the folds' golden sections in lockstep) against the one-sample
rule (`scan_kernel.branch_rule`), bit for bit. Cases: the random hard-case families of test_random_cases (general,
small cores, hollow micro-cores; 1R, 3R and, where the roll has a core, CR), each at its voltages and a sweep to 2.5
times the largest, past folds and the range's end; the named hard cases of test_scan_kernel (the Ri = 0 pitchfork,
vanishing rings, a thin shell, hollow rolls with folds and an asymptote); the bench scene's rolls (hollow, active
and passive core) to 7 kV. The default run takes a prefix of each family (a few seconds); the full families run
under ``-m slow``.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from rdea_lab.physics import branch  # noqa: E402
from rdea_lab.physics import scan_kernel as sk  # noqa: E402
from rdea_lab.physics.models import continuum, one_ring, three_ring  # noqa: E402
from rdea_lab.physics.result import LIMIT_POINT, OK, OUTSIDE_RANGE, SNAPPED  # noqa: E402

from physics_cases import RIZZELLO, THREADS, core, on_threads  # noqa: E402
from test_random_cases import cases  # noqa: E402
from test_scan_kernel import HARD, _close  # noqa: E402

MODULES = {"1r": one_ring, "3r": three_ring, "cr": continuum}
FAMILIES = ("general", "small core", "hollow micro-core")
#: Cases of each family in the default run (a prefix), and in the slow one.
N_DEFAULT, N_ALL = 10, 200


def check(prob, what):
    """The compiled rule against `follow_branch` on every sample and on every other one; returns the statuses."""
    n = prob.K.size
    for sel in (np.arange(n), np.arange(0, n, 2)):
        ref = branch.follow_branch(prob if sel.size == n else prob.subset(sel))
        got = sk.follow_branch_at(prob, sel)
        assert np.array_equal(got.status, ref.status), f"{what}: statuses {got.status} != {ref.status}"
        for name in ("y", "K_crit", "K_range"):
            assert _close(getattr(got, name), getattr(ref, name)), f"{what}: {name}"
        # the blocks (the folds' golden sections in lockstep) equal the one-sample rule bit for bit
        one = sk.follow_branch_at(prob, sel, one_by_one=True)
        for a, b in zip(got, one):
            assert np.array_equal(a, b, equal_nan=True), f"{what}: blocks against one by one"
    return branch.follow_branch(prob).status


def models_of(geom):
    return ("1r", "3r", "cr") if geom.Ri > 0.0 else ("1r", "3r")


def run_family(family, n):
    seen = set()
    for case in cases(family, n):
        vmax = float(np.max(case.voltage))
        v = np.r_[case.voltage, np.linspace(0.0, 2.5 * vmax, 25)]
        for name in models_of(case.geom):
            prob = MODULES[name].problem(case.geom, case.mat, np.full(v.size, case.stretch), v)
            seen.update(check(prob, f"{name} {case.name}").tolist())
    return seen


@pytest.mark.parametrize("family", FAMILIES)
def test_compiled_ramp_rule_equals_the_reference_on_random_cases(family):
    seen = run_family(family, N_DEFAULT)
    assert OK in seen and SNAPPED in seen


@pytest.mark.slow
@pytest.mark.parametrize("family", FAMILIES)
def test_compiled_ramp_rule_equals_the_reference_on_all_random_cases(family):
    seen = run_family(family, N_ALL)
    assert {OK, SNAPPED, LIMIT_POINT, OUTSIDE_RANGE} <= seen  # the hard outcomes are among them


@pytest.mark.parametrize("k", range(len(HARD)))
def test_compiled_ramp_rule_equals_the_reference_on_the_hard_cases(k):
    geom, mat, v_top = HARD[k]
    v = np.linspace(0.0, v_top, 31)
    for l1 in (1.0, 1.5, 3.0):
        for name in models_of(geom):
            check(MODULES[name].problem(geom, mat, np.full(v.size, l1), v), f"{name} hard case {k} l1={l1}")


@pytest.mark.parametrize("threads", THREADS)
@pytest.mark.parametrize("roll", ["hollow", "active", "passive"])
def test_compiled_ramp_rule_equals_the_reference_on_the_bench_rolls(roll, threads, monkeypatch, n=600):
    """The bench scene's stretches and voltages to 7 kV (past pull-in): the active core folds at a few percent
    of its samples within 3.5 kV. On one thread, and (``threads``) on all cores as on an idle machine."""
    on_threads(monkeypatch, threads)
    assert n >= sk.BRANCH_PARALLEL_MIN  # enough samples for the threads
    rng = np.random.default_rng(3)
    l1, v = rng.uniform(1.0, 1.75, n), rng.uniform(0.0, 7000.0, n)
    seen = set()
    for name in models_of(core(roll)):
        seen.update(check(MODULES[name].problem(core(roll), RIZZELLO, l1, v), f"{name} {roll}").tolist())
    assert OK in seen and (roll != "active" or SNAPPED in seen)
