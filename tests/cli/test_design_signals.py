"""``rdea-lab design`` on a local dask cluster, interrupted (issue 25): Ctrl-C is one line and exit 130, not a
traceback from each worker and hundreds of lines from the scheduler; a study whose workers are killed fails with
one line (exit 3) instead of finishing with tracebacks on stderr."""

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from terminal import in_a_group_of_its_own

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "rdea_lab" / "data"
#: Large enough to be still running seconds after its first task (400 000 designs: about 15 s on 2 workers here).
STUDY = f"""name: long
model: su
params: {DATA / "params" / "paper2021_table3.yaml"}
specimen: {DATA / "specimens" / "specimen2.yaml"}
variables: {{L1: [25 mm, 45 mm], L3: [40 um, 70 um], prestretch: [1.1, 1.4]}}
sampling: {{method: lhs, n: 400000, seed: 2}}
voltage: 2.6 kV
bias: {{kind: spring, stiffness: 200 N/m, preload: 1 N}}
objectives: [{{maximize: stroke}}, {{minimize: volume}}]
chunk: 500
"""


def start_study(tmp_path):
    (tmp_path / "long.yaml").write_text(STUDY)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("DASK_SCHEDULER_ADDRESS", None)
    proc = subprocess.Popen([sys.executable, "-m", "rdea_lab.cli.main", "design", str(tmp_path / "long.yaml"),
                             "--out", str(tmp_path / "out"), "--workers", "2", "--no-figures"],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=in_a_group_of_its_own)
    seen, deadline = b"", time.monotonic() + 120
    while b" tasks, " not in seen:  # the progress bar's first line: the cluster is up, the tasks run
        assert time.monotonic() < deadline and proc.poll() is None, (proc.returncode, seen)
        ready, _, _ = select.select([proc.stderr], [], [], 1.0)
        if ready:
            seen += os.read(proc.stderr.fileno(), 65536)
    return proc, seen


def group_members(pgid) -> list[int]:
    out = subprocess.run(["ps", "-e", "-o", "pid=,pgid="], capture_output=True, text=True).stdout.split()
    return [int(p) for p, g in zip(out[::2], out[1::2]) if int(g) == pgid]


def _lines(seen, err):
    return (seen + err).decode().splitlines()


@pytest.mark.slow  # about 10-15 s: a cluster's start-up and a study
@pytest.mark.parametrize("to_group", [True, False], ids=["to the group (a terminal)", "to the process"])
def test_ctrl_c_is_one_line_and_exit_130(tmp_path, to_group):
    proc, seen = start_study(tmp_path)
    time.sleep(0.5)
    if to_group:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    lines = _lines(seen, err)
    assert proc.returncode == 130, lines
    assert lines[-1] == "rdea-lab: interrupted (Ctrl-C)", lines
    # before it only the cluster's line and the progress bar's: no traceback, no dask log
    assert all(ln.startswith(("dask: local cluster", "designs [")) for ln in lines[:-1]), lines
    assert not (tmp_path / "out" / "study.nc").exists()
    deadline = time.monotonic() + 10
    while group_members(proc.pid) and time.monotonic() < deadline:  # the workers end with the study
        time.sleep(0.2)
    assert group_members(proc.pid) == []


def _children(pid) -> dict[int, bytes]:
    """The processes whose parent is ``pid``: their command lines."""
    kids = {}
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text()
            if entry.name.isdigit() and int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                kids[int(entry.name)] = (entry / "cmdline").read_bytes()
        except (OSError, ValueError, IndexError):  # a process that ended meanwhile
            continue
    return kids


def _workers(pid) -> list[int]:
    """The study's worker processes: the fork server's children (multiprocessing forks them from it)."""
    servers = [k for k, cmd in _children(pid).items() if b"forkserver" in cmd]
    return [w for s in servers for w in _children(s)]


@pytest.mark.slow  # about 10 s: a cluster's start-up and part of a study
@pytest.mark.parametrize("which", ["one", "all"])
def test_a_study_whose_workers_are_killed_fails_with_one_line(tmp_path, which):
    proc, seen = start_study(tmp_path)
    workers = _workers(proc.pid)
    assert len(workers) == 2, workers
    for pid in workers[:1] if which == "one" else workers:
        os.kill(pid, signal.SIGKILL)
    out, err = proc.communicate(timeout=120)
    lines = _lines(seen, err)
    assert proc.returncode == 3, lines
    assert lines[-1].startswith("rdea-lab: design: ") and "the study stopped, nothing written" in lines[-1], lines
    assert all(ln.startswith(("dask: local cluster", "designs [")) for ln in lines[:-1]), lines
    assert out == b"" and not (tmp_path / "out" / "study.nc").exists()
