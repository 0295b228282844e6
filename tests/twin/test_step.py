"""`TwinStep` (one compiled call per sample) against the block twin it must equal (`TwinStream`).

The block twin is the reference: the whole series in one `TwinStream.step`
(numpy path solver, the prefix-scan branches). Tolerance 1e-12 of each
field's peak: the stepped twin refines the same roots by the same Newton
iteration and updates the branches by the same exact formula in sequence
instead of a prefix scan (measured 1e-15). Statuses must be identical.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.physics.geometry import RollGeometry
from rdea_lab.physics.result import BAD_INPUT, OUTSIDE_RANGE, SLACK, SNAPPED
from rdea_lab.specs import ParameterSet, ViscoBranch, load_params, load_specimen
from rdea_lab.twin import TwinStep, TwinStream
from rdea_lab.twin.step import FIELDS, FORCE

PROJECT = Path(__file__).resolve().parents[2] / "rdea_lab" / "data"

TABLE3 = load_params(PROJECT / "params" / "paper2021_table3.yaml")
CARD = load_specimen(PROJECT / "specimens" / "specimen2.yaml")
#: finite-strain branches and a parallel damper: the other law, and eta_v0's rate
FINITE = ParameterSet(name="fs", C10=242e3, C20=-69e3, C30=47e3, eps_r=2.8, law="finite_strain", eta_v0=2e3,
                      branches=(ViscoBranch.of("finite_strain", 2757e3, 28.67e3),
                                ViscoBranch.of("finite_strain", 200e3, 300e3)))
HOLLOW = RollGeometry(0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3, L1=34e-3, L1e=34e-3, L3=48e-6)
#: a weakly stiffening material: the hollow core folds (snaps, leaves the solved range) before it goes slack
WEAK = ParameterSet(name="weak", C10=242e3, C20=-20e3, C30=1e3, eps_r=2.8, branches=(ViscoBranch(k=1e6, eta=1e5),))


def stepped(specimen, params, model, t, lam, v):
    twin = TwinStep(specimen, params, model)
    return np.array([twin.step(a, b, c).copy() for a, b, c in zip(t, lam, v)])


def assert_equal_to_block(specimen, params, model, t, lam, v, first=0):
    block = TwinStream(specimen, params, model).step(t, lam, v)
    got = stepped(specimen, params, model, t, lam, v)
    assert np.array_equal(got[first:, -1].astype(np.int8), block["model_status"][first:])
    for j, name in enumerate(FIELDS[:-1]):
        ref, x = np.asarray(block[name], float)[first:], got[first:, j]
        assert np.array_equal(np.isnan(ref), np.isnan(x)), name
        scale = np.nanmax(np.abs(ref)) if np.any(np.isfinite(ref)) else 0.0
        assert np.nanmax(np.abs(ref - x), initial=0.0) <= 1e-12 * scale, (model, name)
    return block


def tensile(n=1500, dt=1e-3, amplitude=2600.0):
    t = np.arange(n) * dt
    lam = 1.0 + 0.25 * (1.0 - np.cos(2 * np.pi * 0.7 * t))
    return t, lam, amplitude * np.sin(2 * np.pi * t) ** 2


@pytest.mark.parametrize("model", ["su", "1r", "3r", "cr"])
def test_stepped_equals_block_on_the_specimen(model):
    assert_equal_to_block(CARD, TABLE3, model, *tensile())


@pytest.mark.parametrize("model", ["su", "3r"])
def test_stepped_equals_block_finite_strain_and_damper(model):
    """From the second sample on: the first one's damper rate is the first interval's slope in a series."""
    t, lam, v = tensile(800)
    assert_equal_to_block(CARD, FINITE, model, t, lam, v, first=1)


@pytest.mark.parametrize("model", ["1r", "3r", "cr"])
def test_stepped_equals_block_across_folds_and_slack(model):
    """The hollow core: voltage loops to 15 kV and back at two stretches (snaps, states beyond the solved
    range, hysteresis, slack): the reference's samples inside a stepped run."""
    up = np.linspace(0.0, 15000.0, 25)
    v = np.tile(np.r_[up, up[::-1]], 2)
    lam = np.repeat([1.5, 3.0], 2 * up.size)
    t = np.arange(v.size) * 1e-2
    status = assert_equal_to_block(HOLLOW, WEAK, model, t, lam, v)["model_status"]
    assert np.any(status == SLACK) and np.any(np.isin(status, (SNAPPED, OUTSIDE_RANGE)))  # the hard cases


