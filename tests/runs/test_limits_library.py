"""Every limit, through the library (not the CLI), on every backend: refused before anything moves.

Stretch, voltage and the field estimate are checked on the plan before any
backend starts: no dataset, no journal, and a rig server never even sees a
connection. The force limit is enforced while running: the run ends
``aborted`` with every received sample kept and the voltage off.
"""

import math
from pathlib import Path

import numpy as np
import pytest

import rdea_lab
import rdea_lab.emulator
from rdea_lab.backends import TwinBackend
from rdea_lab.backends.rig import RigBackend
from rdea_lab.protocols import expand
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.runs import UncheckedPlan, checked_plan, execute
from rdea_lab.specs import LimitError, load_params, load_specimen, protocol_from_yaml
from rdea_lab.specs.truth import load_truth
from rdea_lab.store import open_run

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
TRUTH = ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml"
RigServer = rdea_lab.emulator.RigServer  # before any test records the library's own servers


def protocol(limits: str, stretch: str, voltage: str, name="limit_test"):
    """A 2 s protocol at 100 Hz (201 samples) with explicit channels."""
    return protocol_from_yaml(f"""
name: {name}
kind: custom
sample_rate: 100 Hz
measure: [force]
limits: {limits}
stretch: {stretch}
voltage: {voltage}
""", f"<{name}>")


# Each case exceeds exactly one limit; the others stay at their defaults
# (3 kV, stretch 2, 50 N, 80 V/um) and are not reached.
LIMIT_CASES = {
    # 2.6 kV against a 2 kV limit (field at 2.6 kV, stretch 1.2: 2.6e3 * 1.095 / 48e-6 = 59 V/um < 80)
    "max_voltage": (protocol("{max_voltage: 2 kV}", "[{kind: hold, duration: 2 s, value: 1.2}]",
                             "[{kind: ramp, duration: 2 s, to: 2.6 kV}]", "over_voltage"), "max_voltage"),
    # a ramp to 1.5 against a limit of 1.4
    "max_stretch": (protocol("{max_stretch: 1.4}", "[{kind: ramp, duration: 2 s, to: 1.5}]",
                             "[{kind: hold, duration: 2 s, value: 0 V}]", "over_stretch"), "max_stretch"),
    # a sine 1.02 +- 0.05 dips to 0.97: compression (every segment value given is >= 1)
    "stretch_below_1": (protocol("{}", "[{kind: sine, duration: 2 s, mean: 1.02, amplitude: 0.05, frequency: 1 Hz}]",
                                 "[{kind: hold, duration: 2 s, value: 0 V}]", "compressed"), "below 1"),
    # 2.4 kV at stretch 1.21 on L3 = 48 um: 2.4e3 * 1.1 / 48e-6 = 55 V/um against 54 V/um
    "max_field": (protocol("{max_field: 54 V/um}", "[{kind: hold, duration: 2 s, value: 1.21}]",
                           "[{kind: hold, duration: 2 s, value: 2.4 kV}]", "over_field"), "max_field"),
}

#: at 0 V a ramp to 1.5 pulls far more than 0.05 N (Table 3 material on specimen 2: ~0.3 N at its start)
FORCE_LIMITED = protocol("{max_force: 0.05 N}", "[{kind: hold, duration: 1 s}, {kind: ramp, duration: 1 s, to: 1.5}]",
                         "[{kind: hold, duration: 2 s, value: 0 V}]", "over_force")
MAX_FORCE = 0.05


@pytest.fixture(scope="module")
def card():
    return load_specimen(CARD)


@pytest.fixture(scope="module")
def params():
    return load_params(PARAMS)


@pytest.fixture
def rig(card):
    """An emulated rig server on a free loopback port (its own, so its counters start at 0)."""
    server = RigServer(card, load_truth(TRUTH), port=0)
    host, port = server.start()
    server.url = f"tcp://{host}:{port}"
    yield server
    server.shutdown()


@pytest.fixture
def emulators(monkeypatch):
    """Every RigServer the library makes for the ``emulator`` backend, recorded."""
    made = []

    class Recorded(RigServer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)

    monkeypatch.setattr(rdea_lab.emulator, "RigServer", Recorded)
    return made


