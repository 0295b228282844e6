"""`rdea_lab.physics.designs.solve_designs` against a per-roll loop over the ordinary `solve`.

solve_designs maps many rolls onto one reference roll by an effective voltage
``v sqrt(kappa_d / kappa_ref)`` and scales force and capacitance by the
cross-sections and C0s. The reference here is what that mapping stands in for:
one `rdea_lab.physics.models.solve` call per roll with a scalar `RollGeometry`
and that roll's own scalar material. Every field must agree to 1e-12 of the
roll's largest magnitude of that field (the mapped call sees ``kappa_ref
(v gain)**2`` where the loop sees ``kappa_d v**2``: equal to a few ulps, and
every solver step after that is the same arithmetic), statuses exactly. Nearer a fold (1e-6 to 1e-14
of its load) a state moves by those ulps over h', which vanishes at the fold: there the bound that
solve_designs documents is tested instead.
Histories reach the hard states on purpose: slack (low stretch, high
voltage), and for 1R voltages a hair below and above each roll's own fold and
range end.

3R and CR are not mapped: each roll is solved with its own radii (the compiled
per-sample states over designs x samples, the rest by `solve` per roll); the
same per-roll loop is their reference, with the numpy solver (kernel="numpy").

Also here: `radii_from_membrane` over arrays (entry by entry equal to the
scalar call; NaN or ValueError for membranes that roll into no roll; the
rolled volume equals the flat one) and `RollGeometry` with array fields.
"""

from __future__ import annotations

import importlib.util
from types import SimpleNamespace

import numpy as np
import pytest

from rdea_lab.physics.designs import Material, design_geometry, solve_designs
from rdea_lab.physics.geometry import RollGeometry, radii_from_membrane
from rdea_lab.physics.models import solve
from rdea_lab.physics.models._common import kappa
from rdea_lab.physics.result import LIMIT_POINT, OK, OUTSIDE_RANGE, SLACK, SNAPPED

from physics_cases import assert_close

#: Fields of DesignResult compared with the per-roll ModelResult.
FIELDS = ("force", "sigma1", "tension", "capacitance", "lambda2b", "free_stretch", "critical_voltage",
          "range_voltage")
#: Relative to the roll's largest |value| of the field (see the module docstring).
RTOL = 1e-12
#: Table 3 of the paper as corrected in ERRATA (params/paper2021_table3.yaml).
TABLE3 = SimpleNamespace(C10=242e3, C20=-69e3, C30=47e3, eps_r=2.8)
#: A barely admissible Yeoh material (dW/dI1 dips to a few per cent of C10): its 1R branch folds,
#: snaps and leaves the solved range within a few kV (as in test_random_cases' "kind > 0.85").
FOLDING = SimpleNamespace(C10=100e3, C20=-100e3 * 10**-1.5, C30=(100e3 * 10**-1.5) ** 2 / (3 * 100e3) * 1.2,
                          eps_r=2.8)


# ------------------------------------------------------------------ random membranes
def random_membranes(rng, n):
    """Unwound membranes [m]; some roll into no roll (electrode shorter than the first turn, or
    ``Lp1 + L2e > L2``)."""
    L3 = rng.uniform(20e-6, 80e-6, n)
    Lp1 = rng.uniform(0.0, 15e-3, n)
    L2e = rng.uniform(0.5e-3, 80e-3, n)
    L2 = Lp1 + L2e + rng.uniform(-5e-3, 20e-3, n)
    Ri = np.where(rng.random(n) < 0.5, 0.0, rng.uniform(0.05e-3, 1e-3, n))
    return L2, L3, Lp1, L2e, Ri


