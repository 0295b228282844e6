"""Prediction bands on the real VHB 4910 files: does the 90 % band cover 90 % of held-out samples?

Two kinds of split of ``../shared/data/vhb4910`` (finite-strain law, two branches, least squares, SU at 0 V):

- loading-unloading, leave-one-out over the five ``0d*`` files: each held out file is predicted by a fit to
  the other four, its band from that fit's covariance and a misfit term learnt from the *other* four
  leave-one-out folds' held-out errors (the file's own error never enters its band: jackknife+-style);
- the hold test: the five loading-unloading files fitted, ``relax_2d0`` (0.25 /s to 2.0, 1800 s hold)
  predicted, its misfit term from all five leave-one-out folds.

Per split: rms error / peak, the band's coverage of the held-out samples (fraction inside), the median band
half-width / peak, and the same two for the parameter term alone (the fit's covariance without the misfit),
the parameter term by the 64-draw ensemble (for comparison), the band's status (bounded, widened or
unbounded beyond the calibration envelope: see
:mod:`rdea_lab.calibration.bands`) and the envelope flags. Nothing here is tuned to a held-out file.

    python3 benchmarks/vhb_bands.py [--level 0.9] [--out results.json]
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
VHB = ROOT.parent / "shared" / "data" / "vhb4910"
FIT = {"model": "su", "law": "finite_strain", "branches": 2, "method": "least-squares"}


def imported(folder: Path, files) -> Path:
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    rc = run_cli(cli, ["import", *map(str, files), "--format", "csv", "--map", "time=0,position=1,force=2",
                       "--protocol-kind", "tensile", "--specimen",
                       str(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"), "--credit",
                       "Chongran-Zhao/VHB4910_data (GitHub)", "--out", str(folder)])
    if rc:
        sys.exit(f"import failed ({rc})")
    return folder


def judged(unc, run, level, flags, model="su") -> dict:
    """Coverage and half-width of the band, and of its parameter term alone, on a measured run."""
    from rdea_lab.calibration.bands import coverage

    b = unc.band(run, level, model, flags=flags)
    p = unc.parameter_band(run, level, model)
    e = unc.parameter_band(run, level, model, method="ensemble")
    r = b["force"] - run.force
    half = 0.5 * (b["upper"] - b["lower"])
    return {"rms_rel_error": float(np.sqrt(np.mean(r * r)) / run.peak),
            "coverage": coverage(run.force, b["lower"], b["upper"]),
            "half_width_rel": float(np.median(half) / run.peak) if np.isfinite(half).all() else float("inf"),
            "param_coverage": coverage(run.force, p["lower"], p["upper"]),
            "param_half_width_rel": float(np.median(0.5 * (p["upper"] - p["lower"])) / run.peak),
            "ensemble_coverage": coverage(run.force, e["lower"], e["upper"]),
            "ensemble_half_width_rel": float(np.median(0.5 * (e["upper"] - e["lower"])) / run.peak),
            "misfit_rel": b["misfit_rel"], "status": b["status"], "flags": list(b["flags"]),
            "draws": b["draws"], "refused": b["refused"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=float, default=0.9)
    ap.add_argument("--out", type=Path, help="JSON results")
    args = ap.parse_args(argv)
    from rdea_lab.calibration import Budget, calibrate_runs, cross_validate, load_run
    from rdea_lab.calibration.bands import Uncertainty, misfit_mapping
    from rdea_lab.calibration.envelope import beyond, envelope, run_envelope

    budget = Budget(evaluations=20000, seconds=900)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        lu = imported(Path(tmp) / "lu", sorted(VHB.glob("0d*.csv")))
        hold = imported(Path(tmp) / "hold", [VHB / "relax_2d0.csv"]) / "relax_2d0.nc"
        t0 = time.perf_counter()
        cv = cross_validate(str(lu), cv="leave-one-out", budget=budget, **FIT)
        print(f"leave-one-out: 5 fits in {time.perf_counter() - t0:.1f} s", flush=True)
        runs = {Path(r).name: load_run(r) for r in sorted(lu.glob("*.nc"))}
        for fold in cv.folds:
            (row,) = cv.rows(fold=fold.index, role="predicted")
            unc = Uncertainty.of_fit(fold.result, misfit_mapping(cv, exclude={row["file"]}), fold.envelope)
            rows.append({"split": f"LOO {fold.index}", "held_out": row["file"],
                         **judged(unc, runs[row["file"]], args.level, row["flags"])})
        t0 = time.perf_counter()
        full = calibrate_runs(str(lu), budget=budget, **FIT)
        print(f"fit of the five loading-unloading files: {time.perf_counter() - t0:.1f} s", flush=True)
        unc = Uncertainty.of_fit(full, misfit_mapping(cv), envelope(full.run_data))
        relax = load_run(hold)
        flags = beyond(unc.envelope, run_envelope(relax))
        rows.append({"split": "hold", "held_out": hold.name, **judged(unc, relax, args.level, flags)})
        # for information only: the band as if the hold were inside the envelope (the inside misfit)
        rows.append({"split": "hold (as if inside)", "held_out": hold.name, **judged(unc, relax, args.level, ())})
    head = (f"{'split':20s} {'held-out file':16s} {'rms/peak':>9s} {'coverage':>9s} {'half/peak':>10s} "
            f"{'param cov.':>10s} {'param half':>10s} {'ens. cov.':>10s} {'ens. half':>10s} {'misfit':>7s}  "
            "status; flags")
    print(f"\nband level {args.level:g}; rms, half-widths (median over samples) and misfit in % of the held-out "
          "run's peak force; 'param': the parameter term alone (delta method, the band's), 'ens.': the same by "
          "the 64-draw ensemble\n" + head)
    for r in rows:
        print(f"{r['split']:20s} {r['held_out']:16s} {100 * r['rms_rel_error']:8.2f}% {_frac(r['coverage']):>9s} "
              f"{100 * r['half_width_rel']:9.2f}% {_frac(r['param_coverage']):>10s} "
              f"{100 * r['param_half_width_rel']:9.3f}% {_frac(r['ensemble_coverage']):>10s} "
              f"{100 * r['ensemble_half_width_rel']:9.3f}% {100 * r['misfit_rel']:6.2f}%  {r['status']}; "
              f"{'; '.join(r['flags']) or '-'}")
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


def _frac(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{x:.3f}"


if __name__ == "__main__":
    sys.exit(main())
