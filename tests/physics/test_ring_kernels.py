"""The compiled passes of `rdea_lab.physics.ring_kernels` against the numpy reference they stand in for.

- A slack roll's free state: `ring_kernels.free_states` (through `Evaluation.free`) against the numpy
  `models._common.free_state` with ``kernel="numpy"`` (the reference's trials, solved by `follow_branch`),
  sample by sample: every sample the compiled search finishes must be one the reference finds (``SLACK``),
  with its free stretch and fields to 1e-12 (relative to each field's largest magnitude); the samples it
  leaves go to the reference by construction (checked through `solve` against ``kernel="numpy"``, whose
  statuses must be identical). Cases: the seeded random families of test_random_cases (folds, small cores,
  micro-cores), each at stretches and voltages that make many rolls slack, and the bench scene.
- The free-state searches in lockstep lanes (`_free_lanes`) against the one-by-one search, bit for bit.
- The result fields: `fields1`, `fields3`, `fields_cr` against `one_ring.fields`, `three_ring.ring_fields` and
  `continuum.evaluate`'s numpy fields (also near stretch 1, with rings of zero volume and non-finite
  coordinates); the problems' bounds (`ring_kernels.bounds`)
  against the models' `bounds`, and the buffer they are kept in (`scratch`) shared by no result.
"""

from __future__ import annotations

import numpy as np
import pytest

from rdea_lab.physics import kernels, ring_kernels
from rdea_lab.physics.models import continuum, one_ring, solve, three_ring
from rdea_lab.physics.models._common import free_state, kappa, yeoh_coefficients
from rdea_lab.physics.result import SLACK, is_valid

from physics_cases import RIZZELLO, THREADS, assert_close, core, on_threads
from test_kernels import assert_same
from test_random_cases import cases


MODULES = {"1r": one_ring, "3r": three_ring, "cr": continuum}
KEYS = ("lambda2a", "lambda2b", "lambda2c", "capacitance", "r_i")
RTOL = 1e-12
#: Cases of each family in the default run (a prefix; all of them under ``-m slow``).
N_CASES = 3  # (6 until the default suite neared 4 min in CI)
#: Rolls whose inner or outer passive ring has no volume, and the hollow core [m].
CORES_SPLIT = {"no ring a": (0.86e-3, 0.86e-3, 1.76e-3, 1.8e-3), "no ring c": (0.86e-3, 0.88e-3, 1.8e-3, 1.8e-3),
               "hollow": (0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3)}


def _close(x, y, what):
    assert_close(x, y, what, RTOL)


def _slack_scene(case, rng, n=32):
    """Stretches and voltages of one case where many of its rolls are slack: voltages up to 1.5 times the case's
    largest, stretches 1-2."""
    l1 = rng.uniform(1.0, 2.0, n)
    v = rng.uniform(0.0, 1.5 * float(np.max(case.voltage)), n)
    return l1, v


def check_free_states(model, geom, mat, l1, v):
    """Compiled free states against `free_state` with numpy trials: ``(slack samples, done)``."""
    module = MODULES[model]
    ev = module.evaluate(geom, mat, l1, v, kernel="numba")
    sigma = np.asarray(ev.fields["sigma1"], float)
    with np.errstate(invalid="ignore"):
        slack = np.flatnonzero(is_valid(ev.status) & (sigma < 0.0))
    if not slack.size:
        return 0, 0
    assert ev.free is not None, f"{model}: no compiled free state"
    lam, fields, done = ev.free(slack, sigma[slack])
    lam_r, st_r, f_r = free_state(module.evaluate, geom, mat, l1[slack], v[slack], sigma[slack], kernel="numpy")
    what = f"{model} {geom} {mat}"
    # every sample it finishes is one the reference finds, at the same stretch, with the same fields
    assert np.all(st_r[done] == SLACK), f"{what}: compiled found a free state where the reference did not"
    _close(lam[done], lam_r[done], f"{what}: free stretch")
    for key in KEYS:
        _close(np.broadcast_to(fields[key], lam.shape)[done], np.broadcast_to(f_r[key], lam.shape)[done],
               f"{what}: {key}")
    return slack.size, int(np.count_nonzero(done))


@pytest.mark.parametrize("model, family", [("1r", "general"), ("3r", "general"), ("cr", "general"),
                                           ("1r", "small core"), ("3r", "small core"),
                                           ("3r", "hollow micro-core"), ("cr", "hollow micro-core")])