def test_radii_from_membrane_over_arrays_equal_the_scalar_call():
    rng = np.random.default_rng(20240501)
    L2, L3, Lp1, L2e, Ri = random_membranes(rng, 200)
    arr = radii_from_membrane(L2, L3, Lp1, L2e, Ri, check=False)
    n_bad = 0
    for i in range(L2.size):
        args = (float(L2[i]), float(L3[i]), float(Lp1[i]), float(L2e[i]), float(Ri[i]))
        one = radii_from_membrane(*args, check=False)
        impossible = not (L2e[i] - one["L_pa"] > 0 and L2[i] - Lp1[i] - L2e[i] >= 0)
        if impossible:
            n_bad += 1
            with pytest.raises(ValueError):
                radii_from_membrane(*args)
            assert all(np.isnan(arr[k][i]) for k in ("Ri", "Rie", "Roe", "Ro")), i
            continue  # the scalar call's NaN: test_radii_from_membrane_scalar_check_false_gives_nan
        assert one == radii_from_membrane(*args)  # check=True changes nothing for a good membrane
        for key, value in one.items():
            # Newton in spiral_angle steps on until the slowest entry of the array has converged,
            # so an entry may move by an ulp or two from its scalar value
            assert arr[key][i] == pytest.approx(value, rel=1e-14, abs=1e-300), (i, key)
    assert 10 < n_bad < 190  # both kinds of membrane are drawn


def test_radii_from_membrane_conserve_volume_over_arrays():
    """pi (Ro**2 - Ri**2) = 2 L2 L3: the two membranes' cross-section, rolled or flat."""
    rng = np.random.default_rng(7)
    L2, L3, Lp1, L2e, Ri = random_membranes(rng, 300)
    r = radii_from_membrane(L2, L3, Lp1, L2e, Ri, check=False)
    good = np.isfinite(r["Ro"])
    assert good.sum() > 100
    np.testing.assert_allclose(np.pi * (r["Ro"][good] ** 2 - r["Ri"][good] ** 2), 2 * L2[good] * L3[good],
                               rtol=1e-12, atol=0)
    # the radii are ordered for every roll, and every entry is a roll or NaN throughout
    Ri, Rie, Roe, Ro = (r[k][good] for k in ("Ri", "Rie", "Roe", "Ro"))
    assert np.all((Ri <= Rie) & (Rie < Roe) & (Roe <= Ro))
    assert all(np.isnan(r[k][~good]).all() for k in ("Ri", "Rie", "Roe", "Ro"))


def test_radii_from_membrane_check_raises_for_an_impossible_entry():
    L2 = np.array([99e-3, 99e-3, 50e-3])
    L2e = np.array([76e-3, 76e-3, 76e-3])  # entry 2: Lp1 + L2e = 86 mm > L2 = 50 mm
    with pytest.raises(ValueError, match=r"exceeds L2 .*entry 2 of 3"):
        radii_from_membrane(L2, 48e-6, 10e-3, L2e)
    short = np.array([76e-3, 1e-3])  # entry 1: 1 mm, shorter than the first turn (about 3.8 mm)
    with pytest.raises(ValueError, match=r"L2e = 0\.001 m is shorter .*entry 1 of 2"):
        radii_from_membrane(99e-3, 48e-6, 10e-3, short)
    r = radii_from_membrane(99e-3, 48e-6, 10e-3, short, check=False)
    assert np.isfinite(r["Ro"][0]) and np.isnan(r["Ro"][1]) and np.isnan(r["Rie"][1])


@pytest.mark.parametrize("L2, L2e", [(50e-3, 76e-3), (99e-3, 1e-3)])  # Lp1 + L2e > L2; L2e < first turn
def test_radii_from_membrane_scalar_check_false_gives_nan(L2, L2e):
    as_array = radii_from_membrane(np.array([L2]), 48e-6, 10e-3, L2e, check=False)
    assert np.isnan(as_array["Ro"][0]) and np.isnan(as_array["Roe"][0])
    one = radii_from_membrane(L2, 48e-6, 10e-3, L2e, check=False)
    assert np.isnan(one["Roe"]) and np.isnan(one["Ro"]), one


