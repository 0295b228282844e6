"""The store: journal streaming, crash recovery, the netCDF schema and its round trip."""

import errno
import json
import os
import subprocess
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr

from rdea_lab.store import REQUIRED_ATTRS, VARIABLES, JournalWriter, catalog, journal_path, open_run, recover
from rdea_lab.store.journal import JournalInUse, RunInProgress, journal_writer, read_journal

ROOT = Path(__file__).resolve().parents[2]
ATTRS = {"Conventions": "CF-1.8", "title": "t", "rdea_lab_version": "0", "run_id": "x", "backend": "twin",
         "specimen_id": "s", "specimen": "id: s\n", "protocol_name": "p", "protocol_kind": "tensile",
         "protocol": "name: p\n", "sample_rate": 100.0, "seed": 0, "created": "2026-01-01T00:00:00Z",
         "status": "running", "status_reason": "", "history": "created", "institution": "not stated",
         "source": "a test", "references": "none"}


def block(t0, n):
    t = t0 + np.arange(n) / 100.0
    return {"time": t, "stretch": 1 + 0.1 * t, "position": 0.0034 * t, "voltage": 100 * t, "force": np.sin(t),
            "capacitance": np.full(n, np.nan), "stretch_setpoint": 1 + 0.1 * t, "voltage_setpoint": 100 * t,
            "model_status": np.zeros(n)}


def test_round_trip_keeps_every_sample_units_and_attrs(tmp_path):
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS, extra=("model_status",))
    blocks = [block(0.0, 100), block(1.0, 100), block(2.0, 37)]
    for b in blocks:
        w.append(b)
    w.finish("complete", "")
    assert not journal_path(out).exists()
    ds = open_run(out)
    assert ds.sizes["time"] == 237
    for name in VARIABLES:
        expected = np.concatenate([b[name] for b in blocks])
        np.testing.assert_array_equal(ds[name].values, expected)  # float64 all the way: bit-exact
        assert ds[name].attrs["units"] and ds[name].attrs["long_name"]
    assert ds["time"].attrs["units"] == f"seconds since {ATTRS['created']}"  # CF 1.8: from the run's start
    for key in REQUIRED_ATTRS:
        assert ds.attrs[key] is not None and key in ds.attrs
    assert ds.attrs["status"] == "complete" and ds.attrs["samples"] == 237
    assert "status complete" in ds.attrs["history"]
    with xr.open_dataset(out) as raw:  # plain xarray, and time is the unlimited dimension
        assert raw.encoding["unlimited_dims"] == {"time"}


def test_a_killed_run_leaves_a_journal_that_recover_turns_into_an_interrupted_dataset(tmp_path):
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS, extra=("model_status",))
    w.append(block(0.0, 100))
    w.append(block(1.0, 100))
    # simulate SIGKILL in the middle of the next write: half a row at the end of the file
    os.write(w._fd, np.arange(4, dtype="<f8").tobytes())
    w.close()  # the process is gone: its descriptors, and so its lock, with it
    assert not out.exists()
    rows = catalog(tmp_path)
    assert rows["status"][0].startswith("unfinished") and rows["samples"][0] == 200
    path = recover(journal_path(out))
    ds = open_run(path)
    assert ds.sizes["time"] == 200  # the torn row is dropped, every whole one kept
    assert ds.attrs["status"] == "interrupted"
    assert "200 samples recovered" in ds.attrs["status_reason"]
    assert not journal_path(out).exists()


def test_recover_refuses_what_it_cannot_do(tmp_path):
    with pytest.raises(FileNotFoundError, match="no run journal here"):
        recover(tmp_path / "nothing.nc")
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS)
    w.append(block(0.0, 10))
    w.close()
    out.write_bytes(b"")  # something already sits where the dataset would go
    with pytest.raises(FileExistsError, match="move it away"):
        recover(out)


