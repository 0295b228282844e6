"""The journal tailer: whole rows only, as they are appended; new and vanished journals."""

import shutil

import numpy as np
from journals import COLUMNS, append, make_journal, rows

from rdea_lab.monitor.tail import Follower, JournalTail, dataset_of


def test_rows_appear_as_appended_and_a_torn_row_waits(tmp_path):
    j = make_journal(tmp_path / "a.nc.part")
    tail = JournalTail(j)
    assert tail.read().shape == (0, len(COLUMNS))
    append(j, rows([0.0, 0.01, 0.02]), torn_bytes=8 * 3)  # 3 whole rows and 3 of 8 values of the fourth
    got = tail.read()
    np.testing.assert_array_equal(got[:, 0], [0.0, 0.01, 0.02])
    assert tail.rows == 3
    assert tail.read().shape[0] == 0  # the torn row is not read ...
    with open(j / "samples.f8", "r+b") as fh:  # ... until its writer completes it (and the next one)
        fh.seek(3 * 8 * len(COLUMNS))
        fh.write(rows([0.03, 0.04]).tobytes())
    np.testing.assert_array_equal(tail.read()[:, 4], [0.03, 0.04])
    assert tail.rows == 5


def test_a_journal_without_header_yet_reads_nothing(tmp_path):
    j = tmp_path / "b.nc.part"
    j.mkdir()
    tail = JournalTail(j)
    assert tail.read().size == 0 and tail.read_header() is None
    (j / "header.json").write_text('{"format": "rdea-lab-journal-1", "col')  # being written: not JSON yet
    assert tail.read_header() is None


def test_a_late_or_slow_follower_skips_to_the_newest_rows(tmp_path):
    j = make_journal(tmp_path / "c.nc.part")
    append(j, rows(np.arange(100) * 0.1))
    tail = JournalTail(j, start_rows=10)
    np.testing.assert_allclose(tail.read()[:, 0], np.arange(90, 100) * 0.1)
    assert tail.skipped == 90
    append(j, rows(np.arange(100, 150) * 0.1))
    np.testing.assert_allclose(tail.read(max_rows=20)[:, 0], np.arange(130, 150) * 0.1)
    assert tail.skipped == 120


def test_journals_appear_and_vanish(tmp_path):
    follower = Follower(tmp_path)
    assert follower.poll() == ([], [])
    a = make_journal(tmp_path / "x" / "a.nc.part")
    (tmp_path / "done.nc").write_bytes(b"")  # a finished dataset is not followed
    assert follower.poll() == ([a], [])
    b = make_journal(tmp_path / "b.nc.part")
    assert follower.poll() == ([b], [])
    tail = JournalTail(a)
    shutil.rmtree(a)  # the run ended: its dataset written, the journal removed
    assert tail.gone and tail.read().size == 0
    assert follower.poll() == ([], [a])
    assert dataset_of(a) == tmp_path / "x" / "a.nc"


def test_a_new_run_on_the_same_output_is_a_new_journal(tmp_path):
    follower = Follower(tmp_path)
    a = make_journal(tmp_path / "a.nc.part")
    assert follower.poll() == ([a], [])
    a.rename(tmp_path / "ended")  # the run ended (its folder kept aside: its inode stays taken) ...
    make_journal(tmp_path / "a.nc.part")  # ... and another started on the same output before the next poll
    assert follower.poll() == ([a], [a])
