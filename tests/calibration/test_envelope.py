"""The calibration envelope and its extrapolation flags (issue 13), on runs with known stretch ramps."""

from pathlib import Path

import numpy as np
import pytest

from rdea_lab.calibration import Envelope, beyond, envelope, run_envelope
from rdea_lab.calibration.envelope import HOLD_RATE, longest_hold
from rdea_lab.calibration.objective import run_data
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
