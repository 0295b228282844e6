"""The compiled full scan and path rule (`rdea_lab.physics.scan_kernel`) against the numpy reference.

The reference is `branch._full_scan` and `branch.follow_path` (numpy, all samples at once); the compiled
code replays them for one sample at a time in the same floating-point operations. On the random
hard-case families of test_random_cases (1R, 3R and, where the roll has a core, CR) and on the named
hard cases of test_hard_cases, each a voltage series up past folds and the range's end and back down at
its stretch: the knots and extrema equal to 1e-12 (relative), the path's states, critical and range
loads to 1e-12 and its statuses identical, as a series (from the unloaded roll and from a given start
and label) and as descents from given origins. The default run takes a prefix of each family (a few
seconds); the full families run under ``-m slow``.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from rdea_lab.physics import branch  # noqa: E402
from rdea_lab.physics import scan_kernel as sk  # noqa: E402
from rdea_lab.physics.kernels import _EMPTY_Q, _table  # noqa: E402
from rdea_lab.physics.geometry import RollGeometry  # noqa: E402
from rdea_lab.physics.models import continuum, one_ring, three_ring  # noqa: E402
from rdea_lab.physics.result import LIMIT_POINT, OK, OUTSIDE_RANGE, SNAPPED  # noqa: E402

from physics_cases import RIZZELLO, TABLE3, core  # noqa: E402
from test_hard_cases import NEO, SOFT, SPECIMEN2, WEAK  # noqa: E402
from test_random_cases import GENERAL, SMALL  # noqa: E402

MODULES = {"1r": one_ring, "3r": three_ring, "cr": continuum}
RTOL = 1e-12
N_DEFAULT = {"general": 12, "small core": 6}
FAMILY = {"general": GENERAL, "small core": SMALL}


def _close(a, b, rtol=RTOL):
    a, b = np.asarray(a, float), np.asarray(b, float)
    same_nan = np.array_equal(np.isnan(a), np.isnan(b))
    d = np.abs(np.where(np.isnan(a), 0.0, a) - np.where(np.isnan(b), 0.0, b))
    return same_nan and bool(np.all(d <= rtol * np.maximum(np.abs(np.nan_to_num(b)), 1e-300)))


def _args(prob, i):
    """The compiled arguments of sample ``i`` of a problem: ``(code, l1, R, Q, C)``."""
    code, c = prob.kernel
    if code == 4:
        R = (float(c["xi0"][i]), float(c["x0"][i]), c["Lb"], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        return code, float(c["l1"][i]), R, _table(c["Q"]), c["C"]
    return code, float(c["l1"][i]), c.get("R", (0.0,) * 9), _EMPTY_Q, c["C"]  # read-only, as the package's


def compiled_path(prob, start=None, label=None, origin=None):
    """`follow_path` sample by sample through `scan_kernel.path_rule`."""
    n = prob.K.size
    offsets = np.ascontiguousarray(branch.scale_offsets(prob), float)
    h0 = prob.h_start(np.arange(n))
    y0 = np.broadcast_to(prob.y0, (n,))
    out = np.empty((n, 4))
    lost = np.zeros(n, bool)
    prev = float(y0[0]) if start is None else float(start)
    has_label, lab_s, lab_k = label is not None, *(label if label is not None else (0, np.nan))
    for i in range(n):
        code, l1, R, Q, C = _args(prob, i)
        yp = float(origin[i]) if origin is not None else prev
        y, st, kc, kr, lost[i] = sk.path_rule(code, l1, float(y0[i]), float(prob.y_max[i]), float(prob.K[i]),
                                              float(h0[i]), R, Q, *C, offsets, branch.N_SCAN, prob.pitchfork, yp,
                                              has_label, lab_s, lab_k, origin is not None, 1e-14, 100)
        out[i] = y, st, kc, kr
        prev, has_label, lab_s, lab_k = y, bool(lost[i]), st, kc
    return out, lost


def check_problem(prob, start=None, label=None):
    """Knots, extrema, the path (from the unloaded roll, and from ``start``/``label``) and descents from
    origins: compiled against reference. Returns the reference's statuses."""
    n = prob.K.size
    kx, kh, ey, eh, em = branch._full_scan(prob)
    offsets = np.ascontiguousarray(branch.scale_offsets(prob), float)
    h0 = prob.h_start(np.arange(n))
    y0 = np.broadcast_to(prob.y0, (n,))
    m = 1 + offsets.size + branch.N_SCAN
    for i in range(n):
        code, l1, R, Q, C = _args(prob, i)
        KX, KH, EY, EH, EM = np.empty(5 * m), np.empty(5 * m), np.empty(4 * m), np.empty(4 * m), np.empty(4 * m, bool)
        nk, ne = sk.scan(code, l1, float(y0[i]), float(prob.y_max[i]), float(h0[i]), R, Q, *C, offsets,
                         branch.N_SCAN, prob.pitchfork, KX, KH, EY, EH, EM)
        assert nk == m + ne and ne <= ey.shape[1] and np.all(np.isnan(ey[i, ne:]))
        # CR's quadrature sums in another order than numpy's matrix product (a few ulp): the golden section
        # then places a flat extremum differently within its conditioning, ~sqrt(eps) of the range
        x_tol = 1e-7 if code == 4 else RTOL
        assert _close(KX[:nk], kx[i, :nk], x_tol) and _close(KH[:nk], kh[i, :nk])
        assert _close(EY[:ne], ey[i, :ne], x_tol) and _close(EH[:ne], eh[i, :ne])
        assert np.array_equal(EM[:ne], em[i, :ne])
    statuses = []
    for s, lab in ((None, None), (start, label)):
        ref = branch.follow_path(prob, s, start_label=lab)
        got, lost = compiled_path(prob, s, lab)
        assert np.array_equal(got[:, 1].astype(np.int8), ref.status)
        assert _close(got[:, 0], ref.y) and _close(got[:, 2], ref.K_crit) and _close(got[:, 3], ref.K_range)
        if lost[-1]:  # the label the next block continues with
            assert ref.end[1][0] == int(got[-1, 1]) and _close([ref.end[1][1]], [got[-1, 2]])
        else:
            assert ref.end[1] is None
        statuses.append(ref.status)
    origin = prob.y0 + (prob.y_max - prob.y0) * np.linspace(0.0, 0.6, n) ** 2
    ref = branch.follow_path(prob, origin=origin)
    got, _ = compiled_path(prob, origin=origin)
    assert np.array_equal(got[:, 1].astype(np.int8), ref.status)
    assert _close(got[:, 0], ref.y) and _close(got[:, 2], ref.K_crit) and _close(got[:, 3], ref.K_range)
    statuses.append(ref.status)
    return np.concatenate(statuses)


