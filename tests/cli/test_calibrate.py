"""rdea_lab.cli.calibrate.FitProgress: how a fit's progress reads on a terminal and in a log."""

from types import SimpleNamespace

import pytest

from rdea_lab.cli.calibrate import FitProgress


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_in_a_log_a_line_every_ten_seconds_the_first_at_once(capsys):
    clock = Clock()
    progress = FitProgress(every=10.0, clock=clock)
    progress.tty = False
    for second in range(0, 31):  # the library reports twice a second; here once a second of the fake clock
        clock.t = float(second)
        progress(100 * second + 1, 1.0 / (second + 1), float(second))
    lines = capsys.readouterr().err.splitlines()
    assert [line.split()[1] for line in lines] == ["1", "1001", "2001", "3001"]  # at 0, 10, 20 and 30 s
    assert "\r" not in "".join(lines)


def test_on_a_terminal_one_line_redrawn_then_ended_by_a_stage_or_the_final_line(capsys):
    progress = FitProgress()
    progress.tty = True
    progress(10, 0.5, 0.5)
    progress(20, 0.25, 1.0)
    progress.stage(2, 4, "M = 1, spring a tenth as stiff")
    progress(30, 0.125, 1.5)
    progress.done(SimpleNamespace(nfev=35, objective=0.1, wall_time=1.75, converged=False,
                                  message="time budget 1.75 s reached"))
    err = capsys.readouterr().err
    assert err.count("\n") == 2  # the stage line and the final line; the status was redrawn in place
    first, second, rest = err.split("\r", 3)[1:]
    assert first.startswith("  evaluations     10") and second.startswith("  evaluations     20")
    assert "stage 2/4: M = 1, spring a tenth as stiff" in rest
    assert err.endswith("\rdone: 35 evaluations, best 1.000000e-01, 1.8 s, not converged "
                        "(time budget 1.75 s reached)\n")


def test_quiet_prints_nothing(capsys):
    progress = FitProgress(enabled=False)
    progress(1, 1.0, 0.0)
    progress.stage(1, 1, "M = 1")
    progress.done(SimpleNamespace(nfev=1, objective=1.0, wall_time=0.0, converged=True, message=""))
    assert capsys.readouterr().err == ""


# ---------------------------------------------- what the record says of the fit's end (issue 25)
import yaml  # noqa: E402

from rdea_lab.cli.errors import run as run_cli  # noqa: E402
from rdea_lab.cli.main import cli  # noqa: E402
from pathlib import Path  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "rdea_lab" / "data"


@pytest.fixture(scope="module")
def tensile(tmp_path_factory):
    """A twin run of the 0 V tensile test (Table 3 parameters), to fit Rizzello 2020's C10 and C20 to."""
    path = tmp_path_factory.mktemp("cal") / "t.nc"
    assert run_cli(cli, ["run", str(DATA / "protocols" / "tensile_ramp_sine_0V.yaml"), "--specimen",
                         str(DATA / "specimens" / "specimen2.yaml"), "--backend", "twin", "--model", "su", "--quiet",
                         "--out", str(path)]) == 0
    return path


def _record(path):
    return yaml.safe_load(path.read_text())["calibration"]


def test_a_fit_the_evaluation_budget_stopped_records_not_converged_and_why(tensile, tmp_path, capsys):
    out = tmp_path / "b.yaml"
    assert run_cli(cli, ["calibrate", str(tensile), "--init", str(DATA / "params" / "rizzello2020.yaml"),
                         "--free", "C10,C20", "--max-evals", "10", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    record = _record(out)
    assert record["converged"] is False and record["statistics"]["nfev"] == 10
    assert record["message"] == "stopped at the evaluation budget of 10 evaluations"
    assert record["stages"][0]["budget_reached"] == "evaluations"
    assert err.splitlines()[-1].endswith(", not converged (stopped at the evaluation budget of 10 evaluations)")


def test_a_fit_that_converges_records_converged(tensile, tmp_path):
    out = tmp_path / "a.yaml"
    assert run_cli(cli, ["calibrate", str(tensile), "--init", str(DATA / "params" / "rizzello2020.yaml"),
                         "--free", "C10,C20", "--method", "least-squares", "--quiet", "--out", str(out)]) == 0
    record = _record(out)
    assert record["converged"] is True and record["stages"][0]["budget_reached"] == ""
    assert record["statistics"]["nfev"] < record["budgets"]["max_evals"]
