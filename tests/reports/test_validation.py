"""`rdea-lab report`: the Table 4 analogue against facts that do not come from its output.

The datasets are made by the twin itself (SU, Table 3 parameters), so a
report with the same parameters must find no error at all, and a report with
C10 raised by a known amount must find the error a hand calculation predicts.
"""

import csv
import hashlib
import re
import shutil
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
import xarray as xr
import yaml

from rdea_lab.calibration import goodness, load_run, predict_force
from rdea_lab.cli.errors import run
from rdea_lab.cli.main import cli as main_cli
from rdea_lab.reports.tables import latex_escape
from rdea_lab.reports.validation import COLUMNS, ReportInputError, validation_report
from rdea_lab.specs import dump_params, load_params

ROOT = Path(__file__).resolve().parents[2]
TABLE3 = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def report_cli():
    return main_cli


def _perturbed(path: Path, factor: float) -> Path:
    p = load_params(TABLE3)
    path.write_text(dump_params(p.replace(name=f"c10x{factor}", C10=p.C10 * factor)))
    return path


@pytest.fixture(scope="module")
def same(validate, twin_folder, tmp_path_factory):
    return validate(TABLE3, twin_folder, tmp_path_factory.mktemp("same"))


@pytest.fixture(scope="module")
def plus10(validate, twin_folder, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plus10")
    return validate(_perturbed(tmp / "p.yaml", 1.10), twin_folder, tmp / "out", figures=False)


def _row(result, specimen, experiment, voltage):
    rows = [r for r in result.rows
            if (r["specimen"], r["experiment"], r["voltage"]) == (specimen, experiment, voltage)]
    assert len(rows) == 1, (specimen, experiment, voltage)
    return rows[0]


def test_one_row_per_run_labelled_as_table4(same):
    got = {(r["experiment"], r["voltage"], r["specimen"]) for r in same.rows}
    assert got == {("tensile (force)", "0 V", "specimen-1"), ("tensile (force)", "2.60 kV", "specimen-1"),
                   ("blocking force", "0 V to 2.60 kV", "specimen-1"), ("capacitance", "0 V", "specimen-1"),
                   ("tensile (force)", "0 V", "specimen-2")}
    # the paper's Table 4 beside ours
    assert _row(same, "specimen-1", "tensile (force)", "0 V")["paper_max_rel_error"] == 0.0320
    assert _row(same, "specimen-1", "tensile (force)", "2.60 kV")["paper_max_rel_error"] == 0.0613
    assert _row(same, "specimen-1", "blocking force", "0 V to 2.60 kV")["paper_max_rel_error"] == 0.0090
    assert _row(same, "specimen-1", "capacitance", "0 V")["paper_max_rel_error"] == 0.0499
    assert _row(same, "specimen-2", "tensile (force)", "0 V")["paper_max_rel_error"] == 0.0519


def test_the_twin_reproduces_itself(same):
    """Same model, same parameters, same histories: only rounding differs (the report's SU basis and
    whole-run branch scan against the twin's block-wise solve), far below 1e-9 of the peak."""
    for r in same.rows:
        assert r["max_rel_error"] < 1e-9, r
        assert r["excluded"] == 0
    cap = _row(same, "specimen-1", "capacitance", "0 V")
    assert cap["quantity"] == "capacitance" and cap["unit"] == "F"
    assert cap["samples"] > 1000  # the sweep measures capacitance throughout (at 0 V)


def test_no_calibration_record_is_said(same):
    assert {r["calibrated_on"] for r in same.rows} == {"none recorded"}
    assert "none recorded" in same.caption


def test_c10_plus_10_percent_gives_the_hand_calculated_tensile_error(plus10):
    """0 V tensile, SU: F = A/lambda (b W'(x) + overstress), W' = C10 + 2 C20 x + 3 C30 x^2, so raising
    C10 by dC shifts F by A/lambda b dC, largest at the top stretch 1.5 where the force peaks too:
    error = dC / W'(x) there (the overstress at the turning point is ~k tau * rate = 0, tau = 10 ms).
    x = 1.5^2 + 2/1.5 - 3 = 0.58333; W' = 242 - 2*69*0.58333 + 3*47*0.58333^2 = 209.48 kPa;
    error = 24.2 / 209.48 = 0.1155. Tolerance 2 %: the sampled top may miss 1.5 by a little."""
    err0 = _row(plus10, "specimen-1", "tensile (force)", "0 V")["max_rel_error"]
    assert err0 == pytest.approx(24.2 / 209.48, rel=0.02)
    # the same shift against a peak force lowered by the Maxwell stress: larger relative error
    assert _row(plus10, "specimen-1", "tensile (force)", "2.60 kV")["max_rel_error"] > err0
    # same geometry law for specimen 2 (the error is a stress ratio, independent of the cross-section)
    assert _row(plus10, "specimen-2", "tensile (force)", "0 V")["max_rel_error"] == pytest.approx(err0, rel=1e-6)
    assert _row(plus10, "specimen-1", "blocking force", "0 V to 2.60 kV")["max_rel_error"] > 0.05


def test_force_rows_use_the_calibration_metric(plus10, tmp_path):
    """The rows' metric is the calibration's per-run goodness (Table 4's), on the same prediction."""
    params = load_params(_perturbed(tmp_path / "p.yaml", 1.10))
    for r in plus10.rows:
        if r["kind"] == "tensile":
            run_data = load_run(Path(r["file"]))
            g = goodness(run_data, predict_force(run_data, params, "su"))
            assert r["max_rel_error"] == pytest.approx(g["max_rel_error"], rel=1e-12)
            assert r["rms_error"] == pytest.approx(g["rms_error_N"], rel=1e-12)


def test_capacitance_does_not_depend_on_c10(plus10):
    """SU capacitance is C0 lambda1 (eq. 41): no Yeoh coefficient in it."""
    assert _row(plus10, "specimen-1", "capacitance", "0 V")["max_rel_error"] < 1e-9


def test_error_scales_linearly_with_the_perturbation(validate, twin_folder, plus10, tmp_path):
    """The SU force is linear in C10, so dF doubles exactly from +5 % to +10 %."""
    plus5 = validate(_perturbed(tmp_path / "p.yaml", 1.05), twin_folder, tmp_path / "out", figures=False)
    for r10 in plus10.rows:
        if r10["quantity"] != "force":
            continue
        r5 = next(r for r in plus5.rows if r["file"] == r10["file"])
        assert r10["max_rel_error"] / r5["max_rel_error"] == pytest.approx(2.0, rel=1e-9)


def test_csv_reads_back_to_the_returned_rows(same):
    with open(same.files["csv"], newline="") as fh:
        back = list(csv.DictReader(fh))
    assert len(back) == len(same.rows)
    for b, r in zip(back, same.rows):
        assert b["file"] == r["file"] and b["sha256"] == r["sha256"] and b["specimen"] == r["specimen"]
        assert float(b["max_rel_error"]) == r["max_rel_error"]
        assert float(b["rms_error"]) == r["rms_error"]
        assert int(b["samples"]) == r["samples"]
        assert (float(b["paper_max_rel_error"]) if b["paper_max_rel_error"] else None) == r["paper_max_rel_error"]


def test_latex_is_a_valid_tabular(same):
    tex = Path(same.files["latex"]).read_text()
    body = tex[tex.index(r"\begin{tabular}"):]
    spec = re.match(r"\\begin\{tabular\}\{([lcr|]+)\}", body)
    assert spec and len(spec.group(1).replace("|", "")) == len(COLUMNS)
    assert body.rstrip().endswith(r"\end{tabular}")
    lines = [ln for ln in body.splitlines()[1:-1] if ln != r"\hline"]
    assert len(lines) == len(same.rows) + 1  # header + one line per row
    for ln in lines:
        assert ln.endswith(r" \\")
        assert len(re.findall(r"(?<!\\)&", ln)) == len(COLUMNS) - 1
        assert not re.search(r"(?<!\\)[%_#$]", ln), ln
    assert r"[\%]" in lines[0]
    for line in tex.splitlines():  # the caption comment line may hold %, but only escaped after the first
        assert not re.search(r"(?<!\\)[%_]", line.lstrip("% ")), line


def test_latex_escape():
    assert latex_escape("5 %_a&b") == r"5 \%\_a\&b"
    assert latex_escape("λ1") == r"$\lambda$1"


def test_index_html_shows_every_run_and_its_hash_and_no_urls(same, read_page):
    page = Path(same.files["html"]).read_text()
    shown = read_page(same.files["html"])
    assert len(same.rows) == 5  # the twin_folder fixture's five runs (tests/reports/conftest.py)
    for r in same.rows:
        path = Path(r["file"])
        assert str(path) in shown.text
        assert hashlib.sha256(path.read_bytes()).hexdigest() in shown.attrs  # on hover (title=)
    assert "http" not in page and "<script" not in page
    assert "twin simulations" in page  # the data are said to be simulated, not measured
    assert hashlib.sha256(TABLE3.read_bytes()).hexdigest() in shown.attrs
    for f in same.figures:
        assert Path(f).stat().st_size > 10_000 and Path(f).name in page
    names = {Path(f).name for f in same.figures}
    assert {"blocking_force.png", "capacitance.png", "tensile_specimen-1_tensile_ramp_sine_0V.png"} <= names


def test_calibration_record_marks_roles_and_emulated_data_is_said(validate, twin_folder, tmp_path, read_page):
    """A folder where two runs claim to come from the emulator, one run is aborted, and a parameter
    file whose calibration record names the specimen-2 tensile run."""
    folder = tmp_path / "runs"
    for card, proto in [("specimen1", "tensile_ramp_sine_0V"), ("specimen1", "tensile_ramp_sine_2.6kV"),
                        ("specimen2", "tensile_ramp_sine_0V")]:
        (folder / card).mkdir(parents=True, exist_ok=True)
        shutil.copy(twin_folder / card / f"{proto}.nc", folder / card / f"{proto}.nc")
    for name, attrs in (("specimen1/tensile_ramp_sine_0V.nc", {"emulated": "yes: data from the rdea-lab rig "
                                                               "emulator, not a physical rig",
                                                               "emulator_truth": '{"name": "toy-truth"}'}),
                        ("specimen1/aborted.nc", {"status": "aborted"})):
        src = folder / "specimen1" / "tensile_ramp_sine_2.6kV.nc" if "aborted" in name else folder / name
        with xr.open_dataset(src) as ds:
            ds = ds.load()
        ds.attrs.update(attrs)
        ds.to_netcdf(folder / (name + ".tmp"))
        (folder / (name + ".tmp")).replace(folder / name)
    cal_run = folder / "specimen2" / "tensile_ramp_sine_0V.nc"
    record = {"calibration": {"model": "su", "metric": "rms", "objective": 0.001, "runs": [
        {"file": str(cal_run), "protocol": "tensile_ramp_sine_0V", "specimen": "specimen-2",
         "sha256": hashlib.sha256(cal_run.read_bytes()).hexdigest()}]}}
    params = tmp_path / "cal.yaml"
    params.write_text(TABLE3.read_text() + yaml.safe_dump(record))
    result = validate(params, folder, tmp_path / "out", figures=False)
    roles = {(r["specimen"], r["voltage"]): (r["role"], r["calibrated_on"]) for r in result.rows}
    assert roles == {("specimen-1", "0 V"): ("other specimen", "specimen-2"),
                     ("specimen-1", "2.60 kV"): ("other specimen", "specimen-2"),
                     ("specimen-2", "0 V"): ("calibration run", "specimen-2")}
    # the envelope of the one fitted run (0 V, found among the datasets by its sha256): the 2.6 kV run leaves it
    flags = {(r["specimen"], r["voltage"]): r["flags"] for r in result.rows}
    assert flags[("specimen-2", "0 V")] == () and flags[("specimen-1", "0 V")] == ()
    assert any(f.startswith("voltage 2.6 kV beyond the calibrated 0 V") for f in flags[("specimen-1", "2.60 kV")])
    assert [Path(s["file"]).name for s in result.skipped] == ["aborted.nc"]
    page = Path(result.files["html"]).read_text()
    banner = re.search(r'<p class="banner">(.*?)</p>', page).group(1)
    assert "EMULATOR" in banner and "toy-truth" in banner and "not from a physical rig" in banner
    assert "aborted.nc" in page and "status aborted" in page
    assert "specimen-2/tensile_ramp_sine_0V" in read_page(result.files["html"]).text  # the runs fitted on


def test_auto_names_its_model_per_run(validate, twin_folder, tmp_path):
    result = validate(TABLE3, twin_folder / "specimen2", tmp_path, model="auto", figures=False)
    (row,) = result.rows
    assert row["model"] in {"su", "1r", "3r"} and row["notes"].startswith("auto: ")


def test_library_refuses_an_unknown_model(validate, twin_folder, tmp_path):
    with pytest.raises(ReportInputError, match="'5r' is not a model; allowed: su, 1r, 3r, cr, auto"):
        validate(TABLE3, twin_folder, tmp_path, model="5r")


def _one_line_exit_2(capsys, code, pattern):
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and re.search(pattern, err), err


def test_cli_report_writes_and_prints_the_table(report_cli, twin_folder, tmp_path, capsys):
    code = run(report_cli, ["report", "validation", "--params", str(TABLE3),
                            "--datasets", str(twin_folder / "specimen2"), "--out", str(tmp_path), "--no-figures"])
    out = capsys.readouterr().out
    assert code == 0
    assert "| tensile (force) | 0 V | specimen-2 |" in out and (tmp_path / "index.html").is_file()


@pytest.mark.parametrize("argv, pattern", [
    (["--params", "no/such.yaml", "--datasets", "{folder}"], r"no/such.yaml: file not found"),
    (["--params", str(TABLE3), "--datasets", "{empty}"], r"no complete runs found"),
    (["--params", str(TABLE3), "--datasets", "{folder}", "--model", "5r"], r"'5r' is not one of"),
    (["--params", str(TABLE3)], r"Missing option '--datasets'"),
    (["--params", str(TABLE3), "--datasets", "{folder}/none"], r"no such folder"),
])
def test_cli_bad_input_exits_2_with_one_line(report_cli, twin_folder, tmp_path, capsys, argv, pattern):
    (tmp_path / "empty").mkdir()
    argv = [a.format(folder=twin_folder, empty=tmp_path / "empty") for a in argv]
    _one_line_exit_2(capsys, run(report_cli, ["report", "validation", *argv, "--out", str(tmp_path / "o")]), pattern)


def test_cli_invalid_params_file_exits_2(report_cli, twin_folder, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(TABLE3.read_text().replace("C10: 242 kPa", "C10: -5 kPa"))
    code = run(report_cli, ["report", "validation", "--params", str(bad), "--datasets", str(twin_folder),
                            "--out", str(tmp_path)])
    _one_line_exit_2(capsys, code, r"bad.yaml: yeoh.C10")


def test_robust_measures_beside_table4s_are_numpy_formulas_on_the_runs_residual(twin_folder, plus10):
    """rms/peak and p99/peak (issue 13) against numpy on the twin's residual of the run, read again."""
    params = load_params(Path(plus10.files["csv"]).parents[1] / "p.yaml")  # the fixture's C10 x 1.1
    for r in plus10.rows:
        if r["quantity"] != "force" or r["kind"] == "blocking":
            continue
        run = load_run(r["file"])
        res = np.abs(predict_force(run, params, "su") - run.force)
        peak = np.max(np.abs(run.force))
        assert r["rms_rel_error"] == pytest.approx(np.sqrt(np.mean(res**2)) / peak, rel=1e-9)
        assert r["p99_rel_error"] == pytest.approx(np.percentile(res, 99) / peak, rel=1e-9)
        assert r["max_rel_error"] == pytest.approx(res.max() / peak, rel=1e-9)
        assert r["rms_rel_error"] <= r["p99_rel_error"] <= r["max_rel_error"]  # a smooth error: no outliers
    for r in plus10.rows:  # C10 moves every force (the 0 V capacitance does not depend on it)
        assert (r["rms_rel_error"] > 0 and r["p99_rel_error"] > 0) == (r["quantity"] == "force")


def test_every_rendering_has_the_new_columns_and_the_legend(same):
    md = Path(same.files["markdown"]).read_text()
    header = next(ln for ln in md.splitlines() if ln.startswith("| experiment"))
    assert "| max. rel. error [%] |" in header and "| rms/peak [%] |" in header and "| p99/peak [%] |" in header
    table_end = md.index(same.markdown) + len(same.markdown)
    assert md[table_end:].lstrip("\n").startswith(same.legend)  # the line right under the table
    for word in ("max. rel. error", "rms/peak", "p99/peak", "Table 4"):
        assert word in same.legend
    with open(same.files["csv"], newline="") as fh:
        back = list(csv.DictReader(fh))
    for b, r in zip(back, same.rows):
        assert float(b["rms_rel_error"]) == r["rms_rel_error"] and float(b["p99_rel_error"]) == r["p99_rel_error"]
    tex = Path(same.files["latex"]).read_text()
    assert r"rms/peak [\%]" in tex and r"p99/peak [\%]" in tex and latex_escape(same.legend) in tex
    page = Path(same.files["html"]).read_text()
    assert "<th>p99/peak [%]</th>" in page and "legend" in page and "99th percentile" in page


def test_the_report_is_computed_apart_from_its_files(same, twin_folder, tmp_path):
    """`validation_report` writes nothing; the frozen report's ``write`` returns every file it leaves in the
    folder (tables, PNG and PDF figures, index.html) and refuses a folder that holds them."""
    import dataclasses

    from rdea_lab.store.outputs import OutputError

    with pytest.raises(dataclasses.FrozenInstanceError):
        same.report.caption = ""
    assert list(same.report.table["name"]) == [r["name"] for r in same.rows]
    folder = Path(same.files["html"]).parent
    assert sorted(p.name for p in same.files.values()) == sorted(p.name for p in folder.iterdir())
    assert {p.suffix for p in same.files.values()} == {".md", ".csv", ".tex", ".png", ".pdf", ".html"}
    with pytest.raises(OutputError, match="exists and holds files"):
        same.report.write(folder)
    before = sorted(p.name for p in tmp_path.iterdir())
    validation_report(TABLE3, twin_folder / "specimen2")
    assert sorted(p.name for p in tmp_path.iterdir()) == before
