"""Every package says what is in it and how to start; functions that take a card or parameters say
what they want when given something else."""

import importlib

import numpy as np
import pytest

PACKAGES = ["rdea_lab", "rdea_lab.specs", "rdea_lab.physics", "rdea_lab.twin", "rdea_lab.protocols",
            "rdea_lab.emulator", "rdea_lab.backends", "rdea_lab.store", "rdea_lab.runs", "rdea_lab.calibration",
            "rdea_lab.reports", "rdea_lab.api", "rdea_lab.cli"]


@pytest.mark.parametrize("name", PACKAGES)
def test_each_package_has_a_docstring_and_the_root_the_one_quick_start(name):
    doc = importlib.import_module(name).__doc__ or ""
    assert len(doc.split()) > 20, f"{name}: no real module docstring"
    if name == "rdea_lab":  # the quick start: load card, load params, run, predict
        assert all(w in doc for w in ("load_specimen", "load_params", "run_protocol", "predict", ">>>")), name
    else:  # one quick start, not one per package
        assert ">>>" not in doc and "Quick start::" not in doc, name


def test_the_quick_start_runs(tmp_path, monkeypatch):
    """The package's quick start, as a doctest, in an empty folder (it writes demo.nc there)."""
    import doctest

    import matplotlib

    import rdea_lab

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    failures, tried = doctest.testmod(rdea_lab, verbose=False, report=True)
    assert tried >= 6 and failures == 0
    assert (tmp_path / "demo.nc").is_file()
    import matplotlib.pyplot as plt

    plt.close("all")


def test_physics_takes_objects_and_says_so_when_given_a_path():
    from rdea_lab.physics.geometry import geometry_from_card
    from rdea_lab.physics.models import solve
    import rdea_lab

    with pytest.raises(TypeError, match=r"rdea_lab.geometry\(path\)"):
        geometry_from_card("specimens/specimen2.yaml")
    geom = rdea_lab.geometry("specimens/specimen2.yaml")
    with pytest.raises(TypeError, match=r"rdea_lab.load_params\(path\)"):
        solve("su", geom, "params/paper2021_table3.yaml", np.array([1.1]), 0.0)


def test_twin_functions_accept_paths():
    import rdea_lab
    from rdea_lab.backends import TwinBackend

    card, params = "specimens/specimen2.yaml", "params/paper2021_table3.yaml"
    from rdea_lab.twin import quasi_static_curves

    a = quasi_static_curves(card, params, "su", [1.0, 1.2], [0.0, 2600.0])
    b = quasi_static_curves(rdea_lab.load_specimen(card), rdea_lab.load_params(params), "su",
                                     [1.0, 1.2], [0.0, 2600.0])
    for ca, cb in zip(a.curves, b.curves):
        np.testing.assert_array_equal(ca.force, cb.force)
    assert TwinBackend(card, params).card == rdea_lab.load_specimen(card)


@pytest.mark.parametrize("order", ["rdea_lab first", "xarray first"])
def test_ds_rdea_comes_with_what_returns_a_dataset_and_import_rdea_lab_stays_light(order):
    """``import rdea_lab`` imports no xarray (the CLI's start-up) and installs no import hook; a function
    that returns a dataset brings ``ds.rdea`` with it, whichever of the two was imported first."""
    import subprocess
    import sys

    first, second = ("rdea_lab", "xarray") if order == "rdea_lab first" else ("xarray", "rdea_lab")
    code = (f"import sys; import {first}; light = 'xarray' not in sys.modules; "
            f"import {second}; import rdea_lab; "
            "import xarray as xr; before = hasattr(xr.Dataset(), 'rdea'); rdea_lab.open_run; "
            "ds = xr.Dataset(attrs={'metadata': '{\"operator\": \"ana\"}'}); "
            "print(light, before, ds.rdea.metadata['operator'])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == [str(order == "rdea_lab first"), "False", "ana"]


def test_no_import_hook():
    import sys

    import rdea_lab  # noqa: F401

    assert not [f for f in sys.meta_path if type(f).__module__.startswith("rdea_lab")]
