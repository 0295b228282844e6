"""rdea_lab.cli.calibrate.FitProgress: how a fit's progress reads on a terminal and in a log."""

from types import SimpleNamespace

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
