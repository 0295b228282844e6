"""CF 1.8 compliance of every kind of dataset rdea-lab writes, judged by two external checkers (issue 14).

The IOOS compliance-checker (``--test=cf:1.8``) and the CF community's
cfchecker (``cfchecks``) read the files as any CF tool would; the test asks
them, not our own idea of CF. cfchecker wants the CF standard name, area type
and region tables from cfconventions.org; offline, it gets the standard name
table bundled with compliance-checker and two empty tables (our files use no
area type and no region name). Both are in the test extra; cfchecker's half
skips (saying why) only where the UDUNITS-2 C library it needs is missing.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from vhb_data import LOADING_UNLOADING, MISSING, VHB

import rdea_lab
from rdea_lab.physics.result import STATUS_NAMES
from rdea_lab.store import JournalWriter, open_run, recover
from rdea_lab.store.importers import ImportOptions, import_files
from rdea_lab.twin import simulate

ROOT = Path(__file__).resolve().parents[2]
TABLES = Path(__file__).resolve().parent / "cf_tables"
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
SHIPPED = sorted([*ROOT.glob("datasets/**/*.nc"), *ROOT.glob("reports/**/*.nc")])
KINDS = ("twin", "emulator", "aborted", "recovered", "imported", "simulate")

#: 2 s at 100 Hz, capacitance measured (the LCR bridge reads at 0 V): a run of every backend in a second.
SHORT = """name: cf_short
kind: custom
description: a short ramp for the CF checks
sample_rate: 100 Hz
measure: [force, capacitance]
limits: {{max_voltage: 3 kV, max_stretch: 1.6, max_force: {max_force}, max_field: 80 V/um}}
stretch:
  - {{kind: ramp, duration: 2 s, to: 1.2}}
voltage:
  - {{kind: hold, duration: 2 s, value: 0 V}}
