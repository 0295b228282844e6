"""Every package says what is in it and how to start; functions that take a card or parameters say
what they want when given something else."""

import importlib

import numpy as np
import pytest

PACKAGES = ["rdea_lab", "rdea_lab.specs", "rdea_lab.physics", "rdea_lab.twin", "rdea_lab.protocols",
            "rdea_lab.emulator", "rdea_lab.backends", "rdea_lab.store", "rdea_lab.runs", "rdea_lab.calibration",
            "rdea_lab.reports", "rdea_lab.api", "rdea_lab.cli"]


@pytest.mark.parametrize("name", PACKAGES)
def test_each_package_has_a_docstring_with_a_quick_start(name):
    doc = importlib.import_module(name).__doc__ or ""
    assert len(doc.split()) > 20, f"{name}: no real module docstring"
    if name != "rdea_lab.cli":
        # the three-line start: load card, load params, predict or run_protocol
        assert any(w in doc for w in ("load_specimen", "load_params", "run_protocol", "calibrate_runs")), name
        assert "predict" in doc or "run_protocol" in doc or "calibrate_runs" in doc, name


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
    a = rdea_lab.quasi_static_curves(card, params, "su", [1.0, 1.2], [0.0, 2600.0])
    b = rdea_lab.quasi_static_curves(rdea_lab.load_specimen(card), rdea_lab.load_params(params), "su",
                                     [1.0, 1.2], [0.0, 2600.0])
    for ca, cb in zip(a["curves"], b["curves"]):
        np.testing.assert_array_equal(ca["force"], cb["force"])
    assert TwinBackend(card, params).card == rdea_lab.load_specimen(card)


@pytest.mark.parametrize("order", ["rdea_lab first", "xarray first"])
def test_ds_rdea_is_there_whichever_is_imported_first_and_import_rdea_lab_stays_light(order):
    """``import rdea_lab`` does not import xarray (the CLI's start-up); ``ds.rdea`` works either way."""
    import subprocess
    import sys

    first, second = ("rdea_lab", "xarray") if order == "rdea_lab first" else ("xarray", "rdea_lab")
    code = (f"import sys; import {first}; light = 'xarray' not in sys.modules; import {second}; "
            "import xarray as xr; ds = xr.Dataset(attrs={'metadata': '{\"operator\": \"ana\"}'}); "
            "print(light, ds.rdea.metadata['operator'])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == [str(order == "rdea_lab first"), "ana"]


def test_a_find_spec_probe_of_xarray_does_not_lose_ds_rdea():
    import subprocess
    import sys

    code = ("import importlib.util, rdea_lab; assert importlib.util.find_spec('xarray') is not None; "
            "import xarray as xr; print(xr.Dataset(attrs={'metadata': '{\"a\": \"b\"}'}).rdea.metadata['a'])")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.strip() == "b"