def test_journal_header_is_plain_json_and_refuses_a_second_writer(tmp_path):
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS)
    header = json.loads((journal_path(out) / "header.json").read_text())
    assert header["columns"][0] == "time" and header["attrs"]["status"] == "running"
    with pytest.raises(JournalInUse, match="another run is writing it"):
        JournalWriter(out, ATTRS)
    w.close()


def test_read_journal_rejects_a_foreign_folder(tmp_path):
    folder = tmp_path / "x.nc.part"
    folder.mkdir()
    (folder / "header.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(ValueError, match="not an rdea-lab journal"):
        read_journal(folder)


def test_catalog_lists_unreadable_files_without_failing(tmp_path):
    (tmp_path / "broken.nc").write_bytes(b"not netcdf")
    rows = catalog(tmp_path)
    assert rows["status"][0].startswith("unreadable")


def test_recover_leaves_a_live_run_alone_and_the_catalogue_says_running(tmp_path, capsys):
    """The writer holds an OS lock on its journal: recover (here in the same process, which flock keeps
    apart just as it does two processes) must not take the journal of a run still going."""
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS)
    w.append(block(0.0, 100))
    writer = journal_writer(journal_path(out))
    assert writer["pid"] == os.getpid() and writer["host"] and writer["started"]
    with pytest.raises(RunInProgress, match=f"pid {os.getpid()}"):
        recover(journal_path(out))
    with pytest.raises(RunInProgress):
        recover(out)
    assert catalog(tmp_path)["status"][0].startswith("running")
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli
    # says so, in a status a script can tell from "done" (75, EX_TEMPFAIL: try again later), and leaves it
    assert run_cli(cli, ["recover", str(tmp_path)]) == 75
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "1 of 1 journals belong to runs still going" in err[0], err
    assert (journal_path(out) / "header.json").is_file()
    w.append(block(1.0, 100))  # the run goes on, undisturbed
    w.finish("complete", "")
    assert open_run(out).sizes["time"] == 200 and not journal_path(out).exists()


def test_a_live_run_in_another_process_is_left_alone(tmp_path):
    import subprocess
    import sys
    import time

    out = tmp_path / "run.nc"
    code = ("import sys, time, numpy as np; from rdea_lab.store import JournalWriter; "
            f"w = JournalWriter({str(out)!r}, {ATTRS!r}); "
            "w.append({'time': np.arange(10) / 100.0}); print('ready', flush=True); time.sleep(30)")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        with pytest.raises(RunInProgress, match=f"pid {proc.pid}"):
            recover(journal_path(out))
        assert journal_path(out).is_dir()
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()
    time.sleep(0.05)
    path = recover(journal_path(out))  # killed: the OS dropped its lock, recover may take it now
    assert open_run(path).sizes["time"] == 10


def test_recover_refuses_a_malformed_journal_with_one_line(tmp_path):
    for i, header in enumerate([{"format": "rdea-lab-journal-1", "attrs": {}},
                                {"format": "rdea-lab-journal-1", "columns": ["time", "bogus"], "attrs": {}},
                                {"format": "rdea-lab-journal-1", "columns": ["time"], "attrs": []},
                                ["a", "list"]]):
        folder = tmp_path / f"r{i}.nc.part"
        folder.mkdir()
        (folder / "header.json").write_text(json.dumps(header))
        (folder / "samples.f8").write_bytes(b"")
        with pytest.raises(ValueError, match="journal|columns|attrs"):
            recover(folder)


def test_an_attribute_netcdf_cannot_hold_never_makes_a_run_unrecoverable(tmp_path):
    out = tmp_path / "run.nc"
    w = JournalWriter(out, {**ATTRS, "seed": 2**64, "flag": True, "nested": {"a": [1, 2]}})
    w.append(block(0.0, 10))
    w.close()
    ds = open_run(recover(journal_path(out)))
    assert ds.attrs["seed"] == str(2**64) and ds.attrs["flag"] == 1 and json.loads(ds.attrs["nested"]) == {"a": [1, 2]}