"""


# ------------------------------------------------------------------ the checkers
def ioos(path: Path) -> dict[str, list[str]]:
    """Failed checks of the IOOS compliance-checker, cf:1.8, by priority (``high``, ``medium``, ``low``),
    and ``exceptions``: checks that crashed (each one a check not made). The checker is part of the
    test extra: missing, the test fails."""
    from compliance_checker.runner import CheckSuite

    suite = CheckSuite()
    suite.load_all_available_checkers()
    ds = suite.load_dataset(str(path))
    try:
        groups, crashed = suite.run_all(ds, ["cf:1.8"], skip_checks=[])["cf:1.8"]
    finally:
        ds.close()
    out = {"high": [], "medium": [], "low": [], "exceptions": [f"{k}: {v[0]!r}" for k, v in crashed.items()]}
    level = {3: "high", 2: "medium", 1: "low"}
    for r in groups:
        if r.value[0] < r.value[1]:
            out[level[r.weight]].append(f"{r.name}: {'; '.join(r.msgs)}")
    return out


def cfchecks(path: Path) -> dict[str, list[str]]:
    """Messages of cfchecker (``cfchecks``) for CF 1.8, by category (``FATAL``, ``ERROR``, ``WARN``, ``INFO``)."""
    import compliance_checker as cc  # its standard-name table (cfchecker would download one)

    try:  # cfchecker is in the test extra (missing: ImportError, the test fails)
        from cfchecker.cfchecks import CFChecker
    except FileNotFoundError as exc:  # cfunits without the UDUNITS-2 C library, not on PyPI (apt: libudunits2-0)
        pytest.skip(f"cfchecker cannot run: {exc}")
    names = Path(cc.__file__).parent / "data" / "cf-standard-name-table.xml"
    checker = CFChecker(cfStandardNamesXML=str(names), cfAreaTypesXML=str(TABLES / "area-type-table.xml"),
                        cfRegionNamesXML=str(TABLES / "standardized-region-list.xml"), version="1.8", silent=True)
    results = checker.checker(str(path))
    out = {cat: list(results["global"].get(cat, [])) for cat in ("FATAL", "ERROR", "WARN", "INFO")}
    for var, res in results["variables"].items():
        for cat in out:
            out[cat] += [f"{var}: {m}" for m in res.get(cat, [])]
    return out


# ------------------------------------------------------------------ datasets of every kind
def _protocol(folder: Path, max_force: str) -> Path:
    path = folder / f"short-{max_force.replace(' ', '')}.yaml"
    path.write_text(SHORT.format(max_force=max_force))
    return path


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """One dataset of each kind, written as a user would: kind -> path (None where it cannot be made here)."""
    folder = tmp_path_factory.mktemp("cf")
    short = _protocol(folder, "50 N")
    out = {}
    rdea_lab.run_protocol(short, CARD, rdea_lab.Twin(model="su"), out=folder / "twin.nc",
                          metadata={"institution": "Example Lab, Example University"})
    out["twin"] = folder / "twin.nc"
    rdea_lab.run_protocol(short, CARD, "emulator", out=folder / "emulator.nc", seed=3)
    out["emulator"] = folder / "emulator.nc"
    aborted = rdea_lab.run_protocol(_protocol(folder, "0.01 N"), CARD, rdea_lab.Twin(model="su"),
                                    out=folder / "aborted.nc")
    assert aborted.attrs["status"] == "aborted"
    out["aborted"] = folder / "aborted.nc"
    # a run killed outright: its journal, rebuilt by recover
    ds = open_run(out["twin"])
    attrs = {k: v.item() if isinstance(v, np.generic) else v for k, v in ds.attrs.items()}
    writer = JournalWriter(folder / "recovered.nc", attrs, extra=("model_status",))
    writer.append({k: ds[k].values[:50] for k in ("time", *ds.data_vars)})
    writer.close()
    out["recovered"] = recover(folder / "recovered.nc")
    files = LOADING_UNLOADING[:1]
    if files:
        options = ImportOptions(fmt="csv", mapping={"time": "0", "position": "1", "force": "2"},
                                protocol_kind="tensile", credit="Chongran-Zhao/VHB4910_data (GitHub)")
        from rdea_lab.specs import load_specimen

        (_, target, _), = import_files(files,
                                       load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"),
                                       options, out=folder / "imported", command=f"rdea-lab import {files[0]}")
        out["imported"] = target
    else:
        out["imported"] = None
    t = np.linspace(0.0, 2.0, 201)
    simulate(CARD, PARAMS, t, 1.0 + 0.2 * t / 2.0, np.where(t > 1.0, 2.6e3, 0.0)).to_netcdf(folder / "simulate.nc")
    out["simulate"] = folder / "simulate.nc"
    return out


def _path(written, kind):
    if written[kind] is None:
        pytest.skip(f"no {kind} dataset here: {MISSING}")
    return written[kind]


@pytest.mark.parametrize("kind", KINDS)
def test_the_ioos_checker_finds_nothing_at_any_priority(written, kind):
    found = ioos(_path(written, kind))
    assert found == {"high": [], "medium": [], "low": [], "exceptions": []}


@pytest.mark.parametrize("kind", KINDS)
def test_cfchecker_finds_no_error_and_no_warning(written, kind):
    found = cfchecks(_path(written, kind))
    assert found["FATAL"] == found["ERROR"] == found["WARN"] == []


def _old_schema(path: Path) -> bool:
    with xr.open_dataset(path, decode_times=False) as ds:
        return "time" in ds and " since " not in ds["time"].attrs.get("units", "")


def test_the_shipped_datasets_are_there():
    # the paper campaign's twelve runs (datasets/paper2021/): the test below has something to check
    campaign = ROOT / "datasets" / "paper2021"
    assert len([p for p in SHIPPED if campaign in p.parents]) == 12, SHIPPED


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_dataset_passes_both_checkers(path):
    assert not _old_schema(path), (f"{path.relative_to(ROOT)} predates the CF-1.8 schema (time in plain s): "
                                   "regenerate it")
    found = ioos(path)
    assert found["high"] == found["medium"] == found["exceptions"] == [], found
    found = cfchecks(path)
    assert found["FATAL"] == found["ERROR"] == [], found


# ------------------------------------------------------------------ the rules, one by one
@pytest.mark.parametrize("kind", KINDS)
def test_time_is_seconds_since_the_start_and_open_run_keeps_float_seconds(written, kind):
    path = _path(written, kind)
    ds = open_run(path)
    attrs = ds["time"].attrs
    start = re.fullmatch(r"seconds since (\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)", attrs["units"])
    assert start and start[1] == ds.attrs["created"]
    assert (attrs["standard_name"], attrs["axis"], attrs["calendar"]) == ("time", "T", "standard")
    assert ds["time"].dtype == np.float64 and "_FillValue" not in ds["time"].encoding
    with xr.open_dataset(path) as decoded:  # a CF reader gets dates: the start plus the seconds
        t0 = np.datetime64(start[1].rstrip("Z"), "ns")
        expected = t0 + np.round(ds["time"].values * 1e9).astype("timedelta64[ns]")
        ns = (decoded["time"].values - expected).astype(np.int64)
        assert np.abs(ns).max() <= 1  # the decoder truncates float seconds to whole nanoseconds


@pytest.mark.parametrize("kind", KINDS)
def test_status_variables_carry_flags_from_the_status_codes(written, kind):
    ds = open_run(_path(written, kind))
    if "model_status" not in ds:
        assert kind in ("emulator", "imported")  # measured data: no model
        return
    var = ds["model_status"]
    assert list(var.attrs["flag_values"]) == sorted(STATUS_NAMES) and var.attrs["flag_values"].dtype == var.dtype
    words = var.attrs["flag_meanings"].split(" ")
    assert len(words) == len(STATUS_NAMES) and words[:2] == ["ok", "past_limit_point"] and words[7] == "slack"
    assert not re.search(r"\d", var.attrs["long_name"])  # no codes spelled in the long name
    if "converged" in ds:
        assert list(ds["converged"].attrs["flag_values"]) == [0, 1]


@pytest.mark.parametrize("kind", KINDS)
def test_global_attributes_and_no_machine_paths(written, kind, tmp_path_factory):
    path = _path(written, kind)
    ds = open_run(path)
    for key in ("institution", "source", "references", "history", "Conventions"):
        assert isinstance(ds.attrs[key], str) and ds.attrs[key], key
    assert "doi:10.1088/1361-665X/ac34be" in ds.attrs["references"]
    assert ds.attrs["institution"] == ("Example Lab, Example University" if kind in ("twin", "recovered")
                                       else "not stated")
    machine = [str(ROOT), str(path.parent), str(VHB), "/tmp/"]
    leaks = {k: v for k, v in ds.attrs.items() if isinstance(v, str) and any(m in v for m in machine)}
    assert not leaks
    assert "rig_address" not in ds.attrs  # the emulator's loopback port lives as long as the run


def test_each_writer_says_how_its_data_were_made(written):
    runs = {kind: open_run(p) for kind, p in written.items() if p is not None}
    assert runs["twin"].attrs["source"] == (f"rdea-lab {rdea_lab.__version__} twin, model su, "
                                            "parameters paper2021-table3")
    emu = runs["emulator"].attrs
    assert emu["source"] == "rdea-lab rig emulator (truth paper2021-emulator)"
    assert emu["emulated"] == 1 and emu["comment"] == "data from the rdea-lab rig emulator, not a physical rig"
    assert runs["aborted"].attrs["status"] == "aborted" and runs["recovered"].attrs["status"] == "interrupted"
    assert runs["twin"].attrs["protocol_source"] == "short-50N.yaml"  # outside the project: the name only
    if "imported" in runs:
        imp = runs["imported"].attrs
        assert imp["source"] == f"imported from {imp['source_file']}" and imp["source_credit"]
        assert f"rdea-lab import {written['imported'].stem}.csv" in imp["history"]


def test_a_packaged_protocol_is_named_by_its_packaged_name(tmp_path):
    """No machine's absolute path in a dataset: a packaged input is named as `rdea_lab.paths.resolve` finds it."""
    packaged = ROOT / "rdea_lab" / "data" / "protocols" / "blocking_force.yaml"
    ds = rdea_lab.run_protocol(packaged, CARD, rdea_lab.Twin(model="su"), out=tmp_path / "b.nc",
                               command=f"rdea-lab run {packaged}")
    assert ds.attrs["protocol_source"] == "protocols/blocking_force.yaml"
    assert ds.attrs["history"].split("\n")[0].endswith(": rdea-lab run protocols/blocking_force.yaml")


