"""``rdea-lab design``: a small study end to end; bad study files and an absent scheduler exit 2 with one line."""

import json
import time
from pathlib import Path

import pytest
import xarray as xr

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli as group

ROOT = Path(__file__).resolve().parents[2]
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"

GOOD = f"""name: small
model: su
params: {PARAMS}
specimen: {CARD}
variables:
  L1: [25 mm, 45 mm]
  L3: [40 um, 70 um]
  prestretch: [1.1, 1.4]
sampling: {{method: lhs, n: 24, seed: 2}}
voltage: 2.6 kV
bias: {{kind: spring, stiffness: 200 N/m, preload: 1 N}}
objectives: [{{maximize: stroke}}, {{minimize: volume}}]
constraints: {{field: {{max: 80 V/um}}}}
optimize: {{objective: stroke, starts: 1, max_iter: 3}}
chunk: 8
"""


def test_small_study_writes_its_outputs_and_a_card_the_run_command_reads(tmp_path, capsys):
    (tmp_path / "s.yaml").write_text(GOOD)
    out = tmp_path / "out"
    code = run_cli(group, ["design", str(tmp_path / "s.yaml"), "--out", str(out), "--synchronous", "--json",
                           "--quiet"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    summary = json.loads(captured.out)
    for name in ("study.nc", "pareto.csv", "card.yaml", "summary.json", "pareto.png", "parallel.png",
                 "stroke_map.png"):
        assert (out / name).is_file(), name
    ds = xr.open_dataset(out / "study.nc")
    assert ds.sizes["design"] == 24 and int(ds["feasible"].sum()) == summary["feasible"] > 0
    # the card is the optimum's membrane: the run command's loader reads it back
    import rdea_lab
    card = rdea_lab.load_specimen(out / "card.yaml")
    assert card.membrane.L1 == pytest.approx(summary["optimum"]["variables"]["L1"], rel=1e-5)
    assert card.membrane.L3 == pytest.approx(summary["optimum"]["variables"]["L3"], rel=1e-5)
    # a second run into the same folder is refused, not overwritten
    code = run_cli(group, ["design", str(tmp_path / "s.yaml"), "--out", str(out), "--synchronous", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "--force" in err and len(err.strip().splitlines()) == 1, err


BAD = {
    "unknown variable": ("  L1: [25 mm, 45 mm]", "  L9: [25 mm, 45 mm]", "variables.L9"),
    "empty range": ("  L1: [25 mm, 45 mm]", "  L1: [25 mm, 25 mm]", "variables.L1"),
    "inverted bounds": ("  L1: [25 mm, 45 mm]", "  L1: [45 mm, 25 mm]", "variables.L1"),
    # a thickness no card accepts (was a ZeroDivisionError: L3**2 underflows to 0 in the electrical factor)
    "a thickness below any real one": ("  L3: [40 um, 70 um]", "  L3: [1e-200 m, 70 um]", "variables.L3[0]"),
    "a range without units": ("  L1: [25 mm, 45 mm]", "  L1: [25, 45]", "variables.L1[0]"),
    "unknown metric": ("[{maximize: stroke}, {minimize: volume}]", "[{maximize: strokes}]", "objectives[0]"),
    "unknown key": ("chunk: 8", "chunks: 8", "chunks"),
    "unknown sampling": ("method: lhs", "method: halton", "sampling.method"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_study_files_exit_2_with_one_line_naming_file_and_field(tmp_path, capsys, case):
    old, new, field = BAD[case]
    assert old in GOOD
    path = tmp_path / "s.yaml"
    path.write_text(GOOD.replace(old, new))
    code = run_cli(group, ["design", str(path), "--out", str(tmp_path / "o"), "--synchronous"])
    err = capsys.readouterr().err
    assert code == 2, err
    line = err.strip()
    assert len(line.splitlines()) == 1 and "Traceback" not in err
    assert str(path) in line and field in line, line
    assert not (tmp_path / "o").exists()  # nothing written for a refused study


def test_constraints_no_design_meets_exit_2(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(GOOD.replace("field: {max: 80 V/um}", "field: {max: 1 V/um}"))
    code = run_cli(group, ["design", str(path), "--out", str(tmp_path / "o"), "--synchronous", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "constraints" in err and "field spans" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("how", ["option", pytest.param("environment", marks=pytest.mark.slow)])  # 3 s each
def test_a_scheduler_that_does_not_answer_exits_2_within_seconds(tmp_path, capsys, monkeypatch, how):
    (tmp_path / "s.yaml").write_text(GOOD)
    address = "tcp://127.0.0.1:9"  # the discard port: nothing listens on loopback here
    args = ["--scheduler", address] if how == "option" else []
    if how == "environment":
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", address)
    else:
        monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    t0 = time.monotonic()
    code = run_cli(group, ["design", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "o"), *args, "--quiet"])
    elapsed = time.monotonic() - t0
    err = capsys.readouterr().err
    assert code == 2, err
    assert address in err and "no answer" in err and len(err.strip().splitlines()) == 1
    assert elapsed < 8  # the connect waits 3 s
    assert not (tmp_path / "o").exists()


def test_a_malformed_scheduler_address_exits_2(tmp_path, capsys):
    (tmp_path / "s.yaml").write_text(GOOD)
    code = run_cli(group, ["design", str(tmp_path / "s.yaml"), "--scheduler", "localhost:8786", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "tcp://HOST:PORT" in err, err


def test_the_study_file_allows_exactly_the_models_physics_solves_over_designs():
    from rdea_lab.physics.designs import DESIGN_MODELS
    from rdea_lab.specs.study import DESIGN_MODELS as ALLOWED
    assert ALLOWED == DESIGN_MODELS
