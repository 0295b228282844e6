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