def _full(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_full_disk_while_running_keeps_every_sample_and_says_where(tmp_path, monkeypatch):
    """The disk fills during a block: the engine stops the run (voltage off), cannot write the dataset
    either, and says, as a user's problem (exit 2), that every sample is safe in the journal; no .tmp is
    left; once space is back, recover --out writes the dataset elsewhere with how the run ended."""
    import rdea_lab
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli
    from rdea_lab.store import journal as J

    out = tmp_path / "run.nc"
    seen = []

    class Tracker:
        def __call__(self, block):
            seen.append(len(block))
            if len(seen) == 2:  # from now on the disk is full
                monkeypatch.setattr(J.os, "write", _full)
                monkeypatch.setattr(J.xr.Dataset, "dump_to_store", _full)  # the dataset's layout

    card = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
    with pytest.raises(J.DiskFull, match=r"samples are safe in .*run\.nc\.part; free space and run rdea-lab recover"):
        rdea_lab.run_protocol(ROOT / "rdea_lab" / "data" / "protocols" / "tensile_ramp_sine_0V.yaml", card, "twin",
                              out=out, callbacks=[Tracker()])
    assert not out.exists() and not list(tmp_path.glob("*.tmp"))
    kept = sum(seen)
    monkeypatch.undo()
    elsewhere = tmp_path / "other" / "run.nc"
    assert run_cli(cli, ["recover", str(journal_path(out)), "--out", str(elsewhere)]) == 0
    ds = open_run(elsewhere)
    assert ds.sizes["time"] == kept  # every sample the engine received before the disk filled
    assert ds.attrs["status"] == "aborted" and "the disk filled up" in ds.attrs["status_reason"]


def test_write_dataset_leaves_no_tmp_when_it_fails(tmp_path, monkeypatch):
    from rdea_lab.store import journal as J

    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS)
    w.append(block(0.0, 10))

    def half_then_full(self, store, *a, **k):  # the file is made, its layout half written
        assert Path(store.ds.filepath()).is_file()
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(J.xr.Dataset, "dump_to_store", half_then_full)
    with pytest.raises(J.DiskFull):
        w.finish("complete", "")
    assert not list(tmp_path.glob("*.tmp")) and journal_path(out).is_dir()


def test_the_claim_of_a_run_that_never_started_is_removed_by_recover(tmp_path):
    from rdea_lab.store.journal import EmptyJournal

    out = tmp_path / "run.nc"
    claim = JournalWriter(out, None)
    with pytest.raises(RunInProgress):  # still held: a run about to start
        recover(journal_path(out))
    claim.close()  # its process died before the run began
    with pytest.raises(EmptyJournal, match="never started"):
        recover(journal_path(out))
    assert not journal_path(out).exists()


def test_netcdfs_hdf_error_on_a_full_file_system_is_a_full_disk(tmp_path, monkeypatch):
    """netCDF reports a full disk as a bare RuntimeError 'NetCDF: HDF error'; with no free space left it is
    reported as the full disk it is (and the journal kept); with space left it stays the error it was."""
    import shutil as _shutil
    from collections import namedtuple

    from rdea_lab.store import journal as J

    def hdf_error(self, path, *a, **k):
        raise RuntimeError("NetCDF: HDF error")

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(J.xr.Dataset, "dump_to_store", hdf_error)
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS)
    w.append(block(0.0, 10))
    monkeypatch.setattr(_shutil, "disk_usage", lambda p: usage(10**9, 10**9, 0))
    with pytest.raises(J.DiskFull, match="10 samples are safe"):
        w.finish("complete", "")
    assert journal_path(out).is_dir()
    monkeypatch.setattr(_shutil, "disk_usage", lambda p: usage(10**12, 0, 10**12))
    with pytest.raises(RuntimeError, match="HDF error"):
        recover(journal_path(out))
    assert journal_path(out).is_dir()  # kept, for a later recover


