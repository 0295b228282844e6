"""Compiled kernels against the numpy reference, the per-sample step's latency, and numba's start-up cost.

Part of ``rdea-lab bench`` (keys ``kernels``, ``step_latency_us``,
``compile_s``); alone: ``python3 benchmarks/bench_kernels.py``.

- ``kernels``: samples/s at ``samples`` (1e5) on the hollow core of Section
  3.4 (lambda1 U[1, 1.75], v U[0, 3.5 kV], the material of ref. [36]), compiled
  and reference, and their ratio, at two levels: the kernel (SU's fused
  state into given buffers; the 1R/3R/CR equilibrium coordinates, rising-ramp
  rule, against the reference `follow_branch`), and the whole `solve`
  (statuses, slack, `ModelResult`); plus eq. (44)'s branch update (two
  branches) against the prefix scan.
- ``step_latency_us``: `TwinStep.step` per call, on specimen 2 with Table 3's
  material, a tensile ramp-sine at 2.6 kV, 1 Hz sampled at 10 kHz (20000
  steps after 1000 warm-up steps): median, p99, p99.9, max; and the block
  twin stepped one sample at a time (`TwinStream.step`, the way before) for
  the ratio.
- ``compile_s``: a fresh process compiling every kernel (an empty numba
  cache), and one loading them from the cache, to its first result.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RIZZELLO = SimpleNamespace(C10=241e3, C20=-33.2e3, C30=20.1e3, eps_r=2.8)


def _median_rate(fn, n, repeat):
    """``(median, slowest, fastest)`` samples/s of ``repeat`` calls after a warm-up (bench_models' timing)."""
    from bench_models import _rate, _times  # imported here: bench_models imports this module

    return _rate(n, _times(fn, repeat))


def _pair(compiled, reference, n, repeat):
    c, r = _median_rate(compiled, n, repeat), _median_rate(reference, n, max(1, repeat // 2))
    return {"compiled": c[0], "compiled_spread": [c[1], c[2]], "reference": r[0], "reference_spread": [r[1], r[2]],
            "ratio": c[0] / r[0]}


def kernel_rates(samples=100_000, repeat=7) -> dict:
    from rdea_lab.physics import kernels, viscoelastic
    from rdea_lab.physics.branch import follow_branch
    from rdea_lab.physics.geometry import RollGeometry
    from rdea_lab.physics.models import continuum, one_ring, solve, su, three_ring

    hollow = RollGeometry(0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3, L1=34e-3, L1e=34e-3, L3=48e-6)
    rng = np.random.default_rng(0)
    l1, v = rng.uniform(1.0, 1.75, samples), rng.uniform(0.0, 3500.0, samples)
    C = (RIZZELLO.C10, RIZZELLO.C20, RIZZELLO.C30)
    kap, C0 = su.kappa(hollow, RIZZELLO), hollow.C0(RIZZELLO.eps_r)
    out = tuple(np.empty(samples) for _ in range(3))

    def su_reference():
        return su.stress_from_basis(su.stress_basis(l1, v), hollow, RIZZELLO), 1.0 / np.sqrt(l1), C0 * l1

    result = {"samples": samples, "kernel": {"su": _pair(lambda: kernels.su_state(l1, v, C, kap, C0, out=out),
                                                         su_reference, samples, repeat * 3)},
              "solve": {}}
    for name, module in (("1r", one_ring), ("3r", three_ring), ("cr", continuum)):
        problem = module.problem(hollow, RIZZELLO, l1, v)
        result["kernel"][name] = _pair(lambda: kernels.branch_roots(problem, whole=False),
                                       lambda: follow_branch(problem), samples, repeat)
        result["kernel"][name]["certified"] = float(np.mean(kernels.branch_roots(problem, whole=False)[1]))
    for name in ("su", "1r", "3r", "cr"):
        result["solve"][name] = _pair(lambda: solve(name, hollow, RIZZELLO, l1, v, kernel="numba"),
                                      lambda: solve(name, hollow, RIZZELLO, l1, v, kernel="numpy"), samples, repeat)
    t = np.cumsum(rng.uniform(1e-4, 2e-3, samples))
    lam = 1.0 + 0.4 * np.sin(3.0 * t) ** 2
    dt, slope, tau = np.diff(t), np.diff(lam) / np.diff(t), np.array([1e-3, 1.5])
    q = np.empty((2, samples))
    result["linear_branches"] = _pair(
        lambda: viscoelastic._linear_branches(dt, slope, tau, np.zeros(2), q, kernel="numba"),
        lambda: viscoelastic._linear_branches(dt, slope, tau, np.zeros(2), q, kernel="numpy"), samples, repeat)
    return result


def _latencies(step, t, lam, v, warm=1000):
    for i in range(warm):
        step(t[i], lam[i], v[i])
    ns = np.empty(len(t) - warm)
    clock = time.perf_counter_ns
    for i in range(warm, len(t)):
        a = clock()
        step(t[i], lam[i], v[i])
        ns[i - warm] = clock() - a
    us = ns / 1e3
    return {"median": float(np.median(us)), "p99": float(np.percentile(us, 99)),
            "p99.9": float(np.percentile(us, 99.9)), "max": float(us.max()), "steps": int(us.size)}


def tensile_10khz(n):
    """The tensile ramp-sine at 2.6 kV, 1 Hz (stretch 1 -> 1.5 and back, 0.5 Hz), sampled at 10 kHz."""
    t = np.arange(n) * 1e-4
    lam = 1.0 + 0.25 * (1.0 - np.cos(2 * np.pi * 0.5 * t))
    v = 2600.0 * np.sin(np.pi * 1.0 * t) ** 2
    return t.tolist(), lam.tolist(), v.tolist()


def step_latency(steps=20_000) -> dict:
    """See the module docstring; the block twin's one-sample steps are timed on min(steps / 10, 200) samples."""
    from rdea_lab.specs import load_params
    from rdea_lab.twin import TwinStep, TwinStream

    params = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
    card = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
    out = {}
    for model in ("su", "3r"):
        t, lam, v = tensile_10khz(steps + min(1000, steps))
        twin = TwinStep(card, params, model)
        out[model] = _latencies(twin.step, t, lam, v, warm=min(1000, steps))
        stream = TwinStream(card, params, model)
        m = max(10, min(steps // 10, 200))
        tb, lb, vb = (x[:m + m // 10] for x in (t, lam, v))
        block = _latencies(lambda a, b, c: stream.step(np.array([a]), np.array([b]), np.array([c])),
                           tb, lb, vb, warm=m // 10)
        out[model]["block_twin_one_sample_median"] = block["median"]
        out[model]["block_twin_one_sample_p99"] = block["p99"]
        out[model]["ratio"] = block["median"] / out[model]["median"]
    out["protocol"] = "specimen 2, Table 3, tensile ramp-sine 1-1.5 at 0.5 Hz, 2.6 kV 1 Hz, 10 kHz"
    return out


_PROBE = """
import time, numpy as np
t0 = time.perf_counter()
from rdea_lab.physics.geometry import RollGeometry
from rdea_lab.physics.models import solve
from rdea_lab.specs import load_params
from rdea_lab.twin import TwinStep
g = RollGeometry(0.86e-3, 0.88e-3, 1.76e-3, 1.8e-3, L1=34e-3, L1e=34e-3, L3=48e-6)
p = load_params({params!r})
l1 = np.linspace(1.0, 1.5, 20000); v = np.full(20000, 2600.0)
t1 = time.perf_counter()
for m in ("su", "1r", "3r", "cr"):
    solve(m, g, p, l1, v, kernel="numba"); solve(m, g, p, l1, v, kernel="numba", path=True)
for m in ("su", "3r"):
    TwinStep({card!r}, p, m).step(0.0, 1.2, 2600.0)
print(time.perf_counter() - t1)
"""


def compile_seconds() -> dict:
    """Seconds from the first call to the first results of every kernel: cold (empty cache) and warm."""
    code = _PROBE.format(params=str(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"),
                         card=str(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"))
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        for label in ("cold", "warm"):  # the second run finds the first one's cache
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
            out[label] = float(res.stdout.strip().splitlines()[-1])
    return out


def run(samples=100_000, repeat=7, steps=20_000, compile_probe=True) -> dict:
    return {"kernels": kernel_rates(samples, repeat), "step_latency_us": step_latency(steps),
            "compile_s": compile_seconds() if compile_probe else None}


def format_text(r: dict) -> str:
    k = r["kernels"]
    lines = [f"compiled kernels vs numpy reference, {k['samples']} samples, hollow core (samples/s, median; ratio):"]
    for level in ("kernel", "solve"):
        for m, x in k[level].items():
            extra = f", {x['certified']:.1%} certified" if "certified" in x else ""
            lines.append(f"  {level:<6} {m:<3} {x['compiled']:10.3e} vs {x['reference']:10.3e}  {x['ratio']:6.1f}x"
                         f"{extra}")
    x = k["linear_branches"]
    lines.append(f"  eq. (44) update, 2 branches: {x['compiled']:.3e} vs {x['reference']:.3e}  {x['ratio']:.1f}x")
    s = r["step_latency_us"]
    lines.append(f"TwinStep.step ({s['protocol']}), us per call:")
    for m in ("su", "3r"):
        x = s[m]
        lines.append(f"  {m:<3} median {x['median']:.2f}, p99 {x['p99']:.2f}, p99.9 {x['p99.9']:.1f}, max "
                     f"{x['max']:.0f}; block twin one sample at a time {x['block_twin_one_sample_median']:.0f} "
                     f"({x['ratio']:.0f}x)")
    c = r["compile_s"]
    if c is None:
        return "\n".join(lines)
    lines.append(f"numba start-up to the first results of every kernel: {c['cold']:.1f} s compiling (empty cache), "
                 f"{c['warm']:.2f} s from the cache")
    return "\n".join(lines)


if __name__ == "__main__":
    result = run()
    print(json.dumps(result, indent=2) if "--json" in sys.argv else format_text(result))
