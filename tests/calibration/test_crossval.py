"""Cross-validation (issue 13) on the five VHB 4910 files of ../shared/data: folds, held-out predictions, CLI.

The expected groups come from the file names (``0dRR_SdS[_k]``: rate 0.RR 1/s, stretch S.S, as the data
folder's README says), not from the code that groups them by the data. Fits run 1R at 0 V (uniaxial,
cheap) with a small evaluation budget: they test the plumbing, not the quality of the fit.
"""

import csv
import re
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml
from vhb_data import needs_vhb

from rdea_lab.calibration import Budget, cross_validate, goodness, load_run, predict_force
from rdea_lab.calibration.crossval import CSV_KEYS, make_folds
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import SpecError, load_params

ROOT = Path(__file__).resolve().parents[2]
pytestmark = needs_vhb
FAST = {"model": "1r", "budget": Budget(evaluations=200)}


#: The five loading-unloading files (``0dRR_SdS[_k]``); the folder also holds a step-and-hold test, relax_2d0.
NAMED = re.compile(r"0d\d\d_\dd\d(_\d+)?")


@pytest.fixture(scope="module")
def runs(imported):
    return [load_run(p) for p in sorted(imported.glob("*.nc")) if NAMED.fullmatch(p.stem)]


def from_name(path):
    m = re.fullmatch(r"0d(\d\d)_(\d)d(\d)(_\d+)?", Path(path).stem)
    return float(f"0.{m.group(1)}"), float(f"{m.group(2)}.{m.group(3)}")


def held_out(runs, folds):
    return [sorted(runs[i].path.name for i in pred) for _, _, pred in folds]


def expected_groups(runs, which):
    groups = {}
    for r in runs:
        groups.setdefault(from_name(r.path)[which], []).append(r.path.name)
    return [sorted(v) for _, v in sorted(groups.items())]


def test_leave_one_out_gives_one_fold_per_file(runs):
    folds = make_folds(runs, "leave-one-out")
    assert len(folds) == 5
    for k, (label, fit, pred) in enumerate(folds):
        assert pred == [k] and sorted(fit + pred) == list(range(5)) and label == runs[k].path.name


def test_by_stretch_gives_the_two_stretches_of_the_file_names(runs):
    folds = make_folds(runs, "by-stretch")
    assert len(folds) == 2
    assert held_out(runs, folds) == expected_groups(runs, 1)  # {1.5: three files}, {3.0: two}
    assert [f[0] for f in folds] == ["stretch 1.5", "stretch 3.0"]
    for _, fit, pred in folds:
        assert not set(fit) & set(pred) and sorted(fit + pred) == list(range(5))


def test_by_rate_gives_the_three_rates_of_the_file_names(runs):
    folds = make_folds(runs, "by-rate")
    assert len(folds) == 3
    assert held_out(runs, folds) == expected_groups(runs, 0)
    assert [f[0] for f in folds] == ["rate 0.01 /s", "rate 0.03 /s", "rate 0.05 /s"]


def test_one_group_is_refused(runs):
    same_stretch = [r for r in runs if from_name(r.path)[1] == 1.5]
    with pytest.raises(SpecError, match=r"^arguments: cv: by-stretch gives 1 group .*allowed: inputs that make "
                                        r"at least 2 groups$"):
        make_folds(same_stretch, "by-stretch")