def _other_process_lock(folder):
    """A lock on the journal's ``writer.lock`` from another open file description, as another process's."""
    import fcntl

    fd = os.open(Path(folder) / "writer.lock", os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    return fd


def test_a_recover_between_a_claims_folder_and_its_lock_cannot_leave_the_run_unlocked(tmp_path, monkeypatch):
    """The race of the interrupt soak: a recover looks at a journal folder its writer has made but not yet
    locked. It takes it for the claim of a run killed before it began and removes it; the writer must then
    claim again and hold the lock on the file at the path, so a later recover leaves the live run alone (it used
    to go on without any lock, and a recover then converted the live run's journal beside its writer)."""
    from rdea_lab.store import journal as jr

    out = tmp_path / "run.nc"
    real, looked = jr._try_lock, []

    def racing(folder, create=True):
        if not looked:  # the writer's first attempt: the folder is made, its lock file too, not yet held
            looked.append(True)
            os.close(os.open(Path(folder) / jr.LOCK, os.O_RDWR | os.O_CREAT, 0o644))
            with pytest.raises(jr.EmptyJournal):
                recover(folder)
            assert not Path(folder).exists()
        return real(folder, create)

    monkeypatch.setattr(jr, "_try_lock", racing)
    w = JournalWriter(out, ATTRS)
    monkeypatch.setattr(jr, "_try_lock", real)
    assert looked
    st_held, st_path = os.fstat(w._lock), os.stat(journal_path(out) / jr.LOCK)
    assert os.path.samestat(st_held, st_path)  # the writer's lock is the journal's
    w.append(block(0.0, 10))
    with pytest.raises(RunInProgress):
        recover(out)
    w.finish("complete", "")
    assert open_run(out).sizes["time"] == 10


def test_a_claim_waits_out_a_lock_held_for_a_moment_and_refuses_one_held_for_good(tmp_path, monkeypatch):
    """A catalogue looking whether a writer holds a journal holds its lock for a moment: a writer locking just
    then waits it out (it used to go on without a lock). A lock that stays held is refused, not ignored."""
    import threading

    from rdea_lab.store import journal as jr

    out = tmp_path / "run.nc"
    real, held = jr._try_lock, []

    def probed(folder, create=True):
        if not held:  # someone else holds the fresh lock file for 50 ms just as the writer tries it
            os.close(os.open(Path(folder) / jr.LOCK, os.O_RDWR | os.O_CREAT, 0o644))
            held.append(_other_process_lock(folder))
            threading.Timer(0.05, os.close, (held[0],)).start()
        return real(folder, create)

    monkeypatch.setattr(jr, "_try_lock", probed)
    w = JournalWriter(out, ATTRS)
    assert held
    with pytest.raises(RunInProgress):  # the claim is held by its writer
        recover(out)
    w.abandon()
    assert not journal_path(out).exists()

    held.clear()
    monkeypatch.setattr(jr, "CLAIM_WAIT", 0.2)
    monkeypatch.setattr(jr.threading, "Timer", lambda *a: type("Never", (), {"start": lambda self: None})())
    with pytest.raises(JournalInUse, match="held by another process"):
        JournalWriter(out, ATTRS)
    os.close(held[0])


def test_a_lock_taken_on_a_journal_being_removed_is_no_lock(tmp_path, monkeypatch):
    """A writer removes its journal holding the lock, the lock file last. A recover that opened the lock file
    just before it went and locks it once released holds a file no longer at its path: the journal is gone
    (FileNotFoundError), never converted a second time beside its writer's dataset."""
    import fcntl

    from rdea_lab.store import journal as jr

    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS)
    w.append(block(0.0, 5))
    w._close_fd()
    real_flock = fcntl.flock

    class Racing:
        LOCK_EX, LOCK_NB, LOCK_UN = fcntl.LOCK_EX, fcntl.LOCK_NB, fcntl.LOCK_UN

        @staticmethod
        def flock(fd, op):  # between the recover's open and its lock, the writer removes the lock file and lets go
            if op & fcntl.LOCK_EX:  # (the writer's letting go undoes its lock: LOCK_UN)
                os.unlink(journal_path(out) / jr.LOCK)
                w._release()
            return real_flock(fd, op)

    monkeypatch.setattr(jr, "fcntl", Racing)
    with pytest.raises(FileNotFoundError):
        jr._try_lock(journal_path(out))
    monkeypatch.setattr(jr, "fcntl", fcntl)
    assert not out.exists()


