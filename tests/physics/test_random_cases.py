"""The 1R and 3R solvers against a brute-force reference on seeded random rolls.

For a single (stretch, voltage) the rule is: the state a quasi-static voltage
ramp from 0 V reaches from the unloaded roll (``brute_force``). Each random
case is a roll, a Yeoh material and a stretch with five voltages (three drawn
up to 1.5 times the neo-Hookean asymptote, or around the voltage where a small
core's hole opens; two put by the reference's own landscape just below and
just above a fold, or either side of the range's largest voltage); the
solver's status and free coordinate are compared with the reference's:

* OK / SNAPPED: the reference reaches a state, the free coordinate agrees to
  ``Y_TOL`` (1e-6) of the admissible range, the snap flag agrees, and a
  SNAPPED sample's critical voltage is the first fold's;
* LIMIT_POINT only where the reference finds no state in range and the
  largest ``h`` in range is a fold's (a true fold with no stable state beyond
  it in range); critical voltage: that pull-in voltage, which with one fold
  is the first fold's;
* OUTSIDE_RANGE only where it finds no state and the largest ``h`` in range
  is at the range end (monotone, or climbing past every fold): critical
  voltage NaN; ``range_voltage``, where the result has it, the largest
  voltage with a state in range.

A sample the reference marks ambiguous (the voltage within 1e-6 of a fold's or
of the range end's, or the state at the range end) is counted, not compared.
The solver is called with ``slack=False`` where it offers the switch (the
equilibrium at the given stretch, which is what the reference computes; with
slack a roll that would push reports the state and status of its free
stretch instead); SLACK samples, if any remain, are skipped but counted.

A third family, 3R only, is hollow rolls with a micro-core (Ri/Ro from 1e-7 to
0.02, Rie close above it) on mostly fold-prone materials: their ``h`` folds
within a few ``Ri`` of the unloaded state, far below the scan's regular nodes
(the scan once stepped over it and returned the far state as OK).

The same voltages are also solved as one rising path (``path=True``,
`compare_path`): a rising series reaches the rising-ramp states, with the
snap-through flagged at the first sample past the first fold.

The default run takes the first 15 general, 8 small-core and 4 hollow
micro-core cases of the seeded families (`N_GENERAL_DEFAULT` ...); the full
2400 general, 800 small-core and 800 micro-core cases run under ``-m slow``
(measured here: 1R 4-7 min, 3R 7-10 min; micro-cores 5 min).
"""

from __future__ import annotations

import time
from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest

from rdea_lab.physics import result as _result
from rdea_lab.physics.constants import EPS0
from rdea_lab.physics.geometry import RollGeometry
from rdea_lab.physics.models import solve, three_ring

import brute_force as bf
from physics_cases import RIZZELLO, TABLE3, core

OK, LIMIT_POINT, BAD_INPUT, NOT_CONVERGED = _result.OK, _result.LIMIT_POINT, _result.BAD_INPUT, _result.NOT_CONVERGED
SNAPPED, OVERFLOW, OUTSIDE_RANGE, SLACK = _result.SNAPPED, _result.OVERFLOW, _result.OUTSIDE_RANGE, _result.SLACK
NAMES = {OK: "OK", LIMIT_POINT: "LIMIT_POINT", BAD_INPUT: "BAD_INPUT", NOT_CONVERGED: "NOT_CONVERGED",
         SNAPPED: "SNAPPED", OVERFLOW: "OVERFLOW", OUTSIDE_RANGE: "OUTSIDE_RANGE", SLACK: "SLACK"}
assert (bf.OK, bf.LIMIT_POINT, bf.SNAPPED, bf.OUTSIDE_RANGE) == (OK, LIMIT_POINT, SNAPPED, OUTSIDE_RANGE)

#: The rule under test is the equilibrium at the given stretch. Where the solver can clip a
#: roll that would push (status SLACK: the state of the free stretch instead, with its own
#: status), ask it for the equations' state, ``slack=False``.
TAUT = {"slack": False}

