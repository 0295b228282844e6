"""Speed of the quasi-static solvers SU, 1R, 3R and CR (``rdea-lab bench``).

Headline figures are on the hollow core of Section 3.4 (material of ref. [36],
lambda1 uniform in [1, 1.75], v uniform in [0, 3.5 kV], seed 0): every 1R,
3R and CR sample there needs the full iterative solve (no sample sits on the
bifurcation-free SU state; CR integrates over the cross-section, 13 Gauss
points there), so it is the honest case for throughput. On the solid rolls
(Ri = 0: the specimens, the active and passive cores) CR is the SU state, with
no free coordinate; it still evaluates its state on the quadrature nodes, and
costs about what 3R costs where 3R stays uniaxial. The
per-scene table adds the three paper specimens over the paper's envelope
(lambda1 in [1, 1.5], v in [0, 2.6 kV], Table 3 material) and the active and
passive cores. The fsolve baseline solves the corrected six-equation system
(27) sample by sample (``baseline_3r_fsolve.py``); speed-up and agreement are
measured on the hollow core, where the baseline's first stationary point is
the physical one. Rates are the median of ``repeat`` timed runs after one
warm-up (a run: calls in a row for at least 20 ms, `MIN_RUN_S`, its time per
call), with their spread (slowest and fastest run) beside them, and beside
each the ratio to a plain numpy expression of the model's stress equation on
the same arrays, timed in the same process (`plain_numpy`; for SU also on
specimen 2 at 2.6 kV, where a few percent of the samples are slack). The compiled
kernels against the numpy reference, `TwinStep`'s latency and numba's start-up
are `bench_kernels.py`'s (keys ``kernels``, ``step_latency_us``, ``compile_s``).
"""

from __future__ import annotations

import contextlib
import math
import os
import platform
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from rdea_lab import __version__
from rdea_lab.physics.geometry import RollGeometry, geometry_from_card
from rdea_lab.physics.models import continuum, one_ring, solve, three_ring
from rdea_lab.physics.models._common import kappa
from rdea_lab.physics.result import FIELDS, SLACK
from rdea_lab.specs import load_params, load_specimen

import bench_kernels
from rdea_lab.reports.baseline_3r_fsolve import solve_3r_fsolve

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("su", "1r", "3r", "cr")
RIZZELLO = SimpleNamespace(C10=241e3, C20=-33.2e3, C30=20.1e3, eps_r=2.8)
CORES = {  # Section 3.4, L1 = L1e (alpha_e1 = 1), L3 = 48 um
    "hollow-core": (0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3),
    "active-core": (0.0, 0.088e-3, 1.76e-3, 1.8e-3),
    "passive-core": (0.0, 0.81e-3, 1.76e-3, 1.8e-3),
}


def _core(name):
    return RollGeometry(*CORES[name], L1=34e-3, L1e=34e-3, L3=48e-6)


def _times(fn, repeat, warm_up=True, min_s=0.0):
    """Wall times [s] of ``repeat`` calls of ``fn`` (after one untimed warm-up call). ``min_s`` > 0: each of the
    ``repeat`` runs is as many calls in a row as take ``min_s`` or more, its time per call: a call well under a
    millisecond, timed alone, is mostly the machine's noise (`timeit`'s rule). The count is found after the
    warm-up (whose call may load or compile code), doubling it until a run of warm calls lasts ``min_s``."""
    if warm_up:
        fn()
    calls = 1
    while min_s > 0.0:
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        spent = time.perf_counter() - t0
        if spent >= min_s:
            break
        calls = max(2 * calls, math.ceil(calls * min_s / max(spent, 1e-9)))
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        out.append((time.perf_counter() - t0) / calls)
    return np.array(out)


def _rate(n, times):
    """``(median, slowest, fastest)`` samples per second of runs of ``n`` samples."""
    r = n / np.asarray(times)
    return float(np.median(r)), float(r.min()), float(r.max())