def test_a_claim_never_makes_its_lock_file_again_in_a_folder_being_removed(tmp_path, monkeypatch):
    """A recover removing what looks like an abandoned claim has unlinked its lock file and not yet removed
    the folder when the writer tries its lock again: the writer must not make a new lock file there (the
    recover's second pass would remove it with the writer's files); it waits for the folder to go and claims
    again, and ends holding the lock on its own new folder's file."""
    import threading

    from rdea_lab.store import journal as jr

    out = tmp_path / "run.nc"
    folder = journal_path(out)
    real, calls, removing = jr._try_lock, [], []

    def contested(f, create=True):
        calls.append(create)
        if len(calls) == 1:  # a recover holds the new claim's lock and starts removing it
            removing.append(_other_process_lock(f))
            os.unlink(Path(f) / jr.LOCK)

            def finish_removal():
                jr._remove_journal(folder, removing[0])
                os.close(removing[0])

            threading.Timer(0.05, finish_removal).start()
        return real(f, create)

    monkeypatch.setattr(jr, "_try_lock", contested)
    w = JournalWriter(out, ATTRS)
    monkeypatch.setattr(jr, "_try_lock", real)
    assert not any(calls)  # every attempt without making the lock file
    assert os.path.samestat(os.fstat(w._lock), os.stat(folder / jr.LOCK))
    w.append(block(0.0, 3))
    with pytest.raises(RunInProgress):
        recover(out)
    w.finish("complete", "")
    assert open_run(out).sizes["time"] == 3


def _holders_of(path) -> list[int]:
    """This process's descriptors open on ``path`` (Linux: /proc/self/fd)."""
    fds = []
    for name in os.listdir("/proc/self/fd"):
        try:
            if os.readlink(f"/proc/self/fd/{name}") == str(path):
                fds.append(int(name))
        except OSError:  # the descriptor of the listing itself, gone
            pass
    return fds


class ForkedMeanwhile(netCDF4.Dataset):
    """netCDF4's Dataset, each ``*.nc.tmp`` it opens followed by a child process holding this process's
    descriptors on it (as a subprocess another thread starts just then does until it closes them)."""

    children: list = []

    def __new__(cls, filename, *args, **kwargs):
        if not str(filename).endswith(".nc.tmp"):  # any other file: netCDF4's own
            return cls.__base__(filename, *args, **kwargs)
        return super().__new__(cls)

    def __init__(self, filename, *args, **kwargs):
        super().__init__(filename, *args, **kwargs)
        self.children.append(subprocess.Popen(["sleep", "30"], pass_fds=_holders_of(filename)))


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="finds the open descriptors in /proc")
@pytest.mark.parametrize("by", ["finish", "recover"])
def test_a_process_forked_while_the_dataset_is_written_cannot_make_the_conversion_fail(tmp_path, monkeypatch, by):
    """The interrupt soak's 'NetCDF: HDF error' opening <out>.nc.tmp: HDF5 holds an flock on a file as long as
    it is open, and a flock belongs to the open file description, which a process forked by another thread (a
    subprocess starting: fork, preexec_fn, closing its descriptors, exec) holds too until it closes its copy. A
    converter that wrote the file, closed it and opened it again was refused by that lock, held by nobody that
    writes. Here every open of the temporary is followed by such a child, holding its copy until the end."""
    children = ForkedMeanwhile.children = []
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS, extra=("model_status",))
    blocks = [block(0.0, 100), block(1.0, 57)]
    for b in blocks:
        w.append(b)
    monkeypatch.setattr(netCDF4, "Dataset", ForkedMeanwhile)
    try:
        if by == "finish":
            w.finish("complete", "")
        else:
            w.close()  # killed
            recover(journal_path(out))
    finally:
        monkeypatch.undo()
        for child in children:
            child.kill()
            child.wait()
    assert children  # the temporary was opened, and a child held it meanwhile
    ds = open_run(out)
    np.testing.assert_array_equal(ds["force"].values, np.concatenate([b["force"] for b in blocks]))
    assert ds.attrs["status"] == ("complete" if by == "finish" else "interrupted")
    assert not journal_path(out).exists() and not list(tmp_path.glob("*.tmp"))