SEED = 20211105
N_GENERAL, N_SMALL, N_HOLLOW_MICRO = 2400, 800, 800
#: Cases of each family in the default (not slow) run: a prefix of the seeded lists (60, 30, 16, then 30, 15, 8
#: until the default suite neared CI's 4 minutes).
N_GENERAL_DEFAULT, N_SMALL_DEFAULT, N_HOLLOW_MICRO_DEFAULT = 15, 8, 4
#: Critical voltages agree to this: the reference's fold is the largest secant of h over
#: windows <= 1e-6 wide in c (and <= 1e-5 of the range on the uniform grid), which is
#: within ~1e-9 of the maximum of h; 1e-6 in voltage leaves a wide margin.
V_RTOL = 1e-6


def kappa(geom, mat):
    """Electrical factor ``eps0 eps_r alpha_e1 eta_b / (2 L3**2)`` [Pa/V^2] (ERRATA, ``C0 / Omega``)."""
    return EPS0 * mat.eps_r * geom.alpha_e1 * geom.eta_b / (2.0 * geom.L3**2)


# -------------------------------------------------------------------------------- random cases
def _material(rng):
    C10 = rng.uniform(20e3, 300e3)
    kind = rng.random()
    if kind < 0.1:  # neo-Hookean: h rises to an asymptote, no fold
        C20 = C30 = 0.0
    elif kind > 0.85:
        # barely admissible: dW/dI1 dips to a few per cent of C10 at large I1 - 3 = C10 / |C20|,
        # so the branch can fold and find no stiff state again in range (a true limit point)
        C20 = -C10 * 10.0 ** rng.uniform(-2.5, -1.0)
        C30 = C20 * C20 / (3.0 * C10) * rng.uniform(1.01, 1.5)
    else:
        C20 = C10 * rng.uniform(-0.4, 0.1)
        # dW/dI1 = C10 + 2 C20 x + 3 C30 x**2 > 0 for all x >= 0 needs C20**2 < 3 C10 C30 when C20 < 0
        low = 1.1 * C20 * C20 / (3.0 * C10) if C20 < 0 else 0.0
        C30 = rng.uniform(low, 0.3 * C10) if kind > 0.2 or C20 < 0 else 0.0
    return SimpleNamespace(C10=C10, C20=C20, C30=C30, eps_r=rng.uniform(2.0, 5.0))


def _fold_prone_material(rng):
    """A softening Yeoh material (C20 -0.2 to -0.4 C10, C30 1 to 10 times its admissible least): the
    solid roll's pitchfork is subcritical at small stretches, so a micro-core's roll folds near its core."""
    C10 = rng.uniform(20e3, 300e3)
    C20 = -C10 * rng.uniform(0.2, 0.4)
    C30 = C20 * C20 / (3.0 * C10) * 10.0 ** rng.uniform(0.0, 1.0)
    return SimpleNamespace(C10=C10, C20=C20, C30=C30, eps_r=rng.uniform(2.0, 5.0))


def _outer(rng, rho_ie):
    return 1.0 if rng.random() < 0.1 else rho_ie + (1.0 - rho_ie) * rng.uniform(0.2, 0.98)


def _case(rng, family, k):
    Ro = rng.uniform(0.5e-3, 3e-3)
    if family == "hollow micro-core":
        # a hollow roll whose hole is nanometres to tens of micrometres wide (Ri/Ro 1e-7 to 0.02): h rises
        # from 0 at y0 over a few y0 and, on a fold-prone material, folds there, far below the regular nodes
        rho_i = 10.0 ** rng.uniform(-7.0, np.log10(0.02))
        rho_ie = rho_i + (1.0 - rho_i) * 10.0 ** rng.uniform(-4.0, np.log10(0.3))
    elif family == "small core" or rng.random() < 0.5:
        rho_i = 0.0
        lo, hi = (-6.0, np.log10(0.5)) if family == "small core" else (-3.0, np.log10(0.6))
        rho_ie = max(10.0 ** rng.uniform(lo, hi), 1.000001e-6)
    else:
        rho_i = rng.uniform(0.02, 0.9)
        rho_ie = rho_i if rng.random() < 0.1 else rho_i + (1.0 - rho_i) * rng.uniform(0.005, 0.3)
    rho_oe = _outer(rng, rho_ie)
    L1 = 30e-3
    geom = RollGeometry(rho_i * Ro, rho_ie * Ro, rho_oe * Ro, Ro, L1=L1, L1e=L1 * rng.uniform(0.5, 1.0),
                        L3=rng.uniform(20e-6, 80e-6))
    mat = _fold_prone_material(rng) if family == "hollow micro-core" and rng.random() < 0.7 else _material(rng)
    l1 = 1.0 if rng.random() < 0.1 else rng.uniform(1.0, 2.0)
    v_c = np.sqrt(mat.C10 / kappa(geom, mat)) / l1  # the neo-Hookean 1R asymptote
    v = [rng.uniform(0.0, 1.5) * v_c, 10.0 ** rng.uniform(-3.0, np.log10(1.5)) * v_c]
    if family in ("small core", "hollow micro-core"):
        # around the voltage where the hole opens, 2 sqrt(W1 rho_ie rho_oe / kappa) / l1 (at C10); a hollow
        # micro-core folds near the solid roll's
        v.append(2.0 * np.sqrt(mat.C10 * rho_ie * rho_oe / kappa(geom, mat)) / l1 * 10.0 ** rng.uniform(-0.3, 0.3))
    else:
        v.append(rng.uniform(0.5, 1.5) * v_c)
    return SimpleNamespace(name=f"{family} #{k}", geom=geom, mat=mat, stretch=l1, voltage=np.array(v),
                           seed=[SEED, FAMILY_IDS[family], k])


