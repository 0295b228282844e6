"""The catalogue index (rdea_lab.store.index): written by run, recover and import; rebuilt from the files;
files changed or removed since indexing reported; concurrent writers on SQLite and PostgreSQL.

Expected values come from the files themselves (hashlib over the bytes, the variables read back with
open_run), never from the index under test.
"""

from __future__ import annotations

import hashlib
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rdea_lab
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli
from rdea_lab.specs import SpecError, load_specimen
from rdea_lab.store import JournalWriter, catalog, journal_path, open_run, recover
from rdea_lab.store import index
from rdea_lab.store.importers import ImportOptions, import_files, parse_map

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
CSV = Path(__file__).resolve().parent / "import_data" / "good_semicolon_decimal_comma.csv"
#: 1 s at 100 Hz on the twin: 101 samples
SHORT = """\
name: short_run
kind: custom
sample_rate: 100 Hz
stretch:
  - {kind: ramp, duration: 1 s, to: 1.2}
voltage:
  - {kind: ramp, duration: 1 s, to: 1 kV}
"""


def attrs(run_id, **more):
    return {"Conventions": "CF-1.8", "title": "t", "rdea_lab_version": "0", "run_id": run_id, "backend": "twin",
            "specimen_id": "specimen-2", "specimen": "id: s\n", "protocol_name": "p", "protocol_kind": "tensile",
            "protocol": "name: p\n", "sample_rate": 100.0, "seed": 0, "created": "2026-03-02T10:00:00Z",
            "status": "running", "status_reason": "", "history": "created", "institution": "not stated",
            "source": "a test", "references": "none", "metadata": '{"batch": "B7"}', **more}


def block(t0, n, scale=1.0):
    t = t0 + np.arange(n) / 100.0
    return {"time": t, "stretch": 1 + 0.1 * t, "position": 0.0034 * t, "voltage": 100 * t, "force": -scale * np.sin(t),
            "capacitance": np.full(n, np.nan), "stretch_setpoint": 1 + 0.1 * t, "voltage_setpoint": 100 * t}


def journal_run(out, run_id, n=150, scale=1.0, **more):
    """A finished dataset written through the journal (no index row: the engine's hook is not on this path)."""
    w = JournalWriter(out, attrs(run_id, **more))
    w.append(block(0.0, n, scale))
    w.finish("complete", "")
    return out


def sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def rows(url, folder=None):
    table = index.query(columns=[c for c in index.RUN_COLUMNS if c != "indexed_at"] + ["metadata"], folder=folder,
                        url=url)
    return table.sort_values("run_id").reset_index(drop=True)


@pytest.fixture
def short_file(tmp_path):
    path = tmp_path / "short_run.yaml"
    path.write_text(SHORT)
    return path


def test_a_run_writes_its_row_when_it_ends(tmp_path, short_file):
    out = tmp_path / "runs" / "a.nc"
    ds = rdea_lab.run_protocol(short_file, CARD, rdea_lab.Twin(model="su"), out=out, metadata={"batch": "B7"})
    cat = tmp_path / "runs" / index.CATALOG_FILE
    assert cat.is_file()
    table = rows(index.resolve_catalog(out.parent))
    assert len(table) == 1
    row = table.iloc[0]
    data = open_run(out)
    assert row.run_id == ds.attrs["run_id"] and row.file == str(out)
    assert row.sha256 == sha(out) and row["size"] == out.stat().st_size
    assert row.samples == data.sizes["time"] == 101
    assert row.peak_force == pytest.approx(np.nanmax(np.abs(data["force"].values)), rel=1e-12)
    assert row.peak_stretch == pytest.approx(np.nanmax(data["stretch"].values), rel=1e-12)
    assert row.duration_s == pytest.approx(float(data.time[-1] - data.time[0]))
    assert (row.status, row.specimen, row.protocol, row.origin, row.metadata) == (
        "complete", "specimen-2", "short_run", "twin", "batch=B7")
    assert row.params_hash == hashlib.sha256(data.attrs["parameters"].encode()).hexdigest()
    assert row.created == data.attrs["created"]
    # the stored path is relative to the catalogue's folder, so the folder can move whole
    assert sqlite3.connect(cat).execute("select file from runs").fetchall() == [("a.nc",)]


