"""Every malformed protocol and specimen file: exit 2 and one line naming the file (issue 3)."""

from pathlib import Path

import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli

ROOT = Path(__file__).resolve().parents[2]
BAD_PROTOCOLS = sorted((ROOT / "tests" / "protocols" / "bad").glob("*.yaml"))
BAD_SPECIMENS = sorted((ROOT / "tests" / "specs" / "bad").glob("specimen_*.yaml"))
GOOD_PROTOCOL = ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_2.6kV.yaml"
GOOD_SPECIMEN = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"


def expected_field(path: Path) -> str | None:
    if not path.exists():
        return None
    first = path.read_text(errors="replace").splitlines()[:1]
    return first[0].split("field:", 1)[1].strip() if first and "field:" in first[0] else None


def test_the_corpus_is_large_enough():
    assert len(BAD_PROTOCOLS) + len(BAD_SPECIMENS) >= 25
    assert len(BAD_PROTOCOLS) >= 25


def _check(capsys, args, path):
    rc = run_cli(cli, [str(a) for a in args])
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2, (path.name, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    assert path.name in lines[0], lines[0]
    field = expected_field(path)
    if field and field != "<document>":
        assert field in lines[0], (field, lines[0])
    return lines[0]


@pytest.mark.parametrize("path", BAD_PROTOCOLS, ids=lambda p: p.name)
def test_bad_protocol(capsys, path):
    _check(capsys, ["run", path, "--specimen", GOOD_SPECIMEN, "--dry-run"], path)


@pytest.mark.parametrize("path", BAD_SPECIMENS, ids=lambda p: p.name)
def test_bad_specimen(capsys, path):
    _check(capsys, ["run", GOOD_PROTOCOL, "--specimen", path, "--dry-run"], path)


def test_missing_files(capsys, tmp_path):
    line = _check(capsys, ["run", tmp_path / "none.yaml", "--specimen", GOOD_SPECIMEN, "--dry-run"],
                  tmp_path / "none.yaml")
    assert "not found" in line
    assert "<document>" not in line, line  # no placeholder where a field would be


# ------------------------------------------------ bounds (issue 25): generated files, one case per item
HEADER = "name: bad\nkind: custom\nsample_rate: 100 Hz\n"


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _run_protocol(capsys, path, field):
    line = _check(capsys, ["run", path, "--specimen", GOOD_SPECIMEN, "--dry-run"], path)
    assert field in line, line
    assert "allowed" in line, line
    return line


def test_protocol_file_too_large_is_refused_before_parsing(capsys, tmp_path):
    from rdea_lab.specs.errors import MAX_SPEC_BYTES

    path = _write(tmp_path, "huge_table.yaml", HEADER + "stretch: [{kind: table, duration: 2 s, values: [1.0, 1.1")
    with open(path, "a", encoding="utf-8") as fh:  # a table just above the bound, written in one go
        fh.write(", 1.1" * ((MAX_SPEC_BYTES - path.stat().st_size) // 5 + 1) + "]}]\n")
    assert path.stat().st_size > MAX_SPEC_BYTES
    line = _check(capsys, ["run", path, "--specimen", GOOD_SPECIMEN, "--dry-run"], path)
    assert "MB" in line and "allowed" in line, line


def test_cycles_of_5000_digits(capsys, tmp_path):
    path = _write(tmp_path, "cycles_5000_digits.yaml", "name: bad\nsample_rate: 100 Hz\npreset: tensile_ramp_sine\n"
                  f"settings: {{cycles: {'7' * 5000}}}\n")
    line = _run_protocol(capsys, path, "settings.cycles")
    assert len(line) < 400, line  # the value is not printed whole


IMPORT_CSV = ROOT / "tests" / "store" / "import_data" / "good_trailing_empty_columns.csv"
ROLL = GOOD_SPECIMEN


def _import(csv_path, tmp_path, *extra):
    return ["import", csv_path, "--format", "csv", "--map", "time=0,position=1,force=2", "--specimen", ROLL,
            "--protocol-kind", "tensile", "--out", tmp_path / "out.nc", *extra]


def test_csv_line_longer_than_the_csv_modules_field_limit_is_read(capsys, tmp_path):
    path = _write(tmp_path, "long_preamble.csv", "Comment: " + "x" * 200_000 + "\n" + IMPORT_CSV.read_text())
    rc = run_cli(cli, [str(a) for a in _import(path, tmp_path)])
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert (tmp_path / "out.nc").exists()


def test_csv_field_of_200000_characters_is_refused_for_what_it_holds(capsys, tmp_path):
    path = _write(tmp_path, "long_field.csv", IMPORT_CSV.read_text() + "0.4," + "7x" * 100_000 + ",0.06,,\n")
    line = _check(capsys, _import(path, tmp_path), path)
    assert "line 6" in line and "position" in line, line
    assert len(line) < 400, line
    assert not (tmp_path / "out.nc").exists()


# datasets from elsewhere: an attribute or variable not of the type rdea-lab writes
GOOD_RUN = ROOT / "datasets" / "paper2021" / "specimen-2" / "tensile_ramp_sine_0V.nc"
PARAMS = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"


def _foreign_run(tmp_path, name, change):
    import xarray as xr

    with xr.open_dataset(GOOD_RUN, decode_times=False) as ds:
        ds = ds.load()
    change(ds)
    folder = tmp_path / "runs"
    folder.mkdir(exist_ok=True)
    path = folder / name
    ds.to_netcdf(path)
    return path


def _text_force(ds):
    ds["force"] = ds["force"].astype(str)


def _integer_attr(key):
    def change(ds):
        ds.attrs[key] = 42
    return change


FOREIGN = [("show", "text_force.nc", _text_force, "variable 'force'"),
           ("calibrate", "integer_specimen.nc", _integer_attr("specimen"), "attribute 'specimen'"),
           ("calibrate", "integer_specimen_id.nc", _integer_attr("specimen_id"), "attribute 'specimen_id'"),
           ("report", "integer_specimen.nc", _integer_attr("specimen"), "attribute 'specimen'"),
           ("report", "integer_specimen_id.nc", _integer_attr("specimen_id"), "attribute 'specimen_id'")]


@pytest.mark.parametrize("command,name,change,field", FOREIGN, ids=lambda v: v if isinstance(v, str) else "")
def test_dataset_from_elsewhere(capsys, tmp_path, command, name, change, field):
    path = _foreign_run(tmp_path, name, change)
    args = {"show": ["show", path],
            "calibrate": ["calibrate", path, "--out", tmp_path / "cal.yaml"],
            "report": ["report", "validation", "--params", PARAMS, "--datasets", path.parent, "--out",
                       tmp_path / "report", "--no-figures"]}[command]
    line = _check(capsys, args, path)
    assert field in line and "allowed" in line, line


def test_specimen_id_of_10000_characters(capsys, tmp_path):
    import re

    text = re.sub(r"(?m)^id: .*$", "id: " + "a" * 10_000, GOOD_SPECIMEN.read_text())
    path = _write(tmp_path, "specimen_long_id.yaml", text)
    line = _check(capsys, ["run", GOOD_PROTOCOL, "--specimen", path, "--dry-run"], path)
    assert ": id: " in line and "allowed" in line and "..." in line, line  # the field, not the file's name
    assert len(line) < 400, line  # the id is not printed whole


def test_positions_in_parsecs(capsys, tmp_path):
    path = _write(tmp_path, "parsecs.csv", "time (s),position [pc],force (N)\n0.0,0.0,0.01\n0.1,0.4,0.02\n"
                  "0.2,0.8,0.04\n")
    line = _check(capsys, _import(path, tmp_path), path)
    assert "column 'position [pc]'" in line and "unit 'pc'" in line and "allowed" in line, line  # column, unit
    assert not (tmp_path / "out.nc").exists()


@pytest.mark.parametrize("limit", ["max_force: 1e308 N", "max_voltage: 1e9 kV", "max_field: 1e9 V/um",
                                   "max_stretch: 1e6"])
def test_absurd_limits(capsys, tmp_path, limit):
    path = _write(tmp_path, "absurd_limit.yaml", HEADER + f"limits: {{{limit}}}\n"
                  "stretch: [{kind: hold, duration: 2 s}]\nvoltage: [{kind: hold, duration: 2 s}]\n")
    _run_protocol(capsys, path, "limits." + limit.split(":")[0])


def test_truth_seed_of_2_to_the_64(capsys, tmp_path):
    import re

    truth = ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml"
    path = _write(tmp_path, "truth_seed.yaml", re.sub(r"(?m)^seed: .*$", f"seed: {2**64}", truth.read_text()))
    line = _check(capsys, ["run", GOOD_PROTOCOL, "--specimen", GOOD_SPECIMEN, "--backend", "emulator", "--truth",
                           path, "--out", tmp_path / "run.nc"], path)
    assert ": seed: " in line and "allowed" in line, line  # the field, not the file's name
    assert not (tmp_path / "run.nc").exists()


def test_campaign_whose_second_run_seed_overflows_names_the_file_and_the_run(capsys, tmp_path):
    path = _write(tmp_path, "campaign_seed.yaml", f"name: c\nbackend: twin\nseed: {2**63 - 1}\nout: {tmp_path}/out\n"
                  "specimens: [specimens/specimen2.yaml]\n"
                  "protocols: [protocols/tensile_ramp_sine_0V.yaml, protocols/blocking_force.yaml]\n")
    line = _check(capsys, ["campaign", "run", path], path)
    assert ": seed: " in line and "run 2" in line and "blocking_force" in line and "allowed" in line, line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["run.csv", "run"])
def test_dataset_out_without_nc_suffix(capsys, tmp_path, name):
    out = tmp_path / name
    line = _check(capsys, ["run", GOOD_PROTOCOL, "--specimen", GOOD_SPECIMEN, "--backend", "twin", "--out", out], out)
    assert f"{name}: out: " in line and ".nc" in line and "allowed" in line, line
    assert list(tmp_path.iterdir()) == []


def test_import_out_with_another_suffix(capsys, tmp_path):
    out = tmp_path / "run.csv"
    line = _check(capsys, _import(IMPORT_CSV, tmp_path)[:-1] + [out], out)
    assert "run.csv: --out: " in line and ".nc" in line and "allowed" in line, line
    assert list(tmp_path.iterdir()) == []


def test_a_bare_voltage_hint_is_a_plausible_voltage(capsys):
    path = ROOT / "tests" / "protocols" / "bad" / "voltage_3000_no_unit.yaml"
    line = _check(capsys, ["run", path, "--specimen", GOOD_SPECIMEN, "--dry-run"], path)
    assert "'3000 V'" in line or "'3 kV'" in line, line
    assert "'3000 kV'" not in line, line  # 3 MV: no amplifier, no roll


def test_a_decimal_comma_hint_asks_for_a_decimal_point(capsys):
    path = ROOT / "tests" / "protocols" / "bad" / "decimal_comma.yaml"
    line = _check(capsys, ["run", path, "--specimen", GOOD_SPECIMEN, "--dry-run"], path)
    assert "2.6 kV" in line and "decimal point" in line, line


def test_truncated_tdms_gives_one_line_not_the_librarys_warnings(capfd, tmp_path):
    pytest.importorskip("nptdms")
    import numpy as np
    from nptdms import ChannelObject, TdmsWriter

    path = tmp_path / "truncated.tdms"
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([ChannelObject("Rig", name, np.linspace(0.01, 1.0, 1000)) for name in ("t", "x", "F")])
    with open(path, "r+b") as fh:  # a recording cut off half way
        fh.truncate(path.stat().st_size // 2)
    rc = run_cli(cli, [str(a) for a in ["import", path, "--format", "tdms", "--map", "time=Rig/t,position=Rig/x,"
                                        "force=Rig/F", "--units", "time=s,position=mm,force=N", "--specimen", ROLL,
                                        "--protocol-kind", "tensile", "--out", tmp_path / "out.nc"]])
    out, err = capfd.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and "WARNING" not in err, err  # npTDMS's own log lines are kept, not printed
    assert path.name in lines[0] and "allowed" in lines[0], lines[0]
    assert not (tmp_path / "out.nc").exists()


def test_out_with_invalid_utf8_bytes_is_refused_before_the_run(capsys, tmp_path):
    import os

    out = Path(os.fsdecode(bytes(tmp_path) + b"/run-\xff\xfe.nc"))  # bytes no encoding can store as text
    rc = run_cli(cli, ["run", str(GOOD_PROTOCOL), "--specimen", str(GOOD_SPECIMEN), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert ".nc: out: " in err[0] and "UTF-8" in err[0] and "allowed" in err[0], err[0]
    assert list(tmp_path.iterdir()) == []  # refused before anything was journaled


@pytest.mark.parametrize("length", [300, 251])  # over 255 bytes; over 255 with the journal's ".part"
def test_out_with_a_name_the_file_system_does_not_take_is_refused_before_the_run(capsys, tmp_path, length):
    import os

    if os.pathconf(tmp_path, "PC_NAME_MAX") != 255:
        pytest.skip("the file system here does not take 255-byte names")
    out = tmp_path / ("r" * (length - 3) + ".nc")
    rc = run_cli(cli, ["run", str(GOOD_PROTOCOL), "--specimen", str(GOOD_SPECIMEN), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert f"is {length} bytes" in err[0] and "at most 250 bytes" in err[0], err[0]
    assert len(err[0]) < 400  # the name is not printed whole
    assert list(tmp_path.iterdir()) == []


def test_recover_a_journal_whose_name_is_not_utf8(capsys, tmp_path):
    """A journal under a name no dataset can take (left by an older version or another tool): recover says
    how to get its samples, and --out elsewhere gets every one."""
    import os

    from rdea_lab.store import JournalWriter, journal_path, open_run

    good = tmp_path / "run.nc"
    writer = JournalWriter(good, {"title": "t", "sample_rate": 100.0})
    import numpy as np
    t = np.arange(250) / 100.0
    writer.append({"time": t, "stretch": 1 + 0 * t, "voltage": 0 * t, "force": 0 * t})
    writer._release()  # the process that wrote it died: its lock is gone with it
    os.close(writer._fd)
    bad = Path(os.fsdecode(bytes(tmp_path) + b"/run-\xff.nc.part"))
    os.rename(journal_path(good), bad)
    rc = run_cli(cli, ["recover", str(bad)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "UTF-8" in err[0] and "--out" in err[0], err
    rescued = tmp_path / "rescued.nc"
    assert run_cli(cli, ["recover", str(bad), "--out", str(rescued)]) == 0
    ds = open_run(rescued)
    np.testing.assert_array_equal(ds["time"].values, t)
    ds.close()
