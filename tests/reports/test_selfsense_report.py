"""The self-sensing report (rdea_lab.reports.selfsense) and ``rdea-lab selfsense``.

Reference: a twin run, whose current is the ideal charge change of the
model's own capacitance: inverting that model must give back the encoder's
stretch wherever the roll is taut.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rdea_lab
from rdea_lab.reports.selfsense import selfsense_run
from rdea_lab.specs import SpecError

ROOT = Path(__file__).resolve().parents[2]
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"

PROTOCOL = """
name: sense
kind: custom
sample_rate: 2 kHz
measure: [force, current]
{probe}
stretch:
  - {{kind: hold, duration: 1 s, value: 1.0}}
  - {{kind: sine, duration: 4 s, mean: 1.2, amplitude: 0.2, frequency: 0.25 Hz, phase: -90 deg}}
voltage:
  - {{kind: hold, duration: 1 s, value: 0 V}}
  - {{kind: sine, duration: 4 s, mean: 1 kV, amplitude: 1 kV, frequency: 1 Hz, phase: -90 deg}}
"""


def twin_run(folder, probe="probe: {amplitude: 20 V, frequency: 200 Hz}", name="run.nc"):
    protocol = folder / "sense.yaml"
    protocol.write_text(PROTOCOL.format(probe=probe))
    out = folder / name
    rdea_lab.run_protocol(protocol, ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml",
                          rdea_lab.Twin(PARAMS, "su"), out=out)
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return twin_run(tmp_path_factory.mktemp("sense"))


def test_the_twins_own_capacitance_gives_back_its_stretch(run, tmp_path):
    result = selfsense_run(run, PARAMS, "su", tare="none", out=tmp_path / "s.nc")
    # noise-free, no leakage, the model inverted is the one that made the current: what is left is the
    # second order of the estimator's drift model (C'' tau^2) and the leakage fit's reading of it as a
    # conductance: 6.7e-3 % of the range measured; without the drift fit the lag alone made 0.44 %
    assert result.scored > 5000 and result.max_error_percent < 0.02 and result.rms_error_percent < 0.005
    ds = rdea_lab.open_run(tmp_path / "s.nc")
    for name in ("capacitance_estimate", "stretch_estimate", "stretch_error", "stretch_error_percent",
                 "estimate_valid", "current", "stretch"):
        assert ds[name].attrs["units"] and ds[name].attrs["long_name"]
    assert ds["current"].attrs["units"] == "A" and ds.attrs["max_error_percent"] == result.max_error_percent
    used = ds["estimate_valid"].values == 1
    np.testing.assert_allclose(ds["stretch_error"].values[used],
                               (ds["stretch_estimate"] - ds["stretch"]).values[used], rtol=0, atol=1e-15)


def test_the_tare_fits_one_factor_on_c0(run):
    # the twin's C0 is the model's: the factor over the first rest is 1 to the estimator's noise-free
    # error at 0 V with the probe (rounding and the probe's 1e-6 relative lag term)
    result = selfsense_run(run, PARAMS, "su", tare="rest")
    assert result.gain == pytest.approx(1.0, abs=1e-5)


def test_the_reference_tare_fits_gain_and_offset_on_a_0V_run(run, tmp_path):
    folder = tmp_path / "ref"
    folder.mkdir()
    protocol = folder / "sense0.yaml"
    protocol.write_text(PROTOCOL.format(probe="probe: {amplitude: 20 V, frequency: 200 Hz}").replace(
        "mean: 1 kV, amplitude: 1 kV", "mean: 0 kV, amplitude: 0 kV"))
    ref = folder / "ref.nc"
    rdea_lab.run_protocol(protocol, ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml",
                          rdea_lab.Twin(PARAMS, "su"), out=ref)
    result = selfsense_run(run, PARAMS, "su", reference=ref)
    # the twin's capacitance is the model's: the fitted map gain C0 lambda + offset is C0 lambda over the
    # sweep's stretches to the estimator's error at 0 V with the probe, 1e-5 of C (as the rest tare above);
    # gain and offset alone trade against each other (4e-5 and -1.1e-13 F measured), so 1e-4 each
    C0 = rdea_lab.geometry(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml").C0(2.8)
    lam = np.linspace(1.0, 1.4, 9)
    np.testing.assert_allclose(result.gain * C0 * lam + result.offset, C0 * lam, rtol=1e-5, atol=0)
    assert result.gain == pytest.approx(1.0, abs=1e-4) and abs(result.offset) < 1e-4 * C0
    assert "least squares over" in result.dataset.attrs["selfsense_tare"]
    with pytest.raises(SpecError, match=r"reference: the reference tare needs a reference run"):
        selfsense_run(run, PARAMS, "su", tare="reference")
    other = folder / "other.nc"
    rdea_lab.run_protocol(protocol, ROOT / "rdea_lab" / "data" / "specimens" / "specimen1.yaml",
                          rdea_lab.Twin(PARAMS, "su"), out=other)
    with pytest.raises(SpecError, match=r"other.nc: specimen: the reference run is of specimen-1, the run of "
                                        r"specimen-2"):
        selfsense_run(run, PARAMS, "su", reference=other)


def test_bad_input_is_refused_naming_the_file_and_field(run, tmp_path):
    with pytest.raises(SpecError, match=r"blocking_force.nc: current: the run has no current variable"):
        selfsense_run(ROOT / "datasets" / "paper2021" / "specimen-2" / "blocking_force.nc", PARAMS)
    no_probe = twin_run(tmp_path, probe="", name="noprobe.nc")
    with pytest.raises(SpecError, match=r"noprobe.nc: protocol.probe: the run's protocol has no probe"):
        selfsense_run(no_probe, PARAMS)
    with pytest.raises(SpecError, match=r"missing.nc: no such file"):
        selfsense_run(tmp_path / "missing.nc", PARAMS)
    with pytest.raises(SpecError, match=r"tare: 'zero' is not one of rest, reference, none"):
        selfsense_run(run, PARAMS, tare="zero")


def cli(*args, cwd):
    """``rdea-lab *args`` as a real process in ``cwd``."""
    return subprocess.run([sys.executable, "-m", "rdea_lab.cli.main", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


def cli_here(capsys, monkeypatch, *args, cwd):
    """``rdea-lab *args`` in this process, through the `run` the entry point exits with: what `cli` returns."""
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli as group

    monkeypatch.chdir(cwd)
    capsys.readouterr()
    code = run_cli(group, [str(a) for a in args])
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out, err)


@pytest.mark.slow
def test_cli_prints_one_line_and_writes_the_dataset(run, tmp_path, capsys, monkeypatch):
    out = cli("selfsense", run, "--params", PARAMS, "--tare", "none", "--out", tmp_path / "o.nc", cwd=tmp_path)
    assert out.returncode == 0 and out.stdout.count("\n") == 1 and "% (max)" in out.stdout
    assert (tmp_path / "o.nc").is_file()
    again = cli_here(capsys, monkeypatch, "selfsense", run, "--params", PARAMS, "--out", tmp_path / "o.nc",
                     cwd=tmp_path)
    assert again.returncode == 2 and again.stderr == f"rdea-lab: {tmp_path / 'o.nc'}: out: exists; give --force " \
                                                     "(overwrite=True) to replace it, or another output\n"


@pytest.mark.parametrize("args, message", [
    (("datasets/paper2021/specimen-2/blocking_force.nc", "--params", "params/paper2021_table3.yaml"),
     "rdea-lab: datasets/paper2021/specimen-2/blocking_force.nc: current: the run has no current variable"),
    (("RUN", "--params", "rdea_lab/data/protocols/blocking_force.yaml"),
     "rdea-lab: rdea_lab/data/protocols/blocking_force.yaml: "),
    (("nowhere.nc", "--params", "params/paper2021_table3.yaml"), "rdea-lab: nowhere.nc: no such file"),
])
def test_cli_bad_input_exit_2_one_line(run, tmp_path, capsys, monkeypatch, args, message):
    args = [str(run) if a == "RUN" else a for a in args]
    out = cli_here(capsys, monkeypatch, "selfsense", *args, "--out", tmp_path / "x.nc", cwd=ROOT)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and out.stderr.startswith(message), out.stderr


def test_plot_draws_both_stretches_and_the_error(run, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rdea_lab.reports.selfsense import plot_selfsense

    result = selfsense_run(run, PARAMS, "su", tare="none")
    fig = plot_selfsense(result.dataset, tmp_path / "s.png")
    assert (tmp_path / "s.png").stat().st_size > 10_000 and len(fig.axes) == 2
    top = fig.axes[0]
    assert [line.get_label() for line in top.get_lines()] == ["encoder", "self-sensed"]
    _, ax = plt.subplots()
    assert plot_selfsense(result.dataset, ax=ax) is ax.figure and len(ax.figure.axes) == 1
    plt.close("all")
