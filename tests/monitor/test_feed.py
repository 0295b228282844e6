"""A followed run's display points: decimated when fast, shared between viewers by sequence number."""

import shutil

import numpy as np
from journals import append, make_journal, rows

from rdea_lab.monitor.feed import COLUMNS_PER_UPDATE, RunFeed, decimate


def test_a_fast_run_is_cut_to_min_max_columns_keeping_a_spike(tmp_path):
    n = 100_000  # a tick of the twin at 1e6 samples/s
    force = np.zeros(n)
    force[54_321] = 7.0
    block = rows(np.arange(n) * 1e-6, force=force)
    points, picked = decimate(block, ["time", "stretch", "position", "voltage", "force", "capacitance",
                                      "stretch_setpoint", "voltage_setpoint"])
    assert points["time"].size <= 2 * COLUMNS_PER_UPDATE
    assert points["force"].max() == 7.0  # its column's maximum
    assert np.all(np.diff(block[picked, 0]) > 0)  # the twin's times increase


def test_viewers_get_the_points_after_theirs_and_a_new_one_gets_those_kept(tmp_path):
    j = make_journal(tmp_path / "r.nc.part")
    feed = RunFeed(j, keep=250)
    append(j, rows(np.arange(100) * 0.01))
    assert feed.update() == 100
    seq, points, reset = feed.since(0)
    assert (seq, points["time"].size, reset) == (100, 100, False)
    for a in (100, 200, 300):  # a slow run: each read holds few rows, every one shown
        append(j, rows(np.arange(a, a + 100) * 0.01))
        feed.update()
    seq2, points, reset = feed.since(seq)
    assert (seq2, points["time"].size, reset) == (400, 300, False)
    _, points, reset = feed.since(0)  # a viewer joining now: the newest kept (at least keep), as a reset
    assert reset and points["time"][-1] == 3.99 and points["time"].size >= 250
    _, points, _ = feed.since(0, limit=100)
    assert points["time"].size <= 100
    assert feed.since(400) == (400, None, False)
    shutil.rmtree(j)
    assert feed.update() == 0 and feed.finished


def test_the_twin_beside_the_run_from_its_own_card(tmp_path):
    """The predicted force is the twin's on the run's own stretch and voltage (TwinStream over the same rows,
    so equal to rounding), block by block as the rows arrive."""
    from rdea_lab.specs import dump_specimen, load_params, load_specimen
    from rdea_lab.twin.simulate import TwinStream

    card, params = load_specimen("specimen2"), load_params("paper2021_table3")
    j = make_journal(tmp_path / "r.nc.part", attrs={"specimen": dump_specimen(card)})
    feed = RunFeed(j, params=params, model="su")
    t = np.arange(300) * 0.01
    stretch, voltage = 1 + 0.3 * t / t[-1], np.full(t.shape, 1000.0)
    for a in (0, 100, 200):
        append(j, rows(t[a:a + 100], stretch=stretch[a:a + 100], voltage=voltage[a:a + 100]))
        feed.update()
    _, points, _ = feed.since(0)
    expected = TwinStream(card, params, "su").step(t, stretch, voltage, summary=False)["force"]
    np.testing.assert_allclose(points["force_pred"], expected, rtol=1e-9)
    assert feed.prediction.model == "su" and not feed.prediction_error


def test_auto_picks_the_model_on_the_runs_plan(tmp_path):
    from rdea_lab.paths import resolve
    from rdea_lab.specs import dump_specimen, load_params, load_specimen

    attrs = {"specimen": dump_specimen(load_specimen("specimen2")),
             "protocol": resolve("blocking_force", "protocols").read_text()}
    j = make_journal(tmp_path / "r.nc.part", attrs=attrs)
    feed = RunFeed(j, params=load_params("paper2021_table3"), model="auto")
    append(j, rows(np.arange(10) * 0.001, stretch=1.0, voltage=0.0))  # the first rows say nothing of the plan
    feed.update()
    assert feed.prediction.model in ("su", "1r", "3r", "cr") and "CR" in feed.prediction.reason