SENSE = """name: cf_sense
kind: custom
sample_rate: 1 kHz
measure: [force, current]
probe: {amplitude: 20 V, frequency: 100 Hz}
stretch:
  - {kind: hold, duration: 0.5 s, value: 1.0}
  - {kind: ramp, duration: 1.5 s, to: 1.2}
voltage:
  - {kind: hold, duration: 0.5 s, value: 0 V}
  - {kind: sine, duration: 1.5 s, mean: 1 kV, amplitude: 1 kV, frequency: 1 Hz, phase: -90 deg}
"""


def test_a_run_with_current_and_its_selfsense_dataset_pass_both_checkers(tmp_path):
    protocol = tmp_path / "sense.yaml"
    protocol.write_text(SENSE)
    rdea_lab.run_protocol(protocol, CARD, "emulator", out=tmp_path / "run.nc")
    from rdea_lab.reports.selfsense import selfsense_run

    selfsense_run(tmp_path / "run.nc", PARAMS, out=tmp_path / "sense.nc")
    for path in (tmp_path / "run.nc", tmp_path / "sense.nc"):
        assert ioos(path) == {"high": [], "medium": [], "low": [], "exceptions": []}, path.name
        found = cfchecks(path)
        assert found["FATAL"] == found["ERROR"] == found["WARN"] == [], path.name
    assert open_run(tmp_path / "run.nc")["current"].attrs["units"] == "A"