def test_roll_geometry_with_array_fields_refuses_out_of_order_radii():
    ok = dict(Ri=np.zeros(3), Rie=np.array([0.6e-3, 0.5e-3, 0.4e-3]), Roe=np.array([1.6e-3, 1.2e-3, 1.0e-3]),
              Ro=np.array([1.7e-3, 1.3e-3, 1.1e-3]), L1=0.034, L1e=0.029, L3=48e-6)
    RollGeometry(**ok)
    bad = dict(ok, Roe=np.array([1.6e-3, 0.45e-3, 1.0e-3]))  # entry 1: Roe < Rie
    with pytest.raises(ValueError, match=r"0 <= Ri <= Rie < Roe <= Ro, got Ri=0, Rie=0\.0005, Roe=0\.00045"):
        RollGeometry(**bad)
    bad = dict(ok, Ro=np.array([1.7e-3, 1.3e-3, 0.9e-3]))  # entry 2: Ro < Roe
    with pytest.raises(ValueError, match=r"Roe=0\.001, Ro=0\.0009 m"):
        RollGeometry(**bad)
    with pytest.raises(ValueError, match=r"radii must satisfy"):
        design_geometry(**dict(ok, Ri=np.array([0.0, 0.6e-3, 0.0])))  # entry 1: Ri > Rie


# ------------------------------------------------------------------ solve_designs vs per roll
def random_rolls(rng, n, L3_range=(20e-6, 80e-6)):
    """``n`` rolls from random good membranes: (design geometry, list of scalar RollGeometry)."""
    L2, L3, Lp1, L2e, Ri = [], [], [], [], []
    while len(L2) < n:
        m = random_membranes(rng, 1)
        r = radii_from_membrane(*m, check=False)
        if np.isfinite(r["Ro"][0]):
            for lst, v in zip((L2, L3, Lp1, L2e, Ri), m):
                lst.append(float(v[0]))
    L2, L3, Lp1, L2e, Ri = map(np.array, (L2, L3, Lp1, L2e, Ri))
    L3 = np.interp(L3, (20e-6, 80e-6), L3_range)
    r = radii_from_membrane(L2, L3, Lp1, L2e, Ri, check=False)
    L1 = rng.uniform(10e-3, 60e-3, n)
    L1e = L1 * rng.uniform(0.5, 1.0, n)
    geom = design_geometry(Ri=r["Ri"], Rie=r["Rie"], Roe=r["Roe"], Ro=r["Ro"], L1=L1, L1e=L1e, L3=L3)
    rolls = [RollGeometry(*(float(getattr(geom, k)[i]) for k in ("Ri", "Rie", "Roe", "Ro", "L1", "L1e", "L3")))
             for i in range(n)]
    return geom, rolls


def per_roll(model, rolls, materials, stretch, voltage, **kw):
    """The reference: one ordinary solve per roll, its own scalar geometry and material."""
    n = len(rolls)
    s = np.broadcast_to(stretch, (n, np.shape(stretch)[-1]))
    v = np.broadcast_to(voltage, s.shape)
    return [solve(model, rolls[d], materials[d], s[d], v[d], **kw) for d in range(n)]


def assert_same_as_per_roll(res, refs, what):
    assert res.force.shape == (len(refs), np.size(refs[0].force)), what
    for d, ref in enumerate(refs):
        assert np.array_equal(res.status[d], ref.status), f"{what} roll {d}: status {res.status[d]} != {ref.status}"
        for name in FIELDS:
            x = np.asarray(getattr(res, name)[d], float)
            assert_close(x, np.broadcast_to(np.asarray(getattr(ref, name), float), x.shape), f"{what} roll {d}: {name}",
                         RTOL)


def material_list(mat, n, **per_design):
    return [SimpleNamespace(**{k: float(per_design[k][d]) if k in per_design else float(getattr(mat, k))
                               for k in ("C10", "C20", "C30", "eps_r")}) for d in range(n)]


#: One history for every roll: stretch x voltage, from taut to slack (1.0 and 1.001 go slack at
#: any voltage; 12 kV slackens most stretches).
_S, _V = np.meshgrid([1.0, 1.001, 1.02, 1.1, 1.3, 1.6, 2.0], [0.0, 1e3, 3e3, 6e3, 12e3])
SHARED_STRETCH, SHARED_VOLTAGE = _S.ravel(), _V.ravel()