def test_holdout_prediction_is_predict_force_with_the_folds_parameters(imported, tmp_path):
    """Fit the 0.05 /s, 1.5 run; predict the 0.03 /s, 1.5 run (a slower rate) and the 0.05 /s, 3.0 run
    (a larger stretch): each is flagged for what it goes beyond, and its errors are those of
    `predict_force` with the fold's parameters on the run read again from its file."""
    fit, slower, further = (imported / f"{n}.nc" for n in ("0d05_1d5_1", "0d03_1d5_1", "0d05_3d0"))
    out = tmp_path / "ho.yaml"
    cvr = cross_validate([fit, slower, further], holdout=[slower, further], out=out, **FAST)
    (fold,) = cvr.folds
    assert fold.fitted == ("0d05_1d5_1.nc",) and fold.predicted == ("0d03_1d5_1.nc", "0d05_3d0.nc")
    rows = {r["file"]: r for r in cvr.rows()}
    assert rows["0d05_1d5_1.nc"]["role"] == "fitted" and rows["0d05_1d5_1.nc"]["flags"] == ()
    for path in (slower, further):
        run = load_run(path)
        g = goodness(run, predict_force(run, load_params(out), "1r"))
        row = rows[path.name]
        assert row["role"] == "predicted"
        for k in ("max_rel_error", "rms_rel_error", "p99_rel_error", "rms_error_N"):
            assert row[k] == pytest.approx(g[k], rel=1e-9), k  # the record's YAML rounds nothing: same numbers
    assert rows["0d05_3d0.nc"]["flags"] == ("stretch 3.0 beyond the calibrated 1.5",)
    (flag,) = rows["0d03_1d5_1.nc"]["flags"]
    m = re.fullmatch(r"rate (\S+) /s below the calibrated (\S+)-(\S+) /s", flag)
    # the 1st percentile of a 0.03 /s ramp's rates, against the 1st-99th of a 0.05 /s one: within 1 %
    assert [float(x) for x in m.groups()] == pytest.approx([0.03, 0.05, 0.05], rel=0.01), flag
    # beside the record: the held-out rows as csv, and in the record under calibration.validation
    with open(tmp_path / "ho.holdout.csv", newline="") as fh:
        back = list(csv.DictReader(fh))
    assert [b["file"] for b in back] == ["0d03_1d5_1.nc", "0d05_3d0.nc"]
    assert float(back[1]["p99_rel_error"]) == rows["0d05_3d0.nc"]["p99_rel_error"]
    doc = yaml.safe_load(out.read_text())
    val = doc["calibration"]["validation"]
    assert [h["file"] for h in val["held_out"]] == ["0d03_1d5_1.nc", "0d05_3d0.nc"]
    assert val["held_out"][1]["beyond_calibration"] == ["stretch 3.0 beyond the calibrated 1.5"]
    assert val["envelope"]["stretch"][1] == pytest.approx(1.5, abs=1e-3)
    assert [r["file"] for r in doc["calibration"]["runs"]] == [str(fit)]  # the record: the fitted run only
    assert "rms_rel_error" in doc["calibration"]["runs"][0] and "p99_rel_error" in doc["calibration"]["runs"][0]


def test_cli_cv_writes_the_folder_and_prints_the_table(imported, tmp_path, capsys):
    a, b = imported / "0d05_1d5_1.nc", imported / "0d05_3d0.nc"
    out = tmp_path / "cv"
    rc = run_cli(cli, ["calibrate", str(a), str(b), "--model", "1r", "--max-evals", "200", "--quiet",
                       "--cv", "by-stretch", "--out", str(out)])
    stdout = capsys.readouterr().out
    assert rc == 0, stdout
    with open(out / "cv.csv", newline="") as fh:
        back = list(csv.DictReader(fh))
    assert [(r["fold"], r["role"], r["file"]) for r in back] == [
        ("1", "fitted", b.name), ("1", "predicted", a.name), ("2", "fitted", a.name), ("2", "predicted", b.name)]
    assert back[3]["flags"] == "stretch 3.0 beyond the calibrated 1.5" and back[1]["flags"] == ""
    for k in (1, 2):
        fold = load_params(out / f"fold-{k}.yaml")
        assert float(back[2 * k - 1]["C10_Pa"]) == pytest.approx(fold.C10, rel=1e-5)  # the record: 6 digits
    md = (out / "cv.md").read_text()
    assert "max/peak" in md and "rms/peak" in md and "p99/peak" in md and "Legend:" in md
    # the 200 evaluations end each fold's fit before it converges: the table and each fold's line say so
    assert {r["fold_converged"] for r in back} == {"False"}
    assert md.count("200 evaluations, ") == 2 and md.count(
        ", not converged (stopped at the evaluation budget of 200 evaluations); ") == 2
    last = stdout.split("Legend:")[0].strip().splitlines()[-1]  # the table's last row: fold 2's prediction
    assert re.match(r"\| 2 +\| stretch 3.0 +\| predicted +\| 0d05_3d0.nc ", last), last
    assert "stretch 3.0 beyond the calibrated 1.5" in stdout and "Legend:" in stdout