FAMILY_IDS = {"general": 0, "small core": 1, "hollow micro-core": 2}


def cases(family, n):
    rng = np.random.default_rng([SEED, FAMILY_IDS[family]])
    return [_case(rng, family, k) for k in range(n)]


def targeted_voltages(land, rng):
    """Two voltages at the boundaries between outcomes, where solvers go wrong [V].

    With a fold: one below it (between the pitchfork and the fold where the hole opens
    supercritically first: the bug report's window) and one just above it; without a fold,
    one each side of the largest voltage with a state in range.
    """
    near = 10.0 ** rng.uniform(-5.0, -1.0, 2)
    if land.fold_index is None:
        v_end = np.sqrt(land.h_end)
        return [v_end * (1.0 - near[0]), v_end * (1.0 + near[1])]
    v_f = np.sqrt(land.fold_h)
    v_p = np.sqrt(land.h[0]) if land.y0 == 0.0 else 0.0  # the pitchfork (3R, Ri = 0)
    below = v_p + (v_f - v_p) * rng.uniform(0.02, 0.98) if 0.0 < v_p < v_f * (1 - 1e-3) else v_f * (1 - near[0])
    return [below, v_f * (1.0 + near[1])]


GENERAL = cases("general", N_GENERAL)
SMALL = cases("small core", N_SMALL)
HOLLOW_MICRO = cases("hollow micro-core", N_HOLLOW_MICRO)


# -------------------------------------------------------------------------------- comparison
def _coordinate(model, geom, res):
    """The solver's free coordinate: 1R lambda2, 3R r_i / Ro."""
    return np.asarray(res.lambda2b if model == "1r" else res.r_i / geom.Ro, float)


#: Known misses of the full (slow) run, each checked to be still missed (remove it once fixed):
#: a fold so shallow that neither the scan nodes' values nor their slopes nor a cubic fit
#: between them show it; the state is right, only the snap flag is missing.
KNOWN_MISSES = {
    ("3r", "general #2021"): "h dips by 3.1e-5 (0.075 V at 4716.7 V) between scan nodes 0.0268 and 0.0419 Ro",
}


def _describe(case):
    g, m = case.geom, case.mat
    return (f"{case.name}: radii ({g.Ri:.4g}, {g.Rie:.4g}, {g.Roe:.4g}, {g.Ro:.4g}) m, L1e/L1 {g.alpha_e1:.3f}, "
            f"L3 {g.L3:.4g} m, Yeoh ({m.C10:.6g}, {m.C20:.6g}, {m.C30:.6g}) Pa, eps_r {m.eps_r:.4g}, "
            f"stretch {case.stretch!r}")


def _known(model, case, category, counts):
    """Whether a failure is a known miss (counted as such)."""
    if category.endswith("SNAPPED flag missing") and (model, case.name) in KNOWN_MISSES:
        counts[f"known miss: {case.name}"] += 1
        return True
    return False