@pytest.mark.parametrize("model", ["su", "1r"])
def test_solve_designs_equals_per_roll_with_eps_r_per_design(model):
    rng = np.random.default_rng([11, len(model)])
    n = 10
    geom, rolls = random_rolls(rng, n)
    eps_r = rng.uniform(2.0, 5.0, n)
    mat = Material.of(TABLE3, eps_r=eps_r)
    for slack in (True, False):
        res = solve_designs(model, geom, mat, SHARED_STRETCH, SHARED_VOLTAGE, slack=slack)
        refs = per_roll(model, rolls, material_list(TABLE3, n, eps_r=eps_r), SHARED_STRETCH, SHARED_VOLTAGE,
                        slack=slack)
        assert_same_as_per_roll(res, refs, f"{model} slack={slack}")
        statuses = set(np.concatenate([r.status for r in refs]).tolist())
        assert {OK, SLACK} <= statuses if slack else OK in statuses


def test_solve_designs_su_with_yeoh_coefficients_per_design():
    rng = np.random.default_rng(23)
    n = 12
    geom, rolls = random_rolls(rng, n)
    C10 = rng.uniform(100e3, 300e3, n)
    C20 = C10 * rng.uniform(-0.3, 0.1, n)
    # dW/dI1 > 0 for every I1 needs C20**2 < 3 C10 C30 where C20 < 0
    C30 = np.where(C20 < 0, 1.2 * C20**2 / (3 * C10), 0.0) + C10 * rng.uniform(0.0, 0.2, n)
    eps_r = rng.uniform(2.0, 5.0, n)
    mat = Material(C10, C20, C30, eps_r)
    # per-design histories too: each roll its own stretches and voltages, (n, samples)
    stretch = np.concatenate([np.broadcast_to(SHARED_STRETCH, (n, SHARED_STRETCH.size)),
                              rng.uniform(1.0, 2.2, (n, 20))], axis=1)
    voltage = np.concatenate([np.broadcast_to(SHARED_VOLTAGE, (n, SHARED_VOLTAGE.size)),
                              rng.uniform(0.0, 10e3, (n, 20))], axis=1)
    refs = per_roll("su", rolls, material_list(mat, n, C10=C10, C20=C20, C30=C30, eps_r=eps_r), stretch, voltage)
    # numba: each design's own kappa and Yeoh coefficients in the compiled per-sample loop (design_kernels)
    for kernel in ("numpy", "auto", "numba") if importlib.util.find_spec("numba") else ("numpy", "auto"):
        assert_same_as_per_roll(solve_designs("su", geom, mat, stretch, voltage, kernel=kernel), refs,
                                f"su per-design Yeoh kernel={kernel}")
    assert {OK, SLACK} <= set(np.concatenate([r.status for r in refs]).tolist())


def fold_history(rng, rolls, mats, n_random=6):
    """Per roll (n, samples): random (stretch, voltage) plus, at a few stretches, voltages 1e-7 below and
    above the roll's own fold and range end (found with the ordinary solve on a voltage scan: where the
    samples go, not what they must give)."""
    rows_s, rows_v = [], []
    for roll, mat in zip(rolls, mats):
        s, v = list(rng.uniform(1.0, 2.0, n_random)), list(rng.uniform(0.0, 8e3, n_random))
        for l1 in (1.0, 1.2, 1.5):
            scan = np.linspace(0.0, 30e3, 31)
            r = solve("1r", roll, mat, np.full(scan.size, l1), scan, slack=False)
            marks = np.r_[r.critical_voltage[np.isfinite(r.critical_voltage)][:1],
                          r.range_voltage[np.isfinite(r.range_voltage)][:1]]
            for vm in marks:
                s += [l1, l1]
                v += [vm * (1 - 1e-7), vm * (1 + 1e-7)]
        rows_s.append(s)
        rows_v.append(v)
    width = max(map(len, rows_s))
    pad = lambda rows, fill: np.array([r + [fill] * (width - len(r)) for r in rows])  # noqa: E731
    return pad(rows_s, 1.3), pad(rows_v, 1e3)


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_solve_designs_1r_near_folds_equals_per_roll(kernel):
    rng = np.random.default_rng(31)
    n = 6
    geom, rolls = random_rolls(rng, n, L3_range=(40e-6, 80e-6))
    eps_r = rng.uniform(2.0, 4.0, n)
    mats = material_list(FOLDING, n, eps_r=eps_r)
    stretch, voltage = fold_history(rng, rolls, mats)
    mat = Material.of(FOLDING, eps_r=eps_r)
    for slack in (True, False):
        refs = per_roll("1r", rolls, mats, stretch, voltage, slack=slack, kernel="numpy")
        res = solve_designs("1r", geom, mat, stretch, voltage, slack=slack, kernel=kernel)
        assert_same_as_per_roll(res, refs, f"1r near folds slack={slack} kernel={kernel}")
        statuses = set(np.concatenate([r.status for r in refs]).tolist())
        assert {OK, SNAPPED, OUTSIDE_RANGE} <= statuses, statuses


