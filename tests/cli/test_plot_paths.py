"""``--plot`` of show, protocol show and selfsense: a format matplotlib cannot write, or a place that cannot be
written, is exit 2 and one line before the work (not an internal error after it; issue 25)."""

from pathlib import Path

import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "rdea_lab" / "data"
PARAMS = str(DATA / "params" / "paper2021_table3.yaml")
RUN = str(ROOT / "datasets" / "paper2021" / "specimen-2" / "blocking_force.nc")
PROTOCOL = str(DATA / "protocols" / "blocking_force.yaml")
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


@pytest.fixture(scope="module")
def sense_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sense")
    (folder / "sense.yaml").write_text(SENSE)
    assert run_cli(cli, ["run", str(folder / "sense.yaml"), "--specimen", str(DATA / "specimens" / "specimen2.yaml"),
                         "--backend", "twin", "--model", "su", "--quiet", "--out", str(folder / "sense.nc")]) == 0
    return folder / "sense.nc"


def _command(name, sense_run, tmp_path):
    return {"show": ["show", RUN],
            "protocol show": ["protocol", "show", PROTOCOL],
            "selfsense": ["selfsense", str(sense_run), "--params", PARAMS, "--tare", "none",
                          "--out", str(tmp_path / "s.nc")]}[name]


COMMANDS = ["show", "protocol show", "selfsense"]


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("plot, words", [
    ("run.xyz", "the suffix '.xyz' is not a figure format matplotlib writes; allowed: "),
    ("run", "no suffix is not a figure format matplotlib writes; allowed: "),
    ("a-file/run.png", "is not a folder"),
], ids=["bad suffix", "no suffix", "under a file"])
def test_a_plot_matplotlib_cannot_write_is_exit_2_before_the_work(name, plot, words, sense_run, tmp_path, capsys):
    (tmp_path / "a-file").write_text("a file, not a folder\n")
    target = tmp_path / plot
    capsys.readouterr()
    assert run_cli(cli, [*_command(name, sense_run, tmp_path), "--plot", str(target)]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and captured.err.startswith(f"rdea-lab: {target}: --plot: "), captured.err
    assert words in captured.err and (".png" in captured.err or "folder" in captured.err)
    assert captured.out == ""  # before the work: not even the summary
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file"]  # selfsense's --out not written either


@pytest.mark.parametrize("name", COMMANDS)
def test_a_plot_in_a_folder_that_cannot_be_written_is_exit_2(name, sense_run, tmp_path, capsys):
    target = Path("/proc/rdea-lab-plot.png")  # a pseudo file system: no file can be made there, not even by root
    assert run_cli(cli, [*_command(name, sense_run, tmp_path), "--plot", str(target)]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "cannot write in the folder /proc" in captured.err, captured.err
    assert captured.out == "" and not (tmp_path / "s.nc").exists()


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_a_plot_in_a_format_matplotlib_writes_is_written(name, suffix, sense_run, tmp_path, capsys):
    target = tmp_path / f"figure{suffix}"
    assert run_cli(cli, [*_command(name, sense_run, tmp_path), "--plot", str(target)]) == 0, capsys.readouterr().err
    head = target.read_bytes()[:200]
    assert head.startswith(b"\x89PNG") if suffix == ".png" else b"<svg" in head


def test_a_live_figure_in_a_folder_that_cannot_be_written_is_exit_2_before_the_run(tmp_path, capsys):
    assert run_cli(cli, ["run", PROTOCOL, "--specimen", str(DATA / "specimens" / "specimen2.yaml"), "--backend",
                         "twin", "--live", "/proc/rdea-lab-live.png", "--out", str(tmp_path / "x.nc")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rdea-lab: /proc/rdea-lab-live.png: --live: cannot write"), err
    assert not list(tmp_path.iterdir())