def _envelope(n, stretch_max, voltage_max, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(1.0, stretch_max, n), rng.uniform(0.0, voltage_max, n)


@contextlib.contextmanager
def _others():
    """``{"cores": ...}`` after the block: the CPU the other processes on the machine used while it ran, in
    cores (`kernels._busy`, the machine's busy time, less this process's), None where the kernels or
    ``/proc/stat`` are absent. The headline's figures are this process's only where it is near 0."""
    out = {"cores": None}
    try:
        from rdea_lab.physics.kernels import _busy
    except ImportError:  # no numba
        _busy = lambda: None  # noqa: E731
    t0, b0, o0 = time.monotonic(), _busy(), time.process_time()
    yield out
    t1, b1, o1 = time.monotonic(), _busy(), time.process_time()
    if b0 is not None and b1 is not None and t1 > t0:
        out["cores"] = max(0.0, (b1 - b0) - (o1 - o0)) / (t1 - t0)


def plain_numpy(model, geom, material, l1, v):
    """The plain numpy expression of ``model``'s stress equation on the same arrays, a callable: for SU
    eq. (39) written out (no slack, no status, no result), for 1R, 3R and CR their stress equation
    (33), (27) row 1 and CR's evaluated once at the equilibrium coordinate (solved beforehand, not
    timed): what a whole `solve` call is measured against (``plain_numpy_ratio``)."""
    kap = kappa(geom, material)
    C10, C20, C30 = material.C10, material.C20, material.C30
    if model == "su":
        def su_plain():
            x = l1 * l1 + 2.0 / l1 - 3.0
            return 2.0 * (l1 * l1 - 1.0 / l1) * (C10 + 2.0 * C20 * x + 3.0 * C30 * x * x) - kap * l1 * v * v
        return su_plain
    res = solve(model, geom, material, l1, v, slack=False)
    if model == "1r":
        l2 = res.lambda2b
        return lambda: one_ring.stress(l2, l1, v, C10, C20, C30, kap)
    xi = res.r_i / geom.Ro
    if model == "3r":
        R = three_ring._Rings(geom, l1).constants
        return lambda: three_ring.ring_state(xi, l1, v, R, C10, C20, C30, kap)[0]
    roll = continuum._Roll(geom, l1)
    mechanics = continuum._mechanics(roll, (C10, C20, C30))
    return lambda: continuum._by_blocks(mechanics, xi, l1, roll.xi0, roll.x0, roll.lx0p)[0] - kap * v * v * l1 * (
        1.0 + l1 * roll.Lb * (roll.opening(xi, roll.xi0) + xi * xi))


#: The shortest timed run of a scene [s]: calls in a row (`_times`' ``min_s``), the same rule for `solve` and
#: the plain numpy expression (an SU call of 1e5 samples takes some 0.3 ms, the others one or more runs).
MIN_RUN_S = 0.02


def _scene(geom, material, l1, v, repeat, models=MODELS):
    """Per model: whole-call samples/s of `solve` (median, slowest, fastest of ``repeat`` runs, each at least
    `MIN_RUN_S` of calls in a row), the plain numpy expression's (`plain_numpy`, timed alike) and their ratio,
    timed in turn in this process."""
    out = {}
    for m in models:
        rate, lo, hi = _rate(l1.size, _times(lambda: solve(m, geom, material, l1, v), repeat, min_s=MIN_RUN_S))
        plain = _rate(l1.size, _times(plain_numpy(m, geom, material, l1, v), repeat, min_s=MIN_RUN_S))
        out[m] = {"samples_per_s": rate, "spread": [lo, hi], "plain_numpy": plain[0],
                  "plain_numpy_spread": [plain[1], plain[2]], "plain_numpy_ratio": rate / plain[0]}
        if m == "su":  # a compiled SU result computes most fields when read: the call with every one read too
            read = _rate(l1.size, _times(lambda: _read_all(solve(m, geom, material, l1, v)), repeat,
                                         min_s=MIN_RUN_S))
            out[m].update(every_field_read=read[0], every_field_read_spread=[read[1], read[2]],
                          every_field_read_ratio=read[0] / plain[0])
    return out


def _read_all(result):
    """Every field of ``result`` read (computed, where it computes some when first read)."""
    for name in FIELDS:
        getattr(result, name)


def run(samples=100_000, baseline_samples=1000, repeat=5, vhb=True, steps=20_000, compile_probe=True) -> dict:
    """Measure and return the figures as a JSON-able dict (``vhb=False``: without the VHB calibrations)."""
    l1, v = _envelope(samples, 1.75, 3500.0)
    hollow = _core("hollow-core")
    with _others() as others:
        headline = _scene(hollow, RIZZELLO, l1, v, repeat)
    rate = {m: x["samples_per_s"] for m, x in headline.items()}
    spread = {m: x["spread"] for m, x in headline.items()}

    scenes = {}
    table3 = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
    pl1, pv = _envelope(samples, 1.5, 2600.0, seed=1)
    spec2 = geometry_from_card(load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"))
    # the slack scene: specimen 2 at 2.6 kV over stretch 1-1.5 (a few percent of the samples slack)
    v26 = np.full(samples, 2600.0)
    slack_scene = _scene(spec2, table3, pl1, v26, repeat, ("su",))["su"]
    slack_scene["slack_samples"] = int(np.count_nonzero(solve("su", spec2, table3, pl1, v26).status == SLACK))
    for i in (1, 2, 3):
        geom = geometry_from_card(load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / f"specimen{i}.yaml"))
        scenes[f"specimen-{i}"] = _scene(geom, table3, pl1, pv, repeat)
    for name in ("active-core", "passive-core"):
        scenes[name] = _scene(_core(name), RIZZELLO, l1, v, repeat)

    bl1, bv = l1[:baseline_samples], v[:baseline_samples]
    Ri, Rie, Roe, Ro = CORES["hollow-core"]
    kw = dict(Ri=Ri, Rie=Rie, Roe=Roe, Ro=Ro, L3=48e-6, alpha_e1=1.0, C10=RIZZELLO.C10,
              C20=RIZZELLO.C20, C30=RIZZELLO.C30, eps_r=RIZZELLO.eps_r)
    base = solve_3r_fsolve(bl1, bv, **kw)
    base_times = _times(lambda: solve_3r_fsolve(bl1, bv, **kw), max(1, min(repeat, 3)), warm_up=False)
    t_base = float(np.median(base_times))
    speedups = _rate(baseline_samples, base_times)  # fsolve rates: median, slowest, fastest
    fast = solve("3r", hollow, RIZZELLO, bl1, bv, slack=False)  # the equations (27), as fsolve solves them
    ok = base["converged"] & fast.converged
    diff = np.abs(base["sigma1"][ok] - fast.sigma1[ok])
    max_rel = float(np.max(diff / np.max(np.abs(fast.sigma1[ok]))))
    calibration = bench_calibration(max(1, min(repeat, 3)), vhb=vhb)
    compiled = bench_kernels.run(samples=samples, repeat=max(3, repeat), steps=steps, compile_probe=compile_probe)
    return {
        **compiled,
        "calibration": calibration,
        "samples_per_s": {m: float(r) for m, r in rate.items()},
        "samples_per_s_spread": {m: [float(a), float(b)] for m, (a, b) in spread.items()},
        "plain_numpy_samples_per_s": {m: x["plain_numpy"] for m, x in headline.items()},
        "plain_numpy_ratio": {m: x["plain_numpy_ratio"] for m, x in headline.items()},
        "su_slack_scene": slack_scene,
        "su_every_field_read": {"samples_per_s": headline["su"]["every_field_read"],
                                "spread": headline["su"]["every_field_read_spread"],
                                "plain_numpy_ratio": headline["su"]["every_field_read_ratio"]},
        "speedup_3r_vs_fsolve": float(rate["3r"] / (baseline_samples / t_base)),
        "speedup_3r_vs_fsolve_spread": [float(spread["3r"][0] / speedups[2]), float(spread["3r"][1] / speedups[1])],
        "max_rel_diff_3r_vs_fsolve": max_rel,
        "fsolve_samples_per_s": float(baseline_samples / t_base),
        "baseline_samples": int(baseline_samples),
        "baseline_converged": int(np.count_nonzero(base["converged"])),
        "samples": int(samples),
        "scenes_samples_per_s": scenes,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "processor": platform.machine(), "numpy": np.__version__,
                    "other_processes_cores": others.get("cores")},
        "rdea_lab_version": __version__,
        "notes": ("headline: hollow core, lambda1 U[1,1.75], v U[0,3.5kV]; max_rel_diff = max |dsigma1| / "
                  "max |sigma1| over samples both converge on"),
    }


