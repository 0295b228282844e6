"""``rdea-lab import``: foreign files (CSV, TDMS, .mat) into the run schema (issue 7).

The real fixtures are the five raw loading-unloading exports of a VHB 4910
strip from the public repository Chongran-Zhao/VHB4910_data (GitHub), kept
beside the checkout in ../shared/data/vhb4910 (see tests/vhb_data.py). Every expected value below is read
from the files' text here, independently of the importer.
"""

from __future__ import annotations

import hashlib
import json
import re
import time
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import yaml
from nptdms import ChannelObject, TdmsWriter
from vhb_data import LOADING_UNLOADING, VHB, needs_vhb

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli as main_cli
from rdea_lab.specs import SpecError, load_specimen, specimen_from_yaml
from rdea_lab.store import REQUIRED_ATTRS, VARIABLES, open_run, write_dataset
from rdea_lab.store.importers import ImportOptions, import_file, parse_map, parse_units

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "import_data"
VHB_FILES = LOADING_UNLOADING
#: The step-and-hold run beside them (the shared README), tested on its own.
RELAX = VHB / "relax_2d0.csv"
CREDIT = "Chongran-Zhao/VHB4910_data (GitHub), uniaxial-loading-unloading/original_data"
STRIP = DATA / "vhb4910.yaml"  # {id: vhb4910, kind: strip, length: 80 mm, ...}
ROLL = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"  # L1 = 34 mm


@pytest.fixture(scope="module")
def cli():
    return main_cli


def invoke(cli, capsys, *args):
    rc = run_cli(cli, ["import", *map(str, args)])
    out, err = capsys.readouterr()
    return rc, out, err


def vhb_text(path: Path):
    """Time, displacement [mm] and force [N] of a VHB file, as the text says."""
    lines = path.read_bytes().decode("gbk").splitlines()
    if lines[0] == "":  # the loading-unloading files start with a blank line, the step-and-hold one not
        lines = lines[1:]
    assert lines[0] == "时间,位移,力" and lines[1] == "(s),(mm),(N)"  # GBK header, units row
    rows = [ln for ln in lines[2:] if ln.strip()]
    cells = [[c.strip('"') for c in ln.split(",")] for ln in rows]
    return cells


# ------------------------------------------------------------------ VHB 4910
@needs_vhb
def test_all_five_vhb_files_are_there():
    """The shared folder's README lists five loading-unloading files: three rates to stretch 1.5, two to 3.0."""
    assert [p.name for p in VHB_FILES] == ["0d01_1d5.csv", "0d01_3d0.csv", "0d03_1d5_1.csv", "0d05_1d5_1.csv",
                                           "0d05_3d0.csv"]


