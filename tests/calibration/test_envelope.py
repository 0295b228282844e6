"""The calibration envelope and its extrapolation flags (issue 13), on runs with known stretch ramps."""

import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from vhb_data import MISSING, VHB, needs_vhb

from rdea_lab.calibration import Envelope, beyond, envelope, run_envelope
from rdea_lab.calibration.envelope import (CELL, HOLD, HOLD_RATE, JOINT_DISTANCE, LOADING, RATE_PERCENTILES,
                                           RATE_RTOL, STRETCH_SCALE, longest_hold, phases)
from rdea_lab.calibration.objective import load_run, run_data
from rdea_lab.specs import load_specimen
from rdea_lab.twin import simulate

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
DT = 0.05  # [s]


def ramp_run(name, rate, top, hold=0.0, voltage=0.0):
    """Up from stretch 1 to ``top`` at ``rate`` [1/s], ``hold`` [s] there, back down at ``rate``; the twin's
    force (SU, 0 V: uniaxial), as a dataset with a ``specimen`` attribute, then `run_data`."""
    t_up = (top - 1.0) / rate
    t = np.arange(0.0, 2 * t_up + hold + DT / 2, DT)
    lam = 1.0 + rate * np.clip(np.minimum(t, 2 * t_up + hold - t), 0.0, t_up)
    ds = simulate(load_specimen(CARD), PARAMS, t, lam, voltage, model="su")
    ds.attrs.update({"specimen": CARD.read_text(), "run_id": name, "protocol_name": name})
    return run_data(ds)


@pytest.fixture(scope="module")
def runs():
    return {"slow": ramp_run("slow", 0.01, 1.5, hold=20.0), "fast": ramp_run("fast", 0.03, 1.5),
            "inside": ramp_run("inside", 0.02, 1.4), "far": ramp_run("far", 0.01, 3.0),
            "quick": ramp_run("quick", 0.05, 1.5), "held": ramp_run("held", 0.01, 1.5, hold=600.0)}


def test_envelope_of_known_ramps(runs):
    env = envelope([runs["slow"], runs["fast"]])
    assert env.stretch == pytest.approx((1.0, 1.5), abs=1e-12)
    # a straight ramp's central differences are its rate exactly; the few corner samples (half the
    # rate) lie below the 1st percentile of thousands of moving samples
    assert env.rate == pytest.approx((0.01, 0.03), rel=1e-9)
    assert env.voltage == (0.0, 0.0)
    # still samples of a hold of H between two ramps: the corner samples each side move (half rate),
    # so the still span is H - 2 dt
    assert env.hold == pytest.approx(20.0 - 2 * DT, abs=1e-9)
    assert run_envelope(runs["fast"]).hold == 0.0  # a sharp turn: one still sample, no span
    assert env.runs == ("vhb4910/slow", "vhb4910/fast")


def test_longest_hold_of_two_holds():
    t = np.arange(0, 40, 1.0)
    lam = np.concatenate([np.full(5, 1.0), 1 + 0.1 * np.arange(1, 6), np.full(20, 1.5), 1.5 - 0.1 * np.arange(1, 6),
                          np.full(5, 1.0)])
    assert np.abs(np.diff(lam)).max() > HOLD_RATE
    # at 1.5: t = 9 (the ramp's last sample) to 29; the two ends neighbour a moving sample, so their
    # central differences move (0.05 /s): still t = 10..28, 18 s (the start's hold: t = 0..3, 3 s)
    assert longest_hold(t, lam) == pytest.approx(18.0)
    assert longest_hold(t[:8], lam[:8]) == pytest.approx(3.0)


def test_flags_fire_outside_and_not_inside(runs):
    env = envelope([runs["slow"], runs["fast"]])
    assert beyond(env, runs["inside"]) == ()
    assert beyond(env, runs["slow"]) == () and beyond(env, runs["fast"]) == ()
    assert beyond(env, runs["far"]) == ("stretch 3.0 beyond the calibrated 1.5",)
    assert beyond(env, runs["quick"]) == ("rate 0.05 /s beyond the calibrated 0.01-0.03 /s",)
    no_hold = envelope([runs["fast"]])
    assert "hold 600 s beyond the calibrated 0 s" in beyond(no_hold, runs["held"])


