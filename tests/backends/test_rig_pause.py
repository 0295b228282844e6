"""The rig driver's pause, resume and conditions (issue 29) against a real emulator server on loopback."""

from pathlib import Path

import numpy as np
import pytest

from rdea_lab.backends import PauseRefused
from rdea_lab.backends.rig import RigBackend
from rdea_lab.emulator import RigServer
from rdea_lab.emulator.controller import parse_faults
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.protocols import load_plan
from rdea_lab.protocols.pause import HELD, RAMPING_DOWN, RUNNING
from rdea_lab.runs import checked_plan
from rdea_lab.specs import load_specimen
from rdea_lab.specs.truth import load_truth

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ROOT / "rdea_lab" / "data" / "protocols"


@pytest.fixture(scope="module")
def card():
    return load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")


@pytest.fixture(scope="module")
def truth():
    return load_truth(ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml")


@pytest.fixture
def server(card, truth, request):
    srv = RigServer(card, truth, port=0, **getattr(request, "param", {}))
    host, port = srv.start()
    srv.url = f"tcp://{host}:{port}"
    yield srv
    srv.shutdown()


@pytest.fixture(scope="module")
def plan(card):
    """2.6 kV (within the limits for specimen 2: checked), 100 Hz; the driver takes the plan itself, as the
    engine gives it."""
    plan = load_plan(PROTOCOLS / "tensile_ramp_sine_2.6kV.yaml")
    checked_plan(plan, card, geometry_from_card(card))
    return plan


def read(backend, until):
    """Blocks until ``until(blocks)`` (or the run's end)."""
    blocks = []
    while not until(blocks):
        block = backend.read_block()
        if block is None:
            break
        blocks.append(block)
    return blocks


def joined(blocks):
    return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


def samples(blocks):
    return sum(len(b["time"]) for b in blocks)


def assert_plan_driven_once(rows, plan):
    running = rows["paused"] == RUNNING
    np.testing.assert_array_equal(rows["stretch_setpoint"][running], plan.stretch)
    np.testing.assert_array_equal(rows["voltage_setpoint"][running], plan.voltage)
    np.testing.assert_allclose(rows["time"], np.arange(rows["time"].size) / plan.sample_rate, rtol=0, atol=1e-12)


@pytest.mark.slow
def test_pause_and_resume_through_the_driver_and_the_stall_detector_waits_out_a_hold(server, card, plan):
    backend = RigBackend(server.url, card, stall_timeout=0.5)
    backend.start(plan)
    try:
        assert backend.pausable
        blocks = read(backend, lambda b: samples(b) >= 1000)  # t = 10 s, at 2.6 kV
        with pytest.raises(PauseRefused, match=r"refused CONT: .*the run is not paused"):
            backend.resume()
        backend.pause("operator")
        assert backend.pause_reason == "operator"
        # 2.6 kV to 0 at 1 kV/s (the defaults), then held 1.5 s of the wall clock: 3 stall timeouts
        blocks += read(backend, lambda b: b and np.count_nonzero(joined(b)["paused"] == HELD) >= 150)
        assert np.all(blocks[-1]["paused"] == HELD) and np.all(blocks[-1]["voltage_setpoint"] == 0.0)
        backend.resume()
        blocks += read(backend, lambda b: False)
    finally:
        backend.close()
    rows = joined(blocks)
    assert_plan_driven_once(rows, plan)
    flag = rows["paused"]
    assert np.count_nonzero(flag == RAMPING_DOWN) == 260 and np.count_nonzero(flag == HELD) >= 150
    assert server.controller.state == "DONE" and server.controller.rig.run.pause_state() == ("RUNNING", 1)


def test_an_older_server_runs_as_before_without_pauses(server, card, plan):
    for header in ("CONF:PAUS", "COND?"):  # a server of the protocol before issue 29: ERR -113 for them
        server.controller._commands.pop(header)
    backend = RigBackend(server.url, card)
    backend.start(plan)
    try:
        assert not backend.pausable
        blocks = read(backend, lambda b: len(b) >= 1)
        with pytest.raises(PauseRefused, match="it does not know CONF:PAUS .a server of an older protocol."):
            backend.pause("operator")
        assert backend.conditions() == {}
        blocks += read(backend, lambda b: False)
    finally:
        backend.close()
    assert "paused" not in blocks[0] and samples(blocks) == plan.samples
    assert server.controller.state == "DONE"


@pytest.mark.parametrize("server", [{"faults": parse_faults(["interlock-at=10:3", "overheat-at=5"])}],
                         indirect=True)
def test_the_rig_pauses_itself_when_its_door_opens_and_the_driver_reads_its_conditions(server, card, plan):
    backend = RigBackend(server.url, card)
    backend.start(plan)
    asked = []
    query = backend._query
    backend._query = lambda command: (asked.append(command), query(command))[1]
    try:
        blocks = read(backend, lambda b: b and np.any(b[-1]["paused"] != RUNNING))
        rows = joined(blocks)
        first = int(np.argmax(rows["paused"] != RUNNING))
        assert rows["time"][first] == 10.0  # the door opened at 10 s: the rig paused by itself
        reading = backend.conditions()
        assert reading == {"interlock": "open", "amplifier_temperature": 343.15,
                           "force_offset_drift": pytest.approx(reading["force_offset_drift"])}
        assert backend.conditions() == reading and asked.count("COND?") == 1  # within 0.1 s: the cached one
        with pytest.raises(PauseRefused, match="refused CONT: .*the door interlock is open"):
            backend.resume()
        while backend.conditions()["interlock"] == "open":  # run time 13 s: about 1 s of held samples
            blocks += read(backend, lambda b: len(b) >= 1)
        backend.resume()
        blocks += read(backend, lambda b: False)
    finally:
        backend.close()
    assert_plan_driven_once(joined(blocks), plan)
    assert server.controller.state == "DONE"