@pytest.mark.parametrize("by", ["finish", "recover", "write_dataset"])
def test_a_stale_temporary_is_discarded_and_the_journal_converted_afresh(tmp_path, by):
    """A ``<out>.nc.tmp`` the lock's holder did not write in this conversion (a killed conversion's half file,
    here junk whose file is still locked through a description another process holds) is no part of the run:
    it is discarded and the dataset written from the journal, every row of it; `write_dataset` discards its
    temporary likewise."""
    import sys

    out = tmp_path / "run.nc"
    stale = tmp_path / "run.nc.tmp"
    stale.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(4000))
    with subprocess.Popen([sys.executable, "-c", "import fcntl, sys\nf = open(sys.argv[1], 'rb')\n"
                           "fcntl.flock(f, fcntl.LOCK_EX)\nprint(1, flush=True)\nsys.stdin.read()", str(stale)],
                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True) as holder:
        assert holder.stdout.readline().strip() == "1"
        if by == "write_dataset":  # an import's, a self-sensing estimate's: no journal, the same temporary
            from rdea_lab.store.journal import write_dataset

            b = block(0.0, 120)
            write_dataset(xr.Dataset({k: ("time", b[k]) for k in VARIABLES if k != "time"},
                                     coords={"time": b["time"]}, attrs=ATTRS), out)
        else:
            w = JournalWriter(out, ATTRS)
            w.append(block(0.0, 120))
            if by == "finish":
                w.finish("complete", "")
            else:
                w.close()
                recover(out)
        holder.stdin.close()
    ds = open_run(out)
    np.testing.assert_array_equal(ds["time"].values, block(0.0, 120)["time"])
    assert not journal_path(out).exists() and not stale.exists()


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="finds the open descriptors in /proc")
@pytest.mark.parametrize("by", ["finish", "recover", "write_dataset", "write_blocks"])
def test_a_dataset_written_while_a_process_was_forked_is_read_and_indexed_at_once(tmp_path, monkeypatch, capsys, by):
    """What follows a dataset's writing in the same process (its catalogue row, `open_run`, the overview) reads
    the file at once, while a child forked meanwhile may still hold a copy of the writer's descriptor: the
    writer's lock must not outlive its own close through that copy ("NetCDF: HDF error" reading it), and
    `write_dataset` must write a long run's overview without opening its file a second time. So for the
    dataset of a run (`JournalWriter.finish`), of a killed run (`recover`, which indexes it), of an import
    or a self-sensing estimate (`write_dataset`) and of a prediction written block by block (`write_blocks`)."""
    from rdea_lab.store import journal as J
    from rdea_lab.store.blocks import write_blocks
    from rdea_lab.store.index import read_row
    from rdea_lab.store.overview import read_overview

    monkeypatch.setenv("RDEA_LAB_CATALOG", str(tmp_path / "catalogue.sqlite"))
    monkeypatch.setattr(J, "OVERVIEW_ABOVE", 100)  # an overview for these few samples, as for a day-long run
    children = ForkedMeanwhile.children = []
    out = tmp_path / "run.nc"
    blocks = [block(0.0, 100), block(1.0, 57)]
    with monkeypatch.context() as patched:
        patched.setattr(netCDF4, "Dataset", ForkedMeanwhile)
        try:
            if by == "write_blocks":  # a prediction written block by block (no overview)
                write_blocks(out, 157, [(0, 100, blocks[0]), (100, 157, blocks[1])], lambda: ATTRS)
            elif by == "write_dataset":
                ds = xr.Dataset({k: ("time", np.concatenate([b[k] for b in blocks])) for k in VARIABLES if k != "time"},
                                coords={"time": np.concatenate([b["time"] for b in blocks])}, attrs=ATTRS)
                J.write_dataset(ds, out)
            else:
                w = JournalWriter(out, ATTRS, extra=("model_status",))
                for b in blocks:
                    w.append(b)
                if by == "finish":
                    w.finish("complete", "")
                else:
                    w.close()
                    recover(journal_path(out))  # indexes the dataset it wrote
            assert children  # the temporary was opened, and a child holds it still
            row, _ = read_row(out)  # while the children live
            with open_run(out) as ds:
                np.testing.assert_array_equal(ds["force"].values, np.concatenate([b["force"] for b in blocks]))
            view = read_overview(out)
        finally:
            for child in children:
                child.kill()
                child.wait()
    assert row["samples"] == 157 and row["peak_force"] == max(np.abs(b["force"]).max() for b in blocks)
    if by != "write_blocks":
        assert view is not None and view.samples == 157
        np.testing.assert_array_equal(view.envelopes["force"][1], [max(b["force"].max() for b in blocks)])
    assert "not in the catalogue" not in capsys.readouterr().err
    if by == "recover":
        import sqlite3

        with sqlite3.connect(tmp_path / "catalogue.sqlite") as db:
            assert db.execute("select samples, status from runs").fetchall() == [(157, "interrupted")]