@needs_vhb
@pytest.mark.parametrize("path", VHB_FILES, ids=lambda p: p.name)
def test_vhb_file_imports_as_the_file_says(cli, capsys, tmp_path, path):
    out = tmp_path / f"{path.stem}.nc"
    rc, stdout, err = invoke(cli, capsys, path, "--format", "csv", "--map", "time=0,position=1,force=2",
                             "--specimen", STRIP, "--protocol-kind", "tensile", "--credit", CREDIT, "--out", out)
    assert rc == 0, err
    assert str(out) in stdout
    ds = open_run(out)
    cells = vhb_text(path)
    assert ds.sizes["time"] == len(cells)  # one sample per data line
    t = ds["time"].values
    assert t[0] == float(cells[0][0]) and t[-1] == float(cells[-1][0])
    mm = np.array([float(c[1]) for c in cells])
    newton = np.array([float(c[2]) for c in cells])
    np.testing.assert_array_equal(ds["position"].values, mm / 1000)  # exact: mm -> m divides by 1000
    np.testing.assert_array_equal(ds["force"].values, newton)
    np.testing.assert_array_equal(ds["stretch"].values, 1 + ds["position"].values / 0.08)  # L1 = 80 mm
    # the file name says the stretch loaded to ('1d5': 1.5, peaks 40.00-40.04 mm of 80 mm; '3d0': 3.0)
    named = float(re.match(r"0d\d\d_(\d)d(\d)", path.stem).expand(r"\1.\2"))
    assert ds["stretch"].values.max() == pytest.approx(named, abs=1e-3)
    # raw data: small negative positions near zero load stay as measured, and are reported
    assert mm.min() < 0
    assert ds.attrs["min_position_m"] == mm.min() / 1000
    assert ds["stretch"].values.min() < 1
    assert ds.attrs["source_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert ds.attrs["source_file"] == path.name
    assert ds.attrs["source_credit"] == CREDIT
    assert ds.attrs["sample_rate"] == pytest.approx(50.0)  # 0.02 s steps
    mapping = json.loads(ds.attrs["import_mapping"])
    assert mapping["units"] == {"time": "s", "position": "mm", "force": "N"}
    assert set(mapping["units_from"].values()) == {"file"}  # from the units row (s),(mm),(N)
    assert mapping["columns"] == {"time": "时间", "position": "位移", "force": "力"}  # GBK header decoded


@pytest.mark.skipif(not RELAX.is_file(), reason=f"{RELAX} is absent (see tests/vhb_data.py)")
def test_the_step_and_hold_file_imports_as_its_readme_says(cli, capsys, tmp_path):
    """relax_2d0.csv (the shared README): loaded at about 0.25 /s to stretch 2.0, then held 1800 s, 50 Hz."""
    out = tmp_path / "relax.nc"
    rc, _, err = invoke(cli, capsys, RELAX, "--format", "csv", "--map", "time=0,position=1,force=2",
                        "--specimen", STRIP, "--protocol-kind", "custom", "--credit", CREDIT, "--out", out)
    assert rc == 0, err
    ds = open_run(out)
    cells = vhb_text(RELAX)
    assert ds.sizes["time"] == len(cells)  # one sample per data line
    np.testing.assert_array_equal(ds["force"].values, [float(c[2]) for c in cells])
    t, lam = ds["time"].values, ds["stretch"].values
    assert np.median(np.diff(t)) == pytest.approx(0.02)  # 50 Hz
    held = t >= t[np.argmax(lam >= 1.99)]
    assert lam[held].min() == pytest.approx(2.0, abs=0.01) and lam.max() == pytest.approx(2.0, abs=0.01)
    assert t[held][-1] - t[held][0] == pytest.approx(1800, abs=10)
    ramp = t[np.argmax(lam >= 1.99)] - t[np.argmax(lam >= 1.01)]
    assert 0.98 / ramp == pytest.approx(0.25, rel=0.2)  # "about 0.25 1/s"


@pytest.mark.slow
@pytest.mark.skipif(not RELAX.is_file(), reason=f"{RELAX} is absent (see tests/vhb_data.py)")
def test_skip_start_leaves_out_the_start_up_spike_and_says_so(tmp_path):
    """--skip-start 0.1 on relax_2d0 (its first 0.1 s a start-up spike, README): the data lines with time
    < 0.1 s (counted from the text) are gone, the rest unchanged with their own times; the attrs say it.
    A skip that leaves fewer than two samples is refused, naming the option."""
    cells = vhb_text(RELAX)
    times = np.array([float(c[0]) for c in cells])
    gone = int(np.count_nonzero(times - times[0] < 0.1))
    options = ImportOptions("csv", parse_map("time=0,position=1,force=2"), protocol_kind="tensile", skip_start=0.1)
    ds = import_file(RELAX, load_specimen(STRIP), options)
    assert gone == 5 and ds.sizes["time"] == len(cells) - gone
    np.testing.assert_array_equal(ds["force"].values, [float(c[2]) for c in cells[gone:]])
    assert ds.attrs["skipped_start_s"] == 0.1 and ds.attrs["skipped_start_samples"] == gone
    with pytest.raises(SpecError, match="--skip-start"):
        import_file(RELAX, load_specimen(STRIP), ImportOptions("csv", options.mapping, skip_start=1e4))


@needs_vhb
def test_vhb_dataset_has_the_run_schema(tmp_path):
    options = ImportOptions("csv", parse_map("time=0,position=1,force=2"), protocol_kind="tensile", credit=CREDIT)
    ds = import_file(VHB_FILES[0], load_specimen(STRIP), options, command="rdea-lab import test")
    for name in REQUIRED_ATTRS:
        assert ds.attrs.get(name) is not None, name
    assert ds.attrs["Conventions"] == "CF-1.8"
    assert ds.attrs["backend"] == "import" and ds.attrs["status"] == "complete" and ds.attrs["status_reason"] == ""
    assert ds.attrs["seed"] == 0 and len(ds.attrs["run_id"]) == 32
    assert ds.attrs["specimen_id"] == "vhb4910" and ds.attrs["protocol_kind"] == "tensile"
    assert ds.attrs["protocol_name"] == "0d01_1d5"  # the file stem
    assert specimen_from_yaml(ds.attrs["specimen"]).kind == "strip"
    protocol = yaml.safe_load(ds.attrs["protocol"])
    assert protocol["import"]["source_format"] == "csv" and protocol["import"]["read"]["encoding"] == "gbk"
    assert "rdea-lab import test" in ds.attrs["history"]
    for name, (units, long_name) in VARIABLES.items():
        assert ds[name].attrs == {"units": units, "long_name": long_name}
    assert ds["time"].attrs["units"] == f"seconds since {ds.attrs['created']}"  # CF 1.8, the import's time
    np.testing.assert_array_equal(ds["voltage"].values, 0.0)
    for name in ("capacitance", "stretch_setpoint", "voltage_setpoint"):
        assert np.isnan(ds[name].values).all(), name
    out = tmp_path / "x.nc"
    write_dataset(ds, out)
    back = open_run(out)
    assert back.attrs == ds.attrs
    for name in ds.variables:
        np.testing.assert_array_equal(back[name].values, ds[name].values)


@needs_vhb
def test_vhb_by_header_names_and_explicit_encoding():
    card = load_specimen(STRIP)
    by_index = import_file(VHB_FILES[2], card, ImportOptions("csv", parse_map("time=0,position=1,force=2")))
    by_name = import_file(VHB_FILES[2], card, ImportOptions("csv", parse_map("time=时间,position=位移,force=力"),
                                                            encoding="gbk"))
    for name in VARIABLES:
        np.testing.assert_array_equal(by_name[name].values, by_index[name].values)


@needs_vhb
def test_vhb_wrong_encoding_is_refused(cli, capsys, tmp_path):
    rc, _, err = invoke(cli, capsys, VHB_FILES[2], "--format", "csv", "--map", "time=0,position=1,force=2",
                        "--specimen", STRIP, "--protocol-kind", "tensile", "--encoding", "utf-8",
                        "--out", tmp_path / "x.nc")
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert VHB_FILES[2].name in err and "--encoding" in err and "not utf-8" in err


@needs_vhb
def test_three_vhb_files_to_the_default_folder(cli, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = [*VHB_FILES, "--format", "csv", "--map", "time=0,position=1,force=2", "--specimen", STRIP,
            "--protocol-kind", "tensile"]
    rc, out, err = invoke(cli, capsys, *args)
    assert rc == 0, err
    written = sorted((tmp_path / "datasets" / "imported" / "vhb4910").glob("*.nc"))
    assert [p.stem for p in written] == [p.stem for p in VHB_FILES]
    before = written[0].read_bytes()
    rc, _, err = invoke(cli, capsys, *args)  # again: never overwrite without --force
    assert rc == 2 and "0d01_1d5.nc: --out: exists; give --force" in err and len(err.strip().splitlines()) == 1
    assert written[0].read_bytes() == before
    rc, _, err = invoke(cli, capsys, *args, "--force")
    assert rc == 0, err
    assert open_run(written[0]).attrs["run_id"] != ""


# -------------------------------------------------- instrument CSV quirks
def test_semicolon_decimal_comma_cp1252_imports(tmp_path):
    ds = import_file(DATA / "good_semicolon_decimal_comma.csv", load_specimen(ROLL),
                     ImportOptions("csv", parse_map("time=Zeit,position=Weg,force=Kraft")))
    np.testing.assert_array_equal(ds["time"].values, [0.0, 0.5, 1.0, 1.5])
    np.testing.assert_array_equal(ds["position"].values, np.array([0.0, 1.25, 2.5, 3.75]) / 1000)
    np.testing.assert_array_equal(ds["force"].values, [-0.0012, 0.15, 0.29, 0.41])
    read = yaml.safe_load(ds.attrs["protocol"])["import"]["read"]
    assert read == {"encoding": "cp1252", "separator": "semicolon", "decimal": "comma", "header_line": 3,
                    "units_line": 4, "first_data_line": 5}
    np.testing.assert_allclose(ds["stretch"].values, 1 + np.array([0.0, 1.25, 2.5, 3.75]) / 34, rtol=0, atol=1e-15)


def test_trailing_empty_columns_and_units_in_header_names():
    ds = import_file(DATA / "good_trailing_empty_columns.csv", load_specimen(ROLL),
                     ImportOptions("csv", parse_map("time=time,position=position,force=force (N)")))
    np.testing.assert_array_equal(ds["position"].values, np.array([0.0, 0.4, 0.8, 1.2]) / 1000)
    np.testing.assert_array_equal(ds["force"].values, [0.01, 0.02, 0.04, 0.05])
    assert json.loads(ds.attrs["import_mapping"])["units"] == {"time": "s", "position": "mm", "force": "N"}


def test_sparse_capacitance_column_wider_header_and_protocol_name(tmp_path):
    path = tmp_path / "sparse.csv"  # C measured now and then; rows without it end early
    path.write_bytes("Operator: A. Müller\r\nt;x;F;C\r\ns;mm;N;pF\r\n0,0;0,0;0,01;310,5\r\n0,1;0,2;0,02;\r\n"
                     "0,2;0,4;0,03\r\n0,3;0,6;0,04;311,0\r\n0,4;0,8;0,05\r\n".encode("utf-8"))
    mapping = parse_map("time=t,position=x,force=F,capacitance=C")
    ds = import_file(path, load_specimen(ROLL), ImportOptions("csv", mapping, protocol_name="ramp-1"))
    np.testing.assert_array_equal(ds["capacitance"].values, np.array([310.5, np.nan, np.nan, 311.0, np.nan]) / 1e12)
    np.testing.assert_array_equal(ds["voltage"].values, 0.0)
    assert ds.attrs["protocol_name"] == "ramp-1" and ds.attrs["title"].startswith("ramp-1 on specimen-2")


def test_tabs_quotes_no_header_units_from_the_command_line():
    mapping = parse_map("time=0,position=1,force=2")
    ds = import_file(DATA / "good_tab_no_header.tsv", load_specimen(ROLL),
                     ImportOptions("csv", mapping, parse_units("time=ms,position=um,force=kN", mapping)))
    np.testing.assert_array_equal(ds["time"].values, [0.0, 0.0005, 0.001])
    np.testing.assert_array_equal(ds["position"].values, np.array([0.0, 2.0, 4.0]) / 1e6)
    np.testing.assert_array_equal(ds["force"].values, [100.0, 300.0, 500.0])
    assert ds.attrs["sample_rate"] == pytest.approx(2000.0)


def test_large_csv_is_read_in_one_go(tmp_path):
    n = 200_000
    t = np.arange(n) * 1e-3
    x = 5 * (1 - np.cos(t))  # [mm], >= 0
    path = tmp_path / "big.csv"
    with open(path, "w", newline="") as fh:
        fh.write("t;x;F\r\ns;mm;N\r\n")
        np.savetxt(fh, np.column_stack([t, x, x / 10]), fmt="%.6f", delimiter=";", newline="\r\n")
    start = time.perf_counter()
    ds = import_file(path, load_specimen(ROLL), ImportOptions("csv", parse_map("time=t,position=x,force=F")))
    elapsed = time.perf_counter() - start
    assert ds.sizes["time"] == n
    assert elapsed < 10.0, elapsed  # vectorized: well under a second here; the bound only catches a row loop


# ------------------------------------------------------------------- TDMS
def write_tdms(path, channels):
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([ChannelObject(g, c, data, properties=props) for g, c, data, props in channels])


def test_tdms_round_trip(tmp_path):
    n = 50
    t = np.arange(n) * 0.01
    mm = np.linspace(0.0, 10.0, n)
    force = 0.2 * mm
    kv = np.linspace(0.0, 2.6, n)
    pf = np.full(n, 310.0)
    path = tmp_path / "run.tdms"
    write_tdms(path, [("Rig", "Time", t, {"unit_string": "s"}), ("Rig", "Position", mm, {"unit_string": "mm"}),
                      ("Rig", "Force", force, {"unit_string": "N"}), ("HV", "Voltage", kv, {"unit_string": "kV"}),
                      ("LCR", "C", pf, {"unit_string": "pF"}), ("LCR", "Force", force, {})])
    mapping = parse_map("time=Time,position=Rig/Position,force=Rig/Force,voltage=Voltage,capacitance=LCR/C")
    ds = import_file(path, load_specimen(ROLL), ImportOptions("tdms", mapping, protocol_kind="custom"))
    np.testing.assert_array_equal(ds["time"].values, t)
    np.testing.assert_array_equal(ds["position"].values, mm / 1000)
    np.testing.assert_array_equal(ds["force"].values, force)
    np.testing.assert_array_equal(ds["voltage"].values, kv * 1000)
    np.testing.assert_array_equal(ds["capacitance"].values, pf / 1e12)
    np.testing.assert_array_equal(ds["stretch"].values, 1 + mm / 1000 / 0.034)
    assert ds.attrs["source_format"] == "tdms"
    one_group = tmp_path / "one_group.tdms"  # (npTDMS lists groups in its own order; channels keep theirs)
    write_tdms(one_group, [("Rig", "Time", t, {"unit_string": "s"}), ("Rig", "Position", mm, {"unit_string": "mm"}),
                           ("Rig", "Force", force, {"unit_string": "N"})])
    by_index = import_file(one_group, load_specimen(ROLL),
                           ImportOptions("tdms", parse_map("time=0,position=1,force=2")))
    np.testing.assert_array_equal(by_index["force"].values, force)
    with pytest.raises(SpecError, match=r"run\.tdms: --map force: 'Force' names several channels \(.*Rig/Force"):
        import_file(path, load_specimen(ROLL),
                    ImportOptions("tdms", parse_map("time=Time,position=Position,force=Force")))
    with pytest.raises(SpecError, match=r"run\.tdms: --units force: no unit for force \(channel 'LCR/Force'\)"):
        import_file(path, load_specimen(ROLL),
                    ImportOptions("tdms", parse_map("time=Time,position=Position,force=LCR/Force")))


def test_tdms_timestamps_become_seconds(tmp_path):
    stamps = np.datetime64("2025-03-01T12:00:00") + np.arange(5) * np.timedelta64(250, "ms")
    path = tmp_path / "stamped.tdms"
    write_tdms(path, [("g", "t", stamps, {}), ("g", "x", np.arange(5.0), {"unit_string": "mm"}),
                      ("g", "F", np.arange(5.0), {"unit_string": "N"})])
    ds = import_file(path, load_specimen(ROLL), ImportOptions("tdms", parse_map("time=t,position=x,force=F")))
    np.testing.assert_array_equal(ds["time"].values, [0.0, 0.25, 0.5, 0.75, 1.0])


# -------------------------------------------------------------------- MAT
def test_mat_round_trip(tmp_path):
    t = np.arange(40) * 0.05
    mm = np.linspace(0.0, 6.0, 40)
    force = np.sqrt(mm)
    path = tmp_path / "run.mat"
    scipy.io.savemat(path, {"t": t, "data": np.column_stack([mm, force]), "wide": np.vstack([mm, force]),
                            "fs": 20.0})
    units = "time=s,position=mm,force=N"
    for text in ("time=t,position=data[:, 0],force=data[:,1]", "time=t,position=wide[0, :],force=wide[1,:]",
                 "time=0,position=1,force=2"):
        mapping = parse_map(text)
        ds = import_file(path, load_specimen(ROLL), ImportOptions("mat", mapping, parse_units(units, mapping)))
        np.testing.assert_array_equal(ds["time"].values, t)
        np.testing.assert_array_equal(ds["position"].values, mm / 1000)
        np.testing.assert_array_equal(ds["force"].values, force)
    mapping = parse_map("time=t,position=data[:, 0],force=data[:, 1]")
    with pytest.raises(SpecError, match=r"run\.mat: --units time: no unit for time"):
        import_file(path, load_specimen(ROLL), ImportOptions("mat", mapping))
    with pytest.raises(SpecError, match=r"run\.mat: --map force: no column 'data\[:, 2\]'; available: 0 't', "
                                        r"1 'data\[:, 0\]'"):
        import_file(path, load_specimen(ROLL), ImportOptions("mat", parse_map("time=t,position=t,force=data[:, 2]"),
                                                             parse_units(units, mapping)))


def test_mat_v73_is_refused_clearly(tmp_path):
    path = tmp_path / "new.mat"
    path.write_bytes(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Mar  3 2025 HDF5 schema 1.00 ."
                     .ljust(512, b"\0"))
    with pytest.raises(SpecError, match=r"new\.mat: a MATLAB v7\.3 \(HDF5\) file"):
        import_file(path, load_specimen(ROLL), ImportOptions("mat", parse_map("time=t,position=x,force=F")))


# -------------------------------------------------------- malformed inputs
MAP = "time=0,position=1,force=2"
BAD = {  # file -> (what the one line must say after the file's name, --map)
    "bad_empty.csv": ("the file is empty", MAP),
    "bad_no_data.csv": ("no data rows", MAP),
    "bad_text_in_number.csv": ("line 5, column 'force': 'n/a' is not a number", MAP),
    "bad_time_backwards.csv": ("line 6, column 'time': time does not increase: 0.15 after 0.20 (line 5; samples 2 "
                               "and 3)", MAP),
    "bad_time_repeated.csv": ("line 5, column 'time': time does not increase: 0.10 after 0.10", MAP),
    "bad_unit_furlong.csv": ("column 'force' (unit 'furlong' in the file): unit 'furlong' is not a force unit", MAP),
    "bad_unit_unknown.csv": ("column 'position' (unit 'blorp' in the file): unknown unit 'blorp'", MAP),
    "bad_empty_field.csv": ("line 5, column 'force': an empty field (force)", MAP),
    "bad_nan_time.csv": ("line 4, column 'time': 'nan' is not a finite number (time)", MAP),
    "bad_ragged_row.csv": ("line 5: 4 fields where the data rows have 3", MAP),
    "bad_stretch_below_one.csv": ("line 4, column 'position': position -5.000 gives stretch 0.852941 with L1 = 34 "
                                  "mm, below 0.999", MAP),
    "bad_one_row.csv": ("1 data row(s); need at least 2", MAP),
    "bad_no_units.csv": ("--units time: no unit for time (column 'time'): the file gives none", MAP),
    "bad_one_column.csv": ("cannot tell the column separator", MAP),
    "good_semicolon_decimal_comma.csv": ("--map force: no column 'force'; available: 0 'Zeit', 1 'Weg', 2 'Kraft', "
                                         "3 'Temperatur'", "time=Zeit,position=Weg,force=force"),
    "good_trailing_empty_columns.csv": ("--map force: column index 5 is out of range; the file has 5 columns: "
                                        "0 'time (s)', 1 'position [mm]', 2 'force (N)', 3 (no name), 4 (no name)",
                                        "time=0,position=1,force=5"),
    "good_tab_no_header.tsv": ("--units time: no unit for time (column 0)", MAP),
}


@pytest.mark.parametrize("name", sorted(BAD), ids=str)
def test_malformed_input_exit_2_one_line_naming_the_file(cli, capsys, tmp_path, name):
    expected, mapping = BAD[name]
    rc, _, err = invoke(cli, capsys, DATA / name, "--format", "csv", "--map", mapping, "--specimen", ROLL,
                        "--protocol-kind", "tensile", "--out", tmp_path / "out.nc")
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"rdea-lab: {DATA / name}: "), lines[0]
    assert expected in lines[0], lines[0]
    assert not (tmp_path / "out.nc").exists()


def test_the_corpus_covers_the_brief():
    assert len([n for n in BAD if n.startswith("bad_")]) >= 10
    assert sorted(p.name for p in DATA.glob("bad_*")) == sorted(n for n in BAD if n.startswith("bad_"))


COMMAND_LINE = [  # (arguments replacing the defaults, what the one line says)
    ({"--format": "xls"}, "good.csv: --format: unknown format 'xls'; allowed: csv, tdms, mat"),
    ({"--map": "time0,position=1,force=2"}, "--map: 'time0' is not KEY=VALUE"),
    ({"--map": "time=0,position=1"}, "--map: missing force"),
    ({"--map": "time=0,position=1,force=2,strain=3"}, "--map: unknown key 'strain'"),
    ({"--map": "time=0,position=1,force=2,time=3"}, "--map: 'time' is given twice"),
    ({"--units": "force=furlong"}, "--units force: unit 'furlong' is not a force unit"),
    ({"--units": "force=blorp"}, "--units force: unknown unit 'blorp'; give a force unit"),
    ({"--units": "position=N"}, "--units position: unit 'N' is not a length unit"),
    ({"--units": "time=mm"}, "--units time: unit 'mm' is not a time unit"),
    ({"--units": "voltage=V"}, "--units: a unit for 'voltage', which --map does not map"),
    ({"--units": "force N"}, "--units: 'force N' is not KEY=VALUE"),
    ({"--encoding": "klingon"}, "good.csv: --encoding: unknown encoding 'klingon'"),
    ({"--format": "tdms"}, "good.csv: not a readable TDMS file"),
    ({"--format": "mat"}, "good.csv: not a readable MATLAB .mat file"),
    ({"--specimen": "nowhere.yaml"}, "nowhere.yaml: file not found"),
    ({"--protocol-kind": "fatigue"}, "Invalid value for '--protocol-kind'"),
]


@pytest.mark.parametrize("change,expected", COMMAND_LINE, ids=lambda v: str(v)[:40])
def test_bad_command_line_exit_2_one_line(cli, capsys, tmp_path, change, expected):
    good = tmp_path / "good.csv"
    good.write_bytes((DATA / "good_trailing_empty_columns.csv").read_bytes())
    options = {"--format": "csv", "--map": MAP, "--specimen": str(ROLL), "--protocol-kind": "tensile",
               "--out": str(tmp_path / "out.nc"), **change}
    rc, _, err = invoke(cli, capsys, good, *[x for kv in options.items() for x in kv])
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1, err
    assert expected in lines[0], lines[0]
    assert not (tmp_path / "out.nc").exists()


def test_missing_file_and_directory(cli, capsys, tmp_path):
    base = ["--format", "csv", "--map", "time=0,position=1,force=2", "--specimen", ROLL, "--protocol-kind",
            "tensile", "--out", tmp_path / "o"]
    rc, _, err = invoke(cli, capsys, tmp_path / "absent.csv", *base)
    assert rc == 2 and "absent.csv: file not found" in err and len(err.strip().splitlines()) == 1
    rc, _, err = invoke(cli, capsys, tmp_path, *base)
    assert rc == 2 and "is a directory" in err


def test_a_bad_file_among_good_ones_writes_nothing(cli, capsys, tmp_path):
    rc, _, err = invoke(cli, capsys, DATA / "good_trailing_empty_columns.csv", DATA / "bad_time_backwards.csv",
                        "--format", "csv", "--map", "time=0,position=1,force=2", "--specimen", ROLL,
                        "--protocol-kind", "tensile", "--out", tmp_path / "out")
    assert rc == 2 and "bad_time_backwards.csv" in err
    assert not (tmp_path / "out").exists()


def test_one_nc_for_several_inputs_is_refused(cli, capsys, tmp_path):
    rc, _, err = invoke(cli, capsys, DATA / "good_trailing_empty_columns.csv", DATA / "good_tab_no_header.tsv",
                        "--format", "csv", "--map", "time=0,position=1,force=2", "--specimen", ROLL,
                        "--protocol-kind", "tensile", "--out", tmp_path / "one.nc")
    assert rc == 2 and "one file, for 2 inputs; give a folder" in err


def test_small_negative_positions_are_kept_not_clipped(tmp_path):
    path = tmp_path / "noise.csv"
    path.write_text("t,x,F\ns,mm,N\n0,-0.002,-0.01\n1,0.5,0.1\n2,-0.001,0.0\n")
    ds = import_file(path, load_specimen(ROLL), ImportOptions("csv", parse_map("time=0,position=1,force=2")))
    np.testing.assert_array_equal(ds["position"].values, np.array([-0.002, 0.5, -0.001]) / 1000)
    assert ds.attrs["min_position_m"] == -0.002 / 1000
    assert ds["stretch"].values.min() < 1  # as measured: 1 - 5.9e-5 is noise, above --min-stretch 0.999


def test_help_gives_syntax_examples_and_credit(cli, capsys):
    rc = run_cli(cli, ["import", "--help"])
    out = capsys.readouterr().out
    assert rc == 0
    for text in ("--format", "--map", "--units", "--specimen", "--protocol-kind", "--encoding", "--out", "--name",
                 "--force", "--credit", "data[:, 1]", "group/channel", "Chongran-Zhao/VHB4910_data"):
        assert text in out, text