def test_recover_and_import_write_their_rows(tmp_path):
    out = tmp_path / "killed.nc"
    w = JournalWriter(out, attrs("killed"))
    w.append(block(0.0, 120))
    w.close()  # as SIGKILL leaves it
    assert catalog(tmp_path)["status"].tolist() == ["unfinished (rdea-lab recover)"]  # a journal, scanned
    recover(journal_path(out))
    [(_, target, _)] = import_files([CSV], load_specimen(CARD), ImportOptions(
        "csv", parse_map("time=Zeit,position=Weg,force=Kraft")), out=tmp_path / "imported.nc")
    table = rows(index.resolve_catalog(tmp_path))
    assert sorted(table.file) == sorted([str(out), str(target)])
    got = table.set_index("file")
    assert got.loc[str(out), "status"] == "interrupted" and got.loc[str(out), "samples"] == 120
    assert got.loc[str(out), "sha256"] == sha(out)
    assert got.loc[str(target), "origin"] == "import" and got.loc[str(target), "samples"] == 4
    assert got.loc[str(target), "peak_force"] == pytest.approx(0.41)  # the CSV's largest |Kraft| [N]


def test_rebuild_on_an_empty_catalogue_equals_the_incremental_index(tmp_path, short_file):
    folder = tmp_path / "d"
    rdea_lab.run_protocol(short_file, CARD, rdea_lab.Twin(model="su"), out=folder / "a.nc", metadata={"op": "ana"})
    w = JournalWriter(folder / "b.nc", attrs("b"))
    w.append(block(0.0, 50))
    w.close()
    recover(folder / "b.nc")
    import_files([CSV], load_specimen(CARD), ImportOptions("csv", parse_map("time=Zeit,position=Weg,force=Kraft")),
                 out=folder / "c.nc")
    incremental = rows(index.resolve_catalog(folder))
    fresh = f"sqlite:///{folder / 'fresh.sqlite'}"  # same folder: the same relative paths
    result = index.rebuild(folder, fresh)
    assert result.counts["added"] == 3 and result.consistent is False and not result.unreadable
    rebuilt = rows(fresh)
    assert len(incremental) == 3
    assert rebuilt.equals(incremental), (rebuilt.compare(incremental) if rebuilt.shape == incremental.shape else
                                         (rebuilt, incremental))
    again = index.rebuild(folder, fresh)
    assert again.counts["unchanged"] == 3 and again.consistent