@pytest.mark.parametrize("by", ["close", "failed recover"])
def test_a_journal_let_go_is_not_held_by_a_process_forked_meanwhile(tmp_path, by):
    """A journal's lock is an flock too: a child forked while a writer (or a recover) held it keeps a copy of
    its descriptor until it closes it. A journal let go (`JournalWriter.close`, a `recover` that could not
    write its dataset) must be free for a `recover` at once, not taken for a run in progress meanwhile."""
    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS)
    w.append(block(0.0, 30))
    child = subprocess.Popen(["sleep", "30"], pass_fds=[w._lock])
    try:
        w.close()  # killed, as far as the journal is concerned
        if by == "failed recover":  # this one holds the lock and lets go of it (the dataset is in the way)
            import fcntl

            out.write_bytes(b"in the way")
            real = fcntl.flock

            def forking(fd, op):  # a child forked once recover holds the journal's lock
                real(fd, op)
                if op & fcntl.LOCK_EX:
                    child.kill()
                    child.wait()
                    holders.append(subprocess.Popen(["sleep", "30"], pass_fds=[fd]))

            holders = []
            with pytest.MonkeyPatch.context() as patched:
                patched.setattr(fcntl, "flock", forking)
                with pytest.raises(FileExistsError):
                    recover(out)
            assert holders
            child = holders[0]
            out.unlink()
        assert recover(out) == out
    finally:
        child.kill()
        child.wait()
    np.testing.assert_array_equal(open_run(out)["time"].values, block(0.0, 30)["time"])


def _dataset_of(b):
    return xr.Dataset({k: ("time", b[k]) for k in VARIABLES if k != "time"}, coords={"time": b["time"]}, attrs=ATTRS)


