"""The store's share of a day-long run (issue 28): journal appends, finish (netCDF conversion), open_run.

Each length runs in a fresh subprocess (its peak RSS is its own): twin-like samples (a 1 kHz twin run of
the ramp-sine protocol, tiled with time running on) appended with `JournalWriter` in 1 s blocks of 1000
samples, then `finish`; or, with ``--recover``, the writer dropped (as a SIGKILL would) and `recover`.
Printed per length: wall time of the appends and of finish/recover, samples/s end to end (store only),
peak RSS, file size, compression ratio (journal bytes / file bytes), open_run time (median of 5).

    PYTHONPATH=. python3 benchmarks/long_store.py [--lengths 1e6 1e7 8.64e7] [--recover] [--dir DIR]
    PYTHONPATH=. python3 benchmarks/long_store.py --ratios    # twin and emulator runs: compression ratio
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_2.6kV.yaml"
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"

ONE = r"""
import json, os, resource, statistics, sys, time
import numpy as np
from rdea_lab.store import JournalWriter, open_run, recover
src = open_run(sys.argv[1]).load()
n, out, rec = int(float(sys.argv[2])), sys.argv[3], sys.argv[4] == "1"
extra = [v for v in ("model_status",) if v in src]
cols = ["time", *[v for v in src.data_vars]]
base = {c: np.asarray(src[c].values, float) for c in cols}
period = base["time"].size - base["time"].size % 1000
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
w = JournalWriter(out, {k: v.item() if hasattr(v, "item") else v for k, v in src.attrs.items()}, extra=extra)
for a in range(0, n, 1000):
    k = min(1000, n - a)
    j = a % period
    blk = {c: base[c][j:j + k] for c in cols}
    blk["time"] = np.arange(a, a + k) / 1000.0
    w.append(blk)
t1 = time.perf_counter()
if rec:
    w.close(); recover(out)
else:
    w.finish("complete", "")
t2 = time.perf_counter()
opens = []
for _ in range(5):
    s = time.perf_counter(); ds = open_run(out); opens.append(time.perf_counter() - s); ds.close()
size = os.path.getsize(out)
print(json.dumps({"samples": n, "append_s": t1 - t0, "finish_s": t2 - t1, "per_s": n / (t2 - t0),
                  "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "rss0_mb": rss0 / 1024,
                  "file_mb": size / 1e6, "ratio": n * 8 * len(w.columns) / size,
                  "open_s": statistics.median(opens), "open_spread_s": [min(opens), max(opens)]}))
"""


def twin_source(folder: Path) -> Path:
    """A 1 kHz twin run of the ramp-sine protocol at 2.6 kV (20 cycles: 204 s)."""
    text = PROTOCOL.read_text().replace("sample_rate: 100 Hz", "sample_rate: 1000 Hz").replace("cycles: 5",
                                                                                             "cycles: 20")
    proto = folder / "ramp_sine_1kHz.yaml"
    proto.write_text(text)
    out = folder / "source.nc"
    if not out.exists():
        import rdea_lab

        rdea_lab.run_protocol(proto, rdea_lab.load_specimen(CARD), "twin", out=out)
    return out


def ratios(folder: Path) -> None:
    import rdea_lab
    from rdea_lab.store import open_run

    text = PROTOCOL.read_text().replace("sample_rate: 100 Hz", "sample_rate: 1000 Hz")
    proto = folder / "ratio.yaml"
    proto.write_text(text)
    for backend in ("twin", "emulator"):
        out = folder / f"ratio_{backend}.nc"
        out.unlink(missing_ok=True)
        rdea_lab.run_protocol(proto, rdea_lab.load_specimen(CARD), backend, out=out)
        with open_run(out) as ds:
            n, k = ds.sizes["time"], len(ds.variables)
        print(f"{backend}: {n} samples, {k} variables, file {out.stat().st_size / 1e6:.2f} MB, "
              f"journal/file {n * 8 * k / out.stat().st_size:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lengths", nargs="*", default=["1e6", "1e7", "8.64e7"])
    ap.add_argument("--recover", action="store_true")
    ap.add_argument("--ratios", action="store_true")
    ap.add_argument("--dir", default=None)
    args = ap.parse_args()
    folder = Path(args.dir or tempfile.mkdtemp(prefix="long_store_"))
    folder.mkdir(parents=True, exist_ok=True)
    if args.ratios:
        ratios(folder)
        return
    src = twin_source(folder)
    for n in args.lengths:
        out = folder / f"run_{n}.nc"
        out.unlink(missing_ok=True)
        shutil.rmtree(out.with_name(out.name + ".part"), ignore_errors=True)
        done = subprocess.run([sys.executable, "-c", ONE, str(src), n, str(out), "1" if args.recover else "0"],
                              capture_output=True, text=True)
        if done.returncode:
            sys.exit(done.stderr)
        r = json.loads(done.stdout)
        print(f"{r['samples']:.3g} samples: appends {r['append_s']:.1f} s, {'recover' if args.recover else 'finish'} "
              f"{r['finish_s']:.1f} s, {r['per_s'] / 1e6:.2f} M samples/s end to end; peak RSS {r['rss_mb']:.0f} MB "
              f"(after imports {r['rss0_mb']:.0f} MB); file {r['file_mb']:.1f} MB, ratio {r['ratio']:.2f}; "
              f"open_run {r['open_s'] * 1e3:.1f} ms (min {r['open_spread_s'][0] * 1e3:.1f}, max "
              f"{r['open_spread_s'][1] * 1e3:.1f})", flush=True)
        out.unlink(missing_ok=True)


if __name__ == "__main__":
    main()