def test_tolerances_keep_a_repeat_at_the_same_nominal_setting_inside():
    cal = Envelope(stretch=(1.0, 3.0), rate=(0.01, 0.03), voltage=(0.0, 0.0), hold=0.0)
    same = Envelope(stretch=(0.9995, 3.0001), rate=(0.0099, 0.0302), voltage=(0.0, 2.0), hold=0.5)
    assert beyond(cal, same) == ()
    out = Envelope(stretch=(0.9, 3.1), rate=(0.005, 0.05), voltage=(-100.0, 2600.0), hold=600.0)
    assert beyond(cal, out) == ("stretch 3.1 beyond the calibrated 3.0", "stretch 0.9 below the calibrated 1.0",
                                "rate 0.05 /s beyond the calibrated 0.01-0.03 /s",
                                "rate 0.005 /s below the calibrated 0.01-0.03 /s",
                                "voltage 2.6 kV beyond the calibrated 0 V", "voltage -100 V below the calibrated 0 V",
                                "hold 600 s beyond the calibrated 0 s")


def test_a_run_that_never_moves_has_no_rate_and_an_empty_list_is_refused(runs):
    still = Envelope(stretch=(1.0, 1.0), rate=(np.nan, np.nan), voltage=(0.0, 0.0), hold=10.0)
    assert beyond(still, runs["fast"])[0].startswith("stretch 1.5 beyond the calibrated 1.0")
    assert "rate 0.03 /s beyond the calibrated none (no moving samples)" in beyond(still, runs["fast"])
    with pytest.raises(ValueError, match="no runs"):
        envelope([])


# ---------------------------------------------------------------- the joint test (issue 27)
def path_run(name, t, lam, voltage=0.0):
    """A run as the envelope reads it (times, stretch, voltage, names): no force needed."""
    return SimpleNamespace(t=np.asarray(t, float), stretch=np.asarray(lam, float),
                           voltage=np.full(np.size(t), float(voltage)), specimen="synthetic", protocol=name)


def triangle(name, rate, top, dt=0.05):
    """Up from 1 to ``top`` at ``rate`` [1/s] and straight back down."""
    t_up = (top - 1.0) / rate
    t = np.arange(0.0, 2 * t_up + dt / 2, dt)
    return path_run(name, t, 1.0 + rate * np.minimum(t, 2 * t_up - t).clip(0.0))


def step_hold(name, top, hold, rate=0.25, dt=0.02, overshoot=0.0, creep=0.0):
    """Up at ``rate`` to ``top + overshoot``, settling back to ``top`` with a 0.3 s time constant, held to
    ``hold`` [s]; ``creep``: a further stretch rising linearly over 2 s from t = 100 s (drift in the hold)."""
    t1 = (top + overshoot - 1.0) / rate
    t = np.arange(0.0, t1 + hold, dt)
    lam = np.where(t <= t1, 1.0 + rate * t, top + overshoot * np.exp(-(t - t1) / 0.3))
    return path_run(name, t, lam + creep * np.clip((t - 100.0) / 2.0, 0.0, 1.0)), t1


def old_low_rate(run):
    """The rate range's low end as it was before issue 27: every moving sample, holds included."""
    a = np.abs(np.gradient(run.stretch, run.t))
    return np.percentile(a[a >= HOLD_RATE], RATE_PERCENTILES[0])


