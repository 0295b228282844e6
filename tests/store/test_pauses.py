"""The pauses of a run in its dataset (issue 29): the ``paused`` flag, the notes, the pause table."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

import rdea_lab
from rdea_lab import open_run  # the public name: ds.rdea comes with it
from rdea_lab.protocols import pause as phases
from rdea_lab.specs.variables import global_attrs
from rdea_lab.store import DiskFull, JournalWriter, describe_run, journal, read_journal, recover, write_dataset
from rdea_lab.store import pauses as P

RATE = 100.0
START = "2026-01-02T03:04:05Z"
ATTRS = {"Conventions": "CF-1.8", "title": "a run that pauses", "created": START, "sample_rate": RATE,
         "history": f"{START}: rdea-lab test", **global_attrs("rdea-lab test of the pause table")}


# ------------------------------------------------------------------ helpers
def phase_sequence(rng, n):
    """A random phase per sample: runs of random length, running or a random pause phase (a pause can start
    at sample 0 and the run can end paused)."""
    out = np.empty(n, np.int8)
    i = 0
    while i < n:
        k = int(rng.integers(1, 40))
        out[i:i + k] = rng.choice([0, 0, 1, 2, 3])
        i += k
    return out


def reference(paused, time, notes, rate=RATE):
    """The table, slowly and plainly: sample by sample over the whole column."""
    rows, i, n = [], 0, len(paused)
    while i < n:
        if paused[i] > 0:
            j = i
            while j < n and paused[j] > 0:
                j += 1
            end = time[j] if j < n else time[-1] + 1.0 / rate
            noted = [(r, b) for f, r, b in notes if i <= f < j]
            reason, by = noted[0] if noted else (P.NOT_RECORDED, P.NOT_RECORDED)
            rows.append((float(time[i]), float(end), i, j - i, reason, by))
            i = j
        else:
            i += 1
    return rows


def table_rows(ds):
    if "pause" not in ds.dims:
        return []
    t = ds.rdea.pauses
    return [(float(a), float(b), int(c), int(d), e, f)
            for a, b, c, d, e, f in zip(t.start, t.end, t["first"], t.samples, t.reason, t["by"])]


def write_journal(out, paused, notes, rng=None, close=False, attrs=ATTRS, **kwargs):
    """A journal of ``paused`` (and the other columns) in random blocks, with ``notes``; finished (or closed, as
    a killed run leaves it): the writer."""
    n = len(paused)
    time = np.arange(n) / RATE
    writer = JournalWriter(out, dict(attrs), extra=("paused",), **kwargs)
    cuts = np.sort(rng.choice(np.arange(1, n), size=min(n - 1, 5), replace=False)) if rng is not None and n > 1 \
        else []
    for a, b in zip([0, *cuts], [*cuts, n]):
        block = {"time": time[a:b], "paused": paused[a:b], "stretch": 1.0 + time[a:b] / 100,
                 "voltage": np.where(paused[a:b] > 0, 0.0, 1e3)}
        block.update({k: np.zeros(b - a) for k in ("position", "force", "capacitance", "stretch_setpoint",
                                                   "voltage_setpoint")})
        writer.append(block)
    for note in notes:
        writer.note_pause(*note)
    if close:
        writer.close()
    else:
        writer.finish("complete", "")
    return writer


@pytest.fixture
def small_reads(monkeypatch):
    """Convert the journal a few rows at a time, so pauses span chunks."""
    def set_rows(n):
        monkeypatch.setattr(journal, "READ_ROWS", n)
    return set_rows


# ------------------------------------------------------------------ the flag
def test_paused_is_a_cf_flag_variable_with_the_phases_of_protocols_pause(tmp_path):
    paused = np.array([0, 0, 1, 2, 2, 3, 0], np.int8)
    write_journal(tmp_path / "r.nc", paused, [])
    with open_run(tmp_path / "r.nc") as ds:
        var = ds["paused"]
        assert var.dtype == np.int8 and var.dims == ("time",)
        assert list(var.attrs["flag_values"]) == list(phases.FLAG_VALUES) == [0, 1, 2, 3]
        assert var.attrs["flag_values"].dtype == np.int8
        assert var.attrs["flag_meanings"] == phases.FLAG_MEANINGS == "running ramping_down held ramping_up"
        assert var.attrs["units"] == "1" and "paused" in var.attrs["long_name"]
        np.testing.assert_array_equal(var.values, paused)


# ------------------------------------------------------------------ the table, against the reference
@given(st.lists(st.integers(0, 3), max_size=200), st.lists(st.integers(1, 30), min_size=1, max_size=20),
       st.lists(st.tuples(st.integers(0, 210), st.text(max_size=8), st.text(max_size=5)), max_size=6))
@settings(max_examples=200, deadline=None)
def test_the_edges_fed_in_any_chunks_are_the_reference(values, sizes, notes):
    paused = np.array(values, np.int8)
    time = np.arange(len(paused)) / RATE
    edges, a, k = P.PauseEdges(), 0, 0
    while a < len(paused):
        b = a + sizes[k % len(sizes)]
        edges.add(paused[a:b], time[a:b])
        a, k = b, k + 1
    values = P.table(edges.intervals(RATE), notes)
    got = list(zip(values["pause_start"], values["pause_end"], values["pause_first"], values["pause_samples"],
                   values["pause_reason"], values["pause_by"]))
    assert got == reference(paused, time, notes)
    assert [(f, f + s) for _, _, f, s, _, _ in got] == phases.pause_intervals(paused)


@pytest.mark.parametrize("seed", range(12))
def test_a_finished_run_has_the_table_of_the_reference(tmp_path, small_reads, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    paused = phase_sequence(rng, n)
    small_reads(int(rng.integers(1, 50)))
    starts = [f for f, _ in phases.pause_intervals(paused)]
    notes = [(int(f), f"reason {f}", "operator") for f in starts if rng.random() < 0.7]
    notes += [(int(rng.integers(0, n + 5)), "stray", "nobody") for _ in range(2)]  # dropped, or in a pause
    write_journal(tmp_path / "r.nc", paused, notes, rng)
    with open_run(tmp_path / "r.nc") as ds:
        assert table_rows(ds) == reference(paused, ds["time"].values, notes)
        assert ds.attrs["pauses"] == len(phases.pause_intervals(paused))


def test_a_pause_spanning_many_chunks_is_one_pause(tmp_path, small_reads):
    small_reads(4)
    paused = np.zeros(40, np.int8)
    paused[2:6], paused[6:30], paused[30:33] = 1, 2, 3  # samples 2..32 over chunks 0..8
    paused[36:38] = 2  # a second pause inside chunk 9
    write_journal(tmp_path / "r.nc", paused, [(2, "door opened", "interlock"), (36, "look", "alice")])
    with open_run(tmp_path / "r.nc") as ds:
        assert table_rows(ds) == [(0.02, 0.33, 2, 31, "door opened", "interlock"), (0.36, 0.38, 36, 2, "look", "alice")]


def test_a_run_that_ended_paused_ends_its_pause_one_sample_after_its_last(tmp_path):
    paused = np.array([0, 0, 0, 1, 1, 2, 2], np.int8)
    write_journal(tmp_path / "r.nc", paused, [(3, "end of shift", "bob")])
    with open_run(tmp_path / "r.nc") as ds:
        (start, end, first, samples, reason, by), = table_rows(ds)
        assert (first, samples, reason, by) == (3, 4, "end of shift", "bob")
        assert start == pytest.approx(0.03, abs=1e-12) and end == pytest.approx(0.06 + 1 / RATE, abs=1e-12)


def test_notes_are_matched_by_the_pause_they_fall_in(tmp_path):
    paused = np.array([0, 1, 1, 0, 2, 2, 0, 3, 0], np.int8)
    notes = [(4, "first", "a"), (5, "second in the same pause", "b"), (2, "late note", "c"), (0, "running", "d"),
             (99, "after the run", "e")]
    write_journal(tmp_path / "r.nc", paused, notes)
    with open_run(tmp_path / "r.nc") as ds:
        assert [(r, b) for *_, r, b in table_rows(ds)] == [("late note", "c"), ("first", "a"),
                                                             (P.NOT_RECORDED, P.NOT_RECORDED)]


def test_a_run_that_never_paused_has_no_pause_dimension(tmp_path):
    write_journal(tmp_path / "r.nc", np.zeros(10, np.int8), [(3, "asked, then withdrawn", "alice")])
    with open_run(tmp_path / "r.nc") as ds:
        assert "pause" not in ds.dims and "pause_start" not in ds and ds.attrs["pauses"] == 0
        assert ds.rdea.pauses.empty and list(ds.rdea.pauses.columns) == ["start", "end", "first", "samples",
                                                                          "reason", "by"]


def test_a_run_without_the_flag_has_neither_table_nor_count(tmp_path):
    writer = JournalWriter(tmp_path / "r.nc", dict(ATTRS))
    writer.append({"time": np.arange(5) / RATE, "stretch": np.ones(5)})
    writer.finish("complete", "")
    with open_run(tmp_path / "r.nc") as ds:
        assert "pause" not in ds.dims and "pauses" not in ds.attrs and "paused" not in ds


# ------------------------------------------------------------------ crash safety
def test_recover_of_a_killed_run_gets_the_table_finish_writes(tmp_path, small_reads):
    rng = np.random.default_rng(7)
    paused = phase_sequence(rng, 300)
    paused[-5:] = 2  # killed while held
    small_reads(16)
    notes = [(f, f"why {f}", "engine") for f, _ in phases.pause_intervals(paused)]
    write_journal(tmp_path / "done.nc", paused, notes, np.random.default_rng(1))
    writer = write_journal(tmp_path / "killed.nc", paused, notes, np.random.default_rng(2), close=True)
    with open(writer.dir / P.NOTES, "ab") as fh:
        fh.write(b'{"first": 5, "reason": "torn')  # a kill during a note: the torn line is skipped
    recover(tmp_path / "killed.nc")
    with open_run(tmp_path / "done.nc") as done, open_run(tmp_path / "killed.nc") as killed:
        assert killed.attrs["status"] == "interrupted"
        assert table_rows(killed) == table_rows(done) == reference(paused, done["time"].values, notes)
        assert len(table_rows(done)) == len(notes) > 2


def test_a_note_is_in_the_journal_once_note_pause_returns(tmp_path):
    writer = JournalWriter(tmp_path / "r.nc", dict(ATTRS), extra=("paused",))
    writer.note_pause(12, "limit force", "engine")
    lines = (writer.dir / P.NOTES).read_text().splitlines()
    assert [json.loads(x) for x in lines] == [{"first": 12, "reason": "limit force", "by": "engine"}]
    assert P.read_notes(writer.dir) == [(12, "limit force", "engine")]
    writer.abandon()


def test_the_background_conversion_follows_the_pauses_too(tmp_path, small_reads, monkeypatch):
    small_reads(8)
    monkeypatch.setattr(journal, "SHADOW_FROM", 16)
    rng = np.random.default_rng(3)
    paused = phase_sequence(rng, 500)
    notes = [(f, "shadowed", "engine") for f, _ in phases.pause_intervals(paused)]
    write_journal(tmp_path / "r.nc", paused, notes, rng)
    with open_run(tmp_path / "r.nc") as ds:
        assert table_rows(ds) == reference(paused, ds["time"].values, notes)


def test_a_full_disk_refuses_a_note_and_says_the_samples_are_safe(tmp_path, monkeypatch):
    import errno
    import os

    writer = JournalWriter(tmp_path / "r.nc", dict(ATTRS), extra=("paused",))
    writer.append({"time": np.arange(3) / RATE, "paused": np.array([0, 1, 2], np.int8)})

    def full(fd, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", full)
    with pytest.raises(DiskFull, match=r"disk full writing .*pauses.jsonl; 3 samples are safe in"):
        writer.note_pause(1, "limit", "engine")
    monkeypatch.undo()
    writer.finish("complete", "")
    with open_run(tmp_path / "r.nc") as ds:  # the pause is in the table all the same, its reason unknown
        assert table_rows(ds) == [(0.01, 0.03, 1, 2, P.NOT_RECORDED, P.NOT_RECORDED)]


@pytest.mark.parametrize("first, reason, by, match", [
    (-1, "x", "y", r"first = -1; allowed: the sample index"), (1.5, "x", "y", r"first = 1.5"),
    (True, "x", "y", r"first = True"), (3, None, "y", r"reason = None; allowed: text"),
    (3, "x", 4, r"by = 4; allowed: text"), (3, "\ud800", "y", r"reason = '\\ud800'; allowed: text \(UTF-8\)")])
def test_note_pause_refuses_what_is_no_note(tmp_path, first, reason, by, match):
    writer = JournalWriter(tmp_path / "r.nc", dict(ATTRS), extra=("paused",))
    try:
        with pytest.raises(ValueError, match=match):
            writer.note_pause(first, reason, by)
        assert not (writer.dir / P.NOTES).exists()
    finally:
        writer.abandon()


# ------------------------------------------------------------------ readers, round trip, CF
def test_the_in_memory_journal_and_describe_run_show_the_pauses(tmp_path):
    paused = np.array([0, 1, 2, 3, 0, 0], np.int8)
    writer = write_journal(tmp_path / "r.nc", paused, [(1, "look", "alice")], close=True)
    ds = read_journal(writer.dir)
    assert ds.attrs["pauses"] == 1 and list(ds["pause_reason"].values) == ["look"]
    recover(tmp_path / "r.nc")
    with open_run(tmp_path / "r.nc") as ds:
        text = describe_run(ds)
    assert "paused 0.01 s .. 0.04 s (3 samples): look, by alice" in text


def test_write_and_reload_keep_the_table_and_cf_readers_decode_its_times(tmp_path):
    paused = np.array([0, 1, 2, 2, 3, 0, 0, 2], np.int8)
    notes = [(1, "température", "opérateur"), (7, "", "engine")]  # UTF-8 and an empty reason survive
    write_journal(tmp_path / "r.nc", paused, notes)
    with open_run(tmp_path / "r.nc") as ds:
        rows = table_rows(ds)
        write_dataset(ds.load(), tmp_path / "again.nc")
    assert rows == reference(paused, np.arange(8) / RATE, notes)
    with open_run(tmp_path / "again.nc") as again:
        assert table_rows(again) == rows
        assert again["pause_first"].dtype == np.int32
        assert again["pause_start"].attrs["units"] == f"seconds since {START}"
    with xr.open_dataset(tmp_path / "r.nc") as decoded:  # dates, as time decodes
        t0 = np.datetime64(START.rstrip("Z"), "ns")
        assert list(decoded["pause_start"].values) == [t0 + np.timedelta64(10, "ms"), t0 + np.timedelta64(70, "ms")]
        assert decoded["pause_end"].values[0] == decoded["time"].values[5]
        assert table_rows(decoded) == rows  # ds.rdea.pauses reads decoded times back as seconds


@pytest.fixture(scope="module")
def cf_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cf_pauses")
    out = {}
    rng = np.random.default_rng(11)
    paused = phase_sequence(rng, 300)
    paused[-3:] = 2
    notes = [(f, "operator asked", "alice") for f, _ in phases.pause_intervals(paused)][:-1]
    write_journal(folder / "paused.nc", paused, notes, rng)
    out["paused"] = folder / "paused.nc"
    write_journal(folder / "never.nc", np.zeros(50, np.int8), [], rng)
    out["never paused"] = folder / "never.nc"
    write_journal(folder / "killed.nc", paused, notes, rng, close=True)
    out["recovered"] = recover(folder / "killed.nc")
    with open_run(out["paused"]) as ds:
        write_dataset(ds.load(), folder / "rewritten.nc")
    out["rewritten"] = folder / "rewritten.nc"
    return out


@pytest.mark.parametrize("kind", ["paused", "never paused", "recovered", "rewritten"])
def test_both_cf_checkers_find_nothing(cf_files, kind):
    from test_cf import cfchecks, ioos

    assert ioos(cf_files[kind]) == {"high": [], "medium": [], "low": [], "exceptions": []}
    found = cfchecks(cf_files[kind])
    assert found["FATAL"] == found["ERROR"] == found["WARN"] == [], found


def test_the_layering_holds_one_definition_of_the_phases():
    # specs are below protocols: the flag's values are declared in the variable table and only taken by pause.py
    source = Path(phases.__file__).read_text()
    assert "FLAG_VALUES = PAUSE_FLAG_VALUES" in source and "running ramping_down" not in source
    assert rdea_lab.specs.variables.FLAGS["paused"][1] == phases.FLAG_MEANINGS
