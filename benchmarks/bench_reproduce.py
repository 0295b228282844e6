"""Wall time of ``rdea-lab reproduce``, warm and cold, with its time by stage (``rdea-lab bench --reproduce``).

Each run is the command itself in a fresh process (``python3 -m rdea_lab.cli.main
reproduce --out <fresh temporary folder> --quiet``), timed from outside: the
total includes the interpreter's start and every import. The stage times are
the ones the command prints (0.1 s resolution; with more than one process the
campaign, the calibration and the models overlap, so the stages add up to more
than the total).

- **warm**: one untimed warm-up run (it fills numba's cache and ``__pycache__``
  as a user's first run does), then ``repeat`` timed runs.
- **cold**: ``cold`` runs, each with an empty ``NUMBA_CACHE_DIR`` (every kernel
  compiled) and an empty ``PYTHONPYCACHEPREFIX`` (no byte code reused: every
  module compiled from source), as the first run after a fresh install.

Figures are medians with the spread (fastest and slowest run) beside them. The
load average before each run is recorded with it: on a shared machine the
figures mean little without it.

Run as ``python3 benchmarks/bench_reproduce.py [--repeat N] [--cold N] [--json] [-- REPRODUCE OPTIONS]``;
the ``rdea_lab`` measured is this checkout's (put first on ``PYTHONPATH``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_STAGE = re.compile(r"^  (\S(?:.*\S)?)\s+([0-9.]+) s$")


def _one(extra_env: dict | None = None, args=()) -> dict:
    """One ``reproduce`` in a fresh process into a fresh folder: wall time, stage times, load before."""
    env = dict(os.environ, **(extra_env or {}))
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [env.get("PYTHONPATH")] if p])  # this checkout's
    with tempfile.TemporaryDirectory(prefix="bench-reproduce-") as tmp:
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "rdea_lab.cli.main", "reproduce", "--out", str(Path(tmp) / "out"),
                               "--quiet", *args], env=env, cwd=tmp, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"reproduce exited with {proc.returncode}: {proc.stderr.strip()[-2000:]}")
    table = proc.stdout.split("time by stage:", 1)[1].splitlines()[1:]
    stages = {m.group(1): float(m.group(2)) for m in map(_STAGE.match, table) if m}
    return {"wall_s": wall, "stages_s": stages, "load_before": load}


def _summary(runs: list[dict]) -> dict:
    """Median, fastest and slowest of the total and of each stage."""
    def stat(values):
        return {"median": statistics.median(values), "min": min(values), "max": max(values)}

    names = list(dict.fromkeys(k for r in runs for k in r["stages_s"]))
    return {"runs": len(runs), "wall_s": stat([r["wall_s"] for r in runs]),
            "stages_s": {k: stat([r["stages_s"][k] for r in runs if k in r["stages_s"]]) for k in names},
            "load_before": stat([r["load_before"] for r in runs]), "each": runs}


def run(repeat: int = 3, cold: int = 1, args=()) -> dict:
    """Warm: a warm-up, then ``repeat`` timed runs; cold: ``cold`` runs without numba's cache or byte code.

    ``args``: more options for ``reproduce`` (e.g. ``("--pdf",)`` or ``("--workers", "1")``).
    """
    args = tuple(args)
    out = {"python": platform.python_version(), "machine": platform.machine(), "cores": os.cpu_count(),
           "args": list(args), "command": "python3 -m rdea_lab.cli.main reproduce --out TMP --quiet " + " ".join(args)}
    if repeat:
        _one(args=args)  # warm-up: numba's cache and __pycache__ filled
        out["warm"] = _summary([_one(args=args) for _ in range(repeat)])
    if cold:
        runs = []
        for _ in range(cold):
            with tempfile.TemporaryDirectory(prefix="bench-numba-") as numba, \
                    tempfile.TemporaryDirectory(prefix="bench-pyc-") as pyc:
                runs.append(_one({"NUMBA_CACHE_DIR": numba, "PYTHONPYCACHEPREFIX": pyc}, args))
        out["cold"] = _summary(runs)
    return out


def format_text(r: dict) -> str:
    lines = [f"rdea-lab reproduce ({r['command']}; Python {r['python']}, {r['cores']} cores)"]
    for key, title in (("warm", "warm"), ("cold", "cold (empty NUMBA_CACHE_DIR and PYTHONPYCACHEPREFIX)")):
        if key not in r:
            continue
        s = r[key]
        lines.append(f"{title}: {s['runs']} runs, load average before {s['load_before']['median']:.2f} "
                     f"({s['load_before']['min']:.2f}-{s['load_before']['max']:.2f})")
        lines.append(f"  {'stage':<15} {'median':>8} {'min-max':>15}")
        for name, v in s["stages_s"].items():
            lines.append(f"  {name:<15} {v['median']:7.1f}s {v['min']:7.1f}-{v['max']:.1f} s")
        w = s["wall_s"]
        lines.append(f"  {'wall (process)':<15} {w['median']:7.1f}s {w['min']:7.1f}-{w['max']:.1f} s")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed warm runs after the warm-up (0: none)")
    ap.add_argument("--cold", type=int, default=1, help="cold runs (0: none)")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("reproduce_args", nargs="*", help="more options for reproduce, after --, e.g. -- --pdf")
    a = ap.parse_args(argv)
    result = run(a.repeat, a.cold, a.reproduce_args)
    print(json.dumps(result, indent=2) if a.json else format_text(result))


if __name__ == "__main__":
    main()