def test_the_joint_test_flags_a_combination_that_each_axis_allows():
    """Fitted: 0.01 /s to 1.45 and 0.05 /s to 3.0. A run at 0.01 /s to 3.0 is inside each axis (stretch
    1-3, rate 0.01-0.05) but, above stretch 1.45 + 0.25 (one unit of stretch), its nearest fitted point is
    at 0.05 /s, a factor 5 (log 5 / log 3 = 1.46 units) away: flagged from there to 3.0."""
    fitted = envelope([triangle("slow", 0.01, 1.45), triangle("fast", 0.05, 3.0)])
    far = triangle("far", 0.01, 3.0)
    axes_only = Envelope.from_mapping({k: v for k, v in fitted.mapping().items() if k != "points"})
    assert beyond(axes_only, far) == ()  # what the axis-by-axis test said
    (flag,) = beyond(fitted, far)
    m = re.fullmatch(r"stretch (\S+)-3\.0 at 0\.01 /s \(loading, unloading\): fitted only at 0\.05 /s", flag)
    assert m, flag
    # the first uncovered kept point: above 1.75, within one cell (0.25 units = 0.0625 in stretch)
    # (1.45: no uncovered point lies on the boundary of a distance of exactly 1)
    edge = 1.45 + STRETCH_SCALE * JOINT_DISTANCE
    assert edge < float(m.group(1)) <= edge + CELL * STRETCH_SCALE
    # inside: between the fitted rates (0.03 is a factor 1.7 from 0.05) and below a fitted stretch at a fitted rate
    assert beyond(fitted, triangle("between", 0.03, 1.5)) == ()
    assert beyond(fitted, triangle("lower", 0.01, 1.4)) == ()
    assert beyond(fitted, triangle("fast again", 0.05, 2.5)) == ()


def test_drift_in_a_hold_is_a_hold_not_a_slow_rate():
    """A 0.25 /s step to 2.0 that overshoots by 0.009 and settles back (rates 0.03 /s down to 0.001 /s over
    1 s), then creeps by 0.004 at 0.002 /s in the hold: every sample after the peak is hold, the rate range
    is the ramp's, and against a clean step and hold (to 2.015, the drifting run's largest stretch 2.013)
    nothing is flagged (the old definition saw a slow rate)."""
    clean, _ = step_hold("clean", 2.015, 300.0)
    drift, t1 = step_hold("drift", 2.0, 300.0, overshoot=0.009, creep=0.004)
    phase, x = phases(drift.t, drift.stretch)
    # (the sample next to the peak: its central difference straddles it)
    assert set(phase[drift.t > t1 + 0.02]) == {HOLD} and set(phase[drift.t < t1]) == {LOADING}
    # the span rate, net change / duration: its last sample is the one after the peak, 0.02 s into the settling
    assert x[drift.t < t1] == pytest.approx(0.25, rel=2e-3)
    assert old_low_rate(drift) < 0.25 * (1 - RATE_RTOL)  # the old range: drift read as a slow rate
    assert run_envelope(drift).rate[0] == pytest.approx(0.25, rel=1e-6)
    assert run_envelope(drift).hold == pytest.approx(drift.t[-1] - t1, abs=0.05)
    assert beyond(envelope([clean]), drift) == ()


def test_a_hold_at_a_new_stretch_is_a_new_combination():
    """Fitted: a step to 2.0 held 300 s and a 0.25 /s ramp to 3.0 and back. A step to 3.0 held 300 s is
    inside every axis (stretch, rate, the longest hold) but was never held there."""
    held2, _ = step_hold("held 2.0", 2.0, 300.0)
    fitted = envelope([held2, triangle("to 3.0", 0.25, 3.0, dt=0.02)])
    held3, _ = step_hold("held 3.0", 3.0, 300.0)
    (flag,) = beyond(fitted, held3)
    assert re.fullmatch(r"hold at stretch 3\.0 to 300 s: fitted holds only at stretch 2\.0 \(to 300 s\)", flag), flag
    assert beyond(fitted, held2) == ()


def test_the_points_round_trip_compactly_and_an_old_record_still_loads():
    fitted = envelope([triangle("slow", 0.01, 1.45), triangle("fast", 0.05, 3.0), step_hold("h", 2.0, 1800.0)[0]])
    m = json.loads(json.dumps(fitted.mapping()))
    assert set(m["points"]) == {"loading", "unloading", "hold"}
    # loading and unloading: 1 to 3.0 in cells of 0.0625 (32) at two rates, to 1.5 (8): about 2 x 40 + 8 + 32
    # (the step's ramp), the hold 1 s to 1800 s: log10(1800) / (0.477 * 0.25) = 27 cells
    assert 100 < len(fitted.points) < 300
    back = Envelope.from_mapping(m)
    far = triangle("far", 0.01, 3.0)
    assert beyond(back, far) == beyond(fitted, far) and beyond(back, far)
    old = {k: v for k, v in m.items() if k not in ("points", "definitions")}
    assert Envelope.from_mapping(old).points == () and "axis by axis" in Envelope.from_mapping(old).describe()