def test_solve_designs_1r_limit_points_equal_per_roll():
    """A material whose 1R branch folds with no stable state after it in range: LIMIT_POINT."""
    rng = np.random.default_rng(41)
    n = 5
    geom, rolls = random_rolls(rng, n)
    # dW/dI1 dips to 10 % of C10 near I1 - 3 = 100 and stiffens too late for the solved range
    mat = SimpleNamespace(C10=100e3, C20=-1e3, C30=1.1 * 1e3**2 / (3 * 100e3), eps_r=2.8)
    stretch, voltage = fold_history(rng, rolls, [mat] * n)
    refs = per_roll("1r", rolls, [mat] * n, stretch, voltage, slack=False)
    assert_same_as_per_roll(solve_designs("1r", geom, mat, stretch, voltage, slack=False), refs, "1r limit points")
    statuses = set(np.concatenate([r.status for r in refs]).tolist())
    assert {OK, LIMIT_POINT} <= statuses, statuses
    crit = np.concatenate([r.critical_voltage for r in refs])
    assert np.isfinite(crit).sum() >= n  # each roll's pull-in voltage, compared above


def test_solve_designs_one_scalar_roll_is_the_ordinary_solve():
    roll = RollGeometry(0.0, 0.6e-3, 1.6e-3, 1.7e-3, 0.034, 0.029, 48e-6)
    res = solve_designs("su", roll, TABLE3, SHARED_STRETCH, SHARED_VOLTAGE)
    assert_same_as_per_roll(res, [solve("su", roll, TABLE3, SHARED_STRETCH, SHARED_VOLTAGE)], "one roll")


def test_solve_designs_refuses_what_it_cannot_solve():
    rng = np.random.default_rng(3)
    geom, _ = random_rolls(rng, 3)
    with pytest.raises(ValueError, match=r"unknown model '2r'; allowed: su, 1r, 3r, cr"):
        solve_designs("2r", geom, TABLE3, [1.1], [1e3])
    with pytest.raises(ValueError, match=r"1R branch solver takes one material"):
        solve_designs("1r", geom, Material.of(TABLE3, C10=[200e3, 240e3, 260e3]), [1.1], [1e3])
    with pytest.raises(ValueError, match=r"do not broadcast against 3 designs"):
        solve_designs("su", geom, TABLE3, np.full((2, 3, 4), 1.1), [1e3])  # 3-D: the function's own message


def test_solve_designs_names_a_history_of_the_wrong_number_of_designs():
    geom, _ = random_rolls(np.random.default_rng(3), 3)
    with pytest.raises(ValueError, match=r"do not broadcast against 3 designs"):
        solve_designs("su", geom, TABLE3, np.full((2, 4), 1.1), [1e3])


# ------------------------------------------------------------------ 3R and CR: each roll its own radii
def path_history(rng, n, samples=30):
    """Per roll (n, samples): a stretch up and down between 1 and 1.8 while the voltage ramps to a random
    peak of 4-14 kV and back (slack at the low stretches, and for 3R solid rolls past the hole's opening)."""
    u = np.linspace(0.0, 1.0, samples)
    tri = 1.0 - np.abs(2.0 * u - 1.0)
    stretch = 1.0 + rng.uniform(0.3, 0.8, (n, 1)) * np.sin(np.pi * 3 * u) ** 2
    voltage = rng.uniform(4e3, 14e3, (n, 1)) * tri
    return stretch, voltage


