"""Randomized interrupt soak (issue 11): runs killed at random moments, recover run at random moments.

100 runs on the twin and 20 on the emulator server, each a real ``rdea-lab run --realtime`` process
killed (SIGKILL or SIGINT) at a random moment, two at a time; meanwhile ``recover`` is run on the
folder at random moments, also while runs are live. Checked for every run, against what the journal
held just before the kill (read from its file, not from the code under test):

- nothing lost that was on disk before the kill, and at most the last second of samples lost;
- no sample duplicated or skipped (time is exactly k / rate);
- every dataset readable, with status ``interrupted``;
- a live run is never taken by recover (its process still running when a dataset for it appears).

Bounded: about 7 minutes on 2 cores (421 s measured), so marked slow (``python3 -m pytest -m slow``). The figures
are printed (``-s``) and stated in the session note.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from terminal import as_at_a_terminal

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
RATE = 100.0
PROTOCOL = """\
name: soak
kind: custom
sample_rate: 100 Hz
stretch:
  - {kind: ramp, duration: 4 s, to: 1.3}
  - {kind: ramp, duration: 4 s, to: 1.0}
voltage:
  - {kind: hold, duration: 8 s}
"""
PLANNED = int(8 * RATE) + 1


def journal_samples(out: Path) -> int:
    """Whole rows in the journal's sample file: what is on disk now."""
    part = out.with_name(out.name + ".part")
    try:
        import json

        columns = len(json.loads((part / "header.json").read_text())["columns"])
        return (part / "samples.f8").stat().st_size // (8 * columns)
    except (OSError, ValueError, KeyError):
        return 0


def two_at_a_time(one, jobs) -> None:
    """``one(*job)`` for every job, two at a time (the machine has two cores)."""
    for k in range(0, len(jobs), 2):
        pair = [threading.Thread(target=one, args=job) for job in jobs[k:k + 2]]
        for t in pair:
            t.start()
        for t in pair:
            t.join()


