"""`rdea-lab run` on the twin, and the commands around datasets (issue 3)."""

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.physics.models import solve
from rdea_lab.specs import load_params, load_specimen
from rdea_lab.store import REQUIRED_ATTRS, VARIABLES

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ["tensile_ramp_sine_0V", "tensile_ramp_sine_2.6kV", "blocking_force", "capacitance_sweep"]
SPECIMENS = ["specimen1", "specimen2", "specimen3"]


def rdea(capsys, *args):
    rc = run_cli(cli, [str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """Every preset on every paper specimen, on the twin (model auto)."""
    out = tmp_path_factory.mktemp("campaign")
    paths = {}
    for spec in SPECIMENS:
        for proto in PROTOCOLS:
            path = out / spec / f"{proto}.nc"
            rc = run_cli(cli, ["run", str(ROOT / "rdea_lab" / "data" / "protocols" / f"{proto}.yaml"), "--specimen",
                               str(ROOT / "rdea_lab" / "data" / "specimens" / f"{spec}.yaml"), "--backend", "twin",
                               "--quiet", "--out", str(path)])
            assert rc == 0, (spec, proto)
            paths[spec, proto] = path
    return paths


@pytest.mark.parametrize("spec", SPECIMENS)
@pytest.mark.parametrize("proto", PROTOCOLS)
def test_each_preset_on_each_specimen_is_a_complete_self_describing_file(campaign, spec, proto):
    with xr.open_dataset(campaign[spec, proto]) as ds:
        for key in REQUIRED_ATTRS:
            assert key in ds.attrs and ds.attrs[key] is not None, key
        for key in ("model", "parameters", "model_selection", "run_id"):
            assert ds.attrs[key]
        assert ds.attrs["status"] == "complete" and ds.attrs["protocol_name"] == proto
        assert ds.attrs["specimen_id"] == load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / f"{spec}.yaml").id
        for name in VARIABLES:
            assert ds[name].attrs["units"] and ds[name].attrs["long_name"]
        assert ds.encoding["unlimited_dims"] == {"time"}
        measured_c = np.isfinite(ds["capacitance"].values).any()
        assert measured_c == (proto == "capacitance_sweep")


@pytest.mark.parametrize("spec", SPECIMENS)
def test_force_at_the_top_of_the_0V_tensile_run_is_the_quasi_static_su_force(campaign, spec):
    """Force at the largest stretch vs the SU quasi-static force there. The difference is
    the viscoelastic overstress, bounded by sum_j eta_j |dlambda/dt| (Maxwell branches
    that start relaxed never exceed eta_j times the largest rate) times area / stretch;
    at the top of the sine the rate is ~0 so it is much smaller still."""
    card = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / f"{spec}.yaml")
    params = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
    with xr.open_dataset(campaign[spec, "tensile_ramp_sine_0V"], decode_times=False) as ds:  # t in seconds
        lam, t, force = ds["stretch"].values, ds["time"].values, ds["force"].values
    i = int(np.argmax(lam))
    assert lam[i] == pytest.approx(1.5, abs=1e-3)
    geom = geometry_from_card(card)
    qs = float(solve("su", geom, params, lam[i], 0.0).force)
    rate = np.max(np.abs(np.diff(lam) / np.diff(t)))
    bound = sum(b.eta for b in params.branches) * rate * geom.area / lam[i]
    assert abs(force[i] - qs) <= bound
    assert abs(force[i] - qs) < 0.01 * qs  # and in fact within 1 %


def test_dry_run_prints_the_plan_and_writes_nothing(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, out, err = rdea(capsys, "run", ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml", "--specimen",
                        ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml", "--dry-run")
    assert rc == 0, err
    assert "25001 samples" in out and "limits: ok" in out and "twin: model" in out
    assert not (tmp_path / "datasets").exists()


def test_default_output_path_and_no_overwrite(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = ["run", ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml",
            "--specimen", ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml",
            "--params", ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml", "--model", "su", "--quiet"]
    rc, out, err = rdea(capsys, *args)
    assert rc == 0, err
    files = list((tmp_path / "datasets" / "specimen-2").glob("tensile_ramp_sine_0V-*Z.nc"))
    assert len(files) == 1
    rc, out, err = rdea(capsys, *args, "--out", files[0])
    assert rc == 2 and "exists; give --force" in err and len(err.strip().splitlines()) == 1
    rc, out, err = rdea(capsys, *args, "--out", files[0], "--force")
    assert rc == 0, err


def test_ls_show_and_protocol_show(capsys, campaign, tmp_path):
    folder = campaign["specimen1", "blocking_force"].parent
    rc, out, err = rdea(capsys, "ls", folder)
    assert rc == 0 and "blocking_force" in out and "complete" in out and "25001" in out
    rc, out, err = rdea(capsys, "show", campaign["specimen1", "capacitance_sweep"], "--plot", tmp_path / "c.png")
    assert rc == 0 and "capacitance" in out and (tmp_path / "c.png").stat().st_size > 10_000
    rc, out, err = rdea(capsys, "protocol", "show",
                        ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_2.6kV.yaml",
                        "--plot", tmp_path / "p.png")
    assert rc == 0 and "ramp_sine" in out and (tmp_path / "p.png").stat().st_size > 10_000


@pytest.mark.slow
def test_auto_records_its_choice_and_explicit_models_run(capsys, tmp_path):
    for model in ("su", "1r", "3r", "auto"):
        rc, out, err = rdea(capsys, "run", ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_2.6kV.yaml",
                            "--specimen", ROOT / "rdea_lab" / "data" / "specimens" / "specimen3.yaml", "--model", model,
                            "--quiet", "--out", tmp_path / f"{model}.nc")
        assert rc == 0, err
    with xr.open_dataset(tmp_path / "auto.nc") as ds:
        sel = json.loads(ds.attrs["model_selection"])
        assert sel["model"] == ds.attrs["model"] and sel["tolerance"] == 0.01
    with xr.open_dataset(tmp_path / "3r.nc") as a, xr.open_dataset(tmp_path / "su.nc") as b:
        # specimen 3 (Ri = 0) at 2.6 kV stays on the SU state: the two models agree
        np.testing.assert_allclose(a["force"].values, b["force"].values, rtol=0, atol=1e-9)


@pytest.mark.parametrize("args, words", [
    (["--tolerance", "0"], ["--tolerance", "0.0<x<1.0"]),
    (["--model", "4r"], ["--model", "4r"]),
    (["--params", "nope.yaml"], ["nope.yaml"]),
])
def test_bad_run_options_exit_2_with_one_line(capsys, args, words):
    rc, out, err = rdea(capsys, "run", ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml",
                        "--specimen", ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml", "--dry-run", *args)
    assert rc == 2 and len(err.strip().splitlines()) == 1
    for w in words:
        assert w in err
