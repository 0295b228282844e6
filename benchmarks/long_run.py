"""Day-long runs end to end (issue 28): a 24 h twin run at 1 kHz, an emulator run, memory against run length,
and SIGKILL at random moments.

    python benchmarks/long_run.py                # the issue's figures (24 h twin run: 8.64e7 samples)
    python benchmarks/long_run.py --quick        # a smoke run of a few seconds' worth of samples
    python benchmarks/long_run.py --samples 1e7 --emulator-samples 1e6 --lengths 1e5,1e6,1e7 --kill 5

What it measures (every run in a subprocess, as a user runs it, so that its peak RSS is its own:
``os.wait4``'s ``ru_maxrss`` of that child):

(a) ``rdea-lab run`` of a ramp-sine fatigue protocol (the one of ``rdea_lab/data/protocols/fatigue_24h.yaml``
    when the package has it and the length is 24 h, else the same shape written to the temporary folder at
    the length asked for) on the twin (``--model su``) and on the emulator: samples/s end to end (the
    command's wall time, start-up included), peak RSS, the file's size and its compression ratio (the
    variables' bytes uncompressed over the file's size); then in fresh processes the time of ``open_run``
    (the call only, after the imports), of ``rdea-lab show FILE --plot PNG`` and of ``rdea-lab ls DIR`` (whole
    commands), with their peak RSS.
(b) The twin run's peak RSS at three lengths (``--lengths``), and of ``show --plot`` on each file.
(c) ``--kill N``: N twin runs paced at wall-clock speed (``--realtime``) killed with SIGKILL at a random moment,
    then ``rdea-lab recover``: the samples lost, the samples the run had produced (its pace from the wall time
    of its first block, reported by a subscriber over a pipe) minus those recovered, in seconds of the run;
    and one long run (as fast as it goes) killed at a random moment, to time ``recover`` on a long journal.

Repeated measurements (``--repeat``, the kills) print as median [min, max]. The run length goals of the
issue: >= 1e6 samples/s, peak RSS <= 500 MB, <= 1 s lost to a SIGKILL, open_run <= 1 s, show <= 5 s.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPECIMEN = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
FATIGUE = ROOT / "rdea_lab" / "data" / "protocols" / "fatigue_24h.yaml"
DAY = 86_400_001  # 24 h at 1 kHz, both ends included
RATE = 1000.0


def fatigue_protocol(samples: int, folder: Path) -> Path:
    """A ramp-sine fatigue protocol of ``samples`` samples at 1 kHz: C's ``fatigue_24h.yaml`` for a day, else
    the same shape (5 s holds and voltage ramps at each end, 1 Hz stretch sine, peak 1.05 -> 1.5) scaled."""
    if samples == DAY and FATIGUE.is_file():
        return FATIGUE
    total = (samples - 1) / RATE
    end = min(5.0, total / 10.0)
    middle = total - 2 * end
    text = textwrap.dedent(f"""\
        name: fatigue_{samples}
        kind: tensile
        description: fatigue, ramp sine stretch 1 -> 1.05..1.5 at 1 Hz under 2.6 kV, 1 kHz ({samples} samples)
        source: benchmarks/long_run.py (the shape of fatigue_24h.yaml, shortened)
        sample_rate: 1 kHz
        measure: [force]
        limits: {{max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}}
        stretch:
          - {{kind: hold, duration: {end!r} s, value: 1.0}}
          - {{kind: ramp_sine, duration: {middle!r} s, frequency: 1 Hz, base: 1.0, peak_start: 1.05, peak_end: 1.5}}
          - {{kind: hold, duration: {end!r} s, value: 1.0}}
        voltage:
          - {{kind: ramp, duration: {end!r} s, from: 0 V, to: 2.6 kV}}
          - {{kind: hold, duration: {middle!r} s, value: 2.6 kV}}
          - {{kind: ramp, duration: {end!r} s, to: 0 V}}
        """)
    path = folder / f"fatigue_{samples}.yaml"
    path.write_text(text)
    return path


def env() -> dict:
    """The children's environment: this one's (PYTHONPATH included), unbuffered, headless."""
    return dict(os.environ, PYTHONUNBUFFERED="1", MPLBACKEND="Agg")


def _popen_wait(cmd) -> dict:
    """Run ``cmd``: its wall time [s], peak RSS [MB] (its own, from wait4), exit status and output."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env(), text=True)
    out, err = [], []
    threads = [threading.Thread(target=lambda s, acc: acc.append(s.read()), args=(s, acc), daemon=True)
               for s, acc in ((p.stdout, out), (p.stderr, err))]
    for t in threads:
        t.start()
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    for t in threads:
        t.join()
    p.returncode = os.waitstatus_to_exitcode(status)
    return {"wall": wall, "rss_mb": usage.ru_maxrss / 1024.0, "rc": p.returncode, "stdout": "".join(out),
            "stderr": "".join(err)}


