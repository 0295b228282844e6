"""The public application layer: what a notebook, the CLI and the campaign runner call."""

import io
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import rdea_lab
from rdea_lab.calibration import Budget
from rdea_lab.calibration.parameters import values_of
from rdea_lab.runs.app import OutputInUse, check_outputs
from rdea_lab.runs.callbacks import LiveTable, RunBlock
from rdea_lab.runs.engine import RunResult
from rdea_lab.specs import SpecError, load_params, load_protocol, load_specimen
from rdea_lab.store import open_run

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
MEASURED = ROOT / "datasets" / "paper2021" / "specimen-2" / "tensile_ramp_sine_0V.nc"

#: 3 s at 100 Hz: 301 samples, blocks of one second (100, 100, 100, 1) on the twin
SHORT = """\
name: short_run
kind: custom
sample_rate: 100 Hz
measure: [force, capacitance]
stretch:
  - {kind: ramp, duration: 1.5 s, to: 1.3}
  - {kind: sine, duration: 1.5 s, mean: 1.3, amplitude: 0.1, frequency: 1 Hz}
voltage:
  - {kind: ramp, duration: 3 s, to: 2 kV}
"""
PLANNED = 3 * 100 + 1


@pytest.fixture(scope="module")
def short_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("protocols") / "short_run.yaml"
    path.write_text(SHORT)
    return path


@pytest.fixture(scope="module")
def twin_run(short_file, tmp_path_factory):
    """One su twin run of the short protocol, from paths, with metadata."""
    out = tmp_path_factory.mktemp("runs") / "twin.nc"
    return rdea_lab.run_protocol(short_file, CARD, rdea_lab.Twin(PARAMS, "su"), out=out,
                                 metadata={"operator": "ana", "batch": "B7"})


# ------------------------------------------------------------------ exports
NAMES = ["run_protocol", "calibrate_runs", "predict", "catalog", "open_run", "load_specimen", "load_params"]


@pytest.mark.parametrize("name", NAMES)
def test_import_rdea_lab_exposes_the_application_layer(name):
    assert name in dir(rdea_lab)
    assert callable(getattr(rdea_lab, name))


def test_exports_are_the_library_functions_themselves():
    from rdea_lab.calibration.app import calibrate_runs
    from rdea_lab.runs.app import run_protocol
    from rdea_lab.store.catalog import catalog
    from rdea_lab.twin.predict import predict

    assert rdea_lab.run_protocol is run_protocol
    assert rdea_lab.calibrate_runs is calibrate_runs
    assert rdea_lab.predict is predict
    assert rdea_lab.catalog is catalog
    assert rdea_lab.load_specimen is load_specimen


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no_such_function"):
        rdea_lab.no_such_function


# -------------------------------------------------------------- run_protocol
def test_paths_and_objects_give_identical_data(short_file, twin_run, tmp_path):
    ds = rdea_lab.run_protocol(load_protocol(short_file), load_specimen(CARD), rdea_lab.Twin(load_params(PARAMS), "su"),
                               out=tmp_path / "objects.nc")
    assert set(ds.data_vars) == set(twin_run.data_vars)
    a, b = ds.drop_attrs(deep=False), twin_run.drop_attrs(deep=False)
    for x, run in ((a, ds), (b, twin_run)):  # time units name each run's own start (CF); the rest is identical
        assert x["time"].attrs.pop("units") == f"seconds since {run.attrs['created']}"
    xr.testing.assert_identical(a, b)


def test_metadata_round_trips_and_is_catalogued(twin_run):
    assert twin_run.rdea.metadata == {"operator": "ana", "batch": "B7"}
    table = rdea_lab.catalog(Path(twin_run.encoding["source"]).parent)
    assert table.shape[0] == 1
    assert table["md.operator"].tolist() == ["ana"]
    assert table["md.batch"].tolist() == ["B7"]