#: a solid roll (Ri = 0) past its pitchfork: the hole opens (a snap where it is subcritical) and closes again
SOLID = RollGeometry(0.0, 0.6026e-3, 1.6211e-3, 1.7393e-3, L1=34e-3, L1e=29e-3, L3=48e-6)


def test_stepped_equals_block_where_a_solid_rolls_hole_opens():
    up = np.linspace(0.0, 12000.0, 40)
    v = np.tile(np.r_[up, up[::-1]], 3)
    lam = np.repeat([1.0, 1.3, 2.0], 2 * up.size)
    status = assert_equal_to_block(SOLID, TABLE3, "3r", np.arange(v.size) * 1e-2, lam, v)["model_status"]
    assert np.any(status == SNAPPED)


#: a hollow roll with a micro-core (Ri / Ro 1e-5): where the reference grades its scan toward the core, the
#: step must take the same nodes
MICRO = RollGeometry(1.8e-8, 0.3e-3, 1.62e-3, 1.8e-3, L1=34e-3, L1e=29e-3, L3=48e-6)


def test_stepped_equals_block_on_a_micro_core():
    up = np.linspace(0.0, 12000.0, 40)
    v = np.tile(np.r_[up, up[::-1]], 2)
    lam = np.repeat([1.0, 1.6], 2 * up.size)
    assert_equal_to_block(MICRO, TABLE3, "3r", np.arange(v.size) * 1e-2, lam, v)


@pytest.mark.parametrize(("model", "case"), [("1r", "folds"), ("3r", "folds"), ("3r", "pitchfork")])
def test_no_finite_sample_leaves_the_compiled_step(model, case, monkeypatch):
    """Folds, snaps, pull-in, states beyond the range, slack: the compiled step decides every sample with a
    finite stretch >= 1 and voltage (the reference solver is not called); the numbers are the block's
    (the tests above)."""
    if case == "folds":
        geom, params, up = HOLLOW, WEAK, np.linspace(0.0, 15000.0, 25)
        lam = np.repeat([1.0, 1.5, 3.0], 2 * up.size)
    else:
        geom, params, up = SOLID, TABLE3, np.linspace(0.0, 12000.0, 40)
        lam = np.repeat([1.0, 1.3, 2.0], 2 * up.size)
    v = np.tile(np.r_[up, up[::-1]], 3)
    twin = TwinStep(geom, params, model)
    monkeypatch.setattr(twin, "_reference", lambda *a: pytest.fail(f"the reference solved sample {a}"))
    status = [int(twin.step(t, a, b)[-1]) for t, a, b in zip(np.arange(v.size) * 1e-2, lam, v)]
    assert len(set(status)) >= 3  # not one easy outcome


def test_nan_sample_is_bad_input_and_the_branches_carry_on():
    t, lam, v = tensile(300)
    lam[100] = np.nan
    v[200] = np.nan
    block = assert_equal_to_block(CARD, TABLE3, "3r", t, lam, v)
    assert block["model_status"][100] == BAD_INPUT and block["model_status"][200] == BAD_INPUT


def test_time_must_increase():
    twin = TwinStep(CARD, TABLE3, "su")
    twin.step(0.0, 1.1, 0.0)
    with pytest.raises(ValueError, match="not after the previous sample"):
        twin.step(0.0, 1.1, 0.0)