def compare_path(model, case, voltage, states, counts, failures):
    """The case's voltages in rising order as one path (``path=True``) from the unloaded roll.

    A rising voltage series reaches at each sample the rising-ramp rule's state (descent from the
    previous state, where ``h < K`` holds all the way back to ``y0``, stops at the first upward
    crossing of ``K`` beyond ``y0``), so each sample is compared with ``states``: the same state,
    no state where the reference has none, and the snap-through flagged at the first sample past
    the first fold (with that fold's voltage) and at none before it. Flags after the first snap
    (later folds, which the reference does not locate) are counted, not compared.
    """
    order = np.argsort(voltage, kind="stable")
    v = voltage[order]
    ref = [states[i] for i in order]
    res = solve(model, case.geom, case.mat, np.full(v.size, case.stretch), v, path=True, **TAUT)
    status = np.asarray(res.status).astype(int)
    y_pkg = _coordinate(model, case.geom, res)
    crit = np.asarray(res.critical_voltage, float)
    first = next((n for n, s in enumerate(ref) if s.found and s.snapped), None)
    for n, s in enumerate(ref):
        st = int(status[n])
        counts["path samples"] += 1
        if s.ambiguous:
            counts["path: ambiguous, not compared"] += 1
            continue

        def fail(category, detail=""):
            category = "path: " + category
            if _known(model, case, category, counts):
                return
            counts[f"FAIL {category}"] += 1
            failures.append((category,
                f"[{model} path] {category}: {_describe(case)}, rising voltages {list(np.round(v, 6))} V, "
                f"sample {n} ({s.voltage!r} V); solver {NAMES.get(st, st)} y {y_pkg[n]:.10g} critical "
                f"{crit[n]:.8g} V; reference {NAMES[s.expected]} y {s.y:.10g} (tol {s.tol:.3g}) fold "
                f"{s.fold_voltage:.8g} V{detail}"))

        if st in (OK, SNAPPED):
            if not s.found:
                fail("valid state where the reference has none in range")
            elif not abs(y_pkg[n] - s.y) <= s.tol:
                fail("state differs", f"; |dy| = {abs(y_pkg[n] - s.y):.3g}")
            elif first is None or n < first:
                if st == SNAPPED:
                    fail("SNAPPED without a fold on [y0, y]")
                else:
                    counts["path pass"] += 1
            elif n == first and not (n > 0 and ref[n - 1].ambiguous):
                if st != SNAPPED:
                    fail("SNAPPED flag missing")
                elif not abs(crit[n] - s.fold_voltage) <= V_RTOL * s.fold_voltage:
                    fail("critical voltage of a snap is not the first fold's")
                else:
                    counts["path pass"] += 1
            else:
                counts["path pass (flag after the first snap not compared)"] += 1
        elif st in (LIMIT_POINT, OUTSIDE_RANGE):
            if s.found:
                fail(f"{NAMES[st]}, but the reference reaches a state in range")
            else:
                counts["path pass"] += 1
        elif st == SLACK:
            counts["path: slack, skipped"] += 1
        else:
            fail(f"unexpected status {NAMES.get(st, st)}")


