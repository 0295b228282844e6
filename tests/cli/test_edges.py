"""Edges found by a tester (issue 11): each through the real CLI, exit 2 with one line where it is the user's."""

from pathlib import Path

import numpy as np
import pytest

import rdea_lab
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import protocol_from_yaml

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"


def rdea(capsys, *args):
    code = run_cli(cli, [str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_campaign_listing_one_card_twice_is_refused_naming_both_runs(tmp_path, capsys):
    (tmp_path / "c.yaml").write_text(
        f"name: c\nbackend: twin\nseed: 1\nout: {tmp_path / 'out'}\n"
        f"params: {ROOT / 'rdea_lab' / 'data' / 'params' / 'paper2021_table3.yaml'}\n"
        f"specimens: [{CARD}, {CARD}]\n"
        f"protocols: [{ROOT / 'rdea_lab' / 'data' / 'protocols' / 'blocking_force.yaml'}]\n")
    code, out, err = rdea(capsys, "campaign", "run", tmp_path / "c.yaml")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "specimens[0] (specimen2.yaml, id specimen-2)" in err and "specimens[1] (specimen2.yaml" in err
    assert not (tmp_path / "out").exists()  # refused before anything ran


@pytest.mark.parametrize("args", [["--backend", "Twin"], ["--model", "SU"], ["--backend", "TWIN", "--model", "Auto"]])
def test_choices_are_accepted_in_any_case(capsys, args):
    code, out, err = rdea(capsys, "run", ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml",
                          "--specimen", CARD, "--dry-run", *args)
    assert code == 0, err


def test_the_force_limit_message_has_the_digits_to_tell_force_and_limit_apart(tmp_path):
    proto = protocol_from_yaml("""\
name: p
kind: custom
sample_rate: 100 Hz
limits: {max_force: 1 N}
stretch:
  - {kind: ramp, duration: 5 s, to: 1.5}
voltage:
  - {kind: hold, duration: 5 s}
""")
    ds = rdea_lab.run_protocol(proto, CARD, rdea_lab.Twin(model="su"), out=tmp_path / "x.nc")
    reason = ds.attrs["status_reason"]
    assert ds.attrs["status"] == "aborted"
    shown = float(reason.split("force ")[1].split(" N")[0])
    assert shown > 1.0 and abs(shown - ds["force"].values[np.argmax(np.abs(ds["force"].values) > 1.0)]) < 1e-3


def test_an_unreachable_rig_address_is_exit_2(capsys, tmp_path):
    code, out, err = rdea(capsys, "run", ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml",
                          "--specimen", CARD, "--backend", "rig", "--rig", "tcp://127.0.0.1:1",
                          "--out", tmp_path / "x.nc")
    assert code == 2 and "no answer" in err and len(err.strip().splitlines()) == 1


def test_calibrate_names_every_file_it_leaves_out(tmp_path, capsys):
    import shutil

    for f in (ROOT / "datasets" / "paper2021" / "specimen-2").glob("tensile*.nc"):
        shutil.copy(f, tmp_path)
    (tmp_path / "broken.nc").write_text("not netCDF")
    code, out, err = rdea(capsys, "calibrate", tmp_path, "--out", tmp_path / "c.yaml", "--max-evals", "20")
    assert code == 0, err
    assert f"skipped {tmp_path / 'broken.nc'}: unreadable" in out
    assert "broken.nc" in (tmp_path / "c.yaml").read_text()  # and the record says so


def test_curve_refuses_a_field_no_membrane_survives_unless_told(capsys):
    args = ["curve", "--specimen", CARD, "--params", ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml",
            "--voltage", "3500 kV"]
    code, out, err = rdea(capsys, *args)
    assert code == 2 and "--voltage" in err and "--no-field-check" in err and out == ""
    code, out, err = rdea(capsys, *args, "--no-field-check")
    assert code == 0
    # the paper's own Section 3.4 scene (96 V/um) is well within the default
    code, out, err = rdea(capsys, "curve", "--specimen", ROOT / "rdea_lab" / "data" / "specimens" / "passive_core.yaml",
                          "--params", ROOT / "rdea_lab" / "data" / "params" / "rizzello2020.yaml",
                          "--stretch", "1:1.75:5", "--voltage", "3.5kV")
    assert code == 0, err


def test_a_plot_into_a_new_folder_is_written(tmp_path, capsys):
    target = tmp_path / "new" / "folder" / "run.png"
    code, out, err = rdea(capsys, "show", ROOT / "datasets" / "paper2021" / "specimen-2" / "blocking_force.nc",
                          "--plot", target)
    assert code == 0 and target.stat().st_size > 10_000, err


def test_a_seed_past_2_63_is_exit_2_before_anything_runs(tmp_path, capsys):
    code, out, err = rdea(capsys, "run", ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml",
                          "--specimen", CARD, "--seed", str(2**64), "--out", tmp_path / "x.nc")
    assert code == 2 and err.startswith("rdea-lab: --seed:") and not list(tmp_path.iterdir())


def test_campaign_run_help_has_no_literal_backslash_b(capsys):
    code, out, err = rdea(capsys, "campaign", "run", "--help")
    assert code == 0 and "\\b" not in out and "Example:" in out


def test_the_import_format_is_accepted_in_any_case(tmp_path, capsys):
    csv = tmp_path / "t.csv"
    csv.write_text("time,position,force\ns,mm,N\n" + "".join(f"{i * 0.1:.1f},{i * 0.5:.1f},{i * 0.01:.2f}\n"
                                                          for i in range(20)))
    code, out, err = rdea(capsys, "import", csv, "--format", "CSV", "--map", "time=0,position=1,force=2",
                          "--specimen", ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml",
                          "--protocol-kind", "Tensile", "--out", tmp_path / "t.nc")
    assert code == 0, err