def cli(*args) -> list[str]:
    return [sys.executable, "-m", "rdea_lab.cli", *map(str, args)]


def checked(result: dict, what: str) -> dict:
    if result["rc"] != 0:
        tail = (result["stderr"] or result["stdout"]).strip().splitlines()[-3:]
        raise RuntimeError(f"{what} failed (exit {result['rc']}): {' | '.join(tail)}")
    return result


def file_figures(path: Path) -> dict:
    """Samples, the file's size [MB] and the compression ratio (the variables' uncompressed bytes / size),
    from the file's metadata only (no data read)."""
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        raw = sum(v.size * v.dtype.itemsize for v in nc.variables.values())
        samples = len(nc.dimensions["time"])
        ranges = sum("actual_range" in v.ncattrs() for v in nc.variables.values())
    size = path.stat().st_size
    return {"samples": samples, "size_mb": size / 1e6, "ratio": raw / size if size else math.nan,
            "actual_range_vars": ranges}


OPEN_CODE = ("import sys, time\nfrom rdea_lab.store import open_run\nt = time.perf_counter()\n"
             "ds = open_run(sys.argv[1])\nprint(time.perf_counter() - t)\n")


def run_twin(protocol: Path, out: Path, backend="twin", extra=()) -> dict:
    args = [protocol, "--specimen", SPECIMEN, "--backend", backend, "--out", out, "--quiet", "--force", *extra]
    if backend == "twin":
        args += ["--model", "su"]
    return checked(_popen_wait(cli("run", *args)), f"rdea-lab run ({backend})")


def measure_file(path: Path, png: Path) -> dict:
    """open_run (call only), show --plot and ls (whole commands) on one file, each in a fresh process."""
    opened = checked(_popen_wait([sys.executable, "-c", OPEN_CODE, str(path)]), "open_run")
    shown = checked(_popen_wait(cli("show", path, "--plot", png)), "rdea-lab show --plot")
    listed = checked(_popen_wait(cli("ls", path.parent)), "rdea-lab ls")
    return {"open_s": float(opened["stdout"].split()[-1]), "open_rss_mb": opened["rss_mb"],
            "show_s": shown["wall"], "show_rss_mb": shown["rss_mb"], "ls_s": listed["wall"],
            "ls_rss_mb": listed["rss_mb"]}


def spread(values) -> str:
    values = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    if not values:
        return "-"
    med = statistics.median(values)
    return f"{med:.4g}" if len(values) == 1 else f"{med:.4g} [{min(values):.4g}, {max(values):.4g}]"