def compare_case(model, case, counts, failures, path=True):
    """Solve one case, compare every sample with the reference; tally into ``counts``. With ``path``
    the same voltages are also solved as a rising path (`compare_path`)."""
    land = bf.landscape(model, case.geom, case.mat, case.stretch)
    voltage = np.r_[case.voltage, targeted_voltages(land, np.random.default_rng(case.seed + [len(model)]))]
    states = [land.rising_state(v) for v in voltage]
    l1 = np.full(voltage.shape, case.stretch)
    res = solve(model, case.geom, case.mat, l1, voltage, **TAUT)
    status = np.asarray(res.status).astype(int)
    y_pkg = _coordinate(model, case.geom, res)
    crit = np.asarray(res.critical_voltage, float)
    rng_v = np.asarray(res.range_voltage, float)
    for k, s in enumerate(states):
        st = int(status[k])
        counts["samples"] += 1
        counts[f"reference {NAMES[s.expected]}"] += 1
        counts[f"solver {NAMES.get(st, st)}"] += 1
        if s.fold_margin < 1e-6 and (s.snapped or (not s.found and s.fold)):
            counts["reference fold weaker than 1e-6 of h (decided, but close)"] += 1
        if s.ambiguous:
            counts[f"ambiguous, not compared: {s.ambiguous}"] += 1
            continue
        if st == SLACK:
            counts["slack, skipped"] += 1
            continue

        def fail(category, detail=""):
            if _known(model, case, category, counts):
                return
            counts[f"FAIL {category}"] += 1
            failures.append((category,
                f"[{model}] {category}: {_describe(case)}, voltage {s.voltage!r} V; solver {NAMES.get(st, st)} "
                f"y {y_pkg[k]:.10g} critical {crit[k]:.8g} V; reference {NAMES[s.expected]} y {s.y:.10g} "
                f"(tol {s.tol:.3g}, range {s.y0:.6g}..{s.y_end:.6g}) fold {s.fold_voltage:.8g} V "
                f"(margin {s.fold_margin:.2g}){detail}"))

        if st in (OK, SNAPPED):
            if not s.found:
                fail("valid state where the reference has none in range")
            elif not abs(y_pkg[k] - s.y) <= s.tol:
                fail("state differs" + (" (snapped past the first minimum)" if y_pkg[k] > s.y else ""),
                     f"; |dy| = {abs(y_pkg[k] - s.y):.3g}")
            elif (st == SNAPPED) != s.snapped:
                fail("SNAPPED flag missing" if s.snapped else "SNAPPED without a fold on [y0, y]")
            elif st == SNAPPED and not abs(crit[k] - s.fold_voltage) <= V_RTOL * s.fold_voltage:
                fail("critical voltage of a snap is not the first fold's")
            else:
                counts["pass"] += 1
                dy = abs(y_pkg[k] - s.y)
                counts["max |dy| / range, x1e-9"] = max(counts["max |dy| / range, x1e-9"],
                                                        int(np.ceil(1e9 * dy / s.span)))
                # not asserted (the brief's tolerance is Y_TOL of the range): the same state to
                # 1e-6 of its own distance from y0, which tells a small core's states apart
                if dy > max(1e-6 * abs(s.y - s.y0), 1e-12 * s.span, 2.0 * s.band):
                    counts["info: passes, but |dy| > 1e-6 of |y - y0|"] += 1
        elif st == LIMIT_POINT:
            if s.found:
                fail("LIMIT_POINT, but the reference reaches a state in range")
            elif not s.fold:
                fail("LIMIT_POINT without a fold (h rises monotonically to the range end: outside range)")
            elif s.expected == OUTSIDE_RANGE:
                fail("LIMIT_POINT, but h climbs past every fold to the range end (outside range)")
            elif not abs(crit[k] - s.max_voltage) <= V_RTOL * s.max_voltage:
                fail("critical voltage of a limit point is not the pull-in voltage (the largest h in range)",
                     f"; pull-in {s.max_voltage:.8g} V")
            else:
                counts["pass"] += 1
        elif st == OUTSIDE_RANGE:
            if s.found:
                fail("OUTSIDE_RANGE, but the reference reaches a state in range")
            elif s.expected == LIMIT_POINT:
                fail("OUTSIDE_RANGE, but the largest h in range is a fold's (a limit point)",
                     f"; pull-in {s.max_voltage:.8g} V")
            elif not np.isnan(crit[k]):
                fail("OUTSIDE_RANGE with a critical voltage")
            elif not abs(rng_v[k] - s.max_voltage) <= V_RTOL * s.max_voltage:
                fail("range voltage is not the largest voltage with a state in range",
                     f"; {rng_v[k]:.8g} vs {s.max_voltage:.8g} V")
            else:
                if s.fold:
                    counts["info: outside range after a fold (h climbs past it to the range end)"] += 1
                counts["pass"] += 1
        else:
            fail(f"unexpected status {NAMES.get(st, st)}")
    if path:
        compare_path(model, case, voltage, states, counts, failures)


def run_cases(model, case_list, path=True):
    counts, failures = Counter(), []
    t0 = time.perf_counter()
    for case in case_list:
        compare_case(model, case, counts, failures, path)
    counts["seconds"] = int(round(time.perf_counter() - t0))
    return counts, failures


