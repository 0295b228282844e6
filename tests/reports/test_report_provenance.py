"""What each row of the validation report says: its role, its origin and where it leaves the calibration.

Facts come from what the tests construct, not from the report: the record's sha256s (hashlib on the
files), attributes written into copies of twin runs, an envelope chosen below the runs' stretch, the
files' own maximum stretch (read with xarray).
"""

import csv
import hashlib
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from rdea_lab.cli.errors import run
from rdea_lab.cli.main import cli
from rdea_lab.reports.html import HASH_CHARS
from rdea_lab.reports.validation import COLUMNS

ROOT = Path(__file__).resolve().parents[2]
TABLE3 = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
#: Longest text a table cell may hold without a break opportunity (a space or <wbr>): a 12-character hash,
#: an ISO 8601 time (20), a 2.6kV protocol's last piece; a 64-character hash or a path would break a
#: 1400 px page.
MAX_UNBROKEN = 24


def sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def record(tmp_path, runs, envelope=None) -> Path:
    """TABLE3 with a calibration record that names ``runs`` (paths) as fitted, by their sha256."""
    section = {"model": "su", "metric": "rms", "objective": 0.001, "runs": [
        {"file": str(p), "protocol": p.stem, "specimen": xr.open_dataset(p).attrs["specimen_id"], "sha256": sha(p)}
        for p in runs]}
    if envelope is not None:
        section["validation"] = {"envelope": envelope}
    path = tmp_path / "cal.yaml"
    path.write_text(TABLE3.read_text() + yaml.safe_dump({"calibration": section}))
    return path


def rewrite(path: Path, **attrs) -> None:
    """Set attributes of a dataset file in place."""
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    ds.attrs.update(attrs)
    ds.to_netcdf(path.with_suffix(".tmp"))
    path.with_suffix(".tmp").replace(path)


@pytest.fixture(scope="module")
def fitted_specimen1(validate, twin_folder, tmp_path_factory):
    """Calibrated on specimen 1's 0 V tensile run only: the report on all five twin runs."""
    tmp = tmp_path_factory.mktemp("roles")
    fitted = twin_folder / "specimen1" / "tensile_ramp_sine_0V.nc"
    return validate(record(tmp, [fitted]), twin_folder, tmp / "out", figures=False), fitted


def test_roles_are_per_run_from_the_records_sha256(fitted_specimen1):
    result, fitted = fitted_specimen1
    roles = {Path(r["file"]).relative_to(fitted.parents[1]).as_posix(): r["role"] for r in result.rows}
    assert roles == {"specimen1/tensile_ramp_sine_0V.nc": "calibration run",
                     "specimen1/tensile_ramp_sine_2.6kV.nc": "held out (same specimen)",
                     "specimen1/blocking_force.nc": "held out (same specimen)",
                     "specimen1/capacitance_sweep.nc": "held out (same specimen)",
                     "specimen2/tensile_ramp_sine_0V.nc": "other specimen"}


def test_envelope_of_the_fitted_run_flags_what_leaves_it(fitted_specimen1):
    """Fitted at 0 V on one protocol: the 2.6 kV runs leave it in voltage, the same protocol on another
    specimen does not leave it (same stretch and rate history)."""
    result, _ = fitted_specimen1
    by_name = {(r["specimen"], r["name"]): r for r in result.rows}
    assert by_name[("specimen-1", "tensile_ramp_sine_0V")]["flags"] == ()
    assert by_name[("specimen-2", "tensile_ramp_sine_0V")]["flags"] == ()
    assert by_name[("specimen-1", "tensile_ramp_sine_0V")]["beyond_calibration"] == "—"
    for name in ("tensile_ramp_sine_2.6kV", "blocking_force"):
        assert any(re.fullmatch(r"voltage 2.6 kV beyond the calibrated 0 V", f)
                   for f in by_name[("specimen-1", name)]["flags"]), by_name[("specimen-1", name)]["flags"]
    assert "computed from the 1 fitted run(s)" in result.caption


def test_an_envelope_in_the_record_is_the_one_used(validate, twin_folder, tmp_path):
    """A record whose envelope stops at stretch 1.2: every run stretched further is flagged, by its own
    maximum stretch read from the file."""
    fitted = twin_folder / "specimen2" / "tensile_ramp_sine_0V.nc"
    env = {"stretch": [1.0, 1.2], "rate_per_s": [0.001, 10.0], "voltage_V": [-10.0, 3000.0], "hold_s": 1000.0}
    result = validate(record(tmp_path, [fitted], env), twin_folder, tmp_path / "out", figures=False)
    assert "the record's calibration.validation.envelope" in result.caption
    for r in result.rows:
        with xr.open_dataset(r["file"]) as ds:
            top = float(np.max(ds["stretch"].values))
        assert r["max_stretch"] == pytest.approx(top)
        beyond = [f for f in r["flags"] if f.startswith("stretch")]
        assert (beyond == [f"stretch {top:.3g} beyond the calibrated 1.2"]) == (top > 1.2 * 1.001), (r["name"], top)
    assert any(r["flags"] for r in result.rows)


