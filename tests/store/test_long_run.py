"""Day-long runs in the store (issue 28): the journal streamed into netCDF in bounded memory (finish, the
background conversion, recover), a SIGKILL losing at most the block in flight, and a lazy `open_run`.

The reference is the in-memory path (`read_journal`, then `write_dataset` through xarray's `to_netcdf`):
the streamed file must hold exactly what it holds. Chunk sizes are made small here so that a short journal
crosses many chunks; the slow tests use a few million samples with the shipped sizes.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.store import JournalWriter, describe_run, iter_chunks, journal, journal_path, open_run, recover
from rdea_lab.store.journal import final_attrs, read_journal, write_dataset

ROOT = Path(__file__).resolve().parents[2]
ATTRS = {"Conventions": "CF-1.8", "title": "t", "rdea_lab_version": "0", "run_id": "x", "backend": "twin",
         "specimen_id": "s", "specimen": "id: s\n", "protocol_name": "p", "protocol_kind": "tensile",
         "protocol": "name: p\n", "sample_rate": 1000.0, "seed": 0, "created": "2026-01-01T00:00:00Z",
         "status": "running", "status_reason": "", "history": "created", "institution": "not stated",
         "source": "a test", "references": "none"}
EXTRA = ("model_status", "current")
RATE = 1000.0


def block(start: int, n: int) -> dict:
    """Samples start:start+n of a twin-like run at 1 kHz: a ramp-sine stretch, a force with an infinity and
    a gap (NaN), capacitance never measured, a model status that cycles."""
    i = np.arange(start, start + n)
    t = i / RATE
    force = np.sin(0.7 * t) + 1e-3 * np.cos(37.0 * t)
    force[i % 997 == 5] = np.inf
    force[i % 1009 == 7] = np.nan
    return {"time": t, "stretch": 1 + 0.25 * (1 - np.cos(0.2 * np.pi * t)), "position": 0.003 * t,
            "voltage": np.where(t % 20 < 10, 2600.0, 0.0), "force": force, "capacitance": np.full(n, np.nan),
            "stretch_setpoint": 1 + 0.25 * (1 - np.cos(0.2 * np.pi * t)), "voltage_setpoint": np.full(n, 2600.0),
            "model_status": (i // 1000) % 3, "current": 1e-6 * np.sin(t)}


def write_journal(out: Path, samples: int, per_block: int = 1000, **kwargs) -> JournalWriter:
    w = JournalWriter(out, ATTRS, extra=EXTRA, **kwargs)
    for start in range(0, samples, per_block):
        w.append(block(start, min(per_block, samples - start)))
    return w


def reference(folder: Path, out: Path, status: str, reason: str, history: str = "") -> None:
    """The in-memory writer (the whole journal read, then `write_dataset`) on a copy of a journal."""
    ds = read_journal(folder)
    ds.attrs.update(final_attrs(ds.attrs, status, reason, history))
    write_dataset(ds, out)


def assert_same_content(path: Path, ref: Path, skip=("finished", "history")) -> None:
    with open_run(path) as a, open_run(ref) as r:
        a, r = a.load(), r.load()
        assert list(a.variables) == list(r.variables)
        assert {k: str(v) for k, v in a.attrs.items() if k not in skip} == \
               {k: str(v) for k, v in r.attrs.items() if k not in skip}
        for name in r.variables:
            assert a[name].dtype == r[name].dtype, name
            np.testing.assert_array_equal(a[name].values, r[name].values)  # bit-exact, NaN where NaN
            assert {k: str(v) for k, v in a[name].attrs.items()} == {k: str(v) for k, v in r[name].attrs.items()}


@pytest.fixture
def small_chunks(monkeypatch):
    """Chunks of a few hundred rows, and the background conversion from 3000 rows: a short journal
    crosses every boundary (HDF5 chunks, journal reads, the shadow's start)."""
    monkeypatch.setattr(journal, "READ_ROWS", 700)
    monkeypatch.setattr(journal, "CHUNK", 256)
    monkeypatch.setattr(journal, "SHADOW_FROM", 3000)


@pytest.mark.parametrize("background", [False, True])
def test_the_streamed_file_holds_what_the_in_memory_writer_writes(tmp_path, small_chunks, background):
    out = tmp_path / "run.nc"
    w = write_journal(out, 10_333, per_block=1000, background=background)
    assert (w._shadow is not None) == background  # the background thread did take the run
    shutil.copytree(w.dir, tmp_path / "copy.nc.part")
    w.finish("aborted", "a reason")
    assert not journal_path(out).exists() and not list(tmp_path.glob("**/*.tmp"))
    reference(tmp_path / "copy.nc.part", tmp_path / "ref.nc", "aborted", "a reason")
    assert_same_content(out, tmp_path / "ref.nc")
    with open_run(out) as ds:  # actual_range: of the finite values, float variables only, none if none is
        force = block(0, 10_333)["force"]
        finite = force[np.isfinite(force)]
        np.testing.assert_array_equal(ds["force"].attrs["actual_range"], [finite.min(), finite.max()])
        assert ds["force"].attrs["actual_range"].dtype == np.float64
        assert "actual_range" not in ds["capacitance"].attrs and "actual_range" not in ds["model_status"].attrs
        assert ds.attrs["samples"] == 10_333 and ds.attrs["status"] == "aborted"


def test_recover_streams_what_the_in_memory_writer_writes_and_drops_the_shadow(tmp_path, small_chunks):
    out = tmp_path / "run.nc"
    w = write_journal(out, 7_500)
    os.write(w._fd, np.arange(3, dtype="<f8").tobytes())  # a torn row, as a kill in mid-write leaves
    w.close()  # as a killed process: the half-written shadow stays in the journal
    assert (journal_path(out) / journal.SHADOW).exists()
    shutil.copytree(journal_path(out), tmp_path / "copy.nc.part")
    recover(journal_path(out))
    assert not journal_path(out).exists() and not list(tmp_path.glob("*.tmp"))
    reason = "the process stopped without closing the run; 7500 samples recovered from the journal by rdea-lab recover"
    reference(tmp_path / "copy.nc.part", tmp_path / "ref.nc", "interrupted", reason, "rdea-lab recover")
    assert_same_content(out, tmp_path / "ref.nc")


def test_finish_and_recover_never_read_more_than_a_chunk_of_the_journal(tmp_path, monkeypatch):
    """Every read of the journal by finish and recover is of `READ_ROWS` rows at most, and the in-memory
    reader is never called: what they hold at once does not grow with the run."""
    monkeypatch.setattr(journal, "READ_ROWS", 1024)
    reads = []
    real = journal._read_rows

    def counted(folder, ncolumns, start, stop):
        reads.append(stop - start)
        return real(folder, ncolumns, start, stop)

    def whole(folder):
        raise AssertionError("the whole journal read")

    monkeypatch.setattr(journal, "_read_rows", counted)
    monkeypatch.setattr(journal, "read_journal", whole)
    n = 20_000
    for how in ("finish", "recover"):
        out = tmp_path / f"{how}.nc"
        w = write_journal(out, n, per_block=5_000, background=False)
        reads.clear()
        if how == "recover":
            w.close()
            recover(out)
        else:
            w.finish("complete", "")
        assert max(reads) <= 1024 and sum(reads) == n, (how, reads[:5])
        with open_run(out) as ds:
            np.testing.assert_array_equal(ds["time"].values, np.arange(n) / RATE)


@pytest.mark.slow
def test_finish_and_recover_stay_in_bounded_memory(tmp_path, monkeypatch):
    """40 000 and 80 000 samples converted 1024 rows at a time: Python's allocations (numpy's included,
    which tracemalloc sees) peak far below the journal's size (measured: 0.2-0.35 MB of 3.5-7 MB), for
    finish and for recover, and do not grow with the run."""
    monkeypatch.setattr(journal, "READ_ROWS", 1024)
    from rdea_lab.store import index

    monkeypatch.setattr(index, "index_quietly", lambda path: None)  # the conversion's memory (the row's own
    # sha256 reads 1 MiB at a time, a fixed cost: tests/store/test_index.py)
    write_journal(tmp_path / "warm.nc", 2_000, background=False).finish("complete", "")  # one-time set-up
    write_journal(tmp_path / "warm2.nc", 2_000, background=False).close()
    recover(tmp_path / "warm2.nc")
    for n in (40_000, 80_000):
        for how in ("finish", "recover"):
            out = tmp_path / f"{how}{n}.nc"
            w = write_journal(out, n, per_block=4_000, background=False)
            size = (w.dir / "samples.f8").stat().st_size
            if how == "recover":
                w.close()
            tracemalloc.start()
            try:
                w.finish("complete", "") if how == "finish" else recover(out)
                peak = tracemalloc.get_traced_memory()[1]
            finally:
                tracemalloc.stop()
            assert peak < min(size / 10, 1_000_000), (how, n, peak, size)
            with open_run(out) as ds:
                assert ds.sizes["time"] == n
                np.testing.assert_array_equal(ds["time"][-5:].values, np.arange(n - 5, n) / RATE)


KILLED_WRITER = """
import sys, numpy as np
sys.path.insert(0, {tests!r})
from rdea_lab.store import journal
from test_long_run import write_journal, block
journal.SHADOW_FROM = {shadow}
w = write_journal({out!r}, 0)
k = 0
while True:
    w.append(block(k * 1000, 1000))
    k += 1
    print(k, flush=True)
"""


def killed_at(tmp_path: Path, delay: float, shadow: int) -> tuple[int, Path]:
    """A writer subprocess appending 1000-sample blocks, SIGKILLed after ``delay`` s: the blocks it said
    were appended, and its dataset's path."""
    out = tmp_path / f"killed_{delay:.3f}.nc"
    code = KILLED_WRITER.format(tests=str(Path(__file__).parent), shadow=shadow, out=str(out))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "1"  # started
        time.sleep(delay)
        os.kill(proc.pid, signal.SIGKILL)
        said = 1
        for line in proc.stdout:
            said = int(line)
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()
    return said, out


def check_recovered(said: int, out: Path) -> None:
    recover(journal_path(out))
    with open_run(out) as ds:
        n = ds.sizes["time"]
        assert said * 1000 <= n <= (said + 1) * 1000  # every block it appended; at most the one in flight
        np.testing.assert_array_equal(ds["time"].values, np.arange(n) / RATE)  # none lost or doubled
        np.testing.assert_array_equal(ds["force"].values, block(0, n)["force"])
        assert ds.attrs["status"] == "interrupted" and ds.attrs["samples"] == n


@pytest.mark.slow
def test_a_sigkilled_writer_loses_at_most_the_block_in_flight(tmp_path):
    said, out = killed_at(tmp_path, 0.3, shadow=20_000)  # the background conversion going when it dies
    check_recovered(said, out)


@pytest.mark.slow
def test_sigkills_at_random_moments_lose_at_most_the_block_in_flight(tmp_path):
    rng = np.random.default_rng(28)
    for delay in rng.uniform(0.0, 2.0, 6):
        said, out = killed_at(tmp_path, float(delay), shadow=int(rng.choice([5_000, 50_000, 10**9])))
        check_recovered(said, out)


def reads_counted(monkeypatch) -> list:
    """Every read xarray makes from a netCDF variable, as (name, key)."""
    from xarray.backends import netCDF4_

    seen = []
    real = netCDF4_.NetCDF4ArrayWrapper._getitem

    def counted(self, key):
        seen.append((self.variable_name, key))
        return real(self, key)

    monkeypatch.setattr(netCDF4_.NetCDF4ArrayWrapper, "_getitem", counted)
    return seen


def test_open_run_reads_no_variable_and_slices_read_only_their_samples(tmp_path, monkeypatch):
    import importlib

    catalog = importlib.import_module("rdea_lab.store.catalog")  # the module (the package's `catalog` is a function)
    out = tmp_path / "run.nc"
    write_journal(out, 20_000, background=False).finish("complete", "")
    seen = reads_counted(monkeypatch)
    monkeypatch.setattr(catalog, "INDEX_SAMPLES", 10_000)  # a "long" run: no time index
    with open_run(out) as ds:
        assert seen == []  # attributes and dtypes (check_run) only
        assert ds.attrs["samples"] == 20_000 and ds["force"].attrs["units"] == "N"
        assert ds.sizes["time"] == 20_000 and ds["model_status"].dtype == np.int8
        expected = block(0, 20_000)
        np.testing.assert_array_equal(ds["force"][100:200].values, expected["force"][100:200])
        assert seen == [("force", (slice(100, 200, 1),))]
        chunks = list(iter_chunks(ds, 7_000, names=["time", "force"]))
        assert [(a, b) for a, b, _ in chunks] == [(0, 7_000), (7_000, 14_000), (14_000, 20_000)]
        for a, b, values in chunks:
            np.testing.assert_array_equal(values["time"], expected["time"][a:b])
            np.testing.assert_array_equal(values["force"], expected["force"][a:b])
        assert all(k != (slice(None),) and k != (slice(0, 20_000, 1),) for _, k in seen)  # never the whole
        seen.clear()
        text = describe_run(ds)  # show's summary: the ranges from actual_range, the rest read in chunks
        finite = expected["force"][np.isfinite(expected["force"])]
        assert f"force             [N] {finite.min():.5g} .. {finite.max():.5g}" in text
        assert "capacitance       [F] not measured" in text and "20000 samples over 20 s" in text
        assert {name for name, _ in seen} <= {"time", "capacitance", "model_status"}, seen
    monkeypatch.setattr(catalog, "INDEX_SAMPLES", 1 << 20)
    seen.clear()
    with open_run(out) as ds:  # a short run: its time index built, as an in-memory dataset has it
        assert [name for name, _ in seen] == ["time"] and "time" in ds.indexes
        loaded = ds.load()
        np.testing.assert_array_equal(loaded["voltage"].values, expected["voltage"])
    with pytest.raises(ValueError, match="positive integer"):
        next(iter_chunks(loaded, 0))


LONG = """
import resource, sys, time, numpy as np
sys.path.insert(0, {tests!r})
from rdea_lab.store import journal, recover
from test_long_run import write_journal
write_journal({out!r} + ".warm.nc", 200_000).finish("complete", "")  # the libraries' one-time allocations
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
w = write_journal({out!r}, {n})
if {kill}:
    w.close()
    recover({out!r})
else:
    w.finish("complete", "")
print(base, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, time.perf_counter() - t0)
"""


@pytest.mark.slow
@pytest.mark.parametrize("kill", [False, True])
def test_a_few_million_samples_finish_and_recover_in_bounded_rss(tmp_path, kill):
    """3e6 samples at 1 kHz in 1 s blocks (264 MB of journal), with the shipped chunk sizes and the
    background conversion: the peak RSS of the writing process (after a short run has made the libraries'
    one-time allocations) grows by a tenth of the journal at most (measured: 11-15 MB)."""
    n = 3_000_000
    out = tmp_path / "run.nc"
    code = LONG.format(tests=str(Path(__file__).parent), out=str(out), n=n, kill=kill)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr
    base, peak, _ = map(float, done.stdout.split())
    journal_bytes = n * 8 * 11
    assert (peak - base) * 1024 < journal_bytes / 10, (base, peak)
    with open_run(out) as ds:
        assert ds.sizes["time"] == n and ds.attrs["status"] == ("interrupted" if kill else "complete")
        for a, b, values in iter_chunks(ds, 1 << 20, names=["time", "force"]):
            expected = block(a, b - a)
            np.testing.assert_array_equal(values["time"], expected["time"])
            np.testing.assert_array_equal(values["force"], expected["force"])
        force = block(0, n)["force"]
        finite = force[np.isfinite(force)]
        np.testing.assert_array_equal(ds["force"].attrs["actual_range"], [finite.min(), finite.max()])


def test_a_failing_background_conversion_falls_back_to_the_journal(tmp_path, small_chunks, monkeypatch):
    """The background thread's writing fails (a full disk, say): its file is dropped at once and finish
    converts the journal itself, the file the same as ever."""
    import errno
    import threading

    real = journal._Converter.convert

    def failing_in_the_thread(self, upto, stop=lambda: False):
        if threading.current_thread() is not threading.main_thread():
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, upto, stop)

    monkeypatch.setattr(journal._Converter, "convert", failing_in_the_thread)
    out = tmp_path / "run.nc"
    w = write_journal(out, 8_000)
    shadow = w._shadow
    shadow.wake.set()
    for _ in range(200):
        if shadow.failed is not None:
            break
        time.sleep(0.01)
    assert isinstance(shadow.failed, OSError) and not (w.dir / journal.SHADOW).exists()
    shutil.copytree(w.dir, tmp_path / "copy.nc.part")
    w.finish("complete", "")
    reference(tmp_path / "copy.nc.part", tmp_path / "ref.nc", "complete", "")
    assert_same_content(out, tmp_path / "ref.nc")
