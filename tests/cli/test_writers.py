"""Every command that writes a file refuses an existing output before any work (exit 2, one line naming the
file and --force, the file's bytes unchanged), and writes over it with --force (issue 25)."""

from pathlib import Path

import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "rdea_lab" / "data"
CARD = str(DATA / "specimens" / "specimen2.yaml")
PARAMS = str(DATA / "params" / "paper2021_table3.yaml")
TENSILE = str(DATA / "protocols" / "tensile_ramp_sine_0V.yaml")
CSV = str(ROOT / "tests" / "store" / "import_data" / "good_trailing_empty_columns.csv")
#: What an earlier output holds: any bytes no command writes.
EARLIER = b"an earlier output, not to be lost\n"

SENSE = """name: sense
kind: custom
sample_rate: 2 kHz
measure: [force, current]
probe: {amplitude: 20 V, frequency: 200 Hz}
stretch:
  - {kind: hold, duration: 0.5 s, value: 1.0}
  - {kind: sine, duration: 2 s, mean: 1.2, amplitude: 0.2, frequency: 0.5 Hz, phase: -90 deg}
voltage:
  - {kind: hold, duration: 0.5 s, value: 0 V}
  - {kind: sine, duration: 2 s, mean: 1 kV, amplitude: 1 kV, frequency: 1 Hz, phase: -90 deg}
"""
TARGET = """name: short
target: stretch
sample_rate: 200 Hz
bias: {kind: spring, stiffness: 200 N/m, preload: 1 N}
approach: 2 s
settle: 1 s
samples: {units: {time: s, stretch: "1"}, time: [0, 1, 2, 3], stretch: [1.054, 1.062, 1.062, 1.054]}
"""
STUDY = f"""name: small
model: su
params: {PARAMS}
specimen: {CARD}
variables: {{L1: [25 mm, 45 mm], L3: [40 um, 70 um], prestretch: [1.1, 1.4]}}
sampling: {{method: lhs, n: 8, seed: 2}}
voltage: 2.6 kV
bias: {{kind: spring, stiffness: 200 N/m, preload: 1 N}}
objectives: [{{maximize: stroke}}, {{minimize: volume}}]
optimize: {{objective: stroke, starts: 1, max_iter: 2}}
"""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """The inputs of the writers: a tensile run and a self-sensing run (twin), a target, a study, a campaign."""
    folder = tmp_path_factory.mktemp("inputs")
    (folder / "runs").mkdir()
    (folder / "sense.yaml").write_text(SENSE)
    for protocol, name in ((TENSILE, "tensile.nc"), (str(folder / "sense.yaml"), "sense.nc")):
        assert run_cli(cli, ["run", protocol, "--specimen", CARD, "--backend", "twin", "--model", "su", "--quiet",
                             "--out", str(folder / "runs" / name)]) == 0
    (folder / "target.yaml").write_text(TARGET)
    (folder / "study.yaml").write_text(STUDY)
    (folder / "campaign.yaml").write_text(f"name: tiny\nroot: {DATA}\nbackend: twin\nparams: {PARAMS}\nout: c\n"
                                          "specimens: [specimens/specimen2.yaml]\n"
                                          "protocols: [protocols/capacitance_sweep.yaml]\n")
    return folder


