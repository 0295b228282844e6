"""The run engine: every abort path turns the voltage off and keeps every sample."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rdea_lab.backends import BackendFailure, TwinBackend
from rdea_lab.runs import checked_plan, execute
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.physics.models import solve
from rdea_lab.specs import Limits, load_params, load_specimen
from rdea_lab.store import journal_path, open_run

ROOT = Path(__file__).resolve().parents[2]


class FakePlan(SimpleNamespace):
    """The parts of a Plan the engine uses (its limits are checked like a real plan's)."""

    @property
    def samples(self):
        return self.time.size

    def block_slices(self, seconds=1.0):
        n = max(1, int(round(seconds * self.sample_rate)))
        return [slice(i, min(i + n, self.time.size)) for i in range(0, self.time.size, n)]


def plan(duration=10.0, rate=100.0, max_force=50.0, voltage=0.0, card=None):
    """A plan, checked for ``card`` (specimen 2 by default) as the engine requires."""
    card = card if card is not None else load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
    t = np.arange(int(round(duration * rate)) + 1) / rate
    return checked_plan(bare(t, rate, max_force, voltage), card, geometry_from_card(card))


def bare(t, rate, max_force, voltage):
    return FakePlan(name="p", kind="tensile", sample_rate=rate, measure=("force",), limits=Limits(max_force=max_force),
                    time=t, stretch=1 + 0.25 * (1 - np.cos(2 * np.pi * 0.1 * t)), voltage=np.full(t.size, voltage),
                    stretch_segment=np.zeros(t.size, int), voltage_segment=np.zeros(t.size, int),
                    yaml="name: p\n", source="<test>")


@pytest.fixture(scope="module")
def card():
    return load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")


@pytest.fixture(scope="module")
def params():
    return load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")


class Scripted:
    """A backend that yields fixed blocks, then does what the test says."""

    name = "scripted"
    extra_variables = ()

    def __init__(self, blocks, then):
        self.blocks, self.then, self.aborts, self.closed = list(blocks), then, [], False

    def attrs(self):
        return {}

    def start(self, plan):
        pass

    def read_block(self):
        if self.blocks:
            return self.blocks.pop(0)
        if self.then is None:
            return None
        raise self.then

    def abort(self, reason):
        self.aborts.append(reason)

    def close(self):
        self.closed = True


def blocks(n_blocks, n=50, force=1.0):
    out = []
    for b in range(n_blocks):
        t = (b * n + np.arange(n)) / 100.0
        out.append({"time": t, "stretch": np.ones(n), "position": np.zeros(n), "voltage": np.zeros(n),
                    "force": np.full(n, force), "capacitance": np.full(n, np.nan),
                    "stretch_setpoint": np.ones(n), "voltage_setpoint": np.zeros(n)})
    return out


@pytest.mark.parametrize("exc, status", [(KeyboardInterrupt(), "interrupted"),
                                         (BackendFailure("connection lost at t = 1.5 s"), "aborted")])
def test_interrupt_and_backend_failure_keep_samples_and_switch_off(tmp_path, card, exc, status):
    backend = Scripted(blocks(3), then=exc)
    r = execute(plan(), card, backend, tmp_path / "r.nc")
    assert r.status == status and r.samples == 150
    assert len(backend.aborts) == 1 and backend.closed
    ds = open_run(r.path)
    assert ds.sizes["time"] == 150 and ds.attrs["status"] == status
    assert ds.attrs["status_reason"] == r.reason != ""


def test_internal_error_aborts_keeps_data_and_reraises(tmp_path, card):
    backend = Scripted(blocks(2), then=ZeroDivisionError("boom"))
    with pytest.raises(ZeroDivisionError):
        execute(plan(), card, backend, tmp_path / "r.nc")
    ds = open_run(tmp_path / "r.nc")
    assert ds.sizes["time"] == 100 and ds.attrs["status"] == "aborted"
    assert "ZeroDivisionError: boom" in ds.attrs["status_reason"] and backend.aborts


def test_force_above_the_limit_aborts_with_the_block_kept(tmp_path, card):
    backend = Scripted(blocks(2) + blocks(1, force=80.0) + blocks(2), then=None)
    r = execute(plan(max_force=50.0), card, backend, tmp_path / "r.nc")
    assert r.status == "aborted" and r.samples == 150
    assert "force 80 N at t = 0 s is above the limit max_force = 50 N" in r.reason
    assert backend.aborts == [r.reason]


def test_twin_run_complete_with_attrs_and_quasi_static_force(tmp_path, card, params):
    """At 0 V the twin's force is the SU quasi-static force plus the viscoelastic part,
    bounded by sum(eta_j) max|dlambda/dt| area / lambda (Maxwell branches start relaxed)."""
    p = plan(duration=20.0)
    r = execute(p, card, TwinBackend(card, params, model="su"), tmp_path / "r.nc", seed=7)
    p = p.plan
    ds = open_run(r.path)
    assert r.status == "complete" and ds.sizes["time"] == p.time.size
    assert ds.attrs["seed"] == 7 and ds.attrs["model"] == "su" and ds.attrs["backend"] == "twin"
    geom = geometry_from_card(card)
    qs = solve("su", geom, params, p.stretch, 0.0).force
    rate = np.max(np.abs(np.gradient(p.stretch, p.time)))
    bound = sum(b.eta for b in params.branches) * rate * geom.area / p.stretch
    assert np.all(np.abs(ds["force"].values - qs) <= bound * 1.01)  # 1 %: the discrete slope vs the gradient
    assert np.all(np.isnan(ds["capacitance"].values))  # not measured by this plan
    assert not journal_path(r.path).exists()


def test_auto_model_is_recorded_with_its_deviation(tmp_path, card, params):
    r = execute(plan(voltage=2600.0), card, TwinBackend(card, params, model="auto"), tmp_path / "r.nc")
    ds = open_run(r.path)
    import json
    sel = json.loads(ds.attrs["model_selection"])
    assert ds.attrs["model_requested"] == "auto" and ds.attrs["model"] == sel["model"] == "su"
    # specimen 2 (Ri = 0) is a solid roll: the reference, CR, is the SU state exactly
    assert sel["reference"] == "cr" and sel["deviation_from_reference"]["su"] < 1e-12
