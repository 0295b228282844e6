"""How fast each method reaches the optimum on the five VHB 4910 loading-unloading files.

Finite-strain law (by default), M branches grown from the data (`calibrate_runs`, as ``rdea-lab
calibrate`` does), SU at 0 V, metric rms. Per method and repeat: wall time, evaluations, objective,
converged; then Nelder-Mead's optimum against least squares' (relative difference of the objective and
of each parameter). The machine may be shared: the median of ``--repeat`` runs is printed.

    python3 benchmarks/vhb_fit_speed.py [--M 2] [--law finite_strain] [--methods nelder-mead,least-squares]
                                        [--repeat 3] [--out results.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from vhb_crossval import imported  # noqa: E402


def by_time_scale(values: dict) -> dict:
    """``values`` with the branches renumbered from the fastest (tau = eta / modulus) to the slowest."""
    spring = "mu" if any(k.startswith("mu_v") for k in values) else "k"
    M = sum(k.startswith(f"{spring}_v") for k in values)
    order = sorted(range(1, M + 1), key=lambda j: values[f"eta_v{j}"] / values[f"{spring}_v{j}"])
    out = {k: v for k, v in values.items() if not k.startswith((f"{spring}_v", "eta_v")) or k == "eta_v0"}
    for new, j in enumerate(order, start=1):
        out[f"{spring}_v{new}"], out[f"eta_v{new}"] = values[f"{spring}_v{j}"], values[f"eta_v{j}"]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--M", type=int, default=2)
    ap.add_argument("--law", default="finite_strain")
    ap.add_argument("--methods", default="nelder-mead,least-squares")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--warm-start", default="auto", help="Nelder-Mead's start: auto, least-squares or none")
    ap.add_argument("--out", type=Path, help="JSON results")
    args = ap.parse_args(argv)
    from rdea_lab.calibration import Budget, calibrate_runs

    rows, best = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        data = imported(Path(tmp) / "vhb")
        for method in args.methods.split(","):
            for k in range(args.repeat):
                res = calibrate_runs(str(data), model="su", law=args.law, branches=args.M, method=method,
                                     budget=Budget(evaluations=20000, seconds=args.seconds),
                                     **({"warm_start": args.warm_start} if method == "nelder-mead" else {}))
                rows.append({"method": method, "repeat": k, "wall_time_s": res.wall_time, "nfev": res.nfev,
                             "objective": res.objective, "converged": res.converged, "message": res.message,
                             "values": res.values})
                best[method] = res
                print(f"{method:14s} #{k}: {res.wall_time:7.1f} s {res.nfev:6d} evals objective "
                      f"{res.objective:.8e} converged {res.converged}: {res.message}", flush=True)
            mine = [r for r in rows if r["method"] == method]
            print(f"{method:14s} median of {len(mine)}: {statistics.median(r['wall_time_s'] for r in mine):.1f} s, "
                  f"{statistics.median(r['nfev'] for r in mine):.0f} evaluations", flush=True)
    if {"nelder-mead", "least-squares"} <= set(best):
        nm, ls = best["nelder-mead"], best["least-squares"]
        print(f"objective: NM {nm.objective:.8e}, LSQ {ls.objective:.8e}, rel. diff "
              f"{(nm.objective - ls.objective) / ls.objective:+.2e}")
        a, b = by_time_scale(nm.values), by_time_scale(ls.values)  # the branches' order is no property of the fit
        for name, v in b.items():
            rel = (a[name] - v) / v if v else float("nan")
            print(f"  {name:8s} NM {a[name]:12.6g}  LSQ {v:12.6g}  rel. diff {rel:+.2e}")
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