def report(model, family, counts, failures, show=10):
    """Counts of every category, and up to ``show`` failures taken in turn from each category."""
    lines = [f"{model}, {family}: {len(failures)} failing samples"]
    lines += [f"  {key}: {counts[key]}" for key in sorted(counts)]
    by_category = {}
    for category, text in failures:
        by_category.setdefault(category, []).append(text)
    shown = []
    for depth in range(show):
        shown += [texts[depth] for texts in by_category.values() if depth < len(texts)]
    lines += ["failures (in turn from each category):"] + [f"  {t}" for t in shown[:show]]
    return "\n".join(lines)


FAMILIES = {"general": (GENERAL, N_GENERAL_DEFAULT), "small core": (SMALL, N_SMALL_DEFAULT),
            "hollow micro-core": (HOLLOW_MICRO, N_HOLLOW_MICRO_DEFAULT)}
#: (model, family) pairs: 1R has no core, so the hollow micro-cores are 3R's alone
PAIRS = [(m, f) for m in ("1r", "3r") for f in sorted(FAMILIES) if not (m == "1r" and f == "hollow micro-core")]


@pytest.mark.parametrize("model, family", PAIRS)
def test_random_cases_match_brute_force(model, family):
    case_list, n = FAMILIES[family]
    counts, failures = run_cases(model, case_list[:n])
    print(report(model, family, counts, failures))
    assert counts["samples"] == 5 * n and counts["path samples"] == 5 * n
    assert not failures, report(model, family, counts, failures)


@pytest.mark.slow
@pytest.mark.parametrize("model, family", PAIRS)
def test_all_random_cases_match_brute_force(model, family):
    case_list, _ = FAMILIES[family]
    counts, failures = run_cases(model, case_list)
    print(report(model, family, counts, failures))
    assert not failures, report(model, family, counts, failures)
    for (m, name), why in KNOWN_MISSES.items():
        if m == model and name.startswith(family):
            assert counts[f"known miss: {name}"] > 0, f"{name} is no longer missed ({why}): remove it from KNOWN_MISSES"


# -------------------------------------------------------------------------------- named cases
BUG_GEOM = RollGeometry(0.0, 7.3e-8, 1.09e-4, 3.46e-4, L1=34e-3, L1e=34e-3, L3=44e-6)
BUG_MAT = SimpleNamespace(C10=61.6e3, C20=-5.35e3, C30=0.1565e3, eps_r=2.2)


def test_bug_report_small_core_reaches_the_first_minimum():
    """The bug report's roll (Rie/Ro = 2.1e-4) at stretch 1 and 182 V: g has a minimum at
    r_i = 1.346e-8 m, before a fold at 186.6 V, and a second one at 1.254e-7 m; a ramp to
    182 V stops at the first (the solver scanning too coarsely returned the second)."""
    land = bf.landscape("3r", BUG_GEOM, BUG_MAT, 1.0)
    ref = land.rising_state(182.0)
    assert ref.found and not ref.snapped and not ref.ambiguous
    assert ref.r_i == pytest.approx(1.346e-8, rel=1e-3, abs=0)  # the report's 4 digits
    assert 186.0 < np.sqrt(land.fold_h) < 187.0  # the first minimum's fold lies above 182 V
    res = solve("3r", BUG_GEOM, BUG_MAT, 1.0, 182.0, **TAUT)
    assert int(res.status) == OK, NAMES.get(int(res.status))
    assert abs(float(res.r_i) - ref.r_i) <= ref.tol * BUG_GEOM.Ro, (float(res.r_i), ref.r_i)


def _pitchfork_voltage(geom, mat, l1):
    """Hand calculation: with Ri = 0, at r_i = 0 every ring is uniaxial and
    psi'' = psi_22(l1, l1**-0.5) = 8 W1 (only ring a deforms to first order; eta_a = rho_ie**2),
    c'' = 2 kappa l1**2 / (rho_ie rho_oe); the hole opens at v**2 = psi'' / c''."""
    x = l1 * l1 + 2.0 / l1 - 3.0
    W1 = mat.C10 + 2.0 * mat.C20 * x + 3.0 * mat.C30 * x * x
    rho_ie, rho_oe = geom.Rie / geom.Ro, geom.Roe / geom.Ro
    return 2.0 * np.sqrt(W1 * rho_ie * rho_oe / kappa(geom, mat)) / l1


