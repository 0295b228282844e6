"""A specimen becomes geometry once, where it enters; limits are checked once, in preparation; the engine
runs only a plan that went through that check (issue 26).

The counts come from counters put in place of `geometry_from_card` and `check_plan` in every module of
the library that holds them (the emulator's excepted: the rig's own side, which checks independently).
"""

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

import rdea_lab.physics.geometry as geometry_module
import rdea_lab.protocols.plan as plan_module
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.protocols import load_plan
from rdea_lab.runs import (CheckedPlan, UncheckedPlan, checked_plan, execute, execute_setup, experiments,
                           prepare_run, run_campaign, run_protocol)
from rdea_lab.specs import LimitError, load_params, load_specimen
from rdea_lab.specs.campaign import load_campaign

from .helpers import RecordingTwin

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "rdea_lab" / "data"
CARD = DATA / "specimens" / "specimen2.yaml"
PROTOCOL = DATA / "protocols" / "blocking_force.yaml"


@pytest.fixture
def counted(monkeypatch):
    """Counters in place of `geometry_from_card` and `check_plan`, wherever the library (not the emulator)
    bound them: ``{"geometry": [card ids], "checks": [plan names]}``."""
    import rdea_lab.runs.checked  # noqa: F401  (loaded, so its bindings are replaced too)

    calls = {"geometry": [], "checks": []}
    make, check = geometry_module.geometry_from_card, plan_module.check_plan

    def counted_geometry(card):
        if not sys._getframe(1).f_globals["__name__"].startswith("rdea_lab.emulator"):  # a lazy import's caller
            calls["geometry"].append(card.id)
        return make(card)

    def counted_check(plan, L3=None):
        calls["checks"].append(plan.name)
        return check(plan, L3)

    monkeypatch.setattr(geometry_module, "geometry_from_card", counted_geometry)  # lazy imports get this one
    for name, module in list(sys.modules.items()):
        if not name.startswith("rdea_lab") or name.startswith("rdea_lab.emulator") or module is None:
            continue
        if getattr(module, "geometry_from_card", None) is make:
            monkeypatch.setattr(module, "geometry_from_card", counted_geometry)
        if getattr(module, "check_plan", None) is check and name != "rdea_lab.protocols.plan":
            monkeypatch.setattr(module, "check_plan", counted_check)
    monkeypatch.setattr(plan_module, "check_plan", counted_check)  # first_violation calls it here
    return calls


@pytest.fixture(scope="module")
def card():
    return load_specimen(CARD)


@pytest.fixture(scope="module")
def params():
    return load_params(DATA / "params" / "paper2021_table3.yaml")


# ------------------------------------------------------------------ geometry once
def test_a_twin_run_makes_the_geometry_once_and_checks_its_limits_once(counted, tmp_path):
    ds = run_protocol(PROTOCOL, CARD, "twin", out=tmp_path / "x.nc")
    assert ds.attrs["status"] == "complete"
    assert counted["geometry"] == [ds.attrs["specimen_id"]]
    assert counted["checks"] == [ds.attrs["protocol_name"]]


def test_an_emulated_run_makes_the_geometry_once_on_the_library_side(counted, tmp_path):
    """The driver configures the rig (CONF:LENG, CONF:THIC) from the run's geometry; the emulated rig's own
    truth is the rig's side, not counted."""
    ds = run_protocol(PROTOCOL, CARD, "emulator", out=tmp_path / "x.nc")
    assert ds.attrs["status"] == "complete"
    assert counted["geometry"] == [ds.attrs["specimen_id"]]
    assert counted["checks"] == [ds.attrs["protocol_name"]]


@pytest.mark.parametrize("backend", ["twin", "rig"])
def test_the_backends_take_the_geometry_of_the_setup(backend, card, tmp_path):
    """(Opening a rig backend does not connect: its start does.)"""
    setup = prepare_run(PROTOCOL, card, "tcp://127.0.0.1:9" if backend == "rig" else backend, out=tmp_path / "x.nc")
    with setup.opened() as executor:
        assert executor.geom is setup.geometry


def test_a_twin_campaign_makes_each_geometry_once_and_checks_each_plan_once(counted, tmp_path):
    spec, root = load_campaign(DATA / "campaigns" / "paper2021.yaml")
    spec = spec.model_copy(update={"backend": "twin", "protocols": spec.protocols[2:3]})  # blocking force: short
    results = run_campaign(spec, root, out_dir=tmp_path / "c")
    ids = [load_specimen(root / rel).id for rel in spec.specimens]
    assert [r.status for r in results] == ["complete"] * len(ids)
    assert counted["geometry"] == ids  # once per specimen, in experiments
    assert len(counted["checks"]) == len(results) == len(ids) * len(spec.protocols)  # once per run