@pytest.mark.parametrize("model,kernel", [("3r", "auto"), ("cr", "auto"), ("cr", "numpy")])
def test_solve_designs_3r_cr_equal_per_roll_with_own_radii_and_material(model, kernel):
    """Random rolls (half solid, half on a hollow core), each with its own Yeoh coefficients and eps_r:
    every field to 1e-12, statuses identical, with the rising-ramp rule and on a path, slack or not."""
    rng = np.random.default_rng([41, len(model), len(kernel)])
    n = 6
    geom, rolls = random_rolls(rng, n)
    C10 = rng.uniform(150e3, 300e3, n)
    C20 = C10 * rng.uniform(-0.3, 0.0, n)
    C30 = 1.2 * C20**2 / (3 * C10) + C10 * rng.uniform(0.0, 0.1, n)  # dW/dI1 > 0
    eps_r = rng.uniform(2.0, 5.0, n)
    mat = Material(C10, C20, C30, eps_r)
    mats = material_list(mat, n, C10=C10, C20=C20, C30=C30, eps_r=eps_r)
    stretch, voltage = path_history(rng, n)
    seen = set()
    for path in (False, True):
        s, v = (stretch, voltage) if path else (np.broadcast_to(SHARED_STRETCH, (n, SHARED_STRETCH.size)),
                                                np.broadcast_to(SHARED_VOLTAGE, (n, SHARED_VOLTAGE.size)))
        for slack in (True, False):
            refs = per_roll(model, rolls, mats, s, v, slack=slack, path=path, kernel="numpy")
            res = solve_designs(model, geom, mat, s, v, slack=slack, path=path, kernel=kernel)
            assert_same_as_per_roll(res, refs, f"{model} path={path} slack={slack} kernel={kernel}")
            seen |= set(np.concatenate([r.status for r in refs]).tolist())
    assert {OK, SLACK} <= seen, seen
    assert (geom.Ri == 0).any() and (geom.Ri > 0).any()


@pytest.mark.slow  # it compiles the design loop's threaded variant, which no default test needs
@pytest.mark.parametrize("model", ["su", "3r"])
def test_solve_designs_on_threads_or_one_give_the_same_bits(model, monkeypatch):
    """The design loop's threaded variant (from `kernels.PARALLEL_MIN` samples on, a core free) against its
    one-thread form, on random rolls along paths: every field and status the same, bit for bit."""
    pytest.importorskip("numba")
    from rdea_lab.physics import kernels

    rng = np.random.default_rng([43, len(model)])
    n = 48
    geom, _ = random_rolls(rng, n)
    stretch, voltage = path_history(rng, n, samples=100)
    assert stretch.size >= kernels.PARALLEL_MIN
    got = {}
    for load in (float(kernels._CORES), 0.0):  # every core taken, then all free
        monkeypatch.setattr(kernels, "_other_load", lambda load=load: load)
        assert kernels._parallel(stretch.size) == (load == 0.0)
        got[load] = solve_designs(model, geom, TABLE3, stretch, voltage, path=True, kernel="numba")
    one, threads = got.values()
    assert np.array_equal(one.status, threads.status)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(one, name), getattr(threads, name), err_msg=name)
    assert {OK, SLACK} <= set(np.unique(one.status).tolist())


def test_solve_designs_3r_hands_uncertified_samples_to_solve():
    """Solid 3R rolls at voltages around their hole's opening (the pitchfork): the compiled states leave
    samples to `solve`, on a path in runs continued from the state before; the result is still the loop."""
    pytest.importorskip("numba")
    from rdea_lab.physics.design_kernels import rolls as compiled_rolls

    rng = np.random.default_rng(5)
    n = 4
    geom, rolls = random_rolls(rng, 3 * n)
    solid = [i for i in range(len(rolls)) if rolls[i].Ri == 0.0][:n]
    geom = design_geometry(**{k: np.asarray(getattr(geom, k))[solid] for k in ("Ri", "Rie", "Roe", "Ro", "L1",
                                                                              "L1e", "L3")})
    rolls = [rolls[i] for i in solid]
    stretch, voltage = path_history(rng, len(rolls), samples=60)
    voltage = voltage * 1.5
    rows = [(*(float(getattr(geom, k)[d]) for k in ("Ri", "Rie", "Roe", "Ro", "L1", "L1e", "L3")),
             TABLE3.C10, TABLE3.C20, TABLE3.C30, TABLE3.eps_r) for d in range(len(rolls))]
    got = compiled_rolls("3r", rows, stretch, voltage, path=True, slack=True)
    assert not got["ok"].all() and got["ok"].any()  # both kinds of sample are there
    refs = per_roll("3r", rolls, [TABLE3] * len(rolls), stretch, voltage, path=True, kernel="numpy")
    assert_same_as_per_roll(solve_designs("3r", geom, TABLE3, stretch, voltage, path=True), refs, "3r pitchfork")