def test_a_file_edited_or_deleted_after_indexing_is_reported(tmp_path, capsys):
    import netCDF4

    folder = tmp_path / "d"
    for name in "abc":
        index.index_run(journal_run(folder / f"{name}.nc", name), None)
    with netCDF4.Dataset(folder / "a.nc", "a") as nc:  # edited by hand after the run
        nc.variables["force"][0] = 99.0
        nc.variables["force"].delncattr("actual_range") if "actual_range" in nc.variables["force"].ncattrs() else None
    (folder / "b.nc").unlink()
    (folder / "junk.nc").write_bytes(b"not netcdf")
    table = catalog(folder).set_index("file")
    assert table.loc[str(folder / "a.nc"), "file_state"] == index_listing().CHANGED
    assert table.loc[str(folder / "b.nc"), "file_state"] == index_listing().MISSING
    assert table.loc[str(folder / "c.nc"), "file_state"] == index_listing().OK
    assert table.loc[str(folder / "junk.nc"), "status"].startswith("unreadable")
    assert run_cli(cli, ["ls", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "complete (file changed since indexed)" in out and "complete (file missing)" in out
    assert run_cli(cli, ["catalog", "check", str(folder)]) == 4  # differs: a report, not an error
    capsys.readouterr()
    assert run_cli(cli, ["catalog", "rebuild", str(folder)]) == 0
    out = capsys.readouterr().out
    assert f"{folder / 'a.nc'}: changed since indexed; re-indexed" in out
    assert f"{folder / 'b.nc'}: missing; its row removed" in out
    assert f"{folder / 'junk.nc'}: unreadable" in out
    table = rows(index.resolve_catalog(folder)).set_index("file")
    assert sorted(table.index) == [str(folder / "a.nc"), str(folder / "c.nc")]
    a = table.loc[str(folder / "a.nc")]
    assert a.peak_force == 99.0  # read from the variable: the edit removed actual_range
    assert a.sha256 == sha(folder / "a.nc")
    assert run_cli(cli, ["catalog", "check", str(folder)]) == 4  # junk.nc stays unreadable
    (folder / "junk.nc").unlink()
    capsys.readouterr()
    assert run_cli(cli, ["catalog", "check", str(folder)]) == 0


def test_a_copy_of_a_run_is_listed_once_and_not_indexed(tmp_path):
    import shutil

    out = journal_run(tmp_path / "a.nc", "a")
    index.index_run(out)
    shutil.copy(out, tmp_path / "b.nc")  # a backup beside it: same run id
    for _ in range(2):  # stable: the copy never takes the run's row
        table = catalog(tmp_path).set_index("file")
        assert table.loc[str(out), "file_state"] == "ok"
        assert table.loc[str(tmp_path / "b.nc"), "status"].startswith("not indexed (a copy: run id a is ")
    assert index.rebuild(tmp_path).duplicates == (str(tmp_path / "b.nc"),)


def test_two_files_of_one_run_never_indexed_before_are_listed_once_and_rebuild_agrees(tmp_path):
    """A folder never listed holding a run and its copy (same run id): the first listing indexes one file and
    lists the other as a copy (both went into one batch before, and the last silently won); a rebuild keeps the
    row where the index holds it, and the listing after it is the same."""
    import shutil

    out = journal_run(tmp_path / "src" / "r.nc", "r")
    folder = tmp_path / "f"
    folder.mkdir()
    for name in ("b.nc", "a_copy.nc"):
        shutil.copy(out, folder / name)
    first = catalog(folder).set_index("file")
    assert len(first) == 2
    indexed = [f for f in first.index if not first.loc[f, "status"].startswith("not indexed")]
    assert len(indexed) == 1
    other = next(f for f in first.index if f not in indexed)
    assert first.loc[other, "status"].startswith("not indexed (a copy: run id r is ")
    assert index.rebuild(folder).duplicates == (other,)
    after = catalog(folder).set_index("file")
    assert list(after.loc[indexed, "file_state"]) == ["ok"]
    assert after.loc[other, "status"] == first.loc[other, "status"]


def index_listing():
    from rdea_lab.store import listing

    return listing


def test_a_run_overwritten_in_place_replaces_its_row(tmp_path):
    out = journal_run(tmp_path / "a.nc", "first")
    index.index_run(out)
    out.unlink()
    journal_run(out, "second", scale=2.0)
    index.index_run(out)
    table = rows(index.resolve_catalog(tmp_path))
    assert table.run_id.tolist() == ["second"]
    assert table.peak_force.iloc[0] == pytest.approx(2 * np.sin(1.49))  # max |2 sin t| over t <= 1.49 s


def test_a_catalogue_that_cannot_be_written_leaves_the_run_whole_and_says_so(tmp_path, short_file, monkeypatch,
                                                                            capfd):
    monkeypatch.setattr(index, "BUSY_TIMEOUT", 0.2)
    out = journal_run(tmp_path / "a.nc", "a")
    index.index_run(out)
    locker = sqlite3.connect(tmp_path / index.CATALOG_FILE, isolation_level=None)
    locker.execute("BEGIN IMMEDIATE")  # another writer holds the lock longer than the busy timeout
    try:
        before = sha(out)
        assert index.index_quietly(out) is None
        err = capfd.readouterr().err.splitlines()
        assert len(err) == 1 and "is not in the catalogue" in err[0]
        assert err[0].endswith(f"rdea-lab catalog rebuild {tmp_path}") and "locked" in err[0]
        assert sha(out) == before
    finally:
        locker.rollback() if locker.in_transaction else None
        locker.close()
    # a server that is down: the run is written, one line says it is not indexed
    monkeypatch.setenv(index.ENV, "postgresql://nobody@127.0.0.1:1/none")
    ds = rdea_lab.run_protocol(short_file, CARD, rdea_lab.Twin(model="su"), out=tmp_path / "b.nc")
    err = capfd.readouterr().err.splitlines()
    assert open_run(tmp_path / "b.nc").sizes["time"] == ds.sizes["time"] == 101
    assert len(err) == 1 and "b.nc is not in the catalogue" in err[0] and "rdea-lab catalog rebuild" in err[0]


@pytest.mark.parametrize("text", ["mysql://h/db", "", "postgresql://h", "sqlite://"])
def test_a_bad_catalogue_url_is_refused(text):
    with pytest.raises(SpecError, match="--catalog"):
        index.catalog_url(text)


def test_ls_options_and_their_errors(tmp_path, capsys):
    folder = tmp_path / "d"
    for i in range(5):
        journal_run(folder / f"r{i}.nc", f"r{i}", metadata=f'{{"batch": "B{i % 2}"}}',
                    created=f"2026-03-0{i + 1}T00:00:00Z")
    assert run_cli(cli, ["ls", str(folder), "--where", "md.batch == 'B1'", "--columns", "file,md.batch"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split() == ["file", "md.batch"] and [ln.split()[1] for ln in out[1:]] == ["B1", "B1"]
    assert run_cli(cli, ["ls", str(folder), "--since", "2026-03-04", "--columns", "file"]) == 0
    assert capsys.readouterr().out.split()[1:] == [str(folder / "r3.nc"), str(folder / "r4.nc")]
    assert run_cli(cli, ["ls", str(folder), "--limit", "2"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "(2 of 5 runs: --limit 2)"
    for args, what in ((["--where", "md.batch = 'B1'"], "--where: position 10:"), (["--columns", "file,nope"],
                       "--columns: nope: unknown column"), (["--catalog", "ftp://x"], "--catalog:"),
                       (["--since", "March"], "--since:")):
        assert run_cli(cli, ["ls", str(folder), *args]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"rdea-lab: {what}"), err


# ---- concurrent writers ----

WRITER = """
import sys
from datetime import datetime
from rdea_lab.store.index import Catalog, RUN_COLUMNS
url, first, n, shared = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
def row(i):
    r = {c: None for c in RUN_COLUMNS}
    r.update(run_id=f"run-{i:05d}", file=f"/rig/run-{i:05d}.nc", host="rig", sha256="0" * 64, size=i, mtime=0.0,
             status="complete", samples=i, created=datetime(2026, 3, 1), indexed_at=datetime(2026, 3, 1))
    return r
with Catalog(url) as cat:
    ids = list(range(first, first + n)) + list(range(shared))  # both writers also write the same few runs
    for i in ids:  # one transaction per run, as each run's end writes it
        cat.write([(row(i), {"writer": str(first), "i": str(i)})])
"""


def two_writers(url, total=200, shared=10):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, url, str(first), str(total // 2), str(shared)], env=env,
                              stderr=subprocess.PIPE, text=True) for first in (0, total // 2)]
    for p in procs:
        assert p.wait(timeout=120) == 0, p.stderr.read()
        p.stderr.close()
    with index.Catalog(url) as cat:
        from sqlalchemy import func, select

        ids = [r["run_id"] for r in cat.execute(select(cat.runs.c.run_id))]
        md = cat.execute(select(cat.md.c.run_id, func.count().label("n")).group_by(cat.md.c.run_id))
    assert len(ids) == len(set(ids)) == total  # none lost, none doubled
    assert sorted(ids) == [f"run-{i:05d}" for i in range(total)]
    assert {r["n"] for r in md} == {2} and len(md) == total  # each run's metadata replaced whole, once


@pytest.mark.slow
def test_two_writers_on_sqlite_lose_and_double_no_row(tmp_path):
    two_writers(f"sqlite:///{tmp_path / index.CATALOG_FILE}")


def test_two_threads_on_one_new_sqlite_file_lose_and_double_no_row(tmp_path):
    """The default suite's version of the two-process test: two connections race to create the file and its
    tables, then write 50 runs each, one transaction per run, and both write the same 5."""
    import threading
    from datetime import datetime

    url = f"sqlite:///{tmp_path / index.CATALOG_FILE}"
    errors = []

    def writer(first):
        try:
            with index.Catalog(url) as cat:
                for i in [*range(first, first + 50), *range(5)]:
                    row = {c: None for c in index.RUN_COLUMNS}
                    row.update(run_id=f"run-{i:05d}", file=f"/rig/{i}.nc", host="rig", created=datetime(2026, 3, 1))
                    cat.write([(row, {"writer": str(first)})])
        except Exception as exc:  # noqa: BLE001 (reported by the assertion below)
            errors.append(exc)

    threads = [threading.Thread(target=writer, args=(first,)) for first in (0, 50)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors
    con = sqlite3.connect(tmp_path / index.CATALOG_FILE)
    ids = [r for r, in con.execute("select run_id from runs")]
    assert sorted(ids) == [f"run-{i:05d}" for i in range(100)]
    assert con.execute("select count(*), count(distinct run_id) from run_metadata").fetchone() == (100, 100)
    con.close()


@pytest.fixture
def pg(postgresql_url):
    """The PostgreSQL database, without the catalogue's tables before and after the test."""
    url = index.catalog_url(postgresql_url)

    def drop():
        from sqlalchemy import create_engine

        engine = create_engine(url)
        index._tables()[0].drop_all(engine)
        engine.dispose()

    drop()
    yield url
    drop()


@pytest.mark.slow
def test_two_writers_on_postgresql_lose_and_double_no_row(pg):
    two_writers(pg)


def test_postgresql_answers_as_sqlite(tmp_path, pg):
    folder = tmp_path / "d"
    for i in range(6):
        journal_run(folder / f"r{i}.nc", f"r{i}", n=50 + i, scale=0.5 + i, metadata=f'{{"batch": "B{i % 3}"}}',
                    created=f"2026-03-0{i + 1}T12:00:00Z")
    lite = f"sqlite:///{tmp_path / 'lite.sqlite'}"
    for url in (lite, pg):
        assert index.rebuild(folder, url).counts["added"] == 6
    for where in ("md.batch in ['B0', 'B2'] and samples >= 52", "peak_force > 2.5 or md.batch == 'B1'",
                  "not (md.batch == 'B0') and created >= '2026-03-03'"):
        a = catalog(folder, where=where, catalog=lite, columns=["file", "samples", "peak_force", "md.batch"])
        b = catalog(folder, where=where, catalog=pg, columns=["file", "samples", "peak_force", "md.batch"])
        assert len(a) > 0 and a.equals(b), (where, a, b)
