"""The rig driver against a real emulator server on loopback (issue 4)."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.specs import LimitError

from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.runs import UncheckedPlan, checked_plan, execute
from rdea_lab.runs import run_campaign
from rdea_lab.backends.rig import RigBackend, RigRefused
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.emulator import RigServer
from rdea_lab.protocols import load_plan
from rdea_lab.specs import load_specimen
from rdea_lab.specs.campaign import load_campaign
from rdea_lab.specs.truth import load_truth
from rdea_lab.store import open_run

ROOT = Path(__file__).resolve().parents[2]


def checked(plan, card):
    """``plan`` checked for ``card``, as the engine takes it (`prepare_run` does this for a run)."""
    return checked_plan(plan, card, geometry_from_card(card))


@pytest.fixture(scope="module")
def card():
    return load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")


@pytest.fixture(scope="module")
def truth():
    return load_truth(ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml")


@pytest.fixture
def server(card, truth, request):
    kwargs = getattr(request, "param", {})
    srv = RigServer(card, truth, port=0, **kwargs)
    host, port = srv.start()
    srv.url = f"tcp://{host}:{port}"
    yield srv
    srv.shutdown()


@pytest.mark.slow  # 12 s; one preset per specimen: tests/cli/test_run.py
def test_every_preset_on_every_specimen_is_complete(tmp_path):
    spec, root = load_campaign(ROOT / "rdea_lab" / "data" / "campaigns" / "paper2021.yaml")
    results = run_campaign(spec, root, out_dir=tmp_path)
    assert len(results) == 12 and all(r.status == "complete" for r in results)
    for r in results:
        ds = open_run(r.path)
        plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / f"{ds.attrs['protocol_name']}.yaml")
        # data complete: every sample of the plan, in order, setpoints as commanded
        assert ds.sizes["time"] == plan.time.size == r.samples
        np.testing.assert_allclose(ds["time"].values, plan.time, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(ds["stretch_setpoint"].values, plan.stretch)
        np.testing.assert_array_equal(ds["voltage_setpoint"].values, plan.voltage)
        assert np.all(np.isfinite(ds["force"].values))
        assert ds.attrs["emulated"] == 1 and "rig-emulator" in ds.attrs["rig_idn"]
        assert json.loads(ds.attrs["emulator_truth"])["name"] == "paper2021-emulator"
        # the LCR bridge reads at 0 V only, and only when the protocol measures capacitance
        c = ds["capacitance"].values
        if ds.attrs["protocol_kind"] == "capacitance":
            assert np.all(np.isfinite(c[np.abs(ds["voltage"].values) < 1.0]))
        else:
            assert np.all(np.isnan(c))


def run_with(server, card, plan, out, **kw):
    backend = RigBackend(server.url, card, **kw)
    result = execute(checked(plan, card), card, backend, out)
    return result, open_run(result.path)


@pytest.mark.parametrize("server", [{"faults": [("breakdown", 10.0)]}], indirect=True)
def test_breakdown_mid_run(server, card, tmp_path):
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_2.6kV.yaml")
    r, ds = run_with(server, card, plan, tmp_path / "b.nc")
    assert r.status == "aborted" and "dielectric breakdown" in r.reason
    assert ds.sizes["time"] == server.controller.acquired  # counted on both sides: none lost
    assert 10.0 <= ds["time"].values[-1] <= 10.0 + 1 / plan.sample_rate


@pytest.mark.parametrize("server", [{"faults": [("stall", 3.0)]}], indirect=True)
def test_stall_mid_run(server, card, tmp_path):
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml")
    r, ds = run_with(server, card, plan, tmp_path / "s.nc", stall_timeout=0.5)
    assert r.status == "aborted" and "stalled" in r.reason
    assert ds.sizes["time"] == server.controller.acquired
    assert server.controller.state == "ABORTED"  # the client's ABOR reached the rig: voltage off


@pytest.mark.slow
@pytest.mark.parametrize("server", [{"faults": [("disconnect", 2.0)], "realtime": True}], indirect=True)
def test_disconnect_mid_run_reconnects_and_drains(server, card, tmp_path):
    """Realtime, so the rig holds samples the client has not fetched when the line drops;
    the driver reconnects and fetches them: nothing acquired is lost."""
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml")
    r, ds = run_with(server, card, plan, tmp_path / "d.nc", poll=0.2)
    assert r.status == "aborted"
    assert "lost" in r.reason and "reconnected and fetched all" in r.reason
    assert ds.sizes["time"] == server.controller.acquired
    np.testing.assert_allclose(np.diff(ds["time"].values), 1 / plan.sample_rate, rtol=1e-9)


@pytest.mark.parametrize("server", [{"token": "s3cret-token"}], indirect=True)
def test_a_client_without_the_token_is_refused(server, card, tmp_path):
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml")
    with pytest.raises(RigRefused, match="token"):
        execute(checked(plan, card), card, RigBackend(server.url, card), tmp_path / "x.nc")
    assert not (tmp_path / "x.nc").exists() and not (tmp_path / "x.nc.part").exists()
    assert server.controller.state == "IDLE"
    r, ds = run_with(server, card, plan, tmp_path / "ok.nc", token="s3cret-token")
    assert r.status == "complete"


def test_limits_refused_by_the_rig_before_anything_moves(server, card, tmp_path):
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml")
    tight = dataclasses.replace(plan, limits=plan.limits.model_copy(update={"max_voltage": 2000.0}))
    # the library refuses first: its one check, in preparation ...
    with pytest.raises(LimitError, match="max_voltage = 2 kV"):
        checked(tight, card)
    # ... and an engine given the plan without it refuses it, before it connects
    with pytest.raises(UncheckedPlan):
        execute(tight, card, RigBackend(server.url, card), tmp_path / "x.nc")
    assert not (tmp_path / "x.nc").exists() and not (tmp_path / "x.nc.part").exists()
    assert server.connections == 0
    # ... and a client that skips the library's check is refused by the rig itself, at ARM
    backend = RigBackend(server.url, card)
    try:
        with pytest.raises(RigRefused,
                           match=r"refused ARM: voltage 20[0-9.]+ V at t = [0-9.]+ s is above LIM:VOLT 2000 V"):
            backend.start(tight)
    finally:
        backend.close()
    assert server.controller.state != "RUNNING" and server.controller.acquired == 0


def test_limits_refused_by_the_client_before_connecting(capsys, tmp_path):
    bad = ROOT / "tests" / "protocols" / "bad"
    over = next(p for p in sorted(bad.glob("*.yaml")) if "voltage_above" in p.name)
    rc = run_cli(cli, ["run", str(over), "--specimen", str(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"),
                       "--backend", "rig", "--rig", "tcp://127.0.0.1:9"])  # nothing listens on port 9
    err = capsys.readouterr().err
    assert rc == 2 and "max_voltage" in err and "connect" not in err


def test_cli_emulator_backend_with_a_fault(capsys, tmp_path):
    out = tmp_path / "f.nc"
    rc = run_cli(cli, ["run", str(ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml"), "--specimen",
                       str(ROOT / "rdea_lab" / "data" / "specimens" / "specimen1.yaml"), "--backend", "emulator",
                       "--fault", "breakdown-at=12", "--quiet", "--out", str(out)])
    stdout = capsys.readouterr().out
    assert rc == 3 and "status aborted" in stdout  # exit 3: the run was ended by the rig
    ds = open_run(out)
    assert ds.attrs["status"] == "aborted" and "breakdown" in ds.attrs["status_reason"]
    assert ds["time"].values[-1] == pytest.approx(12.0, abs=1e-3)


def test_each_run_has_its_own_reproducible_noise(server, card, tmp_path):
    """Same trajectory, different seeds: the forces differ by noise only (load-cell sigma
    4 mN in truth/paper2021.yaml, so differences stay within ~10 sigma * sqrt(2)); the
    same seed gives the same data bit for bit."""
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml")
    f = {}
    for name, seed in (("a", 1), ("b", 2), ("c", 1)):
        r = execute(checked(plan, card), card, RigBackend(server.url, card, seed=seed), tmp_path / f"{name}.nc",
                    seed=seed)
        ds = open_run(r.path)
        assert ds.attrs["seed"] == seed
        f[name] = ds["force"].values
    diff = f["a"] - f["b"]
    assert np.any(diff != 0) and np.max(np.abs(diff)) < 10 * 4e-3 * np.sqrt(2)
    assert np.std(diff) == pytest.approx(4e-3 * np.sqrt(2), rel=0.1)  # 5401 samples: std known to ~2 %
    np.testing.assert_array_equal(f["a"], f["c"])


@pytest.mark.slow
@pytest.mark.parametrize("server", [{"realtime": True}], indirect=True)
def test_a_second_driver_is_refused_and_the_running_experiment_completes(server, card, tmp_path, capsys):
    """The audit: a second `rdea-lab run` against a rig already running sent *RST and ended the first run.
    Now it asks first (SYST:CTRL?, STAT?), is refused with exit 2 and sends nothing that changes the rig,
    not even the ABOR of its own failed start."""
    import threading
    import time

    text = (ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml").read_text()
    short = tmp_path / "short.yaml"  # one 2 s cycle after a 1 s settle: 4 s in realtime
    short.write_text(text.replace("frequency: 0.1 Hz, cycles: 5", "frequency: 0.5 Hz, cycles: 1")
                     .replace("settle: 2 s", "settle: 1 s"))
    plan = load_plan(short)
    first = {}
    t = threading.Thread(target=lambda: first.update(r=execute(checked(plan, card), card,
                                                               RigBackend(server.url, card, poll=0.05),
                                                               tmp_path / "first.nc")))
    t.start()
    try:
        t0 = time.monotonic()
        while server.controller.state != "RUNNING" and time.monotonic() - t0 < 10:
            time.sleep(0.02)
        assert server.controller.state == "RUNNING"
        with pytest.raises(RigRefused, match="is busy: RUNNING"):
            execute(checked(plan, card), card, RigBackend(server.url, card), tmp_path / "second.nc")
        card_file = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
        rc = run_cli(cli, ["run", str(short),
                           "--specimen", str(card_file), "--backend", "rig", "--rig", server.url,
                           "--out", str(tmp_path / "third.nc")])
        cap = capsys.readouterr()
        err = cap.err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "is busy" in err[0] and "nothing sent" in err[0]
        assert server.controller.state == "RUNNING"  # untouched
        assert not (tmp_path / "second.nc").exists() and not (tmp_path / "third.nc").exists()
    finally:
        t.join(60)
    r = first["r"]
    ds = open_run(r.path)
    assert r.status == "complete" and ds.attrs["status"] == "complete"
    assert ds.sizes["time"] == plan.time.size  # every sample of the plan


@pytest.fixture
def other_server(truth):
    """An emulated rig that holds specimen 1 (its *IDN? serial says so)."""
    srv = RigServer(load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen1.yaml"), truth, port=0)
    host, port = srv.start()
    srv.url = f"tcp://{host}:{port}"
    yield srv
    srv.shutdown()


def test_a_card_the_rig_does_not_hold_is_refused_unless_trusted(other_server, card, tmp_path, capsys):
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml")
    idn_serial = other_server.controller.idn.split(",")[2]
    assert idn_serial != card.id  # the rig holds specimen 1, the card is specimen 2
    with pytest.raises(RigRefused) as info:
        execute(checked(plan, card), card, RigBackend(other_server.url, card), tmp_path / "x.nc")
    assert idn_serial in str(info.value) and card.id in str(info.value) and "--trust-card" in str(info.value)
    assert other_server.controller.state == "IDLE" and other_server.controller.acquired == 0  # before ARM
    assert not (tmp_path / "x.nc").exists()
    card_file = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
    args = ["run", str(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml"), "--specimen",
            str(card_file), "--backend", "rig", "--rig", other_server.url, "--quiet", "--out"]
    assert run_cli(cli, args + [str(tmp_path / "y.nc")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and idn_serial in err[0] and card.id in err[0]
    assert run_cli(cli, args + [str(tmp_path / "z.nc"), "--trust-card"]) == 0
    ds = open_run(tmp_path / "z.nc")
    assert ds.attrs["status"] == "complete" and ds.attrs["specimen_id"] == card.id
    assert ds.attrs["rig_identity"].startswith("overridden") and idn_serial in ds.attrs["rig_identity"]


def test_the_identity_check_is_recorded(server, card, tmp_path):
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml")
    r, ds = run_with(server, card, plan, tmp_path / "ok.nc")
    assert ds.attrs["rig_identity"] == f"checked: the rig holds {card.id}"


def test_a_plan_longer_than_the_rig_protocol_takes_is_refused_before_the_rig_is_touched(tmp_path):
    """More setpoints than one trajectory block holds (`MAX_POINTS`): refused by the driver with the count and
    the limit, before it connects (the address below has no server), so nothing moves and nothing is written."""
    from rdea_lab.specs import rigwire

    card = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
    plan = load_plan(ROOT / "rdea_lab" / "data" / "protocols" / "fatigue_24h.yaml")
    assert plan.samples > rigwire.MAX_POINTS  # the check below is not vacuous
    backend = RigBackend("tcp://127.0.0.1:9", card)
    with pytest.raises(RigRefused, match=f"{plan.samples} samples.*at most {rigwire.MAX_POINTS}"):
        backend.start(plan)
    assert backend._touched is False