@needs_vhb
def test_leave_one_out_on_the_vhb_files_flags_each_rate_that_alone_reached_3(imported):
    """Leave-one-out over the five files (``0dRR_SdS``: rate 0.RR /s to stretch S.S): each 3.0 run is the only
    one to reach 3.0 at its rate, the other 3.0 run is a factor 5 away in rate: both are flagged, saying the
    other's rate; a 1.5 run always has a fitted run at its rate reaching 1.5 or further, or (0.03) one within
    a factor 3 of it: none is flagged. No axis is left: stretch 1-3, rate 0.01-0.05 in every fold."""
    runs = {p.stem: load_run(p) for p in sorted(imported.glob("0d*.nc"))}
    for name, run in runs.items():
        flags = beyond(envelope([r for k, r in runs.items() if k != name]), run)
        rate, top = float("0." + name[2:4]), float(name[5] + "." + name[7])
        if top == 3.0:
            other = {0.01: "0.05", 0.05: "0.01"}[rate]
            (flag,) = flags
            assert re.fullmatch(rf"stretch 1\.\d+-3\.0 at {rate:g} /s \(loading, unloading\): fitted only at "
                                rf"{other} /s", flag), (name, flag)
        else:
            assert flags == (), (name, flags)


@pytest.mark.slow
@pytest.mark.skipif(not (VHB / "relax_2d0.csv").is_file(), reason=MISSING)
def test_the_vhb_step_and_hold_gives_no_slow_rate(imported, tmp_path):
    """relax_2d0 (0.25 /s to 2.0, overshoot and settling, 1800 s): against the five loading-unloading files
    its rate is beyond (0.25 /s) and so is its hold, and nothing is below."""
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    out = tmp_path / "relax.nc"
    assert run_cli(cli, ["import", str(VHB / "relax_2d0.csv"), "--format", "csv", "--map", "time=0,position=1,force=2",
                         "--protocol-kind", "tensile", "--specimen", str(CARD), "--out", str(out)]) == 0
    relax = load_run(out)
    assert old_low_rate(relax) < 0.00994  # the 0.0017 /s of the settling that was flagged before
    flags = beyond(envelope([load_run(p) for p in sorted(imported.glob("0d*.nc"))]), relax)
    assert not [f for f in flags if "below" in f], flags
    assert any(f.startswith("rate 0.25") and "beyond" in f for f in flags) and any(f.startswith("hold 1.8e+03 s")
                                                                                    for f in flags), flags


def test_a_ramp_at_a_voltage_only_held_before_is_a_new_combination():
    """The shipped specimen-1 runs (datasets/paper2021): the blocking test cycles 0-2.6 kV at a held stretch
    1.5 (its approach ramp at 0 V), the capacitance sweep and the 0 V tensile test move at 0 V. Fitted on
    those three, the 2.6 kV tensile test (the same stretch sine, at 2.6 kV) is inside every axis but moves
    at a voltage at which nothing fitted moved: flagged, naming 2.6 kV and the fitted 0 V."""
    folder = ROOT / "datasets" / "paper2021" / "specimen-1"
    fitted = envelope([load_run(folder / f"{n}.nc") for n in ("blocking_force", "capacitance_sweep",
                                                               "tensile_ramp_sine_0V")])
    hot = load_run(folder / "tensile_ramp_sine_2.6kV.nc")
    axes_only = Envelope.from_mapping({k: v for k, v in fitted.mapping().items() if k != "points"})
    assert beyond(axes_only, hot) == ()
    ramp = beyond(fitted, hot)[0]
    assert re.fullmatch(r"stretch 1\.\d+-1\.5 at \S+ /s, 2\.6 kV \(loading, unloading\): fitted only at \S+ /s "
                        r"\(0 V\)", ramp), ramp
    assert beyond(fitted, load_run(folder / "tensile_ramp_sine_0V.nc")) == ()
