"""The joint calibration envelope on the real VHB 4910 files, without fitting (issue 27).

Leave-one-out over the five loading-unloading files: each file judged against the envelope of the
other four (`rdea_lab.calibration.envelope`); then the step-and-hold test relax_2d0 against the
five. Prints each fold's flags, the number of points each envelope keeps and the time taken.

    python3 benchmarks/vhb_envelope.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from vhb_crossval import ROOT, VHB


def main() -> int:
    from rdea_lab.calibration.envelope import beyond, envelope, run_envelope
    from rdea_lab.calibration.objective import load_run
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    with tempfile.TemporaryDirectory() as tmp:
        rc = run_cli(cli, ["import", *map(str, sorted(VHB.glob("*.csv"))), "--format", "csv", "--map",
                           "time=0,position=1,force=2", "--protocol-kind", "tensile", "--specimen",
                           str(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"), "--out", tmp])
        if rc:
            sys.exit(f"import failed ({rc})")
        runs = {p.stem: load_run(p) for p in sorted(Path(tmp).glob("0d*.nc"))}
        relax = load_run(Path(tmp) / "relax_2d0.nc")
    t0 = time.perf_counter()
    for name, run in runs.items():
        env = envelope([r for k, r in runs.items() if k != name])
        flags = beyond(env, run_envelope(run))
        print(f"leave out {name:11s} ({len(env.points)} points): {'; '.join(flags) or 'inside'}")
    five = envelope(list(runs.values()))
    print(f"relax_2d0 against the five ({len(five.points)} points): {'; '.join(beyond(five, relax))}")
    with_relax = envelope([*runs.values(), relax])
    print(f"the five and relax_2d0: {len(with_relax.points)} points; {with_relax.describe()}")
    print(f"({time.perf_counter() - t0:.2f} s for the envelopes and flags)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