@pytest.mark.parametrize("key", ["1x", "a b", "", "x" * 65])
def test_bad_metadata_keys_are_refused_before_anything_is_written(key, short_file, tmp_path):
    out = tmp_path / "x.nc"
    with pytest.raises(SpecError, match="not a metadata key") as info:
        rdea_lab.run_protocol(short_file, CARD, "twin", out=out, metadata={key: "v"})
    assert info.value.field == key
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("seed", [2**64, 2**63, -1, 1.5, True])
def test_seeds_outside_0_to_2_63_are_refused_before_anything_is_written(seed, short_file, tmp_path):
    with pytest.raises(SpecError, match="seed"):
        rdea_lab.run_protocol(short_file, CARD, "twin", out=tmp_path / "x.nc", seed=seed)
    assert list(tmp_path.iterdir()) == []


def test_the_largest_seed_is_recorded(short_file, tmp_path):
    ds = rdea_lab.run_protocol(short_file, CARD, "twin", out=tmp_path / "x.nc", seed=2**63 - 1)
    assert int(ds.attrs["seed"]) == 2**63 - 1


# ----------------------------------------------------------------- callbacks
def test_a_function_receives_every_sample_exactly_once(short_file, tmp_path):
    blocks = []
    ds = rdea_lab.run_protocol(short_file, CARD, "twin", out=tmp_path / "x.nc", callbacks=blocks.append)
    assert ds.sizes["time"] == PLANNED
    np.testing.assert_array_equal(np.concatenate([b["time"] for b in blocks]), ds["time"].values)
    np.testing.assert_array_equal(np.concatenate([b["force"] for b in blocks]), ds["force"].values)
    first = 0
    for block in blocks:
        assert isinstance(block, RunBlock)
        assert block.first == first
        assert block.samples == first + len(block)
        assert block.planned == PLANNED
        first = block.samples
    assert first == PLANNED


class Recorder:
    def __init__(self):
        self.events = []

    def start(self, attrs):
        self.events.append(("start", attrs))

    def __call__(self, block):
        self.events.append(("block", block))

    def stop(self, result):
        self.events.append(("stop", result))


def test_start_comes_once_before_the_first_block_and_stop_once_at_the_end(short_file, tmp_path):
    rec = Recorder()
    ds = rdea_lab.run_protocol(short_file, CARD, "twin", out=tmp_path / "x.nc", callbacks=[rec])
    kinds = [kind for kind, _ in rec.events]
    assert kinds[0] == "start" and kinds[-1] == "stop"
    assert kinds.count("start") == 1 and kinds.count("stop") == 1
    assert set(kinds[1:-1]) == {"block"}
    attrs, result = rec.events[0][1], rec.events[-1][1]
    assert attrs["protocol_name"] == "short_run" and attrs["specimen_id"] == "specimen-2"
    assert attrs["run_id"] == ds.attrs["run_id"]
    assert isinstance(result, RunResult)
    assert (result.status, result.samples, result.exit_code) == ("complete", PLANNED, 0)
    assert Path(result.path) == tmp_path / "x.nc"


class Boom(RuntimeError):
    pass


def test_a_subscriber_that_raises_aborts_the_run_and_its_error_propagates(short_file, tmp_path):
    seen = []

    def fails_on_second_block(block):
        seen.append(block)
        if len(seen) == 2:
            raise Boom("disk full")

    out = tmp_path / "x.nc"
    with pytest.raises(Boom, match="disk full"):
        rdea_lab.run_protocol(short_file, CARD, "twin", out=out, callbacks=fails_on_second_block)
    ds = open_run(out)
    assert ds.attrs["status"] == "aborted"
    assert "fails_on_second_block" in ds.attrs["status_reason"]
    assert "disk full" in ds.attrs["status_reason"]
    # the samples received up to the failure are kept (the failing block was written before it was handed out)
    np.testing.assert_array_equal(ds["time"].values, np.concatenate([b["time"] for b in seen]))
    assert ds.sizes["time"] < PLANNED
    assert not out.with_name(out.name + ".part").exists()


def test_other_subscribers_still_get_stop_when_one_fails(short_file, tmp_path):
    rec = Recorder()

    def fails(block):
        raise Boom("x")

    with pytest.raises(Boom):
        rdea_lab.run_protocol(short_file, CARD, "twin", out=tmp_path / "x.nc", callbacks=[rec, fails])
    assert [kind for kind, _ in rec.events][-1] == "stop"


