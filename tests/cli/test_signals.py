"""Ctrl-C and SIGKILL against a real `rdea-lab run --realtime` process (issue 3).

Promise: a run interrupted by Ctrl-C closes its dataset with status
``interrupted``; a process killed outright loses at most the last second of
samples, and `rdea-lab recover` rebuilds what was written.
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from rdea_lab.store import journal_path, open_run
from terminal import as_at_a_terminal

ROOT = Path(__file__).resolve().parents[2]
RATE = 100.0  # Hz, tensile_ramp_sine_0V.yaml


def start_run(out: Path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "rdea_lab.cli.main", "run",
                             str(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml"), "--specimen",
                             str(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"), "--realtime", "--quiet",
                             "--out", str(out)],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=as_at_a_terminal)
    header = journal_path(out) / "header.json"
    deadline = time.monotonic() + 30
    while not header.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the run did not start"
        time.sleep(0.01)
    return proc, time.monotonic()


def journal_samples(out: Path) -> int:
    import json
    folder = journal_path(out)
    columns = len(json.loads((folder / "header.json").read_text())["columns"])
    return (folder / "samples.f8").stat().st_size // (8 * columns)


def test_ctrl_c_closes_the_dataset_as_interrupted(tmp_path):
    out = tmp_path / "run.nc"
    proc, started = start_run(out)
    time.sleep(2.5)
    before = journal_samples(out)
    stopped = time.monotonic()
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 130, stderr
    assert "status interrupted" in stdout
    ds = open_run(out)
    n = ds.sizes["time"]
    assert ds.attrs["status"] == "interrupted" and "interrupted by the user" in ds.attrs["status_reason"]
    assert n >= before  # nothing written before the signal is lost
    # the twin runs at wall-clock pace: samples ~ elapsed time * rate, at most a second short
    elapsed = stopped - started
    assert (elapsed - 1.0) * RATE <= n <= (elapsed + 1.0) * RATE + 1
    np.testing.assert_allclose(np.diff(ds["time"].values), 1 / RATE, rtol=1e-9)  # contiguous
    assert not journal_path(out).exists()


def test_sigkill_loses_at_most_a_second_and_recover_rebuilds_the_rest(tmp_path):
    out = tmp_path / "run.nc"
    proc, started = start_run(out)
    time.sleep(2.5)
    killed = time.monotonic()
    proc.kill()
    proc.communicate(timeout=30)
    assert not out.exists()
    before = journal_samples(out)
    elapsed = killed - started
    assert before >= (elapsed - 1.0) * RATE  # at most the last second is lost
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    rec = subprocess.run([sys.executable, "-m", "rdea_lab.cli.main", "recover", str(tmp_path)], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=60)
    assert rec.returncode == 0, rec.stderr
    ds = open_run(out)
    assert ds.sizes["time"] == before  # every whole sample in the journal, none invented
    assert ds.attrs["status"] == "interrupted" and "recovered from the journal" in ds.attrs["status_reason"]
    np.testing.assert_array_equal(ds["time"].values, np.arange(before) / RATE)