@pytest.mark.slow
def test_interrupt_soak(tmp_path):
    import rdea_lab
    from rdea_lab.store import RunInProgress

    rng = random.Random(20261201)
    protocol = tmp_path / "soak.yaml"
    protocol.write_text(PROTOCOL)
    folder = tmp_path / "runs"
    folder.mkdir()
    n_twin, n_emulator = (int(x) for x in os.environ.get("RDEA_LAB_SOAK_RUNS", "100,20").split(","))
    jobs = [("twin", i) for i in range(n_twin)] + [("emulator", 100_000 + i) for i in range(n_emulator)]
    rng.shuffle(jobs)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    records, alive = {}, {}
    lock = threading.Lock()
    stop = threading.Event()
    recovered_live = []
    recover_calls = [0, 0]  # calls, journals left alone because their run was live

    def recoverer():
        while not stop.is_set():
            time.sleep(rng.uniform(0.05, 0.6))
            for part in sorted(folder.glob("*.nc.part")):
                out = part.with_name(part.name[:-5])
                with lock:
                    proc = alive.get(out)
                    live = proc is not None and proc.poll() is None
                try:
                    recover_calls[0] += 1
                    rdea_lab.recover(part)
                    if live and proc.poll() is None:  # it took the journal of a process still running?
                        time.sleep(0.2)  # (or of one between closing its files and becoming a zombie)
                        if proc.poll() is None:
                            recovered_live.append(str(out))
                except RunInProgress:
                    recover_calls[1] += 1
                except (FileNotFoundError, FileExistsError, ValueError):
                    pass  # the run finished (or another recover won) meanwhile

    def one(backend, i):
        out = folder / f"{backend}-{i}.nc"
        args = [sys.executable, "-m", "rdea_lab.cli.main", "run", str(protocol), "--specimen", str(CARD),
                "--backend", backend, "--realtime", "--quiet", "--seed", str(i), "--out", str(out)]
        if backend == "twin":
            args += ["--model", "su"]
        proc = subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                preexec_fn=as_at_a_terminal)
        with lock:
            alive[out] = proc
        part = out.with_name(out.name + ".part")
        t_seen = None
        deadline = time.monotonic() + 60
        while t_seen is None and time.monotonic() < deadline and proc.poll() is None:
            if (part / "samples.f8").exists():
                t_seen = time.monotonic()
            time.sleep(0.02)
        time.sleep(rng.uniform(0.2, 6.5))
        how = rng.choice([signal.SIGKILL, signal.SIGINT])
        before = journal_samples(out)
        elapsed = time.monotonic() - t_seen if t_seen is not None else 0.0
        proc.send_signal(how)
        proc.wait(timeout=60)
        records[out] = {"signal": how.name, "before": before, "elapsed": elapsed, "rc": proc.returncode}

    recover_thread = threading.Thread(target=recoverer, daemon=True)
    recover_thread.start()
    t0 = time.monotonic()
    try:
        two_at_a_time(one, jobs)
    finally:
        stop.set()
        recover_thread.join()
    for part in sorted(folder.glob("*.nc.part")):  # the runs killed outright, not yet recovered
        rdea_lab.recover(part)
    wall = time.monotonic() - t0

    lost, short_of_disk, dup, unreadable, statuses = [], [], [], [], {}
    for out, rec in records.items():
        try:
            ds = rdea_lab.open_run(out)
        except Exception as exc:  # noqa: BLE001  (counted and reported, whatever it is)
            unreadable.append((str(out), repr(exc)))
            continue
        n = ds.sizes["time"]
        t = ds["time"].values
        statuses[ds.attrs["status"]] = statuses.get(ds.attrs["status"], 0) + 1
        if n and not np.array_equal(t, np.arange(n) / RATE):
            dup.append(str(out))
        if n < rec["before"]:
            short_of_disk.append((str(out), n, rec["before"]))
        # at most the last second lost: against the run's own age when it was killed (journal first seen)
        if n < min(PLANNED, RATE * (rec["elapsed"] - 1.0)) - 5:
            lost.append((str(out), n, rec["elapsed"]))
    print(f"\nsoak: {len(records)} runs ({sum(1 for b, _ in jobs if b == 'twin')} twin, "
          f"{sum(1 for b, _ in jobs if b == 'emulator')} emulator) in {wall:.0f} s; signals "
          f"{sum(r['signal'] == 'SIGKILL' for r in records.values())} SIGKILL / "
          f"{sum(r['signal'] == 'SIGINT' for r in records.values())} SIGINT; statuses {statuses}; "
          f"recover calls {recover_calls[0]}, live journals left alone {recover_calls[1]}; "
          f"short of the disk {len(short_of_disk)}, lost beyond a second {len(lost)}, duplicated/skipped "
          f"{len(dup)}, unreadable {len(unreadable)}, live runs taken {len(recovered_live)}")
    assert len(records) == len(jobs)
    assert not unreadable, unreadable[:3]
    assert not short_of_disk, short_of_disk[:3]
    assert not lost, lost[:3]
    assert not dup, dup[:3]
    assert not recovered_live, recovered_live[:3]
    assert set(statuses) <= {"interrupted", "complete"}


#: The cases of issue 25: a live table on the terminal, SIGTERM to a run, SIGTERM to an emulator run's
#: whole process group (as `timeout` and service managers send it: the emulator's threads get it too).
CASES = [("twin", ["--live", "table"], signal.SIGINT, False), ("twin", ["--live", "table"], signal.SIGTERM, False),
         ("twin", [], signal.SIGTERM, False), ("emulator", [], signal.SIGTERM, True),
         ("emulator", ["--live", "table"], signal.SIGINT, False), ("emulator", [], signal.SIGINT, True)]