class WatchedTwin(TwinBackend):
    """The twin, recording whether the engine ever started it."""

    started = False

    def start(self, plan):
        self.started = True
        super().start(plan)


def assert_nothing_written(tmp_path, out):
    assert not out.exists()
    assert not out.with_name(out.name + ".part").exists()
    assert list(tmp_path.iterdir()) == []


def assert_rig_untouched(server):
    assert server.connections == 0
    assert server.controller.state == "IDLE"
    assert server.controller.voltage_on is False


# ------------------------------------------------------------------ run_protocol
@pytest.mark.parametrize("backend", ["twin", "emulator", "rig"])
@pytest.mark.parametrize("case", list(LIMIT_CASES))
def test_run_protocol_refuses_before_anything_moves(case, backend, tmp_path, request, emulators):
    spec, name = LIMIT_CASES[case]
    out = tmp_path / "x.nc"
    if backend == "rig":
        server = request.getfixturevalue("rig")
        backend = rdea_lab.Rig(server.url)
    with pytest.raises(LimitError, match=name):
        rdea_lab.run_protocol(spec, CARD, backend, out=out)
    assert_nothing_written(tmp_path, out)
    assert emulators == []  # not even the built-in emulator was started
    if backend == "rig":
        assert_rig_untouched(server)


# ----------------------------------------------------------------------- engine
@pytest.mark.parametrize("backend", ["twin", "rig"])
@pytest.mark.parametrize("case", list(LIMIT_CASES))
def test_engine_refuses_an_unchecked_plan_before_backend_start(case, backend, tmp_path, card, params, request):
    spec, name = LIMIT_CASES[case]
    out = tmp_path / "x.nc"
    if backend == "rig":
        server = request.getfixturevalue("rig")
        executor = RigBackend(server.url, card)
    else:
        executor = WatchedTwin(card, params)
    with pytest.raises(LimitError, match=name):  # the one check, in preparation
        checked_plan(expand(spec), card, geometry_from_card(card))
    with pytest.raises(UncheckedPlan, match="only a plan checked against its limits"):  # skipped: refused
        execute(expand(spec), card, executor, out)
    assert_nothing_written(tmp_path, out)
    if backend == "rig":
        assert_rig_untouched(server)
    else:
        assert executor.started is False


@pytest.mark.parametrize("stretch, limit, refused", [
    (1.0, "54 V/um", False),   # 2.4e3 * 1.0 / 48e-6 = 50 V/um
    (1.21, "54 V/um", True),   # 2.4e3 * 1.1 / 48e-6 = 55 V/um
    (1.21, "56 V/um", False),
])
def test_field_estimate_uses_sqrt_stretch_and_the_cards_L3(stretch, limit, refused, card):
    # the boundary sits where |v| sqrt(stretch) / L3 puts it, with the card's own thickness
    assert card.L3 == pytest.approx(48e-6, rel=1e-12)
    field = 2.4e3 * math.sqrt(stretch) / card.L3
    assert (field > float(limit.split()[0]) * 1e6) is refused
    spec = protocol(f"{{max_field: {limit}}}", f"[{{kind: hold, duration: 2 s, value: {stretch}}}]",
                    "[{kind: hold, duration: 2 s, value: 2.4 kV}]", "field_edge")
    if refused:
        with pytest.raises(LimitError, match="max_field"):
            rdea_lab.prepare_run(spec, card, rdea_lab.Twin(PARAMS))
    else:
        rdea_lab.prepare_run(spec, card, rdea_lab.Twin(PARAMS))


# -------------------------------------------------------------------- max_force
def check_force_abort(ds, received, planned):
    """Aborted for max_force at the first over-limit sample, every received sample kept."""
    assert ds.attrs["status"] == "aborted"
    assert "max_force" in ds.attrs["status_reason"]
    np.testing.assert_array_equal(ds["time"].values, np.concatenate([b["time"] for b in received]))
    np.testing.assert_array_equal(ds["force"].values, np.concatenate([b["force"] for b in received]))
    assert 0 < ds.sizes["time"] < planned
    over = np.flatnonzero(np.abs(ds["force"].values) > MAX_FORCE)
    assert over.size
    assert f"t = {ds['time'].values[over[0]]:.4g} s" in ds.attrs["status_reason"]