def test_active_core_hole_opening_is_snapped():
    """Paper's active core, Rizzello's material, stretch 1.1: the pitchfork at r_i = 0 is
    (weakly) subcritical, h falls by 6e-6 after it, so the hole opens by a jump from 0 to
    about 4.6-4.9 um: SNAPPED, critical voltage the pitchfork's."""
    geom, l1 = core("active"), 1.1
    v_p = _pitchfork_voltage(geom, RIZZELLO, l1)
    land = bf.landscape("3r", geom, RIZZELLO, l1)
    below, above = land.rising_state(v_p * (1 - 1e-6)), land.rising_state(v_p * (1 + 1e-6))
    assert below.found and below.y == 0.0 and not below.snapped
    assert above.found and above.snapped and 4.5e-6 < above.r_i < 5.0e-6
    res = solve("3r", geom, RIZZELLO, l1, np.array([below.voltage, above.voltage]), **TAUT)
    assert list(res.status) == [OK, SNAPPED], [NAMES.get(int(s)) for s in res.status]
    assert float(res.r_i[0]) == 0.0
    assert abs(float(res.r_i[1]) - above.r_i) <= above.tol * geom.Ro
    assert float(res.critical_voltage[1]) == pytest.approx(v_p, rel=V_RTOL, abs=0)


# -------------------------------------------------------------------------------- the reference itself
NEO = SimpleNamespace(C10=242e3, C20=0.0, C30=0.0, eps_r=2.8)
WEAK = SimpleNamespace(C10=242e3, C20=-20e3, C30=1e3, eps_r=2.8)


@pytest.mark.parametrize("l1", [1.0, 1.3, 2.0])
def test_reference_1r_neo_hookean_closed_form(l1):
    """Neo-Hookean 1R: C10 (1 - l1**-2 l2**-4) = kappa l1**2 v**2, so
    l2 = (l1**2 (1 - kappa l1**2 v**2 / C10))**-0.25, monotone up to the asymptote
    v* = sqrt(C10 / kappa) / l1; past the range end (10 l1**-0.5) no state, no fold."""
    geom = core("hollow")
    kap = kappa(geom, NEO)
    v_star = np.sqrt(NEO.C10 / kap) / l1
    land = bf.landscape("1r", geom, NEO, l1)
    assert land.fold_index is None
    for frac in (0.0, 0.2, 0.7, 0.99, 0.999):
        s = land.rising_state(frac * v_star)
        exact = (l1 * l1 * (1.0 - kap * l1 * l1 * (frac * v_star) ** 2 / NEO.C10)) ** -0.25
        assert s.found and not s.snapped and s.expected == OK
        # Brent on g alone stops at ~1e-8 of the range (g is flat to rounding there); the
        # polish on the reference's dg/dy brings it to rounding, 1e6 times inside Y_TOL
        assert abs(s.y - exact) <= 1e-12 * s.span
    s = land.rising_state(1.01 * v_star)
    assert not s.found and not s.fold and s.expected == OUTSIDE_RANGE
    cap = bf.HOOP_FACTOR / np.sqrt(l1)
    assert s.max_voltage == pytest.approx(v_star * np.sqrt(1 - l1**-2 * cap**-4), rel=1e-9, abs=0)


@pytest.mark.parametrize("l1", [1.0, 1.5])
def test_reference_1r_fold_matches_explicit_voltage_curve(l1):
    """Weakly stiffening Yeoh 1R: along the equilibria v(l2)**2 = psi_2 / (2 l2 kappa l1**2),
    written out by hand; its first maximum is the fold, and just past it the ramp lands at
    the next l2 where v(l2) returns to that voltage (or leaves the range: a limit point)."""
    geom = core("hollow")
    kap = kappa(geom, WEAK)
    l2 = np.linspace(l1**-0.5, bf.HOOP_FACTOR * l1**-0.5, 2_000_001)
    x = l1**2 + l2**2 + (l1 * l2) ** -2 - 3
    W1 = WEAK.C10 + 2 * WEAK.C20 * x + 3 * WEAK.C30 * x**2
    v = np.sqrt(np.maximum(W1 * (2 * l2 - 2 * l1**-2 * l2**-3), 0.0) / (2 * l2 * kap * l1**2))
    top = int(np.flatnonzero(np.diff(v) < 0)[0])
    v_f = v[top]
    land = bf.landscape("1r", geom, WEAK, l1)
    assert np.sqrt(land.fold_h) == pytest.approx(v_f, rel=1e-9, abs=0)  # the hand grid: step 4.5e-6 l2
    before = land.rising_state(v_f * (1 - 1e-3))
    assert before.found and not before.snapped and before.y < l2[top]
    after = land.rising_state(v_f * (1 + 1e-3))
    back = np.flatnonzero((l2 > l2[top]) & (v >= v_f * (1 + 1e-3)))
    if back.size:
        assert after.found and after.snapped and after.expected == SNAPPED
        assert after.y == pytest.approx(l2[back[0]], abs=2 * (l2[1] - l2[0]))
        assert after.fold_voltage == pytest.approx(v_f, rel=1e-9, abs=0)
    else:
        assert not after.found and after.fold and after.expected == LIMIT_POINT


