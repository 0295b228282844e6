"""``kernel="auto"``: decided per call by what the call holds (model, roll, samples), never by what the process
loaded before; the path it picks is the one the result comes from.

The weights are measured (`rdea_lab.physics._backend.AUTO_WEIGHT`, ``benchmarks/auto_vs_numpy.py``); here the
rule is held to what `solve`'s docstring states, and `solve` to passing its choice on.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rdea_lab.physics._backend import auto_kernel
from rdea_lab.physics.models import solve
from rdea_lab.physics.result import SLACK

from physics_cases import RIZZELLO, core, on_threads
from test_kernels import assert_same

pytest.importorskip("numba")


@pytest.mark.parametrize("model, roll, first", [("su", "hollow", 16384), ("su", "active", 16384),
                                                 ("1r", "active", 16384), ("1r", "hollow", 16384),
                                                 ("3r", "hollow", 16384), ("3r", "passive", 16384),
                                                 ("cr", "hollow", 16384)])
def test_auto_compiles_from_the_stated_sample_counts(model, roll, first):
    geom = core(roll)
    assert auto_kernel("auto", model, geom, first - 1) == "numpy"
    assert auto_kernel("auto", model, geom, first) == "numba"
    assert auto_kernel("numpy", model, geom, 10**7) == "numpy" and auto_kernel("numba", model, geom, 1) == "numba"


def test_auto_never_compiles_cr_on_a_solid_roll_nor_when_turned_off(monkeypatch):
    assert auto_kernel("auto", "cr", core("active"), 10**9) == "numpy"  # its compiled path is the numpy one
    monkeypatch.setenv("RDEA_LAB_KERNELS", "numpy")
    assert auto_kernel("auto", "3r", core("hollow"), 10**9) == "numpy"


@pytest.mark.parametrize("model, n", [("3r", 16384), ("1r", 16384), ("su", 16384)])
def test_solve_takes_the_path_auto_picks(model, n, monkeypatch):
    """From the stated count on, ``auto`` is the compiled path (bit for bit); below it the numpy one. Both calls
    on one thread (`kernels._core_free` follows the machine's load from moment to moment): the kernel is what is
    compared here; threads against one thread is `test_thread_choice_...`'s."""
    from rdea_lab.physics import kernels

    monkeypatch.setattr(kernels, "_other_load", lambda: float(kernels._CORES))
    geom = core("hollow")
    rng = np.random.default_rng(n)
    l1, v = rng.uniform(1.0, 1.6, n), rng.uniform(0.0, 3000.0, n)
    auto = solve(model, geom, RIZZELLO, l1, v)
    for name in ("status", "sigma1", "capacitance", "free_stretch"):
        np.testing.assert_array_equal(getattr(auto, name), getattr(solve(model, geom, RIZZELLO, l1, v,
                                                                         kernel="numba"), name))
    below = solve(model, geom, RIZZELLO, l1[:-1], v[:-1])
    assert type(below) is type(solve(model, geom, RIZZELLO, l1[:-1], v[:-1], kernel="numpy"))
    assert_same(solve(model, geom, RIZZELLO, l1[:-1], v[:-1], kernel="numpy"), below, "below")


def test_thread_choice_follows_free_cores(monkeypatch):
    """The threaded variant only where a core is free, and only from `PARALLEL_MIN` samples on (that the result
    is the same either way is `test_threads_or_one_give_the_same_bits_...`'s)."""
    from rdea_lab.physics import kernels

    monkeypatch.setattr(kernels, "_other_load", lambda: 0.0)
    assert kernels._parallel(kernels.PARALLEL_MIN) == 1
    assert kernels._parallel(kernels.PARALLEL_MIN - 1) == 0
    monkeypatch.setattr(kernels, "_other_load", lambda: float(kernels.os.cpu_count() or 1))
    assert kernels._parallel(kernels.PARALLEL_MIN) == 0


class _Clock:
    """The readings `kernels._other_load` takes, set by hand: the time, the machine's busy CPU seconds, this
    process's CPU seconds and the load average."""

    def __init__(self, monkeypatch, kernels):
        from types import SimpleNamespace

        self.t, self.busy, self.own, self.load = 100.0, 5000.0, 10.0, 0.0
        monkeypatch.delenv("RDEA_LAB_THREADS", raising=False)  # the estimate itself, not the test session's
        monkeypatch.setattr(kernels, "_LOAD", {"pid": -1, "start": None, "last": 0.0, "others": None, "own": 0.0})
        monkeypatch.setattr(kernels, "time", SimpleNamespace(monotonic=lambda: self.t, process_time=lambda: self.own))
        monkeypatch.setattr(kernels, "_busy", lambda: self.busy)
        monkeypatch.setattr(kernels.os, "getloadavg", lambda: (self.load, 0.0, 0.0))

    def advance(self, seconds, machine, own, runnable=None):
        """``seconds`` pass with ``machine`` cores busy, ``own`` of them this process's; the load average
        follows the ``runnable`` threads (default ``machine``) as the kernel's does, a minute's exponential
        average."""
        self.t += seconds
        self.busy += machine * seconds
        self.own += own * seconds
        keep = math.exp(-seconds / 60.0)
        self.load = keep * self.load + (1.0 - keep) * (machine if runnable is None else runnable)


def test_rdea_lab_threads_1_takes_every_core_for_other_work(monkeypatch):
    """``RDEA_LAB_THREADS=1``: every core counts as taken, so no call goes to numba's threads, on an idle machine
    too; any other value leaves it to the estimate (here an idle machine: threads)."""
    from rdea_lab.physics import kernels

    clock = _Clock(monkeypatch, kernels)  # an idle machine, the variable unset
    monkeypatch.setattr(kernels, "_CORES", 4)  # whatever this machine has
    kernels._other_load()
    clock.advance(0.5, machine=0.0, own=0.0)
    assert kernels._other_load() < 1e-9 and kernels._parallel(kernels.PARALLEL_MIN) == 1
    monkeypatch.setenv("RDEA_LAB_THREADS", "1")
    assert kernels._other_load() == kernels._CORES and kernels._parallel(kernels.PARALLEL_MIN) == 0
    monkeypatch.setenv("RDEA_LAB_THREADS", "0")
    assert kernels._parallel(kernels.PARALLEL_MIN) == 1


def test_other_load_leaves_out_this_process(monkeypatch):
    """The other processes' CPU use is the machine's less this process's (both cores busy with this process's
    two threads: no other load; one of them another process's: one core), and before any window closes the
    load average less this process's running thread stands in."""
    from rdea_lab.physics import kernels

    clock = _Clock(monkeypatch, kernels)
    clock.load = 1.25
    assert kernels._other_load() == 0.25  # no window yet: the load average less one
    clock.advance(0.5, machine=2.0, own=2.0)
    assert abs(kernels._other_load()) < 1e-9
    assert kernels._core_free()
    clock.load = 2.0  # what a minute of this process's two threads does to the load average: not other work
    assert kernels._core_free()
    clock.advance(0.5, machine=2.0, own=1.0)
    assert abs(kernels._other_load() - 0.5) < 1e-9  # the window so far: 1 s, half a core another's
    clock.advance(1.0, machine=2.0, own=1.0)  # a window starts afresh past 1 s
    clock.advance(0.5, machine=2.0, own=1.0)
    assert abs(kernels._other_load() - 1.0) < 1e-9
    assert not kernels._core_free()


def test_other_load_reads_the_load_average_after_a_long_idle(monkeypatch):
    """A window over 5 s long (this process idle): the load average less this process's share where that is
    larger (work that began a moment ago), else the window's own figure."""
    from rdea_lab.physics import kernels

    clock = _Clock(monkeypatch, kernels)
    kernels._other_load()
    clock.advance(60.0, machine=0.1, own=0.0)
    clock.load = 1.6  # another process began lately
    assert abs(kernels._other_load() - 1.6) < 1e-9
    clock.advance(0.05, machine=1.0, own=0.0)  # within 0.1 s of the last reading: the last estimate
    assert abs(kernels._other_load() - 1.6) < 1e-9


def test_other_load_after_a_pause_does_not_count_this_process_earlier_work(monkeypatch):
    """Two minutes on both cores, alone, then 6 s idle: the load average still holds this process's work, which
    is not other work (its share, averaged over the same minute, is taken off); a process that began during
    the pause is."""
    from rdea_lab.physics import kernels

    clock = _Clock(monkeypatch, kernels)
    kernels._other_load()
    for _ in range(120):
        clock.advance(1.0, machine=2.0, own=2.0)
        assert kernels._other_load() < 1e-9
    assert clock.load > 1.7  # the load average's figure of this process's own work
    clock.advance(6.0, machine=0.0, own=0.0)
    assert kernels._other_load() < 0.05
    assert kernels._core_free()
    clock.advance(0.5, machine=2.0, own=1.0)  # a window: another process on one core, this one on the other
    clock.advance(6.0, machine=1.0, own=0.0, runnable=1.0)  # this one idle, the other on
    assert abs(kernels._other_load() - 1.0) < 0.05


def test_other_load_starts_afresh_in_a_forked_child(monkeypatch):
    """A child's window is its own: its parent's readings are not carried over."""
    from rdea_lab.physics import kernels

    clock = _Clock(monkeypatch, kernels)
    kernels._other_load()
    clock.advance(0.5, machine=2.0, own=0.0)
    assert abs(kernels._other_load() - 2.0) < 1e-9
    kernels._LOAD["pid"] = -2  # as after a fork
    clock.load = 0.5
    assert kernels._other_load() == 0.0  # no window yet: the load average less one, not below 0


# the ring models' threaded passes in the slow step: each model compiles variants of its own, 5-12 s of CPU
@pytest.mark.parametrize("model", ["su", pytest.param("1r", marks=pytest.mark.slow),
                                   pytest.param("3r", marks=pytest.mark.slow),
                                   pytest.param("cr", marks=pytest.mark.slow)])
def test_threads_or_one_give_the_same_bits_on_a_random_hollow_scene(model, monkeypatch):
    """`test_solve_takes_the_path_auto_picks`' scene (slack rolls, folds and all) solved on one thread and on
    numba's threads: every field the same, bit for bit. The samples fill blocks and leave a part of one (SU's
    `SU_BLOCK`, the scan's `BLOCK`), past SU's threshold for threads."""
    from rdea_lab.physics import kernels

    geom = core("hollow")
    rng = np.random.default_rng(16384)
    n = kernels.SU_PARALLEL_MIN + 1234
    l1, v = rng.uniform(1.0, 1.6, n), rng.uniform(0.0, 3000.0, n)
    on_threads(monkeypatch, False)
    one = solve(model, geom, RIZZELLO, l1, v, kernel="numba")
    on_threads(monkeypatch, True)
    threads = solve(model, geom, RIZZELLO, l1, v, kernel="numba")
    assert np.any(one.status == SLACK)
    for name in ("status", "converged", "tension", "sigma1", "force", "capacitance", "lambda2a", "lambda2b",
                 "lambda2c", "r_i", "free_stretch", "critical_voltage"):
        np.testing.assert_array_equal(getattr(one, name), getattr(threads, name), err_msg=name)
