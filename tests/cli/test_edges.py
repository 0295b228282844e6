"""Edges found by a tester (issue 11): each through the real CLI, exit 2 with one line where it is the user's."""

from pathlib import Path

import numpy as np
import pytest

import rdea_lab
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import protocol_from_yaml

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "specimens" / "specimen2.yaml"


def rdea(capsys, *args):
    code = run_cli(cli, [str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_campaign_listing_one_card_twice_is_refused_naming_both_runs(tmp_path, capsys):
    (tmp_path / "c.yaml").write_text(
        f"name: c\nbackend: twin\nseed: 1\nout: {tmp_path / 'out'}\nparams: {ROOT / 'params' / 'paper2021_table3.yaml'}\n"
        f"specimens: [{CARD}, {CARD}]\nprotocols: [{ROOT / 'protocols' / 'blocking_force.yaml'}]\n")
    code, out, err = rdea(capsys, "campaign", "run", tmp_path / "c.yaml")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "specimens[0] (specimen2.yaml, id specimen-2)" in err and "specimens[1] (specimen2.yaml" in err
    assert not (tmp_path / "out").exists()  # refused before anything ran


@pytest.mark.parametrize("args", [["--backend", "Twin"], ["--model", "SU"], ["--backend", "TWIN", "--model", "Auto"]])
def test_choices_are_accepted_in_any_case(capsys, args):
    code, out, err = rdea(capsys, "run", ROOT / "protocols" / "blocking_force.yaml", "--specimen", CARD,
                          "--dry-run", *args)
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
    ds = rdea_lab.run_protocol(proto, CARD, "twin", model="su", out=tmp_path / "x.nc")
    reason = ds.attrs["status_reason"]
    assert ds.attrs["status"] == "aborted"
    shown = float(reason.split("force ")[1].split(" N")[0])
    assert shown > 1.0 and abs(shown - ds["force"].values[np.argmax(np.abs(ds["force"].values) > 1.0)]) < 1e-3


def test_an_unreachable_rig_address_is_exit_2(capsys, tmp_path):
    code, out, err = rdea(capsys, "run", ROOT / "protocols" / "blocking_force.yaml", "--specimen", CARD,
                          "--backend", "rig", "--rig", "tcp://127.0.0.1:1", "--out", tmp_path / "x.nc")
    assert code == 2 and "no answer" in err and len(err.strip().splitlines()) == 1
