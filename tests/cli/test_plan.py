"""``rdea-lab plan``: a voltage protocol from a target, run on the emulator; bad inputs exit 2 with one line."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CARD = str(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
PARAMS = str(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")

SHORT = """name: short
target: stretch
sample_rate: 200 Hz
bias: {kind: spring, stiffness: 200 N/m, preload: 1 N}
approach: 2 s
settle: 1 s
samples: {units: {time: s, stretch: "1"}, time: [0, 1, 2, 3], stretch: [1.054, 1.062, 1.062, 1.054]}
"""


def cli(*args, cwd=None):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "rdea_lab.cli.main", *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=300)


@pytest.mark.slow
def test_plan_run_on_the_emulator_within_the_stated_error(tmp_path):
    (tmp_path / "short.yaml").write_text(SHORT)
    r = cli("plan", "--target", str(tmp_path / "short.yaml"), "--specimen", CARD, "--params", PARAMS,
            "--out", str(tmp_path / "p.yaml"), "--run", "emulator", "--run-out", str(tmp_path / "r.nc"), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["twin_error"] < 1e-6 and (tmp_path / "p.yaml").exists() and (tmp_path / "r.nc").exists()
    t = out["tracking"]
    # Measured (seeds 0, 1, 2): force error rms 77 mN, max 108-112 mN, mean +71 mN; equivalent stretch error
    # max 0.0059 (73 % of the 0.008 stroke). The emulator's truth is not the SU twin with Table 3 by design
    # (truth/paper2021.yaml: continuum roll, a second, slow 1.5 s branch, radii off, Mullins, clamp
    # compliance, sensor offset and noise), and this short target starts 3 s after the approach, while the slow
    # branch still relaxes: the bound leaves a third of margin over the measured figures, no more.
    assert t["force_error_rms_N"] < 0.10 and t["force_error_max_N"] < 0.15
    assert t["stretch_error_max"] < 0.008


@pytest.mark.slow
def test_plan_then_run_then_check(tmp_path, capsys):
    """The README's path: plan, `rdea-lab run` the protocol file (twin backend here), check the run. The two
    plans run in process (the CLI's own `run`, as the console script calls it), the run as a real process."""
    from rdea_lab.cli.errors import run
    from rdea_lab.cli.main import cli as group

    (tmp_path / "short.yaml").write_text(SHORT)
    common = ["--target", str(tmp_path / "short.yaml"), "--specimen", CARD, "--params", PARAMS]
    assert run(group, ["plan", *common, "--out", str(tmp_path / "p.yaml")]) == 0, capsys.readouterr().err
    r = cli("run", str(tmp_path / "p.yaml"), "--specimen", CARD, "--backend", "twin", "--model", "su",
            "--params", PARAMS, "--out", str(tmp_path / "r.nc"), "--quiet")
    assert r.returncode == 0, r.stderr
    capsys.readouterr()
    rc = run(group, ["plan", *common, "--out", str(tmp_path / "p2.yaml"), "--check", str(tmp_path / "r.nc"), "--json"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert json.loads(out)["tracking"]["relative_max"] < 1e-6


@pytest.mark.parametrize("target, extra, match", [
    ("bad_bias.yaml", (), r"bad_bias\.yaml: bias\.stiffness: must be > 0 N/m, got -200 N/m"),
    ("bad_kind.yaml", (), r"bad_kind\.yaml: bias\.kind: 'rubber'; allowed: none, mass, spring"),
    ("bad_time.yaml", (), r"bad_time\.yaml: samples\.time\[2\]: 1 s does not come after 1 s"),
    ("reach.yaml", (), r"reach\.yaml: samples\.stretch: at t = 0 s: stretch 1\.04 is out of reach"),
    ("f.csv", (), r"f\.csv \(options for a CSV target\): stretch: missing"),
    ("f.csv", ("--stretch", "0.8"), r"--stretch: stretch 0\.8 is below 1"),
    ("f.csv", ("--stretch", "1.5", "--sample-rate", "0 Hz"), r"--sample-rate: must be > 0 Hz"),
    ("short.yaml", ("--stretch", "1.5"), r"short\.yaml: the target file gives its own settings"),
    ("missing.yaml", (), r"missing\.yaml: file not found"),
])
def test_bad_inputs_exit_2_with_one_line(tmp_path, capsys, target, extra, match):
    """In process (the CLI's own `run`, as the console script calls it): the same exit status and stderr."""
    from rdea_lab.cli.errors import run
    from rdea_lab.cli.main import cli as group

    (tmp_path / "short.yaml").write_text(SHORT)
    (tmp_path / "bad_bias.yaml").write_text(SHORT.replace("stiffness: 200 N/m", "stiffness: -200 N/m"))
    (tmp_path / "bad_kind.yaml").write_text(SHORT.replace("kind: spring, stiffness: 200 N/m, preload: 1 N",
                                                          "kind: rubber"))
    (tmp_path / "bad_time.yaml").write_text(SHORT.replace("time: [0, 1, 2, 3]", "time: [0, 1, 1, 3]"))
    (tmp_path / "reach.yaml").write_text(SHORT.replace("[1.054, 1.062, 1.062, 1.054]", "[1.04, 1.062, 1.062, 1.054]"))
    (tmp_path / "f.csv").write_text("time [s],force [N]\n0,4.1\n1,4.0\n")
    rc = run(group, ["plan", "--target", str(tmp_path / target), "--specimen", CARD, "--params", PARAMS,
                     "--out", str(tmp_path / "p.yaml"), *extra])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert re.search(match, lines[0]), lines[0]
    assert not (tmp_path / "p.yaml").exists()