# ----------------------------------------------------------------- LiveTable
def fake_blocks(n_blocks, size=25):
    for i in range(n_blocks):
        t = (i * size + np.arange(size)) / 100.0
        data = {"time": t, "stretch": 1 + t / 100, "voltage": np.full(size, 1e3), "force": t,
                "capacitance": np.full(size, 1e-10)}
        yield RunBlock(data, i * size, (i + 1) * size, n_blocks * size)


def test_live_table_prints_about_one_line_per_interval():
    # a block every 0.25 s of (fake) wall time for 20 blocks: t = 0, 0.25, ..., 4.75 s. With a 1 s interval
    # the rows come at t = 0, 1, 2, 3, 4 (exact binary fractions, no rounding); the last block
    # (4.75 s) is printed by stop; plus the two header lines and the closing line.
    ticks = iter(np.arange(20) * 0.25)
    out = io.StringIO()
    table = LiveTable(out, interval=1.0, clock=lambda: next(ticks))
    table.start({"protocol_name": "p", "specimen_id": "s", "backend": "twin"})
    for block in fake_blocks(20):
        table(block)
    table.stop(RunResult(Path("x.nc"), "complete", "", 500))
    lines = out.getvalue().splitlines()
    assert lines[0] == "p on s (twin)"
    assert "force [N]" in lines[1] and "capacitance [pF]" in lines[1]
    rows = lines[2:-1]
    assert len(rows) == 6
    assert [row.split()[0] for row in rows] == ["25/500", "125/500", "225/500", "325/500", "425/500", "500/500"]
    assert float(rows[-1].split()[1]) == pytest.approx(4.99)  # time of the very last sample [s]
    assert lines[-1] == "complete, 500 samples -> x.nc"


def test_live_table_does_not_repeat_the_last_row():
    ticks = iter([0.0, 1.0])
    out = io.StringIO()
    table = LiveTable(out, interval=1.0, clock=lambda: next(ticks))
    table.start({})
    for block in fake_blocks(2):
        table(block)
    table.stop(RunResult(Path("x.nc"), "aborted", "why", 50))
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 + 2 + 1
    assert lines[-1] == "aborted: why, 50 samples -> x.nc"


# ------------------------------------------------------------- check_outputs
def test_two_runs_writing_one_file_are_refused_naming_both(tmp_path):
    with pytest.raises(OutputInUse, match="specimen-2/blocking_force.*specimen-2/blocking_force_again"):
        check_outputs([tmp_path / "a.nc", tmp_path / "." / "a.nc"],
                      names=["specimen-2/blocking_force", "specimen-2/blocking_force_again"])


def test_an_existing_file_is_refused_without_overwrite(tmp_path):
    out = tmp_path / "a.nc"
    out.write_bytes(b"measured")
    with pytest.raises(OutputInUse, match="exists"):
        check_outputs([out])
    assert out.read_bytes() == b"measured"
    check_outputs([out], overwrite=True)
    assert out.read_bytes() == b"measured"  # replaced only when the new run's dataset is written


def test_overwrite_keeps_the_old_dataset_until_the_new_one_is_written(short_file, tmp_path):
    out = tmp_path / "a.nc"
    first = rdea_lab.run_protocol(short_file, CARD, "twin", out=out)
    from rdea_lab.backends.rig import RigRefused

    with pytest.raises(RigRefused):  # nothing listens on port 1: the rig is refused, the old run stays
        rdea_lab.run_protocol(short_file, CARD, rdea_lab.Rig("tcp://127.0.0.1:1"), out=out, overwrite=True)
    assert rdea_lab.open_run(out).attrs["run_id"] == first.attrs["run_id"]
    second = rdea_lab.run_protocol(short_file, CARD, "twin", out=out, overwrite=True)
    assert rdea_lab.open_run(out).attrs["run_id"] == second.attrs["run_id"] != first.attrs["run_id"]


def test_an_unfinished_journal_is_never_overwritten(tmp_path):
    out = tmp_path / "a.nc"
    (tmp_path / "a.nc.part").mkdir()
    with pytest.raises(OutputInUse, match="journal"):
        check_outputs([out], overwrite=True)
    assert (tmp_path / "a.nc.part").exists()


