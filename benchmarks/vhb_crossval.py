"""Cross-validation on the real VHB 4910 files: both viscoelastic laws, M = 1, 2, 3.

Leave-one-out over the five files of ``../shared/data/vhb4910`` (each file
predicted by a fit to the other four), and across stretches (fit the 1.5
files, predict the 3.0 ones, and the reverse), with least squares (the method
for cross-validation loops; rms of the peak-normalized force). The strip is in
uniaxial tension at 0 V, where every quasi-static model is the same (SU). Per
held-out file: rms, 99th percentile and max of |error| / peak, the envelope's
extrapolation flags; per fit: evaluations and wall time. Nothing is tuned on a
held-out file: starts come from the fitted files alone (`initial_guess`), the
branches are grown one at a time.

    python3 benchmarks/vhb_crossval.py [--out results.json] [--laws linear,finite_strain] [--M 1,2,3]
        [--hyperelastic yeoh,yeoh-monotone,neo-hookean]

``--hyperelastic`` loops over the Yeoh choices of the fit (default the paper's Yeoh alone).
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
VHB = ROOT.parent / "shared" / "data" / "vhb4910"


def imported(folder: Path) -> Path:
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    rc = run_cli(cli, ["import", *map(str, sorted(VHB.glob("0d*.csv"))), "--format", "csv", "--map",
                       "time=0,position=1,force=2", "--protocol-kind", "tensile", "--specimen",
                       str(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"), "--credit",
                       "Chongran-Zhao/VHB4910_data (GitHub)", "--out", str(folder)])
    if rc:
        sys.exit(f"import failed ({rc})")
    return folder


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="JSON results")
    ap.add_argument("--laws", default="linear,finite_strain")
    ap.add_argument("--M", default="1,2,3")
    ap.add_argument("--cv", default="leave-one-out,by-stretch")
    ap.add_argument("--hyperelastic", default="yeoh", help="comma-separated: yeoh, yeoh-monotone, neo-hookean")
    args = ap.parse_args(argv)
    from rdea_lab.api import cross_validate
    from rdea_lab.calibration import Budget

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        data = imported(Path(tmp) / "vhb")
        for cv in args.cv.split(","):
            for law, hyper, M in itertools.product(args.laws.split(","), args.hyperelastic.split(","),
                                                   map(int, args.M.split(","))):
                t0 = time.perf_counter()
                res = cross_validate(str(data), cv=cv, model="su", law=law, branches=M, hyperelastic=hyper,
                                     method="least-squares", budget=Budget(evaluations=20000, seconds=900))
                wall = time.perf_counter() - t0
                for fold in res.folds:
                    for r in res.rows(fold=fold.index, role="predicted"):
                        rows.append({"cv": cv, "law": law, "hyperelastic": hyper, "M": M, "fold": fold.index,
                                     "file": r["file"], "C10": fold.result.values["C10"],
                                     "C20": fold.result.values["C20"], "C30": fold.result.values["C30"],
                                     "rms_rel_error": r["rms_rel_error"], "p99_rel_error": r["p99_rel_error"],
                                     "max_rel_error": r["max_rel_error"], "flags": list(r["flags"]),
                                     "nfev": fold.result.nfev, "fit_time_s": fold.result.wall_time,
                                     "objective": fold.result.objective, "converged": fold.result.converged})
                        print(f"{cv:13s} {law:13s} {hyper:13s} M={M} fold {fold.index}: {r['file']:16s} "
                              f"rms {100 * r['rms_rel_error']:6.2f} %  p99 {100 * r['p99_rel_error']:6.2f} %  "
                              f"max {100 * r['max_rel_error']:7.2f} %  {fold.result.nfev:5d} evals "
                              f"{fold.result.wall_time:6.1f} s  {'; '.join(r['flags'])}", flush=True)
                print(f"  ({cv}, {law}, {hyper}, M={M}: {wall:.1f} s in all)", flush=True)
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
