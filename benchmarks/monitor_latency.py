"""Latency of ``rdea-lab monitor``: from a sample made on the rig to its arrival in a browser.

Three processes, as in use: a realtime emulated rig and the run that drives it (a child of this script: the
rig server and ``run_protocol`` through the rig protocol), the monitor (this process), and a headless
chromium with the monitor's page. The realtime emulator makes sample k at wall time ``t0 + k / rate``
(`rdea_lab.emulator.rigstate`: ``advance_realtime``, ``t0`` the run's ``INIT`` on the rig's monotonic clock,
which the child turns into wall time and hands over). A small CustomJS on the live source's ``streaming``
event records, for every update the page receives, ``Date.now()`` and the newest sample's time ``t``; the
latency of that sample is ``arrival - (t0_wall + t)``.

What it includes: the rig's production (its producer thread, every 20 ms), the driver's fetch (``FETC?``;
a poll every 20 ms when nothing is ready), the engine's journal append, the monitor's tick (`TICK`, 100 ms,
the largest part: a sample waits for the next tick, 50 ms on average), the websocket and BokehJS's update of
the source. Measured, not asserted: the machine's load moves it. The JSON also gives the rig -> journal part
(``journal_*``: a thread tailing the journal every 10 ms) and the server's time per viewer tick (``tick_*``).

Measured here (shared 2-core machine, 1 kHz, 40 s, ~370 updates), median / p99: 68 / 192 ms (load average
~1.7), 97 / 287 ms (~2), 136 / 562 ms (~2.4; a run recording ``paused``, shaded), 202 / 946 ms (~3). Journal
~6 ms, tick ~2 ms: the rest is the 100 ms tick and the browser's redraw, which grows with the load and with
the points kept (30000 points made the browser fall behind without bound; hence KEEP = 10000).

Usage::

    python3 benchmarks/monitor_latency.py [--seconds 40] [--rate 1000] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

PROTOCOL = """name: latency
kind: custom
description: a realtime run for the monitor's latency benchmark
source: benchmarks/monitor_latency.py
sample_rate: {rate} Hz
measure: [force]
limits: {{max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}}
stretch:
  - {{kind: sine, duration: {seconds} s, mean: 1.3, amplitude: 0.05, frequency: 0.5 Hz}}
voltage:
  - {{kind: sine, duration: {seconds} s, mean: 1 kV, amplitude: 0.5 kV, frequency: 1 Hz}}
