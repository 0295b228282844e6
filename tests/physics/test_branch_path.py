"""rdea_lab.physics.branch.follow_path's and follow_branch's results: named fields, the same values as
their tuples."""

import numpy as np

from rdea_lab.physics.branch import BranchResult, PathResult, Problem, follow_branch, follow_path
from rdea_lab.physics.result import OK


def linear_problem(K):
    """psi = (y - 1)^2 / 2, c = y: h = psi_y / c_y = y - 1 rises everywhere, the one equilibrium y = 1 + K."""
    n = K.size

    def terms(y, idx, second):
        return y - 1.0, np.ones_like(y), np.ones_like(y), np.zeros_like(y)

    return Problem(terms, np.ones(n), np.full(n, 3.0), K, np.ones(n))


def test_follow_path_names_its_fields_and_unpacks_as_before():
    K = np.array([0.1, 0.5, 0.25])
    found = follow_path(linear_problem(K))
    assert isinstance(found, PathResult) and found._fields == ("y", "status", "K_crit", "K_range", "end")
    np.testing.assert_allclose(found.y, 1.0 + K, rtol=1e-12)  # the analytic equilibrium
    assert np.all(found.status == OK) and np.all(np.isnan(found.K_crit)) and np.all(np.isnan(found.K_range))
    assert found.end == (found.y[-1], None)
    y, status, K_crit, K_range, end = found  # a tuple too, in this order
    assert y is found.y and status is found.status and end is found.end


def test_an_empty_series_continues_from_its_start():
    found = follow_path(linear_problem(np.zeros(0)), 1.5, start_label=None)
    assert found.y.size == 0 and found.end == (1.5, None)


def test_follow_branch_names_its_fields_and_unpacks_as_before():
    K = np.array([0.0, 0.5, 1.25])
    found = follow_branch(linear_problem(K))
    assert isinstance(found, BranchResult) and found._fields == ("y", "status", "K_crit", "K_range")
    np.testing.assert_allclose(found.y, 1.0 + K, rtol=1e-12)  # the analytic equilibrium (y0 = 1 at K = 0)
    assert np.all(found.status == OK) and np.all(np.isnan(found.K_crit)) and np.all(np.isnan(found.K_range))
    y, status, K_crit, K_range = found  # a tuple too, in this order
    assert y is found.y and K_range is found.K_range
