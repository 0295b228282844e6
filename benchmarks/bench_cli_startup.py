"""Start-up time of the ``rdea-lab`` command line (issue 24: ``rdea-lab --help`` <= 0.3 s).

Runs each command line ``--repeat`` times in a fresh process (after one
warm-up run, so the file cache is warm) and prints the median wall time with
the fastest and slowest run beside it. Measured, not asserted: the machine's
load moves these numbers; the import graph (what ``import rdea_lab.cli.main``
loads) is what the tests check.

Usage::

    python3 benchmarks/bench_cli_startup.py [--repeat 10] [--json]
    python3 benchmarks/bench_cli_startup.py -- rdea-lab geometry specimen2
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time

COMMANDS = (
    (sys.executable, "-m", "rdea_lab.cli.main", "--help"),
    ("rdea-lab", "--help"),
    (sys.executable, "-m", "rdea_lab.cli.main", "calibrate", "--help"),
    (sys.executable, "-m", "rdea_lab.cli.main", "geometry", "specimen2"),
    (sys.executable, "-c", "pass"),  # the interpreter alone: the floor
)


def time_command(argv, repeat: int) -> dict:
    """Wall times [s] of `repeat` runs of `argv` (after one untimed warm-up)."""
    env = dict(os.environ)
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, check=False)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, check=False)
        times.append(time.perf_counter() - t0)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(argv)}: exit {done.returncode}: {done.stderr.decode().strip()}")
    return {"command": " ".join("python3" if a == sys.executable else a for a in argv),
            "median_s": statistics.median(times), "min_s": min(times), "max_s": max(times), "runs": repeat}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("command", nargs="*", help="one command line to time instead of the default set")
    args = parser.parse_args(argv)
    commands = [tuple(args.command)] if args.command else [c for c in COMMANDS if shutil.which(c[0])]
    rows = [time_command(list(c), args.repeat) for c in commands]
    if args.json:
        print(json.dumps({"load_average": os.getloadavg(), "rows": rows}, indent=2))
        return 0
    print(f"load average {os.getloadavg()[0]:.2f}; {args.repeat} runs each, median (fastest-slowest)")
    for r in rows:
        print(f"  {r['median_s']:6.3f} s ({r['min_s']:.3f}-{r['max_s']:.3f})  {r['command']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