def sweep(v_top, n=13):
    """A voltage series up to ``v_top`` and back down [V]."""
    up = np.linspace(0.0, v_top, n)
    return np.r_[up, up[::-1]]


def case_problems(case):
    """The case's voltages and twice its largest, up and down in order, at its stretch, for each model that
    applies (CR only to a roll with a core)."""
    v = np.sort(case.voltage)
    v = np.r_[v, 2.0 * v[-1], v[::-1]]
    l1 = np.full(v.size, case.stretch)
    models = ("1r", "3r", "cr") if case.geom.Ri > 0.0 else ("1r", "3r")
    return [MODULES[m].problem(case.geom, case.mat, l1, v) for m in models]


def run_family(family, n):
    seen = set()
    for case in FAMILY[family][:n]:
        for prob in case_problems(case):
            # a later block's start: a state high in the range, as a lost sample's label would continue
            st = check_problem(prob, float(prob.y_max[0]), (OUTSIDE_RANGE, np.nan))
            seen.update(st.tolist())
    return seen


@pytest.mark.parametrize("family", sorted(FAMILY))
def test_compiled_scan_and_path_equal_the_reference_on_random_cases(family):
    seen = run_family(family, N_DEFAULT[family])
    assert OK in seen


@pytest.mark.slow
@pytest.mark.parametrize("family", sorted(FAMILY))
def test_compiled_scan_and_path_equal_the_reference_on_all_random_cases(family):
    seen = run_family(family, len(FAMILY[family]))
    assert {OK, SNAPPED, LIMIT_POINT, OUTSIDE_RANGE} <= seen  # the hard outcomes are among them


HOLLOW = RollGeometry(0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3, L1=34e-3, L1e=34e-3, L3=48e-6)
HARD = [  # (geometry, material, largest voltage [V]) of test_hard_cases
    (core(SPECIMEN2, L1e=29e-3), TABLE3, 12000.0),  # the Ri = 0 pitchfork
    (core((0.88e-3 * (1 - 1e-9), 0.88e-3, 1.76e-3, 1.8e-3)), RIZZELLO, 8000.0),  # ring a vanishing
    (core((0.86e-3, 0.88e-3, 1.8e-3 * (1 - 1e-10), 1.8e-3)), RIZZELLO, 8000.0),  # ring c vanishing
    (core((1.70e-3, 1.705e-3, 1.795e-3, 1.8e-3)), RIZZELLO, 8000.0),  # a thin shell
    (HOLLOW, WEAK, 15000.0),  # folds, snaps and the range's end
    (HOLLOW, NEO, 15000.0),  # an asymptote: outside the range
    (HOLLOW, SOFT, 15000.0),
]


@pytest.mark.parametrize("k", range(len(HARD)))
def test_compiled_path_equals_the_reference_on_the_hard_cases(k):
    geom, mat, v_top = HARD[k]
    seen = set()
    for l1 in (1.0, 1.5, 3.0):
        v = sweep(v_top)
        stretch = np.full(v.size, l1)
        for name in ("1r", "3r", "cr") if geom.Ri > 0.0 else ("1r", "3r"):
            prob = MODULES[name].problem(geom, mat, stretch, v)
            seen.update(check_problem(prob, float(prob.y0[0]), (LIMIT_POINT, 1.0)).tolist())
    assert OK in seen