def test_no_allocation_per_step_and_one_output_array():
    """No Python object outlives a step (the interpreter's count of allocated blocks stays put over 2800
    steps; a leak of one object per step would add 2800) and the output is one array, overwritten.
    The count is the whole process's: the least growth of three rounds, so that what another thread
    allocates meanwhile (xdist's messaging in a worker) is not counted as the step's."""
    twin = TwinStep(CARD, TABLE3, "3r")
    t, lam, v = (a.tolist() for a in tensile(3000))
    first = twin.step(t[0], lam[0], v[0])
    grown = []
    for _ in range(3):
        twin.reset()
        for i in range(200):  # warm
            twin.step(t[i], lam[i], v[i])
        before = sys.getallocatedblocks()
        for i in range(200, 3000):
            out = twin.step(t[i], lam[i], v[i])
        grown.append(sys.getallocatedblocks() - before)
        assert out is first
    assert min(grown) < 100, f"{grown} blocks more after 2800 steps"


def test_reset_starts_over():
    twin = TwinStep(CARD, TABLE3, "su")
    t, lam, v = tensile(50)
    a = [twin.step(*s)[FORCE] for s in zip(t, lam, v)]
    twin.reset()
    b = [twin.step(*s)[FORCE] for s in zip(t, lam, v)]
    assert a == b


def test_unknown_model_and_strip_refused():
    with pytest.raises(ValueError, match="model 'x'; allowed: su, 1r, 3r, cr"):
        TwinStep(CARD, TABLE3, "x")
    strip = load_specimen(PROJECT / "specimens" / "vhb4910_strip.yaml")
    with pytest.raises(Exception, match="3R model describes a roll"):
        TwinStep(strip, TABLE3, "3r")


#: A hollow roll with a 40 nm hole (Ri/Ro = 2e-5) on a softening material: its 3R branch folds within
#: 1 um of the axis (at about 545-600 V), far below the regular scan nodes; the step scans the nodes graded
#: toward the core that the reference scans (`three_ring.core_scale`), and hands the fold's samples over.
MICRO = RollGeometry(40e-9, 2.2e-6, 0.56e-3, 2e-3, L1=30e-3, L1e=30e-3, L3=50e-6)
MICRO_MAT = ParameterSet(name="soft", C10=180e3, C20=-37e3, C30=6.3e3, eps_r=4.0,
                         branches=(ViscoBranch(k=1e5, eta=1e4),))


def test_stepped_equals_block_across_a_micro_core_fold():
    up = np.linspace(0.0, 900.0, 31)
    v = np.tile(np.r_[up, up[::-1]], 2)
    lam = np.repeat([1.1, 1.3], 2 * up.size)
    t = np.arange(v.size) * 1e-2
    status = assert_equal_to_block(MICRO, MICRO_MAT, "3r", t, lam, v)["model_status"]
    assert np.count_nonzero(status == SNAPPED) >= 2  # the fold is crossed (up and down)


@pytest.mark.parametrize("model, Ri", [("1r", 0.0), ("3r", 0.0), ("3r", 0.5e-3)])
def test_the_free_states_fields_are_the_state_solved_at_its_stretch(model, Ri):
    """`step_kernel._free` returns the fields of its search's last trial (the stretch it returns) instead of
    solving that state again: they must be the state `_state` solves afresh there, and pass the final check."""
    import dataclasses
    import math

    from rdea_lab.physics import step_kernel as sk
    from rdea_lab.physics.geometry import geometry_from_card

    geom = geometry_from_card(CARD)
    if Ri:
        geom = dataclasses.replace(geom, Ri=Ri)
    code, P, R, B, off, fork = sk.constants(model, geom, TABLE3, (), (), 0.0, "linear")
    found_any = 0
    for l1 in (1.0, 1.02, 1.1):
        for v in (2600.0, 4000.0, 6000.0):
            s, _, _, y, st, _, _ = sk._state(code, P, R, B, off, fork, l1, v, math.nan, False, 0, math.nan, False)
            if not (st == 0 and s < 0.0):
                continue
            cap, l2b, found, x = sk._free(code, P, R, B, off, fork, l1, v, s, y, np.empty(5))
            if not found:
                continue
            found_any += 1
            sig2, cap2, l2b2, _, st2, _, _ = sk._state(code, P, R, B, off, fork, x, v, y, False, 0, 0.0, True)
            assert st2 in (0, SNAPPED) and abs(sig2) <= 1e-6 * abs(s) + 1e-6
            assert (cap, l2b) == (cap2, l2b2) and x > l1
    assert found_any >= 2  # slack samples with a free state were tried