# ------------------------------------------------------------------ accessor
def test_predict_on_a_twin_run_reproduces_its_force(twin_run):
    # the engine steps the twin block by block (TwinStream, one block a second); predict runs the whole
    # series at once: two code paths of the stepping. The branch update is exact over every interval, so
    # they agree to rounding (the prefix scans differ in length): 1e-12 of the peak force.
    twin = twin_run.rdea.predict(PARAMS, "su")
    force = twin_run["force"].values
    np.testing.assert_allclose(twin["force"].values, force, rtol=0, atol=1e-12 * np.max(np.abs(force)))
    np.testing.assert_allclose(twin["capacitance"].values, twin_run["capacitance"].values, rtol=1e-12)
    np.testing.assert_array_equal(twin["time"].values, twin_run["time"].values)


def test_accessor_gives_back_the_loaded_specs(twin_run, short_file):
    assert twin_run.rdea.specimen == load_specimen(CARD)
    assert twin_run.rdea.protocol == load_protocol(short_file)
    assert twin_run.rdea.parameters == load_params(PARAMS)
    assert twin_run.rdea.path == twin_run.encoding["source"]


# -------------------------------------------------------------- path or object
def test_simulate_takes_paths_or_objects():
    t = np.linspace(0.0, 2.0, 201)
    lam = 1.0 + 0.2 * np.sin(np.pi * t / 4)
    by_path = rdea_lab.simulate(str(CARD), str(PARAMS), t, lam, 0.0)
    by_object = rdea_lab.simulate(load_specimen(CARD), load_params(PARAMS), t, lam, 0.0)
    for ds in (by_path, by_object):  # the creation time, to the second: the two calls may straddle one
        for key in ("created", "history"):
            ds.attrs.pop(key)
        assert ds["time"].attrs.pop("units").startswith("seconds since ")
    xr.testing.assert_identical(by_path, by_object)


@pytest.mark.parametrize("specimen, params, expected", [
    (42, PARAMS, "specimen: expected a SpecimenCard"),
    (CARD, 42, "params: expected a ParameterSet"),
    (CARD, {"C10": 1e5}, "params: expected a ParameterSet"),
    ("swap", "swap", "specimen: expected a SpecimenCard"),  # (params, card): the arguments swapped
])
def test_a_wrong_type_is_a_type_error_saying_what_is_expected(specimen, params, expected):
    if specimen == "swap":
        specimen, params = load_params(PARAMS), load_specimen(CARD)
    t = np.linspace(0.0, 1.0, 11)
    with pytest.raises(TypeError, match=expected):
        rdea_lab.simulate(specimen, params, t, np.full(11, 1.1), 0.0)


def test_a_protocol_given_as_the_specimen_is_a_type_error(short_file):
    t = np.linspace(0.0, 1.0, 11)
    with pytest.raises(TypeError, match="specimen: expected a SpecimenCard"):
        rdea_lab.simulate(load_protocol(short_file), PARAMS, t, np.full(11, 1.1), 0.0)


# ---------------------------------------------------------------- calibration
def test_calibrate_runs_in_memory_equals_on_files():
    mem = open_run(MEASURED).copy(deep=True)
    mem.encoding = {}  # not backed by a file any more
    kwargs = dict(free="C10,C20,C30", budget=Budget(evaluations=200))
    on_files = rdea_lab.calibrate_runs([MEASURED], **kwargs)
    in_memory = rdea_lab.calibrate_runs([mem], **kwargs)
    assert on_files.free_names == in_memory.free_names == ("C10", "C20", "C30")
    assert in_memory.values == on_files.values
    assert in_memory.nfev == on_files.nfev <= 200  # the evaluation budget is a hard stop
    # what was not free did not move
    for name in set(on_files.values) - {"C10", "C20", "C30"}:
        assert on_files.values[name] == values_of(on_files.start)[name]


def test_calibrate_runs_names_an_unknown_free_parameter():
    with pytest.raises(SpecError, match="C99") as info:
        rdea_lab.calibrate_runs([MEASURED], free="C10,C99", branches=1, budget=Budget(evaluations=10))
    assert info.value.field == "free"


def test_calibrate_runs_with_no_branches_returns_no_branches():
    result = rdea_lab.calibrate_runs([MEASURED], free="C10,C20,C30", branches=0, budget=Budget(evaluations=50))
    assert result.params.M == 0
    assert "k_v1" not in result.values
