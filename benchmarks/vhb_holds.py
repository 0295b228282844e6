"""Holds on the real VHB 4910 files: what fits with and without the hold test predict for holds they did not see.

The five loading-unloading files and the one step-and-hold test ``relax_2d0``
of ``../shared/data/vhb4910`` (0.25 /s to stretch 2.0, then 1800 s), imported
as kind tensile; ``relax_2d0`` with ``--skip-start 0.1`` (its first 0.1 s hold
a start-up spike of the machine, README). Splits (nothing is tuned on what a
split holds out; starts come from the fitted runs, `initial_guess`):

- ``A``: fit the five loading-unloading files and the first 600 s of
  ``relax_2d0``; predict the remaining 1200 s of its hold (``hold>600s``);
- ``B``: fit the five loading-unloading files only; predict the whole of ``relax_2d0``;
- ``C``: fit all six (in-sample; beside ``B``: what the hold does to the ramps);
- ``D``: fit four loading-unloading files and ``relax_2d0``, predict the fifth (five folds);
- ``E``: as ``D`` without ``relax_2d0``.

Configurations: ``2`` and ``3`` Maxwell branches (least squares, grown one at a
time), ``spectrum`` (`rdea_lab.calibration.spectrum`, its grid one decade past
the longest run) and ``spectrum0`` (the grid ending at the longest run), each
under the ``linear`` and ``finite_strain`` laws. Every fit weighs phases as
`rdea_lab.calibration.phases.PHASE_RULE` says. Errors: rms of (predicted -
measured) over the phase's samples, divided by the whole run's peak force (the
run is always predicted whole, from its start; only the error is taken per
phase). Results are appended to ``--out`` (JSON lines) as each fit ends, so a
long run can be stopped and its table printed (``--table``).

    python3 benchmarks/vhb_holds.py [--configs spectrum:linear,2:finite_strain,...] [--splits A,B,C,D,E]
                                    [--out holds.jsonl] [--table holds.jsonl]
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
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"
RELAX = "relax_2d0"
#: The part of the hold split A fits [s of the run's time].
SPLIT_AT = 600.0
CONFIGS = ("spectrum:finite_strain,spectrum:linear,spectrum0:finite_strain,spectrum0:linear,2:finite_strain,2:linear,"
           "3:finite_strain,3:linear")


def _import(files, folder: Path, *extra) -> None:
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    rc = run_cli(cli, ["import", *map(str, files), "--format", "csv", "--map", "time=0,position=1,force=2",
                       "--protocol-kind", "tensile", "--specimen", str(CARD), "--credit",
                       "Chongran-Zhao/VHB4910_data (GitHub)", "--out", str(folder), *extra])
    if rc:
        sys.exit(f"import failed ({rc})")


def imported(folder: Path) -> dict:
    """Name -> dataset path of the six files (relax_2d0 without its first 0.1 s)."""
    folder.mkdir(parents=True, exist_ok=True)
    _import(sorted(VHB.glob("0d*.csv")), folder)
    _import([VHB / f"{RELAX}.csv"], folder, "--skip-start", "0.1")
    return {p.stem: p for p in sorted(folder.glob("*.nc"))}


def first_part(path: Path, seconds: float):
    """The run's samples up to ``seconds`` after its first, as a dataset in memory."""
    from rdea_lab.calibration import load_run
    from rdea_lab.store import open_run

    run = load_run(path)
    n = int(np.searchsorted(run.t - run.t[0], seconds, side="right"))
    ds = open_run(path).isel(time=slice(0, n)).load()
    ds.attrs["protocol_name"] = f"{RELAX} (first {seconds:g} s)"
    return ds


def phase_errors(path: Path, params) -> dict:
    """rms/peak [%] of the prediction of the whole run per phase (and, for a hold, before and after SPLIT_AT)."""
    from rdea_lab.calibration import load_run, predict_force
    from rdea_lab.calibration.phases import HOLD, LOADING, UNLOADING, phases

    run = load_run(path)
    e = predict_force(run, params, "su") - run.force
    ph = phases(run.t, run.stretch)
    t = run.t - run.t[0]
    masks = {"loading": ph == LOADING, "unloading": ph == UNLOADING, "hold": ph == HOLD,
             "all": np.ones(run.n, bool)}
    if masks["hold"].any():
        masks[f"hold<={SPLIT_AT:g}s"] = masks["hold"] & (t <= SPLIT_AT)
        masks[f"hold>{SPLIT_AT:g}s"] = masks["hold"] & (t > SPLIT_AT)
    return {k: float(100 * np.sqrt(np.mean(e[m] ** 2)) / run.peak) for k, m in masks.items() if m.sum() > 10}


def fit(inputs, config: str):
    """``M:law``: M Maxwell branches (least squares, grown), ``spectrum`` (its default grid, one decade past the
    longest run) or ``spectrum0`` (the grid ending at the longest run: ``beyond=0``)."""
    from rdea_lab.calibration import Budget, calibrate_runs, gather_runs, initial_guess
    from rdea_lab.calibration.spectrum import fit_spectrum

    M, law = config.split(":")
    if M == "spectrum0":
        runs = gather_runs(inputs)
        return fit_spectrum(runs, initial_guess(runs, 1, 2.8, law=law), beyond=0)
    branches = "spectrum" if M == "spectrum" else int(M)
    return calibrate_runs(inputs, model="su", law=law, branches=branches, method="least-squares",
                          budget=Budget(evaluations=20000, seconds=300))