def test_cli_holdout_prints_the_fit_and_the_held_out_row(imported, tmp_path, capsys):
    a, b = imported / "0d05_1d5_1.nc", imported / "0d03_1d5_1.nc"
    out = tmp_path / "h.yaml"
    rc = run_cli(cli, ["calibrate", str(a), str(b), "--holdout", str(b), "--model", "1r", "--max-evals", "200",
                       "--quiet", "--out", str(out)])
    stdout = capsys.readouterr().out
    assert rc == 0, stdout
    assert "rms/peak" in stdout and "p99/peak" in stdout  # fit_report's per-run line
    assert "0d03_1d5_1.nc" in stdout.split("Legend:")[0].strip().splitlines()[-1]  # the last row: held out
    assert (tmp_path / "h.holdout.csv").is_file() and load_params(out).C10 > 0


@pytest.mark.parametrize("extra, message", [
    (["--holdout", "{elsewhere}"], r"--holdout: .*elsewhere.nc is not among the inputs; allowed: one of "),
    (["--cv", "by-stretch", "--only15"], r"--cv: by-stretch gives 1 group \(stretch 1.5: .*\); allowed: inputs "
                                         r"that make at least 2 groups"),
    (["--cv", "k-fold"], r"--cv: 'k-fold'; allowed: leave-one-out, by-rate, by-stretch"),
    (["--cv", "by-rate", "--holdout", "{a}"], r"--cv: not together with --holdout; allowed: one of them"),
    (["--holdout", "{a}", "--holdout", "{b}"], r"--holdout: every input is held out; allowed: "),
])
def test_cli_exit_2_with_one_line_naming_the_option(imported, tmp_path, capsys, extra, message):
    a, b = imported / "0d05_1d5_1.nc", imported / "0d03_1d5_1.nc"
    inputs = [str(a), str(b)] if "--only15" in extra else [str(a), str(imported / "0d05_3d0.nc")]
    if "--holdout" in extra and "{b}" in extra:
        inputs = [str(a), str(b)]
    extra = [e.format(elsewhere=tmp_path / "elsewhere.nc", a=a, b=b) for e in extra if e != "--only15"]
    rc = run_cli(cli, ["calibrate", *inputs, *extra, "--max-evals", "20", "--quiet", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1 and re.search(message, err), err
    assert not (tmp_path / "o").exists()  # refused before any fit


def test_out_folder_without_cv_is_refused(imported, tmp_path, capsys):
    rc = run_cli(cli, ["calibrate", str(imported / "0d05_1d5_1.nc"), "--max-evals", "20", "--quiet",
                       "--out", str(tmp_path)])
    assert rc == 2 and "is a directory" in capsys.readouterr().err


def test_fold_done_is_called_after_each_fold_with_its_fit_and_rows(imported):
    seen = []
    cv = cross_validate(imported, cv="by-stretch", **FAST,
                        monitor=SimpleNamespace(fold_done=lambda *a: seen.append(a)))  # its one method
    assert [s[:2] for s in seen] == [(k, len(cv.folds)) for k in range(1, len(cv.folds) + 1)]
    for (k, _, fold, rows), expected in zip(seen, cv.folds):
        assert fold is expected
        assert list(rows) == cv.rows(fold=k)
        # the table gives back the Python values the fold made (a float a float, a missing sha256 None)
        assert [[type(v) for v in r.values()] for r in rows] == [[type(v) for v in r.values()]
                                                                  for r in cv.rows(fold=k)]
    assert list(cv.table.columns) == CSV_KEYS
    assert len(cv.table) == sum(len(f.fitted) + len(f.predicted) for f in cv.folds)
    assert cv.table["rms_rel_error"].dtype == float and cv.table["fold"].dtype.kind == "i"
    ft = cv.fold_table
    assert list(ft["fold"]) == [f.index for f in cv.folds] and list(ft["nfev"]) == [f.nfev for f in cv.folds]
    assert list(ft["held_out"]) == [f.label for f in cv.folds]
    assert list(ft["C10_Pa"]) == [f.params.C10 for f in cv.folds] and list(ft["record"]) == [""] * len(cv.folds)


def test_cli_cv_prints_each_fold_done_on_stderr(imported, tmp_path, capsys):
    assert run_cli(cli, ["calibrate", str(imported), "--model", "1r", "--max-evals", "200", "--cv", "by-stretch",
                         "--out", str(tmp_path / "cv")]) == 0
    err = capsys.readouterr().err
    done = [line for line in err.splitlines() if " done: " in line]
    assert [line.split(" done:")[0] for line in done] == [f"fold {k}/{len(done)}" for k in range(1, len(done) + 1)]
    assert len(done) >= 2 and all("200 evaluations" in line for line in done)  # FAST's budget ends each fit
