"""Operating a run while it goes (issue 29): pause, resume and abort requests through the engine, checked
against the plan itself and against an undisturbed run; requests from another process (``rdea-lab pause``)
and the question a first Ctrl-C asks."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import rdea_lab
from rdea_lab.protocols import load_plan
from rdea_lab.protocols.pause import HELD, RUNNING, pause_intervals
from rdea_lab.runs.control import RunControl, read_state
from terminal import as_at_a_terminal

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
PROTOCOL = ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_2.6kV.yaml"


def read(path):
    with xr.open_dataset(path) as ds:
        return ds.load()


class PauseOnce:
    """Pause at the first block past `at` samples; resume (or abort) once `held` held samples came."""

    def __init__(self, control, at, held=1, then="resume"):
        self.control, self.at, self.held, self.then = control, at, held, then
        self.asked = self.done = False
        self.seen = 0

    def __call__(self, block):
        phase = np.asarray(block.data["paused"])
        if not self.asked and block.samples >= self.at:
            self.control.pause("look at the specimen")
            self.asked = True
        elif self.asked and not self.done:
            self.seen += int((phase == HELD).sum())
            if self.seen >= self.held:
                getattr(self.control, self.then)()
                self.done = True


def test_a_pause_withdrawn_before_any_sample_changes_nothing(tmp_path):
    """The twin computes several blocks per step; a pause gives back the blocks computed ahead and takes the
    model's state back. A pause asked for and withdrawn at once must leave the run as an undisturbed run
    of the same plan (force to rounding: the given-back part of a step is computed again)."""
    plain = read(rdea_lab.run_protocol(PROTOCOL, CARD, rdea_lab.Twin(model="su"), out=tmp_path / "a.nc")
                 .encoding["source"])
    control = RunControl()

    def withdraw(block):
        if block.first == 500:  # a block boundary inside a step of several blocks
            control.pause()
            control.resume()

    rdea_lab.run_protocol(PROTOCOL, CARD, rdea_lab.Twin(model="su"), out=tmp_path / "b.nc", control=control,
                          callbacks=[withdraw])
    got = read(tmp_path / "b.nc")
    assert got.sizes["time"] == plain.sizes["time"]
    assert not got["paused"].values.any()
    np.testing.assert_array_equal(got["voltage_setpoint"].values, plain["voltage_setpoint"].values)
    # rounding of a step computed in two parts instead of one: a few ulps of the force's scale
    np.testing.assert_allclose(got["force"].values, plain["force"].values, rtol=0, atol=1e-12)


def test_twin_pause_ramps_down_holds_and_resumes_where_the_plan_was(tmp_path):
    plan = load_plan(PROTOCOL)
    control = RunControl()
    at = int(20 * plan.sample_rate)  # 20 s in: the voltage is on (2.6 kV from 2 s)
    rdea_lab.run_protocol(PROTOCOL, CARD, rdea_lab.Twin(model="su"), out=tmp_path / "p.nc", control=control,
                          callbacks=[PauseOnce(control, at, held=30)])
    ds = read(tmp_path / "p.nc")
    flag = ds["paused"].values
    (a, b), = pause_intervals(flag)
    running = flag == RUNNING
    assert running.sum() == plan.samples  # every plan sample once, in order
    np.testing.assert_array_equal(ds["voltage_setpoint"].values[running], plan.voltage)
    np.testing.assert_array_equal(ds["stretch_setpoint"].values[running], plan.stretch)
    v = ds["voltage_setpoint"].values
    # down at the default 1 kV/s: from the plan's voltage at the pause to 0 in ceil(v / (rate step)) samples
    down = int(np.ceil(abs(v[a - 1]) / (1000.0 / plan.sample_rate) - 1e-9))
    assert v[a + down - 1] == 0.0 and v[a + down - 2] > 0.0
    assert np.all(np.diff(v[a - 1:a + down]) < 0)
    held = flag == HELD
    assert held.sum() >= 30 and np.all(v[held] == 0.0)
    assert np.ptp(ds["stretch_setpoint"].values[a:b]) == 0.0  # the stretch held where it was
    assert v[b] == plan.voltage[np.flatnonzero(running)[np.flatnonzero(running) < a].size]  # on where it left
    t = ds["time"].values
    t = (t - t[0]) / np.timedelta64(1, "s") if np.issubdtype(t.dtype, np.datetime64) else t - t[0]
    # uniform through the pause (xarray decodes time to datetime64[ns]: a step is exact to a nanosecond)
    np.testing.assert_allclose(np.diff(t), 1.0 / plan.sample_rate, rtol=0, atol=2e-9)
    assert str(ds["pause_reason"].values[0]) == "look at the specimen"
    assert ds.attrs["status"] == "complete"


def test_abort_from_a_pause_ends_the_run_aborted_with_every_sample(tmp_path):
    control = RunControl()
    ds = rdea_lab.run_protocol(PROTOCOL, CARD, rdea_lab.Twin(model="su"), out=tmp_path / "x.nc",
                               control=control, callbacks=[PauseOnce(control, 1000, held=5, then="abort")])
    assert ds.attrs["status"] == "aborted" and "aborted by the user" in ds.attrs["status_reason"]
    flag = ds["paused"].values
    assert flag[-1] == HELD and (flag == RUNNING).sum() < load_plan(PROTOCOL).samples
    assert ds.sizes["pause"] == 1


def test_a_backend_that_cannot_pause_refuses_and_runs_on(tmp_path):
    from rdea_lab.backends.twin import TwinBackend
    from rdea_lab.specs import load_params

    class NoPause(TwinBackend):  # a Backend of one's own, without pause()/resume()
        pause = resume = None

    control = RunControl()
    executor = NoPause(CARD, load_params("paper2021_table3"), model="su")
    ds = rdea_lab.run_protocol(PROTOCOL, CARD, executor, out=tmp_path / "n.nc", control=control,
                               callbacks=[lambda block: control.pause() if block.first == 0 else None])
    assert ds.attrs["status"] == "complete" and not ds["paused"].values.any()
    assert "cannot pause" in control._handled[0]["refused"]


# ---------------------------------------------------------------- from another process, and Ctrl-C
def start(out: Path, *extra, stdin=None):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "rdea_lab.cli.main", "run", str(PROTOCOL), "--specimen", str(CARD),
                             "--model", "su", "--realtime", "--quiet", "--out", str(out), *extra],
                            cwd=out.parent, env=env, stdin=stdin or subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=as_at_a_terminal)
    deadline = time.monotonic() + 60
    while (read_state(out) or {}).get("samples", 0) < 50:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the run did not start"
        time.sleep(0.02)
    return proc


def cli(*args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "rdea_lab.cli.main", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=120)


def wait_state(out, wanted, seconds=20.0):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        state = read_state(out) or {}
        if state.get("state") == wanted:
            return state
        time.sleep(0.02)
    raise AssertionError(f"the run did not become {wanted}: {read_state(out)}")


@pytest.mark.slow
def test_pause_resume_abort_from_another_terminal(tmp_path):
    out = tmp_path / "live.nc"
    with start(out) as proc:
        done = cli("pause", str(out), "--reason", "check the electrode", cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        wait_state(out, "paused")
        again = cli("pause", str(out), cwd=tmp_path)  # refused: exit 2, one line saying why
        assert again.returncode == 2 and "paused already" in again.stderr and again.stderr.count("\n") == 1
        assert cli("resume", str(out), cwd=tmp_path).returncode == 0
        wait_state(out, "running")
        assert cli("abort", str(out), "--reason", "enough", cwd=tmp_path).returncode == 0
        err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 3, err
    ds = read(out)
    assert ds.attrs["status"] == "aborted" and ds.attrs["status_reason"] == "enough"
    assert [str(r) for r in ds["pause_reason"].values] == ["check the electrode"]
    assert str(ds["pause_by"].values[0]) == "rdea-lab pause"
    gone = cli("pause", str(out), cwd=tmp_path)  # the run has ended: nothing to pause
    assert gone.returncode == 2 and "no run in progress" in gone.stderr


@pytest.mark.slow
def test_first_ctrl_c_pauses_and_asks_a_second_interrupts(tmp_path):
    out = tmp_path / "ask.nc"
    with start(out, "--on-ctrl-c", "ask", stdin=subprocess.PIPE) as proc:
        proc.send_signal(signal.SIGINT)
        wait_state(out, "paused")
        proc.stdin.write("r\n")
        proc.stdin.flush()
        wait_state(out, "running")
        proc.send_signal(signal.SIGINT)  # asks again
        wait_state(out, "paused")
        proc.send_signal(signal.SIGINT)  # the second while asked: interrupted at once, voltage off
        err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 130, err
    assert "Type r + Enter to resume" in err
    ds = read(out)
    assert ds.attrs["status"] == "interrupted" and ds.sizes["pause"] == 2
    assert ds["paused"].values[-1] != RUNNING


def test_ask_on_ctrl_c_reads_the_answer():
    from rdea_lab.cli.operate import AskOnCtrlC

    control, said = RunControl(), []
    ask = AskOnCtrlC(control, stream=io.StringIO("what?\na\n"), echo=said.append)
    assert ask() is True
    for _ in range(200):
        if not ask.open:
            break
        time.sleep(0.01)
    assert [r.action for r in control.poll()] == ["pause", "abort"]
    assert any("r to resume, a to abort" in s for s in said)
    assert ask() is True  # answered: the next Ctrl-C asks again (and its reader finds the terminal closed)
    assert ask() is False  # while asked: the Ctrl-C interrupts