def test_free_states_equal_free_state_on_random_families(model, family, n_cases=None):
    n_slack = n_done = 0
    rng = np.random.default_rng(41)
    for case in cases(family, N_CASES if n_cases is None else n_cases):
        if model == "cr" and case.geom.Ri == 0.0:
            continue  # CR of a solid roll is SU: no free coordinate
        l1, v = _slack_scene(case, rng)
        s, d = check_free_states(model, case.geom, case.mat, l1, v)
        n_slack, n_done = n_slack + s, n_done + d
        # and the whole solve: statuses identical to the reference's, numbers to 1e-12
        assert_same(solve(model, case.geom, case.mat, l1, v, kernel="numpy"),
                    solve(model, case.geom, case.mat, l1, v, kernel="numba"), f"{model} {case.name}")
    # the compiled search runs (a trial near a fold, which `kernels._one` does not certify, sends its sample to
    # the reference: on solid rolls near their pitchfork most of them)
    assert n_slack > 0 and n_done > 0


@pytest.mark.slow
@pytest.mark.parametrize("model, family", [("1r", "general"), ("3r", "general"), ("cr", "general"),
                                           ("1r", "small core"), ("3r", "small core"),
                                           ("3r", "hollow micro-core"), ("cr", "hollow micro-core")])
def test_free_states_many_cases(model, family):
    """The test above on 200 cases of each family (minutes)."""
    test_free_states_equal_free_state_on_random_families(model, family, n_cases=200)


def _bench_scene(n):
    # benchmarks/bench_models.py's scene: hollow core, lambda1 U[1, 1.75], v U[0, 3.5 kV]
    rng = np.random.default_rng(0)
    return core("hollow"), rng.uniform(1.0, 1.75, n), rng.uniform(0.0, 3500.0, n)


@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_bench_scene_equal_reference(model, n=4000):
    geom, l1, v = _bench_scene(n)
    s, d = check_free_states(model, geom, RIZZELLO, l1, v)
    assert s > 0 and d == s  # on the bench scene every slack roll's free state is compiled
    assert_same(solve(model, geom, RIZZELLO, l1, v, kernel="numpy"), solve(model, geom, RIZZELLO, l1, v,
                                                                            kernel="numba"), f"{model} bench")


@pytest.mark.slow
@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_bench_scene_whole_equal_reference(model, monkeypatch):
    """The test above on the bench's 1e5 samples, on numba's threads (the roots, fields and free states)."""
    on_threads(monkeypatch, True)
    test_bench_scene_equal_reference(model, n=100_000)


@pytest.mark.parametrize("threads", THREADS)
@pytest.mark.parametrize("geom", [core("hollow"), core("active"), core("passive")])
def test_fields_equal_numpy(geom, threads, monkeypatch):
    """Each compiled field pass against its numpy function at the same coordinates (not only at equilibria)."""
    on_threads(monkeypatch, threads)
    rng = np.random.default_rng(7)
    n = 2 * kernels.PARALLEL_MIN + 1000  # enough for numba's threads (from 4096 samples on)
    l1, v = rng.uniform(1.0, 2.0, n), rng.uniform(0.0, 4000.0, n)
    C, kap, C0 = yeoh_coefficients(RIZZELLO), kappa(geom, RIZZELLO), geom.C0(RIZZELLO.eps_r)
    # the problems' bounds and loads in one pass against the models' numpy `bounds`
    roll = continuum._Roll(geom, l1)
    for fast, prob in ((one_ring.problem(geom, RIZZELLO, l1, v, ring_kernels), one_ring.problem(geom, RIZZELLO, l1, v)),
                       (three_ring.problem(geom, RIZZELLO, l1, v, ring_kernels),
                        three_ring.problem(geom, RIZZELLO, l1, v))) + (
            ((continuum._problem(roll, geom, RIZZELLO, l1, v, ring_kernels),
              continuum._problem(roll, geom, RIZZELLO, l1, v)),) if geom.Ri > 0.0 else ()):
        for key in ("y0", "y_max", "K", "load"):
            _close(getattr(fast, key), getattr(prob, key), f"bounds {key}")
    l2 = rng.uniform(0.5, 2.0, n) / np.sqrt(l1)
    for x, y in zip(ring_kernels.fields1(l2, l1, v, C, kap, C0, geom.Ro, geom.Ri),
                    one_ring.fields(l2, l1, v, *C, kap, C0, geom.Ro, geom.Ri)):
        _close(x, y, "1r")
    rings = three_ring._Rings(geom, l1)
    xi = rings.rho_i / np.sqrt(l1) + rng.uniform(0.0, 0.3, n)
    for x, y in zip(ring_kernels.fields3(xi, l1, v, rings.constants, C, kap, C0, geom.Ro),
                    three_ring.ring_fields(xi, l1, v, rings.constants, *C, kap, C0, geom.Ro)):
        _close(x, y, "3r")
    xi = roll.xi0 + (rng.uniform(0.0, 0.3, n) if geom.Ri > 0.0 else 0.0)
    mech, *hoop = continuum._by_blocks(continuum._mechanics(roll, C), xi, l1, roll.xi0, roll.x0, roll.lx0p)
    sigma1, cap, r_i = continuum.closing(mech, xi, roll.xi0, l1, v, roll.Lb, kap, C0, geom.Ro)
    hoop = [h if there else np.full(n, np.nan) for h, there in zip(hoop, roll.present)]
    for x, y, name in zip(ring_kernels.fields_cr(xi, l1, v, roll, C, kap, C0, geom.Ro),
                          (sigma1, *hoop, cap, r_i), ("sigma1", "lambda2a", "lambda2b", "lambda2c", "C", "r_i")):
        _close(x, y, f"cr {name}")