def test_an_unreadable_record_envelope_exits_2_with_one_line(twin_folder, tmp_path, capsys):
    fitted = twin_folder / "specimen2" / "tensile_ramp_sine_0V.nc"
    params = record(tmp_path, [fitted], {"stretch": [1.0]})
    code = run(cli, ["report", "validation", "--params", str(params), "--datasets", str(twin_folder / "specimen2"),
                     "--out", str(tmp_path / "o"), "--no-figures"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "cal.yaml: calibration.validation.envelope: unreadable" in err


def test_without_a_record_nothing_is_checked_and_it_says_so(validate, twin_folder, tmp_path):
    result = validate(TABLE3, twin_folder / "specimen2", tmp_path, figures=False)
    (row,) = result.rows
    assert row["role"] == "none recorded" and row["beyond_calibration"] == "not checked (no envelope)"
    assert "no calibration record: no envelope" in result.caption


@pytest.fixture(scope="module")
def origins(validate, twin_folder, tmp_path_factory):
    """Copies of three twin runs: one imported (with a credit), one from the emulator, one from a physical rig."""
    tmp = tmp_path_factory.mktemp("origins")
    folder = tmp / "runs"
    folder.mkdir()
    made = {"imported": ("specimen1", "tensile_ramp_sine_0V"), "emulated": ("specimen1", "tensile_ramp_sine_2.6kV"),
            "physical": ("specimen2", "tensile_ramp_sine_0V")}
    for name, (card, proto) in made.items():
        shutil.copy(twin_folder / card / f"{proto}.nc", folder / f"{name}.nc")
    rewrite(folder / "imported.nc", backend="import", source_file="strip_0d01.csv", source_format="csv",
            source_sha256="ab" * 32, source_credit="Jane Doe, Example Lab (2025)")
    rewrite(folder / "emulated.nc", backend="rig", emulated=1, emulator_truth='{"name": "toy-truth"}')
    rewrite(folder / "physical.nc", backend="rig", emulated=0, rig_idn="ACME,LOADFRAME,42,1.0")
    result = validate(record(tmp, [folder / "imported.nc"]), folder, tmp / "out", figures=False)
    return result, folder


def test_origin_of_each_run_is_what_its_file_says(origins, read_page):
    result, _ = origins
    got = {r["name"]: (r["origin"], r["source_credit"]) for r in result.rows}
    assert got == {"imported": ("import", "Jane Doe, Example Lab (2025)"), "emulated": ("emulator", ""),
                   "physical": ("rig", "")}
    banner = re.search(r'<p class="banner">(.*?)</p>', Path(result.files["html"]).read_text()).group(1)
    assert "1 of 3 runs are measurements imported from other files (strip_0d01.csv)" in banner
    assert "Jane Doe, Example Lab (2025)" in banner  # the credit, on the page
    assert "EMULATOR (truth: toy-truth)" in banner and "1 of 3 runs come from a physical rig" in banner
    assert "do not say they are emulated" not in banner
    page = read_page(result.files["html"])
    for text in ("imported from strip_0d01.csv (csv, sha256 abababababab); credit: Jane Doe, Example Lab (2025)",
                 "rdea-lab rig emulator, truth toy-truth", "physical rig (ACME,LOADFRAME,42,1.0)"):
        assert text in page.text  # the provenance table
    with open(result.files["csv"], newline="") as fh:
        back = {r["name"]: r for r in csv.DictReader(fh)}
    assert back["imported"]["source_credit"] == "Jane Doe, Example Lab (2025)"
    assert back["imported"]["source_file"] == "strip_0d01.csv" and back["emulated"]["origin"] == "emulator"


def test_every_rendering_has_the_rows_name_protocol_rate_stretch_role_and_flags(origins):
    """One line per run in md and tex, one record in csv, one row in html, each with the same fields."""
    result, _ = origins
    files = result.files
    md = Path(files["markdown"]).read_text()
    tex = Path(files["latex"]).read_text()
    page = Path(files["html"]).read_text().replace("<wbr>", "")
    with open(files["csv"], newline="") as fh:
        back = {r["name"]: r for r in csv.DictReader(fh)}
    headers = [h for _, h, _ in COLUMNS]
    for h in ("run", "protocol", "rate [/s]", "max. stretch", "data", "role", "beyond the calibration"):
        assert h in headers
        assert f"| {h} |" in md and f"<th>{h}</th>" in page
    for r in result.rows:
        fields = [r["name"], r["protocol"], f"{r['rate_per_s']:.3g}", r["role"], r["origin"]]
        line = next(ln for ln in md.splitlines()
                    if ln.startswith(f"| {r['experiment']} |") and f"| {r['name']} |" in ln)
        row = next(tr for tr in re.findall(r"<tr>(.*?)</tr>", page) if f"<td>{r['name']}</td>" in tr)
        texline = next(ln for ln in tex.splitlines() if r["name"] in ln and ln.endswith(r"\\"))
        for f in fields:
            assert f"| {f} |" in line and f">{f}<" in row and f in texline.replace(r"\_", "_"), (f, r["name"])
        b = back[r["name"]]
        assert (b["protocol"], b["role"], b["origin"]) == (r["protocol"], r["role"], r["origin"])
        assert float(b["rate_per_s"]) == r["rate_per_s"] and float(b["max_stretch"]) == r["max_stretch"]
        assert b["beyond_calibration"] == r["beyond_calibration"]
    flagged = [r for r in result.rows if r["flags"]]
    assert flagged  # the 2.6 kV run, fitted at 0 V
    for r in flagged:
        assert r["beyond_calibration"] in md and r["beyond_calibration"] in page


def test_html_tables_fit_the_page_and_hashes_are_short(fitted_specimen1, read_page):
    result, _ = fitted_specimen1
    page = read_page(result.files["html"])
    longest = page.longest_unbreakable()
    assert len(longest) <= MAX_UNBROKEN, longest
    assert not [c for c in page.cells if re.search(r"[0-9a-f]{13,}", c)]  # no hash shown longer than 12 characters
    for r in result.rows:
        full = sha(r["file"])
        assert full in page.attrs and f"{full[:HASH_CHARS]}…" in page.cells
        with open(result.files["csv"], newline="") as fh:
            assert full in {b["sha256"] for b in csv.DictReader(fh)}  # the CSV keeps the whole hash
