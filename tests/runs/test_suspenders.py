"""Suspenders through the engine on the emulated rig (issue 29): a condition the emulator raises (fault
injection) pauses the run and, once it clears, resumes it; one that outlasts its wait aborts the run
(exit 3) with every sample kept. Checked against the plan (every plan sample once, in order) and against
the injected fault's times."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

import rdea_lab
from rdea_lab.protocols import load_plan
from rdea_lab.protocols.pause import HELD, RAMPING_DOWN, RUNNING, pause_intervals

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
RATE = 100.0

PROTOCOL = """\
name: suspend_check
kind: custom
sample_rate: {rate:g} Hz
measure: [force]
limits: {{max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}}
pause: {{ramp_rate: 10 kV/s}}
suspend:
{suspend}
stretch:
  - {{kind: ramp, duration: 3 s, to: 1.3}}
  - {{kind: ramp, duration: 3 s, to: 1.1}}
voltage:
  - {{kind: ramp, duration: 1 s, to: 1 kV}}
  - {{kind: hold, duration: 5 s}}
"""


def protocol(folder: Path, *suspenders: str) -> Path:
    path = folder / "suspend_check.yaml"
    path.write_text(PROTOCOL.format(rate=RATE, suspend="\n".join(f"  - {s}" for s in suspenders)))
    return path


def read(path):
    with xr.open_dataset(path) as ds:
        return ds.load()


def check_plan_kept(ds, plan):
    running = ds["paused"].values == RUNNING
    assert running.sum() <= plan.samples
    n = int(running.sum())
    np.testing.assert_array_equal(ds["stretch_setpoint"].values[running], plan.stretch[:n])
    np.testing.assert_array_equal(ds["voltage_setpoint"].values[running], plan.voltage[:n])
    return n


def seconds(ds, name):
    values = ds[name].values
    if np.issubdtype(values.dtype, np.datetime64):
        return (values - ds["time"].values[0]) / np.timedelta64(1, "s")
    return values


def test_an_open_door_pauses_the_run_and_its_closing_resumes_it(tmp_path):
    path = protocol(tmp_path, "{name: door, when: interlock == open, wait: 30 s}")
    ds = rdea_lab.run_protocol(path, CARD, rdea_lab.Emulator(faults=["interlock-at=2:1.5"], stall_timeout=30),
                               out=tmp_path / "door.nc")
    ds = read(ds.encoding["source"])
    plan = load_plan(path)
    assert ds.attrs["status"] == "complete", ds.attrs["status_reason"]
    assert check_plan_kept(ds, plan) == plan.samples
    (a, b), = pause_intervals(ds["paused"].values)
    t = seconds(ds, "time")
    assert abs(t[a] - 2.0) <= 1.0 / RATE + 1e-9  # the rig paused at the first sample with its door open
    assert t[b] >= 3.5  # and did not go on before the door closed (2 s + 1.5 s of run time)
    v, flag = ds["voltage_setpoint"].values, ds["paused"].values
    assert np.all(v[flag == HELD] == 0.0) and (flag == HELD).sum() >= 1.5 * RATE * 0.9
    down = int(np.ceil(1000.0 / (10e3 / RATE)))  # 1 kV at 10 kV/s: the samples of the ramp down
    assert v[a + down - 1] == 0.0 and np.all(flag[a:a + down] == RAMPING_DOWN)
    assert ds.sizes["pause"] == 1


def test_an_overheated_amplifier_pauses_until_it_cools_below_the_resume_condition(tmp_path):
    path = protocol(tmp_path, "{name: hot, when: amplifier_temperature > 60 degC, "
                              "resume: amplifier_temperature < 50 degC, wait: 30 s}")
    ds = rdea_lab.run_protocol(path, CARD, rdea_lab.Emulator(faults=["overheat-at=2.5:2"], stall_timeout=30),
                               out=tmp_path / "hot.nc")
    ds = read(ds.encoding["source"])
    plan = load_plan(path)
    assert ds.attrs["status"] == "complete", ds.attrs["status_reason"]
    assert check_plan_kept(ds, plan) == plan.samples
    (a, b), = pause_intervals(ds["paused"].values)
    t = seconds(ds, "time")
    assert 2.5 <= t[a] <= 2.5 + 1.0 + 0.1  # seen after the block (<= 1 s of samples) it began in
    assert t[b] >= 4.5  # not resumed before the amplifier cooled
    assert "amplifier_temperature > 60 degC" in str(ds["pause_reason"].values[0])
    assert str(ds["pause_by"].values[0]) == "suspender"


def test_a_drift_that_outlasts_its_wait_aborts_the_run_keeping_every_sample(tmp_path):
    path = protocol(tmp_path, '{name: zero, when: "|force_offset_drift| > 5 mN", wait: 1 s}')
    result = rdea_lab.runs.execute_setup(rdea_lab.prepare_run(
        path, CARD, rdea_lab.Emulator(faults=["drift-at=2"], stall_timeout=30), out=tmp_path / "drift.nc"))
    assert result.exit_code == 3  # the CLI's exit status of an aborted run
    ds = read(tmp_path / "drift.nc")
    assert ds.attrs["status"] == "aborted"
    assert "suspender 'zero'" in ds.attrs["status_reason"] and "waited longer" in ds.attrs["status_reason"]
    n = check_plan_kept(ds, load_plan(path))
    t = seconds(ds, "time")
    assert abs(t[n] - 2.0) <= 1.0  # paused soon after the drift began
    (a, b), = pause_intervals(ds["paused"].values)
    assert b == ds.sizes["time"]  # it ended paused, every sample of the pause kept
    # after waiting its 1 s of wall time, held samples paced by the wall clock: 1 s of samples, less what
    # the last fetch before the abort had not yet taken (the driver polls every 20 ms)
    assert t[-1] - t[a] >= 0.9
    assert np.all(ds["voltage_setpoint"].values[-3:] == 0.0)


def test_a_campaigns_suspenders_are_added_to_each_protocols_own(tmp_path):
    """A campaign's ``suspend:`` applies to every run besides the protocol's own: the plan each experiment runs
    (and so its dataset's ``protocol`` attribute) holds both, the protocol's first, a shared one once."""
    from rdea_lab.runs import experiments
    from rdea_lab.specs.campaign import load_campaign

    protocol(tmp_path, "{name: door, when: interlock == open, wait: 30 s}")
    (tmp_path / "c.yaml").write_text(f"""name: c
root: .
backend: emulator
out: {tmp_path / 'out'}
specimens: [{CARD}]
protocols: [suspend_check.yaml]
suspend:
  - {{name: door, when: interlock == open, wait: 30 s}}
  - {{name: hot, when: amplifier_temperature > 60 degC, resume: amplifier_temperature < 50 degC}}
""")
    spec, folder = load_campaign(tmp_path / "c.yaml")
    run, = experiments(spec, folder)
    assert [s.name for s in run.plan.spec.suspend] == ["door", "hot"]
    assert "amplifier_temperature > 60 degC" in run.plan.yaml