def bench_calibration(repeat: int = 3, vhb: bool = True) -> dict:
    """Calibration speed: specimen 2's two tensile tests on the emulator, SU with one branch and eta_v0
    (6 free parameters) from a start estimated from the data, as `rdea-lab calibrate` does, Nelder-Mead and
    least squares; and, where the shared VHB 4910 files are present, two finite-strain branches grown on all
    five (0 V, uniaxial) by both methods. Times are `wall_time` of the fit (data already loaded): median and
    spread of ``repeat`` runs (Nelder-Mead on VHB: one run, it takes tens of seconds)."""
    import tempfile

    from rdea_lab.runs import checked_plan, execute
    from rdea_lab.runs import emulated_rig as _emulator
    from rdea_lab.backends.rig import RigBackend
    from rdea_lab.calibration import Budget, calibrate, calibrate_runs, initial_guess, load_run
    from rdea_lab.protocols import load_plan
    from rdea_lab.specs.truth import load_truth

    card = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
    truth = load_truth(ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml")
    geom = geometry_from_card(card)
    with tempfile.TemporaryDirectory() as tmp, _emulator(card, truth, realtime=False) as address:
        paths = []
        for name in ("tensile_ramp_sine_0V", "tensile_ramp_sine_2.6kV"):
            out = Path(tmp) / f"{name}.nc"
            plan = checked_plan(load_plan(ROOT / "rdea_lab" / "data" / "protocols" / f"{name}.yaml"), card, geom)
            execute(plan, card, RigBackend(address, card, geometry=geom), out)
            paths.append(out)
        runs = [load_run(p) for p in paths]
    start = initial_guess(runs, 1, 2.8)
    # warm-up: the compiled kernels load from their cache
    calibrate(runs, start, model="su", budget=Budget(evaluations=20))

    def timed(fn, n):
        results = [fn() for _ in range(n)]
        secs = sorted(r.wall_time for r in results)
        return results[0], {"seconds": float(np.median(secs)), "seconds_spread": [secs[0], secs[-1]], "runs": n,
                            "evaluations": results[0].nfev, "objective": results[0].objective,
                            "converged": results[0].converged}

    res, nm = timed(lambda: calibrate(runs, start, model="su"), repeat)
    _, ls = timed(lambda: calibrate(runs, start, model="su", method="least-squares"), repeat)
    out = {"specimen2_su_M1_seconds": nm["seconds"], "specimen2_su_M1_seconds_spread": nm["seconds_spread"],
           "evaluations": res.nfev, "evaluations_per_s": res.nfev / nm["seconds"],
           "samples_per_evaluation": int(sum(r.n for r in runs)), "objective": res.objective,
           "restarts": res.restarts, "converged": res.converged, "specimen2_su_M1_least_squares": ls}
    vhb = ROOT.parent / "shared" / "data" / "vhb4910" if vhb else None
    if vhb is not None and vhb.is_dir():
        from rdea_lab.cli.errors import run as run_cli
        from rdea_lab.cli.main import cli

        import contextlib
        import io

        with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()):  # the import's lines
            rc = run_cli(cli, ["import", *map(str, sorted(vhb.glob("0d*.csv"))), "--format", "csv", "--map",
                               "time=0,position=1,force=2", "--protocol-kind", "tensile", "--specimen",
                               str(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"), "--out", tmp])
            if rc == 0:
                kw = dict(model="su", law="finite_strain", branches=2, budget=Budget(seconds=900))
                _, out["vhb5_finite_strain_M2_least_squares"] = timed(
                    lambda: calibrate_runs(tmp, method="least-squares", **kw), repeat)
                _, out["vhb5_finite_strain_M2_nelder_mead"] = timed(lambda: calibrate_runs(tmp, **kw), 1)
    return out


def format_text(r: dict) -> str:
    others = r.get("machine", {}).get("other_processes_cores")
    busy = "" if others is None else f"; other processes used {others:.2f} of {r['machine']['cpus']} cores meanwhile"
    lines = [f"quasi-static solvers, {r['samples']} samples (hollow core, lambda1 1-1.75, 0-3.5 kV), "
             f"median (slowest-fastest) of the runs (each {1e3 * MIN_RUN_S:g} ms or more of calls in a row){busy}:"]
    for m, x in r["samples_per_s"].items():
        lo, hi = r["samples_per_s_spread"][m]
        extra = ""
        if "plain_numpy_ratio" in r:
            extra = (f"; plain numpy {r['plain_numpy_samples_per_s'][m]:.3e}: "
                     f"{r['plain_numpy_ratio'][m]:.2f}x")
        lines.append(f"  {m:<3} {x:12.3e} samples/s ({lo:.3g}-{hi:.3g}){extra}")
        if m == "su" and "su_every_field_read" in r:
            y = r["su_every_field_read"]
            lines.append(f"      with every field read: {y['samples_per_s']:.3e} samples/s ({y['spread'][0]:.3g}-"
                         f"{y['spread'][1]:.3g}): {y['plain_numpy_ratio']:.2f}x")
    if "su_slack_scene" in r:
        x = r["su_slack_scene"]
        lines.append(f"  su on specimen 2, stretch 1-1.5 at 2.6 kV ({x['slack_samples']} slack): "
                     f"{x['samples_per_s']:.3e} samples/s ({x['spread'][0]:.3g}-{x['spread'][1]:.3g}); plain numpy "
                     f"{x['plain_numpy']:.3e} ({x['plain_numpy_spread'][0]:.3g}-{x['plain_numpy_spread'][1]:.3g}): "
                     f"{x['plain_numpy_ratio']:.2f}x")
        if "every_field_read" in x:
            lines.append(f"      with every field read: {x['every_field_read']:.3e} samples/s "
                         f"({x['every_field_read_spread'][0]:.3g}-{x['every_field_read_spread'][1]:.3g}): "
                         f"{x['every_field_read_ratio']:.2f}x")
    lo, hi = r["speedup_3r_vs_fsolve_spread"]
    lines.append(f"3R vs per-sample fsolve of (27) on {r['baseline_samples']} samples: "
                 f"{r['speedup_3r_vs_fsolve']:.0f}x faster ({lo:.0f}-{hi:.0f}x; fsolve "
                 f"{r['fsolve_samples_per_s']:.0f} samples/s), max rel. diff {r['max_rel_diff_3r_vs_fsolve']:.1e}")
    c = r["calibration"]
    lo, hi = c["specimen2_su_M1_seconds_spread"]
    lines.append(f"calibration of specimen 2 (SU, 1 branch + eta_v0, emulator data): Nelder-Mead "
                 f"{c['specimen2_su_M1_seconds']:.2f} s ({lo:.2f}-{hi:.2f}), "
                 f"{c['evaluations']} evaluations, {c['evaluations_per_s']:.0f} evaluations/s "
                 f"({c['samples_per_evaluation']} samples each)")
    for key, label in (("specimen2_su_M1_least_squares", "specimen 2, least squares"),
                       ("vhb5_finite_strain_M2_nelder_mead",
                        "VHB 4910, 5 files, 2 finite-strain branches, Nelder-Mead"),
                       ("vhb5_finite_strain_M2_least_squares",
                        "VHB 4910, 5 files, 2 finite-strain branches, least squares")):
        if key in c:
            x = c[key]
            lines.append(f"  {label}: {x['seconds']:.2f} s ({x['seconds_spread'][0]:.2f}-{x['seconds_spread'][1]:.2f}, "
                         f"{x['runs']} runs), {x['evaluations']} evaluations, objective {x['objective']:.4g}")
    lines.append("per scene [samples/s, median (slowest-fastest); x: against the plain numpy expression]:")
    lines.append(" " * 16 + " |".join(f"{m:>32}" for m in MODELS))
    for name, rates in r["scenes_samples_per_s"].items():
        cells = []
        for m in MODELS:
            x = rates.get(m)
            if isinstance(x, dict):
                cells.append(f"{x['samples_per_s']:9.3e} ({x['spread'][0]:.2g}-{x['spread'][1]:.2g}) "
                             f"{x['plain_numpy_ratio']:4.2f}x")
            elif x is not None:  # an older result: the median alone
                cells.append(f"{x:.3e}")
        lines.append(f"  {name:<14}" + " |".join(f"{c:>32}" for c in cells))
    if "kernels" in r:
        lines.append(bench_kernels.format_text(r))
    return "\n".join(lines)


if __name__ == "__main__":
    print(format_text(run()))