@pytest.mark.parametrize("threads", THREADS)
@pytest.mark.parametrize("radii", [CORES_SPLIT["no ring a"], CORES_SPLIT["no ring c"], CORES_SPLIT["hollow"]])
def test_field_passes_at_the_edges(radii, threads, monkeypatch):
    """`fields1` and `fields3` against the numpy functions where the invariant's arrangement matters: stretches
    1e-14 to 1e-3 above 1, rings of zero volume (NaN stretch), NaN and infinite coordinates, a call long enough
    for numba's threads (on them with ``threads``) and one too short for them."""
    on_threads(monkeypatch, threads)
    geom = core(radii)
    rng = np.random.default_rng(3)
    n = kernels.PARALLEL_MIN + 7
    l1 = np.where(rng.random(n) < 0.5, 1.0 + 10.0 ** rng.uniform(-14, -3, n), rng.uniform(1.0, 3.0, n))
    v = rng.uniform(0.0, 5000.0, n)
    l1[:2], v[2] = np.nan, np.inf
    C, kap, C0 = yeoh_coefficients(RIZZELLO), kappa(geom, RIZZELLO), geom.C0(RIZZELLO.eps_r)
    rings = three_ring._Rings(geom, l1)
    l2 = rng.uniform(0.9, 1.1, n) / np.sqrt(l1)
    xi = rings.rho_i / np.sqrt(l1) + rng.uniform(0.0, 0.05, n) * (rng.random(n) < 0.9)
    l2[3], xi[4] = np.nan, np.inf
    with np.errstate(all="ignore"):
        for m in (n, 100):
            s = slice(0, m)
            for x, y in zip(ring_kernels.fields1(l2[s], l1[s], v[s], C, kap, C0, geom.Ro, geom.Ri),
                            one_ring.fields(l2[s], l1[s], v[s], *C, kap, C0, geom.Ro, geom.Ri)):
                _close(x, y, f"1r {radii}")
            for x, y in zip(ring_kernels.fields3(xi[s], l1[s], v[s], rings.constants, C, kap, C0, geom.Ro),
                            three_ring.ring_fields(xi[s], l1[s], v[s], rings.constants, *C, kap, C0, geom.Ro)):
                _close(x, np.broadcast_to(y, x.shape), f"3r {radii}")