@pytest.mark.slow
def test_interrupt_soak_live_table_and_sigterm(tmp_path):
    """Every interrupt (Ctrl-C or SIGTERM, to the process or its group) ends exit 130 with the dataset
    closed as ``interrupted``: no unclosed run, no "connection lost", none killed by the signal. At least
    100 interrupts, two runs at a time, each at a random moment of its acquisition (102 in 400 s here)."""
    import rdea_lab

    rng = random.Random(20261203)
    protocol = tmp_path / "soak.yaml"
    protocol.write_text(PROTOCOL)
    folder = tmp_path / "runs"
    folder.mkdir()
    n = int(os.environ.get("RDEA_LAB_SOAK_INTERRUPTS", "102"))
    jobs = [(i, CASES[i % len(CASES)]) for i in range(n)]
    rng.shuffle(jobs)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    records = {}

    def one(i, case):
        backend, extra, sig, group = case
        out = folder / f"{backend}-{i}.nc"
        args = [sys.executable, "-m", "rdea_lab.cli", "run", str(protocol), "--specimen", str(CARD), "--backend",
                backend, "--realtime", "--seed", str(i), "--out", str(out), *extra]
        if not extra:
            args.append("--quiet")
        proc = subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                start_new_session=group,
                                preexec_fn=as_at_a_terminal)
        part = out.with_name(out.name + ".part")
        t_seen, deadline = None, time.monotonic() + 60
        while t_seen is None and time.monotonic() < deadline and proc.poll() is None:
            if (part / "samples.f8").exists():
                t_seen = time.monotonic()
            time.sleep(0.02)
        time.sleep(rng.uniform(0.0, 6.5))  # the run lasts 8 s: any moment of its acquisition
        before = journal_samples(out)
        if group:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
        records[out] = {"case": f"{backend}{' ' + ' '.join(extra) if extra else ''} {sig.name}"
                                + (" (group)" if group else ""),
                        "rc": proc.returncode, "before": before, "stderr": stderr, "stdout": stdout[-300:]}

    t0 = time.monotonic()
    two_at_a_time(one, jobs)
    wall = time.monotonic() - t0

    bad_exit, unclosed, not_interrupted, short, noisy, dup = [], [], [], [], [], []
    for out, rec in records.items():
        if rec["rc"] != 130:
            bad_exit.append((rec["case"], rec["rc"], rec["stderr"][-200:]))
        if out.with_name(out.name + ".part").exists() or not out.exists():
            unclosed.append((rec["case"], str(out)))
            continue
        if "Traceback" in rec["stderr"] or len(rec["stderr"].splitlines()) > 1:
            noisy.append((rec["case"], rec["stderr"][-300:]))
        ds = rdea_lab.open_run(out)
        if ds.attrs["status"] != "interrupted" or "interrupted by the user" not in ds.attrs["status_reason"]:
            not_interrupted.append((rec["case"], ds.attrs["status"], ds.attrs["status_reason"]))
        if ds.sizes["time"] < rec["before"]:
            short.append((rec["case"], ds.sizes["time"], rec["before"]))
        if not np.array_equal(ds["time"].values, np.arange(ds.sizes["time"]) / RATE):
            dup.append(rec["case"])
        ds.close()
    by_case = {}
    for rec in records.values():
        by_case[rec["case"]] = by_case.get(rec["case"], 0) + 1
    print(f"\nsoak (issue 25): {len(records)} interrupts in {wall:.0f} s, {by_case}; exit != 130: {len(bad_exit)}, "
          f"unclosed {len(unclosed)}, status not interrupted {len(not_interrupted)}, more than one stderr line "
          f"{len(noisy)}, short of the disk {len(short)}, duplicated/skipped {len(dup)}")
    assert len(records) == n and (n >= 100 or "RDEA_LAB_SOAK_INTERRUPTS" in os.environ)  # a shorter try, asked for
    assert not bad_exit, bad_exit[:3]
    assert not unclosed, unclosed[:3]
    assert not not_interrupted, not_interrupted[:3]
    assert not noisy, noisy[:3]
    assert not short, short[:3]
    assert not dup, dup[:3]
