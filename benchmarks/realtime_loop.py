"""A 10 kHz soft-real-time loop with the twin inside: does each step meet its deadline?

Every 100 us a tick: read the stretch the rig's protocol sets (here the
tensile ramp-sine, 1 -> 1.5 at 0.5 Hz), step the plant (a `TwinStep`,
standing in for the actuator) at the voltage the controller chose on the
previous tick, and let a PI controller (around a constant 1.8 kV
feedforward) choose the next voltage so the force follows a reference: the
force the roll carries under 1.8 kV + 0.8 kV sin(2 pi 1 Hz t), computed
offline, which the controller does not know. A tick whose work ends after
its deadline (the start of the next tick) is missed; the loop then goes on
at the next tick on the clock (no catching up: the samples stay in order,
later), as a real-time loop would. Every 1R/3R sample stays in compiled
code (`benchmarks/step_worst_case.py` measures its worst case on folds and
slack); a CR sample of a roll with a core is the reference solver's
(milliseconds: misses). A missed deadline otherwise is the machine's (another
process preempting the loop: run it on an idle machine; or, in a virtual
machine, the host taking the core away: the run reports the steal time the
kernel counted meanwhile, ``/proc/stat``).

The loop waits by spinning on ``time.perf_counter_ns`` (a sleep's wake-up on
a general-purpose kernel is 50-100 us late): it takes one core for the run.
CPython's garbage collector is switched off for the run (what a control loop
in Python does first).

``--realtime`` runs it as a real-time control loop is run: the loop thread
under ``SCHED_FIFO`` (no ordinary process preempts it), on one core, its
memory locked (``mlockall``: no page fault mid-tick). A FIFO thread that never
sleeps is stopped by the kernel's real-time throttling (``sched_rt_runtime_us``,
by default 50 ms of every second), so it sleeps until ``--spin-us`` before each
tick (a FIFO thread's wake-up is a few us late) and spins the rest. Each of the
three is asked for and the output says which the system granted (needs root or
``CAP_SYS_NICE``/``CAP_IPC_LOCK``; otherwise the loop runs as without the flag).

    python3 benchmarks/realtime_loop.py [--seconds 5] [--model su] [--rate 10000] [--realtime [--spin-us 40]]
                                        [--json]

Prints the ticks, the missed deadlines (count and share), the work per tick
(median, p99, p99.9, max, in us), the same for the loop thread's CPU time in
it (``time.thread_time_ns``: the work without the time the thread was off the
core), and the force tracking error (RMS and max, in N and as % of the
reference's swing). A missed tick is one of three kinds: it started late (its
work fit in a tick: the loop was not running when the tick came), the thread
was taken off the core during its work (the work's wall time over a tick, its
CPU time not), or its work itself took more CPU time than a tick (the step's
own cost: the only kind the code can remove).
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import json
import os
import time
from pathlib import Path

import numpy as np

from rdea_lab.specs import load_params
from rdea_lab.twin import TwinStep
from rdea_lab.twin.step import FORCE

ROOT = Path(__file__).resolve().parents[1]


def _steal_ms() -> float | None:
    """The time the hypervisor took the cores away so far [ms] (``/proc/stat``, all cores; None where unknown)."""
    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()
        return 1e3 * int(fields[8]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def _realtime(granted: dict) -> None:
    """Ask for the real-time set-up (`--realtime`): ``SCHED_FIFO``, the last core, memory locked. ``granted`` gets
    what was granted and what `_restore` puts back (the scheduling and the cores the process had)."""
    try:
        granted["before"] = (os.sched_getscheduler(0), os.sched_getparam(0), os.sched_getaffinity(0))
    except (AttributeError, OSError):
        granted["before"] = None
    try:
        os.sched_setaffinity(0, {max(os.sched_getaffinity(0))})
        granted["core"] = max(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        granted["core"] = None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        granted["mlockall"] = libc.mlockall(3) == 0  # MCL_CURRENT | MCL_FUTURE
    except (OSError, AttributeError):
        granted["mlockall"] = False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
        granted["sched_fifo"] = True
    except (AttributeError, OSError):
        granted["sched_fifo"] = False


def _restore(granted: dict) -> None:
    """Undo `_realtime`: the process's scheduling and cores as they were, its memory unlocked."""
    before = granted.pop("before", None)
    if granted.get("mlockall"):
        try:
            ctypes.CDLL(None).munlockall()
        except (OSError, AttributeError):
            pass
    if before is not None:
        policy, param, cores = before
        try:
            os.sched_setscheduler(0, policy, param)
            os.sched_setaffinity(0, cores)
        except (AttributeError, OSError):
            pass