#: name -> (the command's arguments before --force, the existing output (a file, or a file in an output folder),
#: the path the refusal names).
#: ``{i}`` is the inputs' folder, ``{o}`` the test's own.
WRITERS = {
    "run": (["run", TENSILE, "--specimen", CARD, "--backend", "twin", "--model", "su", "--quiet",
             "--out", "{o}/x.nc"], "x.nc", "x.nc"),
    "plan": (["plan", "--target", "{i}/target.yaml", "--specimen", CARD, "--params", PARAMS, "--out", "{o}/p.yaml"],
             "p.yaml", "p.yaml"),
    "plan --run-out": (["plan", "--target", "{i}/target.yaml", "--specimen", CARD, "--params", PARAMS,
                        "--out", "{o}/p.yaml", "--run", "twin", "--run-out", "{o}/r.nc"], "r.nc", "r.nc"),
    "selfsense": (["selfsense", "{i}/runs/sense.nc", "--params", PARAMS, "--tare", "none", "--out", "{o}/s.nc"],
                  "s.nc", "s.nc"),
    "import": (["import", CSV, "--format", "csv", "--map", "time=0,position=1,force=2", "--specimen", CARD,
                "--protocol-kind", "tensile", "--out", "{o}/imp.nc"], "imp.nc", "imp.nc"),
    "campaign run": (["campaign", "run", "{i}/campaign.yaml", "--out", "{o}/c", "--quiet"],
                     "c/specimen-2/capacitance_sweep.nc", "c/specimen-2/capacitance_sweep.nc"),
    "design": (["design", "{i}/study.yaml", "--out", "{o}/d", "--synchronous", "--no-figures", "--quiet"],
               "d/summary.json", "d"),
    "calibrate": (["calibrate", "{i}/runs/tensile.nc", "--init", PARAMS, "--free", "C10", "--max-evals", "10",
                   "--quiet", "--out", "{o}/cal.yaml"], "cal.yaml", "cal.yaml"),
    "calibrate history": (["calibrate", "{i}/runs/tensile.nc", "--init", PARAMS, "--free", "C10", "--max-evals",
                           "10", "--quiet", "--out", "{o}/cal.yaml"], "cal.history.csv", "cal.history.csv"),
    "report validation": (["report", "validation", "--params", PARAMS, "--datasets", "{i}/runs", "--out", "{o}/v",
                           "--no-figures"], "v/table4.md", "v"),
    "report speed": (["report", "speed", "--out", "{o}/sp", "--repeats", "1"], "sp/earlier.txt", "sp"),
    "reproduce": (["reproduce", "--out", "{o}/rep", "--quiet", "--no-speed", "--workers", "1"], "rep/index.html",
                  "rep"),
    "reproduce --datasets": (["reproduce", "--out", "{o}/rep", "--datasets", "{o}/ds", "--quiet", "--no-speed",
                              "--workers", "1"], "ds/specimen-2/blocking_force.nc", "ds"),
}
#: The writers whose work takes minutes: with --force they are stopped where the work begins (the check passed).
SLOW = {"report speed": "rdea_lab.reports.speed.scenes", "reproduce": "rdea_lab.reports.reproduce.load_campaign",
        "reproduce --datasets": "rdea_lab.reports.reproduce.load_campaign"}


class WorkBegan(Exception):
    """Raised where a slow writer's work begins."""


def _args(name, inputs, out):
    args, existing, named = WRITERS[name]
    return [a.format(i=inputs, o=out) for a in args], out / existing, out / named


@pytest.mark.parametrize("name", WRITERS)
def test_an_existing_output_is_refused_before_any_work_and_kept(name, inputs, tmp_path, capsys):
    args, existing, named = _args(name, inputs, tmp_path)
    existing.parent.mkdir(parents=True, exist_ok=True)
    existing.write_bytes(EARLIER)
    before = sorted(p for p in tmp_path.rglob("*"))
    capsys.readouterr()
    assert run_cli(cli, args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--force" in err, err
    assert err.startswith(f"rdea-lab: {named}: "), err
    assert existing.read_bytes() == EARLIER
    assert sorted(p for p in tmp_path.rglob("*")) == before  # nothing else written either


@pytest.mark.parametrize("name", WRITERS)
def test_force_writes_over_it(name, inputs, tmp_path, capsys, monkeypatch):
    args, existing, _ = _args(name, inputs, tmp_path)
    existing.parent.mkdir(parents=True, exist_ok=True)
    existing.write_bytes(EARLIER)
    if name in SLOW:
        def began(*a, **k):
            raise WorkBegan("the work began")

        monkeypatch.setattr(SLOW[name], began)
        assert run_cli(cli, [*args, "--force"]) == 1
        assert "WorkBegan: the work began" in capsys.readouterr().err
        return
    assert run_cli(cli, [*args, "--force"]) == 0, capsys.readouterr().err
    assert existing.read_bytes() != EARLIER


def test_calibrate_does_not_replace_a_shipped_parameter_file(inputs, tmp_path, capsys):
    """The issue's case: calibrate --out onto a parameter file replaced it (the packaged Table 3 here, copied)."""
    table3 = tmp_path / "paper2021_table3.yaml"
    table3.write_bytes(Path(PARAMS).read_bytes())
    assert run_cli(cli, ["calibrate", str(inputs / "runs" / "tensile.nc"), "--init", PARAMS, "--free", "C10",
                         "--max-evals", "10", "--quiet", "--out", str(table3)]) == 2
    assert capsys.readouterr().err == (f"rdea-lab: {table3}: out: exists; give --force (overwrite=True) to replace "
                                       "it, or another output\n")
    assert table3.read_bytes() == Path(PARAMS).read_bytes()