@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_free_lanes_equal_one_by_one(model, monkeypatch):
    """The lockstep free-state searches (`ring_kernels._free_lanes`, each round's trials in one batched scan)
    against the one-by-one search (`_free_loop`, each trial `kernels._one`) bit for bit: the same samples done,
    the same free stretches and fields, on the random families' slack scenes (more samples than one task of
    lanes) and the bench scene."""
    rng = np.random.default_rng(5)
    scenes = [(case.geom, case.mat) + _slack_scene(case, rng, 300)
              for family in ("general", "small core", "hollow micro-core") for case in cases(family, 3)
              if not (model == "cr" and case.geom.Ri == 0.0)]
    scenes.append((core("hollow"), RIZZELLO) + _bench_scene(3000)[1:])
    free_states = ring_kernels.free_states
    n_done = 0
    for geom, mat, l1, v in scenes:
        ev = MODULES[model].evaluate(geom, mat, l1, v, kernel="numba")
        sigma = np.asarray(ev.fields["sigma1"], float)
        with np.errstate(invalid="ignore"):
            slack = np.flatnonzero(is_valid(ev.status) & (sigma < 0.0))
        out = {}
        for one in (True, False):
            # several tasks of lanes, some lanes idle at each one's end
            monkeypatch.setattr(ring_kernels, "free_states",
                                lambda *a, **k: free_states(*a, **k, one_by_one=one, chunk=64))
            out[one] = ev.free(slack, sigma[slack])
        (lam, f, done), (lam_l, f_l, done_l) = out[True], out[False]
        assert np.array_equal(done, done_l) and np.array_equal(lam, lam_l, equal_nan=True), f"{model} {geom}"
        for key in KEYS:
            assert np.array_equal(np.broadcast_to(f[key], lam.shape), np.broadcast_to(f_l[key], lam.shape),
                                  equal_nan=True), f"{model} {geom} {key}"
        n_done += int(np.count_nonzero(done))
    assert n_done > 200  # the lanes ran (a floor, not a figure)


_AT_EXIT = """
import atexit, os, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from physics_cases import RIZZELLO, core
from rdea_lab.physics import kernels
from rdea_lab.physics.models import solve
kernels._other_load = lambda: 0.0  # threads, as on an idle machine

n = 10000
l1, v = np.linspace(1.0, 1.7, n), np.full(n, 2000.0)
ref = solve(sys.argv[2], core("hollow"), RIZZELLO, l1, v, kernel="numpy")

def at_exit():
    r = solve(sys.argv[2], core("hollow"), RIZZELLO, l1, v, kernel="numba")
    print(bool(np.array_equal(r.status, ref.status) and np.allclose(r.sigma1, ref.sigma1, rtol=1e-12, atol=0.0)))

atexit.register(at_exit)
"""


@pytest.mark.slow  # it compiles the threaded variants (in a process of its own), which no default test needs
@pytest.mark.parametrize("model", ["1r", "3r"])
def test_a_solve_from_an_atexit_handler(model, tmp_path):
    """A solve while the interpreter shuts down (an ``atexit`` handler, a finalizer: no Python thread can start
    then) on numba's threads gives the reference's result."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    script = tmp_path / "at_exit.py"
    script.write_text(_AT_EXIT)
    here = Path(__file__).parent
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(here.parents[1]), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, str(script), str(here), model], capture_output=True, text=True,
                         timeout=300, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["True"], out.stdout + out.stderr[-2000:]


@pytest.mark.parametrize("model", ["1r", "3r"])
def test_bounds_scratch_never_reaches_a_result(model):
    """The problem's bounds live in a reused buffer of the thread (`ring_kernels.scratch`): no field of a result
    shares its memory, and a second solve leaves the first result as it was (the active core: samples of both
    solves go to the numpy reference, whose free states solve inside the first solve's block)."""
    from rdea_lab.physics.result import FIELDS

    geom, l1, v = _bench_scene(3000)
    first = solve(model, core("active"), RIZZELLO, l1, v, kernel="numba")
    kept = {name: np.array(getattr(first, name)) for name in FIELDS if isinstance(getattr(first, name), np.ndarray)}
    solve(model, geom, RIZZELLO, l1[::-1].copy(), v, kernel="numba")
    buf = ring_kernels._SCRATCH.buf
    for name, value in kept.items():
        assert not np.shares_memory(getattr(first, name), buf), name
        assert np.array_equal(getattr(first, name), value, equal_nan=True), name
    assert_same(solve(model, core("active"), RIZZELLO, l1, v, kernel="numpy"), first, f"{model} active core")


@pytest.mark.parametrize("n, threads", [(1, 1), (100, 2), (1023, 2), (2210, 2), (2049, 2), (5000, 3), (4096, 1)])
def test_free_chunk_covers_the_samples_in_equal_tasks(n, threads):
    """`ring_kernels.free_chunk`: the tasks cover every sample, none is empty or over `FREE_CHUNK`, and their count
    is a multiple of the threads wherever the samples fill one task per thread."""
    chunk = ring_kernels.free_chunk(n, threads)
    tasks = -(-n // chunk)
    assert 1 <= chunk <= ring_kernels.FREE_CHUNK and tasks * chunk >= n and (tasks - 1) * chunk < n
    if n >= threads * chunk:
        assert tasks % threads == 0
    assert ring_kernels.free_chunk(0, threads) >= 1  # no samples: no task, and no division by zero