@pytest.mark.parametrize("backend", ["twin", "emulator", "rig"])
def test_run_protocol_aborts_at_max_force(backend, tmp_path, request, emulators):
    received = []
    name = backend
    if backend == "rig":
        server = request.getfixturevalue("rig")
        backend = rdea_lab.Rig(server.url)
    ds = rdea_lab.run_protocol(FORCE_LIMITED, CARD, backend, out=tmp_path / "x.nc", callbacks=received.append)
    check_force_abort(ds, received, expand(FORCE_LIMITED).samples)
    if name == "rig":
        assert server.connections >= 1  # the counter counts: the refusals above really never connected
        assert server.controller.state == "ABORTED"
        assert server.controller.voltage_on is False
    elif backend == "emulator":
        (made,) = emulators
        assert made.controller.state == "ABORTED"
        assert made.controller.voltage_on is False


@pytest.mark.parametrize("backend", ["twin", "rig"])
def test_engine_aborts_at_max_force_with_exit_code_3(backend, tmp_path, card, params, request):
    received = []
    if backend == "rig":
        server = request.getfixturevalue("rig")
        executor = RigBackend(server.url, card)
    else:
        executor = TwinBackend(card, params)
    plan = expand(FORCE_LIMITED)
    result = execute(checked_plan(plan, card, geometry_from_card(card)), card, executor, tmp_path / "x.nc",
                     callbacks=received.append)
    assert result.status == "aborted"
    assert result.exit_code == 3
    ds = open_run(result.path)
    assert result.samples == ds.sizes["time"]
    check_force_abort(ds, received, plan.samples)
    if backend == "rig":
        assert server.controller.voltage_on is False
        assert server.controller.state == "ABORTED"


# ---------------------------------------------------------------------- predict
def history(stretch, voltage):
    t = np.linspace(0.0, 2.0, 201)
    return {"time": t, "stretch": np.array(np.broadcast_to(stretch, t.shape)),
            "voltage": np.array(np.broadcast_to(voltage, t.shape))}


PREDICT_CASES = {
    # (history, protocol, name in the message, field)
    "max_voltage": (history(1.2, 2.6e3), "{max_voltage: 2 kV}", "max_voltage", "voltage"),
    "max_stretch": (history(np.linspace(1.0, 1.5, 201), 0.0), "{max_stretch: 1.4}", "max_stretch", "stretch"),
    "max_field": (history(1.21, 2.4e3), "{max_field: 54 V/um}", "max_field", "voltage"),
}


def limits_protocol(limits):
    return protocol(limits, "[{kind: hold, duration: 2 s, value: 1.0}]", "[{kind: hold, duration: 2 s, value: 0 V}]",
                    "limits_only")


@pytest.mark.parametrize("case", list(PREDICT_CASES))
def test_predict_with_protocol_checks_its_limits(case, card, params):
    hist, limits, name, field = PREDICT_CASES[case]
    with pytest.raises(LimitError, match=name) as info:
        rdea_lab.predict(hist, params, "su", specimen=card, protocol=limits_protocol(limits))
    assert info.value.field == field


@pytest.mark.parametrize("case", list(PREDICT_CASES))
def test_predict_without_protocol_is_a_bare_model_evaluation(case, card, params):
    hist = PREDICT_CASES[case][0]
    out = rdea_lab.predict(hist, params, "su", specimen=card)
    assert np.all(np.isfinite(out["force"].values))


def test_predict_with_protocol_refuses_compression(card, params):
    hist = history(1.0 + 0.05 * np.sin(np.linspace(0.0, 2 * np.pi, 201)), 0.0)  # down to 0.95
    with pytest.raises(LimitError, match="below 1") as info:
        rdea_lab.predict(hist, params, "su", specimen=card, protocol=limits_protocol("{}"))
    assert info.value.field == "stretch"


def test_predict_takes_a_plans_read_only_setpoints(card, params):
    plan = expand(limits_protocol("{}"))
    assert not plan.stretch.flags.writeable
    out = rdea_lab.predict((plan.time, plan.stretch, plan.voltage), params, "su", specimen=card)
    assert np.all(np.isfinite(out["force"].values))