def loop(seconds=5.0, model="su", rate=10_000.0, gain=(2e3, 2e5), realtime=False, spin_us=40.0) -> dict:
    if not 0.0 <= spin_us * 1e-6 < 1.0 / rate:
        raise ValueError(f"spin_us {spin_us}: allowed 0 <= spin_us < one period ({1e6 / rate:g} us)")
    params = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
    card = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
    n = int(seconds * rate)
    dt = 1.0 / rate
    t = np.arange(n) * dt
    lam = (1.0 + 0.25 * (1.0 - np.cos(2 * np.pi * 0.5 * t))).tolist()
    v_target = 1800.0 + 800.0 * np.sin(2 * np.pi * t)
    offline = TwinStep(card, params, model)
    f_ref = [float(offline.step(a, b, c)[FORCE]) for a, b, c in zip(t.tolist(), lam, v_target.tolist())]
    v_ff = 1800.0
    plant = TwinStep(card, params, model)
    kp, ki = gain  # V per N, V per (N s)
    v, integral = 0.0, 0.0
    work = np.empty(n)
    cpu = np.empty(n)  # the loop thread's CPU time in each tick's work: the work without the time it was off the core
    force = np.full(n, np.nan)
    missed = 0
    started_late = 0  # missed ticks whose work fit in a period: the loop was not running at the tick
    preempted = 0  # missed ticks whose work took longer than a period, its CPU time did not: off the core meanwhile
    tl = t.tolist()
    period = int(round(dt * 1e9))
    granted = {}
    spin = None
    steal0 = _steal_ms()
    gc.disable()
    try:
        if realtime:
            _realtime(granted)
        # under SCHED_FIFO: sleep until `spin_us` before the tick (a FIFO thread that never sleeps is throttled)
        spin = int(spin_us * 1e3) if granted.get("sched_fifo") else None
        deadline = time.perf_counter_ns() + 2 * period
        for i in range(n):
            if spin is not None:
                rest = deadline - period - spin - time.perf_counter_ns()
                if rest > 0:
                    time.sleep(rest / 1e9)
            while time.perf_counter_ns() < deadline - period:  # wait for the tick
                pass
            t0 = time.perf_counter_ns()
            c0 = time.thread_time_ns()
            f = plant.step(tl[i], lam[i], v)[FORCE]
            err = f_ref[i] - f  # too little force: less voltage (the Maxwell stress relaxes the roll)
            integral += err * dt
            v = min(max(v_ff - kp * err - ki * integral, 0.0), 3000.0)
            c1 = time.thread_time_ns()
            t1 = time.perf_counter_ns()
            work[i] = (t1 - t0) / 1e3
            cpu[i] = (c1 - c0) / 1e3
            force[i] = f
            if t1 > deadline:  # missed: the next tick is the next one on the clock (no catching up)
                missed += 1
                started_late += t1 - t0 <= period  # the work would have fit a tick: it started late
                preempted += (t1 - t0 > period) and (c1 - c0 <= period)
                deadline += period * ((t1 - deadline) // period + 1)
            deadline += period
    finally:
        gc.enable()
        _restore(granted)
    steal1 = _steal_ms()
    err = np.asarray(f_ref) - force
    swing = float(np.max(f_ref) - np.min(f_ref))
    settled = slice(int(0.5 * rate), None)  # after the first half second
    return {"model": model, "rate_hz": rate, "realtime": granted or None,
            "spin_us": spin_us if spin is not None else None, "ticks": n, "missed": int(missed),
            "missed_share": missed / n,
            "missed_started_late": int(started_late), "missed_preempted": int(preempted),
            "missed_over_budget": int(missed - started_late - preempted),
            "work_us": _percentiles(work), "cpu_us": _percentiles(cpu),
            "steal_ms": None if steal0 is None or steal1 is None else steal1 - steal0,
            "tracking_rms_N": float(np.sqrt(np.mean(err[settled] ** 2))),
            "tracking_max_N": float(np.max(np.abs(err[settled]))),
            "tracking_rms_percent_of_swing": 100 * float(np.sqrt(np.mean(err[settled] ** 2))) / swing}


def _percentiles(x) -> dict:
    return {"median": float(np.median(x)), "p99": float(np.percentile(x, 99)),
            "p99.9": float(np.percentile(x, 99.9)), "max": float(x.max())}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--model", default="su", choices=["su", "1r", "3r", "cr"])
    ap.add_argument("--rate", type=float, default=10_000.0)
    ap.add_argument("--realtime", action="store_true",
                    help="SCHED_FIFO, one core, memory locked, where the system grants them")
    ap.add_argument("--spin-us", type=float, default=40.0, help="under SCHED_FIFO: spin this long before each tick")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    if not 0.0 <= a.spin_us * 1e-6 < 1.0 / a.rate:
        ap.error(f"--spin-us {a.spin_us:g}: allowed 0 <= spin-us < one period ({1e6 / a.rate:g} us)")
    r = loop(a.seconds, a.model, a.rate, realtime=a.realtime, spin_us=a.spin_us)
    if a.json:
        print(json.dumps(r, indent=2))
        return
    w, c = r["work_us"], r["cpu_us"]
    rt = r["realtime"]
    how = ("" if rt is None else f" (realtime: SCHED_FIFO {'granted' if rt['sched_fifo'] else 'refused'}, core "
           f"{rt['core']}, mlockall {'granted' if rt['mlockall'] else 'refused'}"
           + (f", spinning the last {r['spin_us']:.0f} us before each tick)" if r["spin_us"] is not None else ")"))
    print(f"{r['model']} at {r['rate_hz']:.0f} Hz{how}: {r['ticks']} ticks, {r['missed']} missed deadlines "
          f"({100 * r['missed_share']:.3f} %; {r['missed_started_late']} of them started late, their work in time; "
          f"{r['missed_preempted']} off the core during their work, its CPU time in time; "
          f"{r['missed_over_budget']} with more CPU work than a tick); "
          f"work per tick median {w['median']:.1f} us, p99 {w['p99']:.1f}, "
          f"p99.9 {w['p99.9']:.1f}, max {w['max']:.0f}; its CPU time median {c['median']:.1f} us, p99 {c['p99']:.1f}, "
          f"p99.9 {c['p99.9']:.1f}, max {c['max']:.0f}; force tracking (after 0.5 s) RMS {r['tracking_rms_N']:.4f} N "
          f"({r['tracking_rms_percent_of_swing']:.2f} % of the swing), max {r['tracking_max_N']:.4f} N"
          + ("" if r["steal_ms"] is None else f"; the hypervisor took {r['steal_ms']:.0f} ms of the cores meanwhile"))


if __name__ == "__main__":
    main()
