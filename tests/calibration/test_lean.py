"""The objective's lean evaluation (`rdea_lab.calibration.methods._lean_residuals`: no parameter set built per
trial point, the runs' data prepared once) against the full one it stands for (`Objective.evaluate` building
each set, `_fast_builder`, and `residuals` composing it): the same refusals and residuals to the last bit, the
same Jacobian probes, so a fit takes the same path, evaluation for evaluation (issue 30, reproduce's
calibration stage)."""

import numpy as np
import pytest

from rdea_lab.calibration import Budget, calibrate, gather_runs, initial_guess, methods
from rdea_lab.calibration.branches import calibrate_auto
from rdea_lab.calibration.fit import fit_parameters
from rdea_lab.calibration.methods import Objective
from rdea_lab.calibration.parameters import values_of
from rdea_lab.specs import ViscoBranch

from calibration_cases import SPECIMEN2, TABLE3

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def runs():
    return gather_runs([SPECIMEN2])


def _full_path(monkeypatch):
    """Objectives made from here on evaluate through the full build (the path before the lean one)."""
    monkeypatch.setattr(methods, "_lean_residuals", lambda *a: None)


def objectives(runs, start, monkeypatch, metric="rms", fixed=(), hyperelastic="yeoh"):
    params = fit_parameters(start, set(values_of(start)) - set(fixed), hyperelastic)
    lean = Objective(runs, start, params, "su", metric, 10**6, 1e6)
    with monkeypatch.context() as m:
        _full_path(m)
        full = Objective(runs, start, params, "su", metric, 10**6, 1e6)
    assert lean._lean is not None and full._lean is None
    return lean, full


@pytest.mark.parametrize("M, metric, fixed, hyperelastic", [
    (0, "rms", (), "yeoh"), (1, "rms", (), "yeoh"), (3, "rms", (), "yeoh"),
    (2, "max", ("C30", "k_v1"), "yeoh"),  # the largest error; some parameters held
    (1, "rms", ("eta_v0",), "yeoh-monotone"),  # C20 a plain box, not the Yeoh margin
])
def test_the_lean_evaluation_is_the_full_one_to_the_last_bit(runs, monkeypatch, M, metric, fixed, hyperelastic):
    """Random points over the bounds (Nelder-Mead's variables; some not physical, refused by both) and
    least squares' [0, 1] variables (C20 as the Yeoh margin, or a plain box), their bounds included."""
    branches = (ViscoBranch(k=3e5, eta=9e4), ViscoBranch(k=1e5, eta=1.5e6), ViscoBranch(k=2e6, eta=2e3))[:M]
    start = TABLE3.replace(branches=branches, eta_v0=1e3)
    if hyperelastic == "yeoh-monotone":
        start = start.replace(C20=abs(start.C20))
    lean, full = objectives(runs, start, monkeypatch, metric, fixed, hyperelastic)
    rng = np.random.default_rng(M)
    refused = 0
    for _ in range(40):
        v = lean.values(rng.uniform(-np.pi / 2, np.pi / 2, len(lean.free)))
        (f1, r1), (f2, r2) = lean.evaluate(v), full.evaluate(v)
        assert (r1 is None) == (r2 is None) and f1 == f2, v
        if r1 is None:
            refused += 1
        else:
            assert np.array_equal(r1, r2), v
    # both kinds of point were tried (a monotone Yeoh material is admissible everywhere: none refused)
    assert refused < 40 and (refused > 0) == (hyperelastic != "yeoh-monotone")
    for _ in range(10):
        u = rng.uniform(0.0, 1.0, len(lean.free))
        u[rng.random(u.size) < 0.3] = rng.choice([0.0, 1.0])  # some at their bounds
        assert np.array_equal(lean.residual_vector(u), full.residual_vector(u))
    assert lean.nfev == full.nfev == 50  # every evaluation counted alike


def test_a_probes_values_are_those_of_the_whole_map(runs):
    """`Objective.values_unit_moved` (one variable moved) against `Objective.values_unit`, every variable
    (C10 and C30 move the Yeoh margin's C20 too)."""
    start = TABLE3.replace(branches=TABLE3.branches + (ViscoBranch(k=1e5, eta=1e6),), eta_v0=1e3)
    obj = Objective(runs, start, fit_parameters(start, set(values_of(start))), "su", "rms", 10, 10.0)
    assert obj._margin_slot() is not None
    rng = np.random.default_rng(7)
    for _ in range(20):
        u = rng.uniform(0.0, 1.0, len(obj.free))
        base = obj.values_unit(u)
        for i in range(u.size):
            moved = u.copy()
            moved[i] = min(max(u[i] + rng.choice([-1, 1]) * 1.49e-8, 0.0), 1.0)
            got, want = obj.values_unit_moved(moved, base, i), obj.values_unit(moved)
            assert list(got) == list(want) and all(got[n] == want[n] for n in want), (i, got, want)


def test_a_growing_fit_takes_the_same_path_with_and_without_the_lean_evaluation(runs, monkeypatch):
    """Branches auto up to one (least squares for M = 0 and 1, about 290 evaluations, then Nelder-Mead's
    polish until the budget stops it): the same evaluations, history, optimum and choice."""
    start, budget = initial_guess(runs, 1, 2.8), Budget(evaluations=350)
    lean = calibrate_auto(runs, start, 1, model="su", budget=budget)
    _full_path(monkeypatch)
    full = calibrate_auto(runs, start, 1, model="su", budget=budget)
    assert lean.stages[-1]["label"].endswith("Nelder-Mead polish") and lean.nfev == 350
    assert lean.nfev == full.nfev and [s["nfev"] for s in lean.stages] == [s["nfev"] for s in full.stages]
    assert lean.objective == full.objective and lean.values == full.values
    assert np.array_equal(lean.history, full.history)
    assert lean.branch_choice["tried"] == full.branch_choice["tried"]


@pytest.mark.slow
def test_reproduces_calibration_stage_is_the_same_with_and_without_the_lean_evaluation(runs, monkeypatch):
    """`rdea-lab reproduce`'s fit (branches auto, 0 to 3) to its end both ways."""
    start = initial_guess(runs, 1, 2.8)
    lean = calibrate_auto(runs, start, 3, model="su")
    _full_path(monkeypatch)
    full = calibrate_auto(runs, start, 3, model="su")
    assert [s["label"] for s in lean.stages] == [s["label"] for s in full.stages]
    assert lean.nfev == full.nfev and [s["nfev"] for s in lean.stages] == [s["nfev"] for s in full.stages]
    assert lean.objective == full.objective and lean.values == full.values
    assert np.array_equal(lean.history, full.history)


def test_least_squares_within_a_budget_counts_every_probe_alike(runs, monkeypatch):
    """A budget that stops least squares (every Jacobian probe counts): the same count, point and history."""
    start = initial_guess(runs, 1, 2.8)
    lean = calibrate(runs, start, model="su", method="least-squares", budget=Budget(evaluations=25))
    _full_path(monkeypatch)
    full = calibrate(runs, start, model="su", method="least-squares", budget=Budget(evaluations=25))
    assert lean.nfev == full.nfev == 25 and lean.message == full.message
    assert lean.values == full.values and np.array_equal(lean.history, full.history)