def test_a_second_writer_of_the_same_output_never_costs_a_run_its_samples(tmp_path, monkeypatch):
    """Two writers given one output (a run finishing while an import writes to its name): the import, which
    made way for its own temporary file (`_hdf5.claim`), writes the output; the run finds its temporary file
    replaced, renames nothing and keeps its journal, every row of which `recover` then writes elsewhere."""
    from rdea_lab.store import _hdf5, journal
    from rdea_lab.store.journal import write_dataset

    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS, background=False)
    blocks = [block(0.0, 100), block(1.0, 57)]
    for b in blocks:
        w.append(b)
    convert = journal._Converter.convert

    def meanwhile(self, upto, stop=lambda: False):  # the import runs while the run's rows are converted
        write_dataset(_dataset_of(block(5.0, 7)), out)
        return convert(self, upto, stop)

    monkeypatch.setattr(journal._Converter, "convert", meanwhile)
    with pytest.raises(_hdf5.TmpTaken):
        w.finish("complete", "")
    monkeypatch.undo()
    assert open_run(out)["time"].size == 7  # the import's, whole
    assert journal_path(out).exists()
    saved = recover(journal_path(out), tmp_path / "saved.nc")
    np.testing.assert_array_equal(open_run(saved)["force"].values, np.concatenate([b["force"] for b in blocks]))
    assert not list(tmp_path.glob("*.tmp"))


@pytest.mark.parametrize("by", ["finish", "write_dataset"])
def test_a_temporary_file_whose_making_failed_is_not_left_behind(tmp_path, monkeypatch, by):
    """The make of the temporary file fails after the file is on disk (a full disk at its first write): the
    file is removed, as every half-written file is; a file a live writer holds is not (`_hdf5.drop_unmade`)."""
    from rdea_lab.store.journal import DiskFull, write_dataset

    real = netCDF4.Dataset

    def full(path, mode="r", **kw):
        if mode == "w":
            Path(path).write_bytes(b"\x89HDF\r\n\x1a\n")  # made, then the disk is full
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real(path, mode, **kw)

    out = tmp_path / "run.nc"
    w = JournalWriter(out, ATTRS, background=False) if by == "finish" else None
    if w is not None:
        w.append(block(0.0, 50))
    monkeypatch.setattr(netCDF4, "Dataset", full)
    with pytest.raises((OSError, DiskFull)):
        if w is not None:
            w.finish("complete", "")
        else:
            write_dataset(_dataset_of(block(0.0, 50)), out)
    monkeypatch.undo()
    assert not list(tmp_path.glob("*.tmp")) and not out.exists()
    if w is not None:
        assert journal_path(out).exists()  # the journal stays, for recover


def test_a_failed_make_leaves_a_live_writers_file_alone(tmp_path, monkeypatch):
    """Where the make failed because another writer made the file first (and holds it open, locked), that
    file is not removed."""
    import sys

    from rdea_lab.store.journal import write_dataset

    out = tmp_path / "run.nc"
    theirs = tmp_path / "run.nc.tmp"
    real = netCDF4.Dataset

    def beaten(path, mode="r", **kw):
        if mode == "w":
            raise OSError(errno.EEXIST, "File exists", str(path))
        return real(path, mode, **kw)

    theirs.write_bytes(b"theirs")
    with subprocess.Popen([sys.executable, "-c", "import fcntl, sys\nf = open(sys.argv[1], 'rb')\n"
                           "fcntl.flock(f, fcntl.LOCK_EX)\nprint(1, flush=True)\nsys.stdin.read()", str(theirs)],
                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True) as holder:
        assert holder.stdout.readline().strip() == "1"
        monkeypatch.setattr("rdea_lab.store._hdf5.claim", lambda tmp: None)  # they made it after our claim
        monkeypatch.setattr(netCDF4, "Dataset", beaten)
        with pytest.raises(OSError):
            write_dataset(_dataset_of(block(0.0, 50)), out)
        monkeypatch.undo()
        assert theirs.read_bytes() == b"theirs"
        holder.stdin.close()