def part_a(args, folder: Path, table: list) -> None:
    startup = [checked(_popen_wait(cli("--version")), "rdea-lab --version")["wall"] for _ in range(3)]
    row = {"part": "a", "what": "CLI start-up (rdea-lab --version), in each command's time",
           "seconds": spread(startup)}
    table.append(row)
    print(json.dumps(row), flush=True)
    for backend, samples in (("twin", args.samples), ("emulator", args.emulator_samples)):
        protocol = fatigue_protocol(samples, folder)
        runs = []
        for k in range(args.repeat):
            out = folder / backend / f"run{k}.nc"
            out.parent.mkdir(exist_ok=True)
            r = run_twin(protocol, out, backend)
            runs.append({**r, **file_figures(out), **measure_file(out, folder / f"{backend}{k}.png")})
        n = runs[0]["samples"]
        row = {"part": "a", "what": f"{backend} run", "samples": n,
               "samples_per_s": spread([n / r["wall"] for r in runs]),
               "peak_rss_mb": spread([r["rss_mb"] for r in runs]),
               "file_mb": spread([r["size_mb"] for r in runs]), "compression": spread([r["ratio"] for r in runs]),
               "open_run_s": spread([r["open_s"] for r in runs]), "show_s": spread([r["show_s"] for r in runs]),
               "show_rss_mb": spread([r["show_rss_mb"] for r in runs]), "ls_s": spread([r["ls_s"] for r in runs]),
               "open_rss_mb": spread([r["open_rss_mb"] for r in runs]),
               "actual_range": runs[0]["actual_range_vars"]}
        table.append(row)
        print(json.dumps(row), flush=True)


def part_b(args, folder: Path, table: list) -> None:
    for samples in args.lengths:
        protocol = fatigue_protocol(samples, folder)
        out = folder / "lengths" / f"run_{samples}.nc"
        out.parent.mkdir(exist_ok=True)
        r = run_twin(protocol, out)
        shown = checked(_popen_wait(cli("show", out, "--plot", folder / f"len{samples}.png")), "show")
        row = {"part": "b", "what": "twin run, memory against length", "samples": samples,
               "samples_per_s": f"{samples / r['wall']:.4g}", "peak_rss_mb": f"{r['rss_mb']:.4g}",
               "show_s": f"{shown['wall']:.4g}", "show_rss_mb": f"{shown['rss_mb']:.4g}",
               "file_mb": f"{out.stat().st_size / 1e6:.4g}"}
        table.append(row)
        print(json.dumps(row), flush=True)
        out.unlink()


KILL_CODE = """
import sys, time
from rdea_lab.runs.app import run_protocol
from rdea_lab.runs.backend import Twin
rate = float(sys.argv[4])
def first(block):
    if block.first == 0:  # the run's start on the wall clock: now, less the block's samples at its pace
        print("T0", time.time() - block.samples / rate, flush=True)
run_protocol(sys.argv[1], sys.argv[2], Twin(model="su", realtime=sys.argv[5] == "1"), out=sys.argv[3],
             overwrite=True, callbacks=[first])
"""