def test_a_campaign_shown_first_is_not_checked_again(counted, tmp_path):
    """What `rdea-lab campaign run` does: experiments, then run_campaign with them."""
    spec, root = load_campaign(DATA / "campaigns" / "paper2021.yaml")
    spec = spec.model_copy(update={"backend": "twin", "protocols": spec.protocols[2:3],
                                   "specimens": spec.specimens[1:2]})
    runs = experiments(spec, root, tmp_path / "c")
    (result,) = run_campaign(spec, root, out_dir=tmp_path / "c", runs=runs)
    assert result.status == "complete"
    assert len(counted["geometry"]) == len(counted["checks"]) == 1


def test_experiments_hold_checked_plans_for_their_own_cards(tmp_path):
    spec, root = load_campaign(DATA / "campaigns" / "paper2021.yaml")
    for run in experiments(spec, root, tmp_path):
        assert isinstance(run.checked, CheckedPlan) and run.checked.is_for(run.card)
        assert run.checked.geometry.L3 == geometry_from_card(run.card).L3


# ------------------------------------------------------------------ the engine's assertion
def test_a_bare_plan_is_refused_before_the_backend_starts(card, params, tmp_path):
    backend = RecordingTwin(card, params)
    with pytest.raises(UncheckedPlan, match="only a plan checked against its limits, not a Plan"):
        execute(load_plan(PROTOCOL), card, backend, tmp_path / "x.nc")
    assert backend.calls == ["close"]  # never started: no setpoint reached it
    assert list(tmp_path.iterdir()) == []  # no dataset, no journal


def test_a_plan_edited_after_its_check_is_refused(card, params, tmp_path):
    checked = checked_plan(load_plan(PROTOCOL), card, geometry_from_card(card))
    voltage = checked.plan.voltage
    voltage.setflags(write=True)  # read-only arrays can be made writable: the fingerprint sees it
    voltage[voltage.size // 2] = 1e6
    backend = RecordingTwin(card, params)
    with pytest.raises(UncheckedPlan, match="changed after its limits were checked"):
        execute(checked, card, backend, tmp_path / "x.nc")
    assert backend.calls == ["close"]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("change", ["plan", "limits", "geometry"])
def test_a_checked_plan_with_a_part_replaced_is_refused(change, card, params, tmp_path):
    checked = checked_plan(load_plan(PROTOCOL), card, geometry_from_card(card))
    plan = checked.plan
    if change == "plan":  # another plan in its place (twice the voltage)
        voltage = np.array(plan.voltage) * 2.0
        voltage.setflags(write=False)
        replaced = dataclasses.replace(checked, plan=dataclasses.replace(plan, voltage=voltage))
    elif change == "limits":  # the same setpoints under a looser limit
        looser = plan.limits.model_copy(update={"max_voltage": 10 * plan.limits.max_voltage})
        replaced = dataclasses.replace(checked, plan=dataclasses.replace(plan, limits=looser))
    else:  # a thicker membrane would lower the field estimate
        geom = checked.geometry
        replaced = dataclasses.replace(checked, geometry=dataclasses.replace(geom, L3=2 * geom.L3))
    backend = RecordingTwin(card, params)
    with pytest.raises(UncheckedPlan, match="changed after its limits were checked"):
        execute(replaced, card, backend, tmp_path / "x.nc")
    assert backend.calls == ["close"]


def test_a_plan_checked_for_another_specimen_is_refused(card, params, tmp_path):
    other = load_specimen(DATA / "specimens" / "specimen1.yaml")
    checked = checked_plan(load_plan(PROTOCOL), other, geometry_from_card(other))
    backend = RecordingTwin(card, params)
    with pytest.raises(UncheckedPlan, match=f"checked for specimen {other.id!r}, the run is on {card.id!r}"):
        execute(checked, card, backend, tmp_path / "x.nc")
    assert backend.calls == ["close"]


def test_a_setup_runs_its_checked_plan(card, tmp_path):
    setup = prepare_run(PROTOCOL, card, "twin", out=tmp_path / "x.nc")
    assert setup.checked.is_for(card) and setup.plan is setup.checked.plan
    assert execute_setup(setup).status == "complete"


def test_prepare_run_checks_a_plan_checked_for_another_card_again(card, counted, tmp_path):
    other = load_specimen(DATA / "specimens" / "specimen1.yaml")
    for_other = checked_plan(load_plan(PROTOCOL), other, geometry_from_card(other))
    counted["geometry"].clear()
    counted["checks"].clear()
    setup = prepare_run(for_other, card, "twin", out=tmp_path / "x.nc")
    assert setup.checked.is_for(card) and setup.plan is for_other.plan
    assert counted["geometry"] == [card.id] and len(counted["checks"]) == 1


def test_checked_plan_is_the_limit_check(card):
    plan = load_plan(PROTOCOL)
    tight = dataclasses.replace(plan, limits=plan.limits.model_copy(update={"max_voltage": 1000.0}))
    with pytest.raises(LimitError, match="max_voltage = 1 kV"):
        checked_plan(tight, card, geometry_from_card(card))
