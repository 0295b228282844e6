"""Throughput of a long twin (or emulator) run end to end, and its peak memory (issue 28).

Runs ``rdea_lab/data/protocols/fatigue_24h.yaml`` (a ramp-sine stretch at 1 Hz under 2.6 kV, 1 kHz)
shortened to ``--samples`` samples, on specimen 2 with the SU twin (or ``--backend emulator``), each
length in a fresh subprocess so that its peak RSS (``resource.getrusage(RUSAGE_SELF).ru_maxrss``) is its
own. Prints one JSON line per run: samples, the times of preparation (the limit check, window by
window), of the acquisition loop (backend + engine + journal appends, to the last block) and of the
journal's finish (the netCDF conversion), samples/s end to end and of the loop, the peak RSS [MB] up to
the last block (``loop_peak_rss_MB``) and over the whole run (``peak_rss_MB``, the finish included).

``--no-fsync`` stubs out ``os.fsync`` in the journal, to time the plan, backend and engine alone (the
journal's fsync and finish are the store's); ``--no-finish`` leaves the journal unconverted (its
samples file is then the file whose size is given).

    PYTHONPATH=. python3 benchmarks/twin_throughput.py --samples 1e6 1e7 [--no-fsync] [--backend emulator]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "rdea_lab" / "data"


def protocol(samples: int, rate: float = 1000.0):
    """fatigue_24h with its ramp sine shortened so that the protocol has `samples` samples."""
    import yaml

    from rdea_lab.specs import protocol_from_mapping

    mapping = yaml.safe_load((DATA / "protocols" / "fatigue_24h.yaml").read_text())
    duration = (samples - 1) / rate
    middle = duration - 10.0  # the 5 s holds (ramps) either side
    mapping["name"] = f"fatigue_{samples}"
    mapping["stretch"][1]["duration"] = f"{middle!r} s"
    mapping["voltage"][1]["duration"] = f"{middle!r} s"
    return protocol_from_mapping(mapping, f"<fatigue_24h shortened to {samples} samples>")


def one(samples: int, backend: str, fsync: bool, out: Path, finish: bool = True) -> dict:
    import resource

    import rdea_lab.store.journal as journal
    from rdea_lab.runs import Emulator, Twin, execute_setup, prepare_run

    if not fsync:
        journal.os = _NoFsync(journal.os)
    if not finish:  # the journal is left as it is (its size is the file's): no netCDF conversion
        def kept(writer, status, reason, history=""):
            writer.close()
            return writer.dir / "samples.f8"

        journal.JournalWriter.finish = kept
    t0 = time.perf_counter()
    spec = protocol(samples)
    which = Twin(model="su") if backend == "twin" else Emulator()
    setup = prepare_run(spec, DATA / "specimens" / "specimen2.yaml", which, out=out)
    t1 = time.perf_counter()
    marks = {}

    def last_block(block):
        marks["loop"] = time.perf_counter()
        if block.samples == block.planned:  # the peak before the journal's finish (the store's conversion)
            marks["loop_rss"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    result = execute_setup(setup, callbacks=[last_block])
    t2 = time.perf_counter()
    assert result.status == "complete" and result.samples == samples, result
    out = result.path
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # [MB] (Linux: kB)
    return {"samples": samples, "backend": backend, "fsync": fsync, "prepare_s": round(t1 - t0, 2),
            "loop_s": round(marks["loop"] - t1, 2), "finish_s": round(t2 - marks["loop"], 2),
            "end_to_end_samples_per_s": round(samples / (t2 - t0)),
            "loop_samples_per_s": round(samples / (marks["loop"] - t1)),
            "loop_peak_rss_MB": round(marks["loop_rss"]), "peak_rss_MB": round(rss),
            "file_MB": round(out.stat().st_size / 1e6, 1)}


class _NoFsync:
    """``os`` with ``fsync`` doing nothing (the benchmark of the plan, backend and engine alone)."""

    def __init__(self, os_module):
        self._os = os_module

    def __getattr__(self, name):
        return (lambda fd: None) if name == "fsync" else getattr(self._os, name)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, nargs="+", default=[1e6, 1e7])
    parser.add_argument("--backend", choices=("twin", "emulator"), default="twin")
    parser.add_argument("--no-fsync", action="store_true")
    parser.add_argument("--no-finish", action="store_true")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        with tempfile.TemporaryDirectory() as tmp:
            row = one(int(args.samples[0]), args.backend, not args.no_fsync, Path(tmp) / "run.nc",
                      not args.no_finish)
        print(json.dumps(row))
        return
    for n in args.samples:
        for _ in range(args.repeat):
            cmd = [sys.executable, __file__, "--child", "--samples", str(int(n)), "--backend", args.backend]
            cmd += ["--no-fsync"] if args.no_fsync else []
            cmd += ["--no-finish"] if args.no_finish else []
            done = subprocess.run(cmd, capture_output=True, text=True)
            print(done.stdout.strip() or done.stderr.strip()[-2000:], flush=True)


if __name__ == "__main__":
    main()