def kill_trial(protocol: Path, out: Path, at: float, realtime: bool) -> dict:
    """Start a run, SIGKILL it ``at`` seconds after its first block, recover it; what was lost."""
    p = subprocess.Popen([sys.executable, "-c", KILL_CODE, str(protocol), str(SPECIMEN), str(out), str(RATE),
                          "1" if realtime else "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env(),
                         text=True)
    line = p.stdout.readline()
    if not line.startswith("T0"):
        p.kill()
        raise RuntimeError(f"kill trial: the run did not start ({line!r} {p.stderr.read()[-300:]!r})")
    t0 = float(line.split()[1])
    time.sleep(max(0.0, t0 + at - time.time()))
    p.send_signal(signal.SIGKILL)
    killed = time.time()
    p.wait()
    journal = out.with_name(out.name + ".part")
    size = sum(f.stat().st_size for f in journal.rglob("*") if f.is_file()) if journal.exists() else 0
    rec = _popen_wait(cli("recover", journal))
    if rec["rc"] != 0:
        return {"ok": False, "why": (rec["stderr"] or rec["stdout"]).strip()[-200:]}
    recovered = file_figures(out)["samples"]
    produced = (killed - t0) * RATE if realtime else math.nan
    return {"ok": True, "seconds": killed - t0, "recovered": recovered, "lost_s": (produced - recovered) / RATE,
            "recover_s": rec["wall"], "recover_rss_mb": rec["rss_mb"], "journal_mb": size / 1e6}


def part_c(args, folder: Path, table: list) -> None:
    rng = random.Random(args.seed)
    paced = fatigue_protocol(int(RATE * (args.kill_seconds + 5)) + 1, folder)
    trials = []
    for k in range(args.kill):
        out = folder / "kill" / f"k{k}.nc"
        out.parent.mkdir(exist_ok=True)
        trials.append(kill_trial(paced, out, rng.uniform(0.5, args.kill_seconds), realtime=True))
    good = [t for t in trials if t["ok"]]
    row = {"part": "c", "what": f"SIGKILL at random (realtime twin, {len(good)} of {len(trials)} recovered)",
           "seconds_run": spread([t["seconds"] for t in good]), "lost_s": spread([t["lost_s"] for t in good]),
           "recover_s": spread([t["recover_s"] for t in good]), "failures": [t["why"] for t in trials if not t["ok"]]}
    table.append(row)
    print(json.dumps(row), flush=True)
    long = fatigue_protocol(args.samples, folder)
    out = folder / "kill" / "long.nc"
    t = kill_trial(long, out, rng.uniform(0.3, 0.9) * args.samples / args.expected_rate, realtime=False)
    row = {"part": "c", "what": "SIGKILL of the long run (as fast as it goes), recover", **(
        {k: f"{t[k]:.4g}" for k in ("seconds", "recovered", "journal_mb", "recover_s", "recover_rss_mb")}
        if t["ok"] else {"failure": t["why"]})}
    table.append(row)
    print(json.dumps(row), flush=True)


def print_table(table: list) -> None:
    """One Markdown table per part (its own columns)."""
    for part in dict.fromkeys(row["part"] for row in table):
        rows = [r for r in table if r["part"] == part]
        keys = [k for k in dict.fromkeys(k for row in rows for k in row) if k != "part"]
        print(f"\n({part})\n| " + " | ".join(keys) + " |\n|" + "---|" * len(keys))
        for row in rows:
            print("| " + " | ".join(str(row.get(k, "")) for k in keys) + " |")


def number(text: str) -> int:
    return int(float(text))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=number, default=DAY, help="twin run length [samples] (default 24 h at 1 kHz)")
    ap.add_argument("--emulator-samples", type=number, default=10_000_001)
    ap.add_argument("--lengths", type=lambda s: [number(x) for x in s.split(",")],
                    default=[1_000_001, 10_000_001, DAY], help="(b): run lengths, comma-separated")
    ap.add_argument("--repeat", type=int, default=1, help="(a): repeats of each run")
    ap.add_argument("--kill", type=int, default=5, help="(c): SIGKILL trials (0: none)")
    ap.add_argument("--kill-seconds", type=float, default=20.0, help="(c): latest kill after the start [s]")
    ap.add_argument("--expected-rate", type=float, default=1e6,
                    help="(c): the twin's samples/s, to kill the long run in its middle")
    ap.add_argument("--parts", default="abc", help="which of a, b, c to run")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", metavar="DIR", help="work in DIR and keep the files (default: a temporary folder)")
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: 2e5-sample twin, 5e4 emulator, lengths 2e4,1e5,2e5, 2 kills within 3 s")
    args = ap.parse_args(argv)
    if args.quick:
        args.samples, args.emulator_samples, args.lengths = 200_001, 50_001, [20_001, 100_001, 200_001]
        args.kill, args.kill_seconds, args.expected_rate = 2, 3.0, 1e5
    table = []
    with tempfile.TemporaryDirectory(prefix="long_run_") as tmp:
        folder = Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for part, fn in (("a", part_a), ("b", part_b), ("c", part_c)):
            if part in args.parts and (part != "c" or args.kill):
                try:
                    fn(args, folder, table)
                except RuntimeError as exc:  # a part that cannot run yet (a missing interface): say so, go on
                    table.append({"part": part, "what": "FAILED", "why": str(exc)[:300]})
                    print(f"part {part}: {exc}", file=sys.stderr, flush=True)
    print_table(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
