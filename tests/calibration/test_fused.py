"""The objective's compiled residual pass (`rdea_lab.physics.models.su.residual_pass`) against the numpy composition it
replaces (`predict_force`: `rdea_lab.twin.compose` on the SU stress basis): the same numbers to the last bit,
so a fit takes the same path, evaluation for evaluation (issue 30, reproduce's calibration stage)."""

import numpy as np
import pytest

from rdea_lab.calibration import Budget, calibrate, gather_runs, initial_guess
from rdea_lab.calibration import objective
from rdea_lab.calibration.branches import calibrate_auto
from rdea_lab.specs import ViscoBranch

from calibration_cases import SPECIMEN2, TABLE3

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def runs():
    return gather_runs([SPECIMEN2])


def reference(runs, params, model):
    """The residuals as `objective.residuals` composes them without the compiled pass."""
    return np.concatenate([(objective.predict_force(r, params, model) - r.force) * s
                           for r, s in zip(runs, objective.residual_scale(runs))])


def sets():
    two = TABLE3.branches + (ViscoBranch(k=2e5, eta=4e4),)
    return {"table 3": TABLE3, "no branch": TABLE3.replace(branches=()),
            "two branches, damper": TABLE3.replace(branches=two, eta_v0=3.4e5),
            "damper alone": TABLE3.replace(branches=(), eta_v0=1e3),
            # a soft material at 2.6 kV: the electrostatic stress pushes, many samples slack (force clipped)
            "slack": TABLE3.replace(C10=2e3, C20=0.0, C30=0.0)}


@pytest.mark.parametrize("name", list(sets()))
def test_the_compiled_residuals_are_those_of_the_numpy_composition_to_the_last_bit(runs, name):
    params = sets()[name]
    assert objective._fused_kernel() is not None  # the compiled pass is what is tested here
    got = objective.residuals(runs, params, "su")
    want = reference(runs, params, "su")
    assert np.array_equal(got, want), np.max(np.abs(got - want))
    if name == "slack":  # the clip acted: some samples read 0 N where the model pushes
        forces = np.concatenate([objective.predict_force(r, params, "su") for r in runs])
        assert np.any(forces == 0.0)


def test_another_model_at_voltage_keeps_the_numpy_composition(runs):
    """The pass is SU's stress basis: 1R at 2.6 kV solves the model (and 0 V runs still use the basis)."""
    got = objective.residuals(runs, TABLE3, "1r")
    assert np.array_equal(got, reference(runs, TABLE3, "1r"))


def _without_fused(monkeypatch):
    monkeypatch.setattr(objective, "_fused_kernel", lambda: None)


@pytest.mark.parametrize("method, evaluations", [("least-squares", 30), ("nelder-mead", 300)])
def test_a_fit_takes_the_same_path_with_and_without_the_compiled_pass(runs, monkeypatch, method, evaluations):
    """Within a budget (least squares: a few Jacobians; its SVD runs threaded under pytest, slow on a busy
    machine): the same evaluations, best point and history."""
    start, budget = initial_guess(runs, 1, 2.8), Budget(evaluations=evaluations)
    fast = calibrate(runs, start, model="su", method=method, warm_start="none", budget=budget)
    _without_fused(monkeypatch)
    slow = calibrate(runs, start, model="su", method=method, warm_start="none", budget=budget)
    assert fast.nfev == slow.nfev == evaluations and fast.objective == slow.objective
    assert fast.values == slow.values and np.array_equal(fast.history, slow.history)


@pytest.mark.slow
def test_reproduces_calibration_stage_finds_what_the_numpy_composition_finds(runs, monkeypatch):
    """`rdea-lab reproduce`'s fit (branches auto, 0 to 3) both ways: the same stages, evaluations, optimum and
    criterion. Within a budget that reaches the first M = 2 candidate (the whole fit takes a minute where
    BLAS runs threaded on a busy machine, as under pytest; `rdea-lab` runs it on one thread)."""
    start, budget = initial_guess(runs, 1, 2.8), Budget(evaluations=800)
    fast = calibrate_auto(runs, start, 3, model="su", budget=budget)
    _without_fused(monkeypatch)
    slow = calibrate_auto(runs, start, 3, model="su", budget=budget)
    assert [st["label"] for st in fast.stages] == [st["label"] for st in slow.stages]
    assert any(st["label"].startswith("M = 2") for st in fast.stages)  # the budget ran out growing to two
    assert fast.params.M == slow.params.M
    assert fast.nfev == slow.nfev and fast.objective == slow.objective
    assert fast.values == slow.values
    assert fast.branch_choice["tried"] == slow.branch_choice["tried"]
