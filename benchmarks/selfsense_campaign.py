"""The self-sensing figures of the README: the emulated campaign at 2.6 kV, 1 Hz, specimens 1-3.

For each specimen: ``protocols/selfsense_2.6kV.yaml`` (the tensile ramp-sine stretch under a 0-2.6 kV
sine at 1 Hz, 20 V 200 Hz probe, current at 2 kHz) and ``protocols/selfsense_0V.yaml`` (the same
stretch at 0 V) on the built-in emulator (truth/paper2021.yaml, seed 0); then ``selfsense`` with the
SU model of Table 3 (params/paper2021_table3.yaml) and each tare, and the small-signal estimator beside.
Errors: of the self-sensed stretch against the encoder's, in % of the run's stretch range, over the
samples where the estimate is valid and the roll taut. The breakdown (only an emulator can give it)
replays the emulator's true roll on the run's stretch and voltage: estimator (estimated against true
capacitance), model (the true capacitance against the tared model's at the electroded zone's stretch)
and zone (the electroded zone's stretch against the encoder's).

    python3 benchmarks/selfsense_campaign.py [OUT_FOLDER]     # about 3 minutes on 2 cores
"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

import rdea_lab  # noqa: E402
from rdea_lab.emulator import true_geometry  # noqa: E402
from rdea_lab.emulator.rig import BLOCK  # noqa: E402
from rdea_lab.emulator.roll import TrueRoll  # noqa: E402
from rdea_lab.physics.geometry import geometry_from_card  # noqa: E402
from rdea_lab.reports.selfsense import selfsense_run  # noqa: E402

PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
TRUTH = ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml"


def breakdown(run, result):
    """Max and rms (% of range) of the estimator, model and zone parts of the error."""
    ds, r = rdea_lab.open_run(run), result.dataset
    t, lam, v = (ds[k].values for k in ("time", "stretch", "voltage"))
    card, truth = ds.rdea.specimen, rdea_lab.load_truth(TRUTH)
    roll = TrueRoll(true_geometry(card, truth), truth)
    outs = [roll.step(t[k:k + BLOCK], np.maximum(lam[k:k + BLOCK], 1.0), v[k:k + BLOCK])
            for k in range(0, t.size, BLOCK)]
    C_true = np.concatenate([o["capacitance"] for o in outs])
    la = np.concatenate([o["lambda_a"] for o in outs])
    C0 = geometry_from_card(card).C0(rdea_lab.load_params(PARAMS).eps_r) * result.gain
    used = r["estimate_valid"].values == 1
    span = r.attrs["stretch_range"]
    parts = {"estimator": (r["capacitance_estimate"].values - C_true) / C0,
             "model": (C_true - result.offset) / C0 - la, "zone": la - lam}
    return {k: (np.nanmax(np.abs(e[used])) / span * 100, np.sqrt(np.nanmean(e[used] ** 2)) / span * 100)
            for k, e in parts.items()}


def main(folder: Path):
    rows = []
    for s in (1, 2, 3):
        card = ROOT / "rdea_lab" / "data" / "specimens" / f"specimen{s}.yaml"
        runs = {}
        for name in ("selfsense_2.6kV", "selfsense_0V"):
            out = folder / f"specimen{s}-{name}.nc"
            t0 = time.perf_counter()
            rdea_lab.run_protocol(ROOT / "rdea_lab" / "data" / "protocols" / f"{name}.yaml", card, "emulator",
                                  truth=TRUTH, out=out, overwrite=True)
            runs[name] = (out, time.perf_counter() - t0)
        run, run_time = runs["selfsense_2.6kV"]
        for label, kwargs in (("secant, rest tare", {}),
                              ("secant, 0 V reference", {"reference": runs["selfsense_0V"][0]}),
                              ("small-signal, rest tare", {"estimator": "small-signal"}),
                              ("secant, nothing fitted", {"tare": "none"})):
            t0 = time.perf_counter()
            result = selfsense_run(run, PARAMS, "su", **kwargs)
            sense_time = time.perf_counter() - t0
            parts = breakdown(run, result)
            rows.append((s, label, result, parts, run_time, sense_time))
    print("| specimen | estimator, calibration | max % | rms % | estimator max/rms | model max/rms | zone max/rms "
          "| C0 factor | emulator run | selfsense |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for s, label, r, parts, run_time, sense_time in rows:
        p = "| ".join(f"{parts[k][0]:.2f} / {parts[k][1]:.2f} " for k in ("estimator", "model", "zone"))
        print(f"| {s} | {label} | {r.max_error_percent:.2f} | {r.rms_error_percent:.2f} | {p}| {r.gain:.4f} "
              f"| {run_time:.1f} s | {sense_time:.2f} s |")


if __name__ == "__main__":
    if len(sys.argv) > 1:
        target = Path(sys.argv[1])
        target.mkdir(parents=True, exist_ok=True)
        main(target)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp))
