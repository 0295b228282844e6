"""Abort paths and outcomes the application layer must get right (found in review of issue 10)."""

import io
from pathlib import Path

import pytest

import rdea_lab
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.protocols import expand
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.runs import LiveTable, checked_plan, default_out, execute, run_campaign
from rdea_lab.specs import load_params, load_specimen, protocol_from_yaml
from rdea_lab.specs.campaign import load_campaign

from .helpers import RecordingTwin

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
SHORT = """\
name: short_run
kind: custom
sample_rate: 100 Hz
measure: [force]
limits: {max_force: %s}
stretch:
  - {kind: ramp, duration: 3 s, to: 1.4}
voltage:
  - {kind: hold, duration: 3 s}
"""


def short(max_force="50 N"):
    return protocol_from_yaml(SHORT % max_force)


def checked(plan, card):
    """``plan`` checked for ``card``, as the engine takes it (`prepare_run` does this for a run)."""
    return checked_plan(plan, card, geometry_from_card(card))


def test_an_output_that_cannot_be_claimed_is_refused_before_the_backend_starts(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    spy = RecordingTwin(load_specimen(CARD), load_params(PARAMS))
    with pytest.raises(OSError):
        execute(checked(expand(short()), card := load_specimen(CARD)), card, spy, tmp_path / "file" / "x.nc")
    assert spy.calls == ["close"]  # nothing started


def test_a_journal_that_cannot_be_written_after_start_aborts_the_backend(tmp_path, monkeypatch):
    from rdea_lab.store.journal import JournalWriter

    def full(self, attrs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(JournalWriter, "begin", full)
    spy = RecordingTwin(load_specimen(CARD), load_params(PARAMS))
    with pytest.raises(OSError):
        execute(checked(expand(short()), card := load_specimen(CARD)), card, spy, tmp_path / "x.nc")
    assert spy.calls == ["start", "abort", "close"]
    assert not (tmp_path / "x.nc.part").exists()  # the claim is given up


def test_a_second_run_on_the_same_output_is_refused_before_it_starts(tmp_path):
    from rdea_lab.store.journal import JournalInUse, JournalWriter

    claim = JournalWriter(tmp_path / "x.nc", None)  # the first run has claimed it
    spy = RecordingTwin(load_specimen(CARD), load_params(PARAMS))
    with pytest.raises(JournalInUse, match="another run is writing it"):
        execute(checked(expand(short()), card := load_specimen(CARD)), card, spy, tmp_path / "x.nc")
    assert spy.calls == ["close"]
    claim.abandon()
    assert not (tmp_path / "x.nc.part").exists()


def test_an_unwritable_output_is_refused_before_anything_moves(tmp_path, capsys):
    (tmp_path / "file").write_text("not a folder")
    rc = run_cli(cli, ["run", str(ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml"),
                       "--specimen", str(CARD), "--backend", "emulator", "--out", str(tmp_path / "file" / "x.nc")])
    err = capsys.readouterr().err
    assert rc == 2 and "is not a folder" in err and len(err.strip().splitlines()) == 1


def test_the_force_limit_keeps_its_reason_when_a_subscriber_fails_in_the_same_block(tmp_path):
    def fails(block):
        raise RuntimeError("window closed")

    with pytest.raises(RuntimeError, match="window closed"):
        rdea_lab.run_protocol(short("0.5 N"), CARD, "twin", out=tmp_path / "x.nc", callbacks=[fails])
    ds = rdea_lab.open_run(tmp_path / "x.nc")
    assert ds.attrs["status"] == "aborted" and "max_force" in ds.attrs["status_reason"]


def test_ctrl_c_in_run_protocol_writes_the_file_then_raises(tmp_path):
    def ctrl_c(block):
        if block.first > 0:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt, match="samples kept in"):
        rdea_lab.run_protocol(short(), CARD, "twin", out=tmp_path / "x.nc", callbacks=[ctrl_c])
    ds = rdea_lab.open_run(tmp_path / "x.nc")
    assert ds.attrs["status"] == "interrupted" and "(Ctrl-C)" in ds.attrs["status_reason"]
    assert ds.sizes["time"] == 200  # the two blocks received (1 s each at 100 Hz)


def test_ctrl_c_ends_the_campaign_not_only_the_run(tmp_path):
    (tmp_path / "p.yaml").write_text(SHORT % "50 N")
    (tmp_path / "c.yaml").write_text(f"name: c\nbackend: twin\nseed: 1\nout: {tmp_path / 'out'}\nparams: {PARAMS}\n"
                                     f"specimens: [{CARD}, "
                                     f"{ROOT / 'rdea_lab' / 'data' / 'specimens' / 'specimen1.yaml'}]\n"
                                     f"protocols: [{tmp_path / 'p.yaml'}]\n")
    spec, root = load_campaign(tmp_path / "c.yaml")
    blocks = []

    def ctrl_c_in_the_first_run(block):
        blocks.append(block)
        if len(blocks) == 2:
            raise KeyboardInterrupt

    results = run_campaign(spec, root, callbacks=[ctrl_c_in_the_first_run])
    assert [r.status for r in results] == ["interrupted"]  # the second specimen never ran
    assert not (tmp_path / "out" / "specimen-1").exists()


def test_default_outputs_never_collide(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    first = default_out("s", "p")
    first.parent.mkdir(parents=True)
    first.write_text("x")
    second = default_out("s", "p")
    assert second != first and second.name.startswith(first.stem)


def test_a_live_table_prints_the_first_block_of_every_run_of_a_campaign(tmp_path):
    out = io.StringIO()
    table = LiveTable(out, interval=3600.0, clock=lambda: 0.0)  # a frozen clock: only first rows and stops
    for i in range(2):
        rdea_lab.run_protocol(short(), CARD, "twin", out=tmp_path / f"{i}.nc", callbacks=[table])
    rows = [line for line in out.getvalue().splitlines() if "/301" in line]
    assert len(rows) == 4  # per run: its first block, and its last at stop


@pytest.mark.parametrize("args, option", [
    (["--seed", "-1"], "--seed"),
    (["--backend", "rig"], "--rig"),
    (["--backend", "emulator", "--fault", "melt-at=1"], "--fault"),
    (["--fault", "stall-at=1"], "--fault/--truth"),
])
def test_library_argument_errors_name_the_cli_option(capsys, args, option):
    rc = run_cli(cli, ["run", str(ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml"),
                       "--specimen", str(CARD), "--dry-run", *args])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith(f"rdea-lab: {option}:"), err


def test_report_with_the_old_options_says_where_they_went(capsys):
    assert run_cli(cli, ["report", "--params", "p.yaml", "--datasets", "d"]) == 2
    assert "report validation --params" in capsys.readouterr().err


def test_a_rig_that_does_not_answer_is_exit_2(capsys, tmp_path):
    rc = run_cli(cli, ["run", str(ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml"),
                       "--specimen", str(CARD), "--backend", "rig", "--rig", "tcp://127.0.0.1:1",
                       "--out", str(tmp_path / "x.nc")])
    err = capsys.readouterr().err
    assert rc == 2 and "no answer" in err and not (tmp_path / "x.nc").exists()