def jobs(files: dict, splits):
    """``(split, label, inputs, [(name, role, phases to report)])`` of each fit the splits need."""
    lu = [n for n in files if n != RELAX]
    out = []
    if "A" in splits:
        out.append(("A", f"5 LU + {RELAX} first {SPLIT_AT:g} s", [files[n] for n in lu] + [first_part(files[RELAX],
                   SPLIT_AT)], [(RELAX, "held out", (f"hold>{SPLIT_AT:g}s",)),
                               (RELAX, "fitted", ("loading", f"hold<={SPLIT_AT:g}s"))]
                    + [(n, "fitted", ("loading", "unloading")) for n in lu]))
    if "B" in splits:
        out.append(("B", "5 LU", [files[n] for n in lu],
                    [(RELAX, "held out", ("loading", "hold", f"hold<={SPLIT_AT:g}s", f"hold>{SPLIT_AT:g}s"))]
                    + [(n, "fitted", ("loading", "unloading")) for n in lu]))
    if "C" in splits:
        out.append(("C", f"5 LU + {RELAX}", [files[n] for n in files],
                    [(RELAX, "fitted", ("loading", "hold", f"hold<={SPLIT_AT:g}s", f"hold>{SPLIT_AT:g}s"))]
                    + [(n, "fitted", ("loading", "unloading")) for n in lu]))
    for split, with_hold in (("D", True), ("E", False)):
        if split in splits:
            for left in lu:
                names = [n for n in lu if n != left] + ([RELAX] if with_hold else [])
                out.append((split, f"4 LU{' + ' + RELAX if with_hold else ''} (without {left})",
                            [files[n] for n in names], [(left, "held out", ("loading", "unloading", "all"))]))
    return out


def table(rows) -> str:
    """Markdown: one line per (split, configuration, file, role), the phases' rms/peak [%]."""
    cols = ["loading", "unloading", "hold", f"hold<={SPLIT_AT:g}s", f"hold>{SPLIT_AT:g}s", "all"]
    lines = ["| split | config | fit | file | role | " + " | ".join(cols) + " | fit s |",
             "|" + "---|" * (len(cols) + 6)]
    for r in rows:
        cells = [f"{r['errors'][c]:.2f}" if c in r["errors"] and c in r["phases"] else "" for c in cols]
        lines.append(f"| {r['split']} | {r['config']} | {r['fit']} | {r['file']} | {r['role']} | "
                     + " | ".join(cells) + f" | {r['fit_time_s']:.1f} |")
    return "\n".join(lines)


def summary(rows) -> str:
    """Mean held-out rms/peak [%] per split, configuration and phase."""
    acc = {}
    for r in rows:
        if r["role"] != "held out":
            continue
        for ph in r["phases"]:
            if ph in r["errors"]:
                acc.setdefault((r["split"], r["config"], ph), []).append(r["errors"][ph])
    lines = ["| split | config | phase | held-out rms/peak % (mean, max over folds) |", "|---|---|---|---|"]
    for (s, c, ph), v in sorted(acc.items()):
        lines.append(f"| {s} | {c} | {ph} | {np.mean(v):.2f} (max {np.max(v):.2f}, {len(v)} fold(s)) |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", default=CONFIGS)
    ap.add_argument("--splits", default="A,B,C,D,E")
    ap.add_argument("--out", type=Path, help="JSON lines, appended as each fit ends")
    ap.add_argument("--table", type=Path, help="print the tables of a --out file and stop")
    args = ap.parse_args(argv)
    if args.table:
        rows = [json.loads(line) for line in args.table.read_text().splitlines() if line.strip()]
        print(table(rows) + "\n\n" + summary(rows))
        return 0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        files = imported(Path(tmp) / "vhb")
        todo = jobs(files, args.splits.split(","))
        for config in args.configs.split(","):
            for split, label, inputs, report in todo:
                t0 = time.perf_counter()
                res = fit(inputs, config)
                wall = time.perf_counter() - t0
                for name, role, phases_ in report:
                    row = {"split": split, "config": config, "fit": label, "file": name, "role": role,
                           "phases": list(phases_), "errors": phase_errors(files[name], res.params),
                           "fit_time_s": wall, "nfev": res.nfev, "converged": res.converged,
                           "branches": res.params.M, "message": res.message}
                    rows.append(row)
                    if args.out:
                        with open(args.out, "a") as fh:
                            fh.write(json.dumps(row) + "\n")
                    errs = ", ".join(f"{p} {row['errors'][p]:.2f} %" for p in phases_ if p in row["errors"])
                    print(f"{split} {config:22s} {label:40s} {name:12s} {role:8s} {errs}  ({wall:.1f} s)",
                          flush=True)
    print("\n" + table(rows) + "\n\n" + summary(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