"""

RECORD = """
if (window.__latency === undefined) window.__latency = [];
const t = source.data.time;
if (t.length) window.__latency.push([Date.now(), t[t.length - 1]]);
"""


def rig_run(protocol: str, out: str, t0_file: str) -> None:
    """The child: a realtime emulated rig on loopback and a run through the rig protocol; writes the run's
    ``t0`` as wall time [s] into ``t0_file`` once the rig says RUNNING."""
    from rdea_lab import run_protocol
    from rdea_lab.emulator import RigServer
    from rdea_lab.runs.backend import DEFAULT_TRUTH, Rig, project_default
    from rdea_lab.specs import load_specimen
    from rdea_lab.specs.truth import load_truth

    card = load_specimen("specimen2")
    server = RigServer(card, load_truth(project_default(None, DEFAULT_TRUTH, "truth")), port=0, realtime=True)
    host, port = server.start()
    rig = server.controller.rig

    def watch():
        while rig.state != "RUNNING":
            time.sleep(0.001)
        wall_minus_mono = time.time() - time.monotonic()  # the rig's clock is time.monotonic
        Path(t0_file).write_text(json.dumps({"t0_wall": wall_minus_mono + rig._t0}))

    threading.Thread(target=watch, daemon=True).start()
    try:
        run_protocol(protocol, card, Rig(f"tcp://{host}:{port}"), out=out)
    finally:
        server.shutdown()


def percentile(values, q):
    s = sorted(values)
    k = (len(s) - 1) * q
    lo, hi = int(k), min(int(k) + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (k - lo)


def measure(seconds: float, rate: float) -> dict:
    from bokeh.models import CustomJS
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    from rdea_lab.monitor import Monitor

    work = Path(tempfile.mkdtemp(prefix="rdea-monitor-latency-"))
    runs = work / "runs"
    runs.mkdir()
    protocol = work / "latency.yaml"
    protocol.write_text(PROTOCOL.format(rate=rate, seconds=seconds))
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]

    ticks = []
    from rdea_lab.monitor import app

    tick = app.LiveView.tick

    def timed(self):  # the server's share: one viewer's tick (the hub's update included)
        start = time.perf_counter()
        tick(self)
        ticks.append(time.perf_counter() - start)
    app.LiveView.tick = timed

    def hook(view):
        view.source.js_on_change("streaming", CustomJS(args={"source": view.source}, code=RECORD))

    mon = Monitor(runs, port=port, on_session=hook).start()
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1200,900"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    child = subprocess.Popen([sys.executable, __file__, "--child", str(protocol), str(runs / "latency.nc"),
                              str(work / "t0.json")], env=env)
    journal_seen, stop = [], threading.Event()

    def tail():  # the same sample's arrival in the journal, for the split (rig -> journal -> browser)
        from rdea_lab.monitor.tail import JournalTail

        t = JournalTail(runs / "latency.nc.part")
        while not stop.wait(0.01):
            rows = t.read()
            if rows.size:
                journal_seen.append((time.time(), float(rows[-1, 0])))

    threading.Thread(target=tail, daemon=True).start()
    try:
        driver.get(mon.urls[0])
        child.wait(timeout=seconds + 120)
        stop.set()
        time.sleep(0.5)
        events = driver.execute_script("return window.__latency || []")
    finally:
        driver.quit()
        mon.stop()
        if child.poll() is None:
            child.terminate()
    t0 = json.loads((work / "t0.json").read_text())["t0_wall"]
    latency = [arrival / 1000.0 - (t0 + t) for arrival, t in events]
    if len(latency) < 10:
        raise SystemExit(f"only {len(latency)} updates arrived; is the page working?")
    latency = latency[5:]  # the first updates hold the page's catch-up, not live samples
    journal = [wall - (t0 + t) for wall, t in journal_seen]
    return {"tick_median_ms": 1000 * percentile(ticks, 0.5), "tick_p99_ms": 1000 * percentile(ticks, 0.99),
            "journal_median_ms": 1000 * percentile(journal, 0.5), "journal_p99_ms": 1000 * percentile(journal, 0.99),
            "updates": len(latency), "seconds": seconds, "rate_hz": rate,
            "median_ms": 1000 * percentile(latency, 0.5), "p99_ms": 1000 * percentile(latency, 0.99),
            "p10_ms": 1000 * percentile(latency, 0.1), "p90_ms": 1000 * percentile(latency, 0.9),
            "min_ms": 1000 * min(latency), "max_ms": 1000 * max(latency),
            "series_ms": [round(1000 * x) for x in latency]}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=40.0, help="run length [s] (10 updates a second)")
    parser.add_argument("--rate", type=float, default=1000.0, help="sample rate [Hz]")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--child", nargs=3, metavar=("PROTOCOL", "OUT", "T0_FILE"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        rig_run(*args.child)
        return
    result = measure(args.seconds, args.rate)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"rig sample -> browser, {result['updates']} updates of a {result['rate_hz']:g} Hz realtime run: "
              f"median {result['median_ms']:.0f} ms, p99 {result['p99_ms']:.0f} ms "
              f"(p10 {result['p10_ms']:.0f}, p90 {result['p90_ms']:.0f}, min {result['min_ms']:.0f}, "
              f"max {result['max_ms']:.0f} ms)")


if __name__ == "__main__":
    main()