@pytest.mark.parametrize("mat", [RIZZELLO, TABLE3], ids=["rizzello", "table3"])
@pytest.mark.parametrize("l1", [1.0, 1.1, 1.6])
def test_reference_3r_pitchfork_matches_hand_calculation(mat, l1):
    """The first value of h at r_i = 0 is the hand-calculated pitchfork: below it the state is
    r_i = 0; above it the hole opens, by a snap where h falls after the pitchfork."""
    geom = core("active")
    v_p = _pitchfork_voltage(geom, mat, l1)
    land = bf.landscape("3r", geom, mat, l1)
    assert np.sqrt(land.h[0]) == pytest.approx(v_p, rel=1e-9, abs=0)
    below = land.rising_state(v_p * (1 - 1e-4))
    assert below.found and below.y == 0.0 and below.expected == OK
    above = land.rising_state(v_p * (1 + 1e-4))
    assert above.found and above.y > 0.0
    if land.fold_index is not None and land.fold_y < 1e-3:  # subcritical: a fold at the pitchfork
        assert above.snapped and above.fold_voltage == pytest.approx(v_p, rel=1e-9, abs=0)


@pytest.mark.parametrize("model", ["1r", "3r"])
def test_reference_agrees_with_the_solver_on_monotone_cases(model):
    """Where the solver is known right (hollow core, up to 3.5 kV, no fold), the reference
    agrees to 1e-12 of the range (seen: 5e-16), a million times inside the comparison tolerance."""
    geom = core("hollow")
    for l1 in (1.0, 1.25, 1.75):
        v = np.array([0.0, 1000.0, 2600.0, 3500.0])
        res = solve(model, geom, RIZZELLO, np.full(4, l1), v, **TAUT)
        assert np.all(res.status == OK)
        y = _coordinate(model, geom, res)
        for k, s in enumerate(bf.rising_states(model, geom, RIZZELLO, l1, v)):
            assert s.expected == OK and not s.ambiguous
            assert abs(y[k] - s.y) <= 1e-12 * s.span, (l1, v[k], y[k], s.y)


def test_reference_range_end_is_the_hoop_stretch_cap():
    """The 3R range end: lambda2b = 10 / sqrt(l1), as the solver's own kinematics give it."""
    for name in ("hollow", "active", "passive"):
        geom = core(name)
        for l1 in (1.0, 1.4):
            land = bf.landscape("3r", geom, TABLE3, l1)
            xi = three_ring.xi_at_hoop_stretch(bf.HOOP_FACTOR / np.sqrt(l1), l1,
                                                *three_ring._Rings(geom, np.asarray([l1])).bound_constants[1:])
            assert land.y_end == pytest.approx(float(np.ravel(xi)[0]), rel=1e-12, abs=0)
            # c grows as lambda2b**2: at the range end it is 100 times c(y0)
            assert (land.c0 + land.dc[-1]) / land.c0 == pytest.approx(bf.HOOP_FACTOR**2, rel=1e-12, abs=0)


def test_reference_refuses_a_model_that_is_not_the_packages():
    """The closed-form g - g(y0) is checked against the package's enthalpy: change the
    reference's material by 1e-6 and the check trips (so the reference cannot drift)."""
    land = bf.landscape("3r", core("active"), TABLE3, 1.3)
    land.C = (land.C[0] * (1 + 1e-6), land.C[1], land.C[2])
    land.dpsi, land.dc = land.increments(land.y)
    with pytest.raises(bf.ReferenceModelMismatch, match="disagrees with the package's enthalpy"):
        land._check_against_package()
