"""How soon a pause acts (issue 29): from ``RunControl.pause()`` to the first sample flagged paused, on a run
paced at wall-clock speed (the twin with ``realtime``, the emulated rig in real time), and from
``rdea_lab.runs.control.request`` in another thread (the way ``rdea-lab pause`` and the monitor ask, through
the run's journal folder) to the run's answer.

Each pause is asked at a random moment of a running run and resumed once held; the delay is measured in wall
time (the request to the engine's receiving the block that carries the first paused sample) and in run time
(the first paused sample's time minus that of the newest sample the engine had received at the request: what
the run did after it was asked, the samples in flight to the engine included). Prints one JSON
line per backend with median, p99 and max over ``--pauses`` pauses.

    PYTHONPATH=. python3 benchmarks/pause_latency.py --pauses 40
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"

PROTOCOL = """\
name: pause_latency
kind: custom
sample_rate: 1 kHz
measure: [force]
limits: {{max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}}
pause: {{ramp_rate: 20 kV/s}}
stretch:
  - {{kind: sine, duration: {duration:g} s, mean: 1.2, amplitude: 0.1, frequency: 0.5 Hz}}
voltage:
  - {{kind: hold, duration: {duration:g} s, value: 1 kV}}
"""


class Probe:
    """Asks for pauses at random moments (from its own thread), records when each acts, resumes once held."""

    def __init__(self, control, pauses, seed, folder=None):
        self.control, self.left, self.rng, self.folder = control, pauses, np.random.default_rng(seed), folder
        self.asked = None  # (wall time, newest run time received) of the pending request
        self.latest = 0.0  # time of the newest sample received
        self.delays = []  # (run-time delay [s], wall delay [s])
        self.lock = threading.Lock()
        self.state = "running"

    def start(self, attrs):
        threading.Timer(0.5, self.ask).start()

    def __call__(self, block):
        phase = np.asarray(block["paused"])
        now = time.monotonic()
        with self.lock:
            if self.asked is not None and (phase != 0).any():
                i = int(np.argmax(phase != 0))
                wall, run = self.asked
                self.delays.append((float(block["time"][i]) - run, now - wall))
                self.asked = None
                self.state = "paused"
            elif self.state == "paused" and phase[-1] == 2:
                self.control.resume()
                self.state = "resuming"
            elif self.state == "resuming" and (phase == 0).all():
                self.state = "running"
                if self.left:
                    threading.Timer(self.rng.uniform(0.2, 0.6), self.ask).start()
            self.latest = float(block["time"][-1])

    def ask(self):
        with self.lock:
            self.left -= 1
            wall = time.monotonic()
            self.asked = (wall, self.latest)
        if self.folder is not None:
            from rdea_lab.runs.control import request

            request(self.folder, "pause", "benchmark", by="benchmark", wait=0)
        else:
            self.control.pause("benchmark")


def measure(kind, pauses, seed, through_folder):
    import rdea_lab
    from rdea_lab.runs.control import RunControl

    folder = Path(tempfile.mkdtemp())
    path = folder / "p.yaml"
    path.write_text(PROTOCOL.format(duration=pauses * 1.6 + 5))
    out = folder / "run.nc"
    control = RunControl()
    probe = Probe(control, pauses, seed, out if through_folder else None)
    backend = rdea_lab.Twin(model="su", realtime=True) if kind == "twin" else rdea_lab.Emulator(realtime=True)
    rdea_lab.run_protocol(path, CARD, backend, out=out, control=control, callbacks=[probe])
    run, wall = np.array(probe.delays).T
    q = lambda x: {"median": float(np.median(x)), "p99": float(np.percentile(x, 99)), "max": float(x.max())}  # noqa: E731
    return {"backend": kind, "asked": "journal folder" if through_folder else "in process", "pauses": len(run),
            "run_time_delay_s": q(run), "wall_delay_s": q(wall)}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--pauses", type=int, default=40)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    for kind in ("twin", "emulator"):
        for through_folder in (False, True):
            print(json.dumps(measure(kind, args.pauses, args.seed, through_folder)), flush=True)


if __name__ == "__main__":
    main()