def _h_1r(l2, l1, m):
    """1R by hand: the load ``K = kappa l1**2 v**2`` at which ``lambda2 = l2`` is an equilibrium (eq. 33:
    ``h = psi_2 / c_2``, ``c = l1**2 l2**2``), ``W1(x) (1 - l1**-2 l2**-4)``, and its slope ``dh/dl2``."""
    x = l1**2 + l2**2 + (l1 * l2) ** -2 - 3
    W1 = m.C10 + 2 * m.C20 * x + 3 * m.C30 * x**2
    q = 1 - l1**-2 * l2**-4
    return W1 * q, (2 * m.C20 + 6 * m.C30 * x) * (2 * l2 - 2 * l1**-2 * l2**-3) * q + W1 * 4 * l1**-2 * l2**-5


def test_solve_designs_within_1e_14_of_a_fold_keeps_the_documented_bound():
    """Right at a fold the mapping's rounding of the load (a few ulps) moves a state by dK / h'(y), and h'
    vanishes there: the documented bound |d lambda2| <= 16 eps K / |h'| + 4 eps lambda2 holds (h' by hand,
    not the solver's; measured up to 2.7 eps K / |h'|), and statuses are equal from 1e-14 of the fold's
    load on. Loads 1e-6 to 1e-14 below and above the fold of FOLDING at three stretches (the fold found
    on the hand formula)."""
    from scipy.optimize import minimize_scalar

    rng = np.random.default_rng(53)
    n = 5
    geom, rolls = random_rolls(rng, n, L3_range=(40e-6, 80e-6))
    eps_r = rng.uniform(2.0, 4.0, n)
    mats = material_list(FOLDING, n, eps_r=eps_r)
    delta = np.r_[10.0 ** -np.arange(6, 15), -(10.0 ** -np.arange(6, 15))]  # below the fold, and above
    eps = np.finfo(float).eps
    worst = 0.0
    for l1 in (1.0, 1.2, 1.5):
        top = minimize_scalar(lambda t: -_h_1r(t, l1, FOLDING)[0], bounds=(l1**-0.5, 2.0 * l1**-0.5),
                              method="bounded", options={"xatol": 1e-13})
        K_f = -top.fun
        assert 0.0 < _h_1r(top.x, l1, FOLDING)[0] and abs(_h_1r(top.x, l1, FOLDING)[1]) < 1e-3 * K_f  # a fold
        K = K_f * (1.0 - delta)
        V = np.array([np.sqrt(K / (float(kappa(r, m)) * l1 * l1)) for r, m in zip(rolls, mats)])
        S = np.full_like(V, l1)
        refs = per_roll("1r", rolls, mats, S, V, slack=False, kernel="numpy")
        res = solve_designs("1r", geom, Material.of(FOLDING, eps_r=eps_r), S, V, slack=False, kernel="numpy")
        for d, ref in enumerate(refs):
            assert np.array_equal(res.status[d], ref.status), (l1, d, res.status[d], ref.status)
            assert set(ref.status[delta > 0].tolist()) == {OK} and set(ref.status[delta < 0].tolist()) == {SNAPPED}
            y = ref.lambda2b
            bound = 16.0 * eps * K / np.abs(_h_1r(y, l1, FOLDING)[1]) + 4.0 * eps * y
            err = np.abs(res.lambda2b[d] - y)
            assert np.all(err <= bound), (l1, d, err / bound)
            worst = max(worst, float(np.max(err / y)))
    assert worst > 1e-12  # the states do move near the fold: the bound is what is tested, not equality
