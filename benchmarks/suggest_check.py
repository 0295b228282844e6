"""`rdea-lab suggest` against brute force, on an emulated truth beyond the model.

The truth: a VHB-4910-like strip (``rdea_lab/data/specimens/vhb4910_strip.yaml``, 0 V, SU) with two
finite-strain Maxwell branches, a fast one (tau 2 s) and a slow one (tau 300 s). The model fitted is
the finite-strain law with ONE branch (least squares, branches grown from the data as ``calibrate``
does): it cannot follow both time scales and compromises toward those its data show. The small initial
fit set: two loading-unloading runs to stretch 2.0 at 0.05 and 0.25 /s (the fast time scale only).
The scene: a step-and-hold, 0.25 /s to stretch 2.5, held 900 s, ramped back.

Each candidate of `rdea_lab.calibration.suggest.candidates` (limits: max_stretch 3) is run on the truth
(its force plus 4 mN Gaussian noise from a seeded generator), added to the initial set, and the model
refitted (from the initial fit's optimum); the scene's error is the rms of (refitted prediction - true
force) over its samples, over the true peak. The suggestion (linearized, from the initial fit's record
only) is then placed among these brute-force reductions.

    python3 benchmarks/suggest_check.py [--out results.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"
NOISE = 4e-3  # [N] load-cell noise, standard deviation (the emulator truth's force_noise)


def truth():
    """The emulated material: Yeoh with two finite-strain branches (tau 2 s and 300 s)."""
    from rdea_lab.specs import ParameterSet, ViscoBranch

    return ParameterSet(name="vhb-like-truth", C10=18e3, C20=-0.2e3, C30=0.02e3, eps_r=4.7, law="finite_strain",
                        branches=(ViscoBranch.of("finite_strain", 25e3, 50e3),
                                  ViscoBranch.of("finite_strain", 12e3, 3.6e6)), eta_v0=0.0,
                        description="emulated truth of benchmarks/suggest_check.py")


def emulate(spec, card, params, rng):
    """A run of protocol ``spec`` on the truth: its force plus Gaussian noise."""
    from rdea_lab.calibration.objective import predict_force
    from rdea_lab.calibration.suggest import plan_run

    run = plan_run(spec, card)
    clean = predict_force(run, params, "su")
    run.force = clean + rng.normal(0.0, NOISE, clean.shape)
    run.peak = float(np.max(np.abs(run.force)))
    run.path = Path(f"<emulated {spec.name}>")
    return run, clean


def scene_error(spec, card, params, true_force) -> float:
    from rdea_lab.calibration.objective import predict_force
    from rdea_lab.calibration.suggest import plan_run

    pred = predict_force(plan_run(spec, card), params, "su")
    return float(np.sqrt(np.mean((pred - true_force) ** 2)) / np.max(np.abs(true_force)))


def fit(runs, start=None):
    from rdea_lab.calibration import Budget, initial_guess
    from rdea_lab.calibration.fit import calibrate, calibrate_growing

    kw = dict(model="su", method="least-squares", budget=Budget(evaluations=20000, seconds=300))
    if start is None:
        return calibrate_growing(runs, initial_guess(runs, 1, 4.7, law="finite_strain"), 1, **kw)
    return calibrate(runs, start, **kw)


def check(seed: int = 27, verbose: bool = True) -> dict:
    """Run the whole comparison; returns the figures (see the module docstring)."""
    from scipy.stats import spearmanr

    from rdea_lab.calibration.suggest import candidate_spec, candidates, suggest
    from rdea_lab.specs import as_specimen
    from rdea_lab.specs.limits import Limits

    card = as_specimen(CARD)
    rig = Limits(max_stretch=3.0)
    rng = np.random.default_rng(seed)
    true = truth()
    initial = [emulate(candidate_spec("ramp", 2.0, r, 0.0, rig), card, true, rng)[0] for r in (0.05, 0.25)]
    scene = candidate_spec("hold", 2.5, 0.25, 900.0, rig).model_copy(update={"name": "scene_hold_2.5_for_900s"})
    _, scene_true = emulate(scene, card, true, np.random.default_rng(0))
    t0 = time.perf_counter()
    base = fit(initial)
    e0 = scene_error(scene, card, base.params, scene_true)
    if verbose:
        print(f"initial fit ({base.wall_time:.1f} s, objective {base.objective:.4g}): scene error "
              f"{100 * e0:.2f} % rms of peak", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        record = Path(tmp) / "initial.yaml"
        base.write(record)
        ts = time.perf_counter()
        sug = suggest(record, card, scene=scene, limits=rig)
        t_suggest = time.perf_counter() - ts
        dopt = suggest(record, card, limits=rig)  # without the scene: D-optimal
    if verbose:
        print(sug.table(), flush=True)
        print(f"suggest: {t_suggest:.1f} s", flush=True)
    kept, _ = candidates(card, rig)
    brute = {}
    for c in kept:
        run, _ = emulate(c.spec, card, true, np.random.default_rng([seed, len(brute)]))
        res = fit(initial + [run], start=base.params)
        e = scene_error(scene, card, res.params, scene_true)
        brute[c.name] = {"error": e, "reduction": e0 - e, "fit_s": res.wall_time, "converged": res.converged}
        if verbose:
            print(f"  {c.name:<28} scene error {100 * e:6.2f} %  reduction {100 * (e0 - e):+6.2f} points  "
                  f"({res.wall_time:.1f} s)", flush=True)
    reductions = np.array([b["reduction"] for b in brute.values()])
    best = sug.best.name
    top = max(brute, key=lambda n: brute[n]["reduction"])
    out = {"scene_error_initial": e0, "suggested": best, "suggested_reduction": brute[best]["reduction"],
           "median_reduction": float(np.median(reductions)), "best_brute": top,
           "best_brute_reduction": float(reductions.max()),
           "suggested_brute_rank": int(1 + np.sum(reductions > brute[best]["reduction"])),
           "d_optimal": dopt.best.name, "d_optimal_reduction": brute[dopt.best.name]["reduction"],
           "spearman_linearized_vs_brute": float(spearmanr([r["shrink"] for r in sug.rows],
                                                           [brute[r["name"]]["reduction"] for r in sug.rows])[0]),
           "candidates": len(brute), "ranking": [dict(r) for r in sug.rows], "brute": brute,
           "suggest_s": t_suggest, "total_s": time.perf_counter() - t0}
    if verbose:
        print(f"suggested {best}: reduction {100 * out['suggested_reduction']:.2f} points (brute-force rank "
              f"{out['suggested_brute_rank']} of {len(brute)}); median candidate {100 * out['median_reduction']:.2f}; "
              f"best {out['best_brute']} {100 * out['best_brute_reduction']:.2f}; D-optimal (no scene) "
              f"{out['d_optimal']} {100 * out['d_optimal_reduction']:.2f}; Spearman (linearized shrink, brute "
              f"reduction) {out['spearman_linearized_vs_brute']:.2f}", flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="JSON results")
    ap.add_argument("--seed", type=int, default=27)
    args = ap.parse_args(argv)
    out = check(args.seed)
    if args.out:
        args.out.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
