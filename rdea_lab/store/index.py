"""The catalogue index: one row per run in a database (SQLite beside the runs, or a lab's PostgreSQL).

The files stay the source of truth: a row says what its file held when it was indexed (sha256, size,
mtime with it), `query` stats each file it lists and marks one that changed or vanished since, and
`rebuild` re-reads every file below a folder. Rows are written when a run ends (the engine's
`~rdea_lab.runs.app.execute_setup`), by `~rdea_lab.store.journal.recover` and by
`~rdea_lab.store.importers.import_files`; `index_quietly` never lets the catalogue break a run.

Where the catalogue is (`resolve_catalog`): ``url`` (``--catalog``) > the environment variable
``RDEA_LAB_CATALOG`` > the SQLite file ``rdea-lab-catalog.sqlite`` in the nearest folder at or above the
run's folder that has one, else in that folder. One SQL layer (SQLAlchemy Core) for both engines: the same
statements, ``INSERT .. ON CONFLICT DO UPDATE`` on ``run_id`` in one transaction per run, so several
writers (rig PCs, a campaign's workers) neither lose nor double a row. In a SQLite file beside the runs a
run's ``file`` is stored relative to the catalogue's folder (the folder can be moved or copied whole);
elsewhere it is absolute, with the ``host`` that wrote it.
"""

from __future__ import annotations

import hashlib
import math
import os
import socket
import sys
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..specs.errors import DOCUMENT, SpecError, UserError, show

#: The SQLite catalogue's file name, beside the runs.
CATALOG_FILE = "rdea-lab-catalog.sqlite"
#: The environment variable naming the catalogue (a URL), below ``--catalog``.
ENV = "RDEA_LAB_CATALOG"
#: How long a writer waits for another's lock on a SQLite catalogue [s] before the run is left unindexed.
BUSY_TIMEOUT = 30.0
#: How long a connection to a PostgreSQL catalogue may take [s].
CONNECT_TIMEOUT = 5
#: Samples read at a time when a file has no ``actual_range`` (older files).
CHUNK = 1 << 20

#: The columns of ``runs``: name -> (SQLAlchemy type name, what it holds).
RUN_COLUMNS = {
    "run_id": ("text", "the run's id (its ``run_id`` attribute), unique"),
    "file": ("text", "the dataset (relative to a SQLite catalogue's folder when below it, else absolute)"),
    "host": ("text", "the machine that indexed it"),
    "sha256": ("text", "sha256 of the file when indexed"),
    "size": ("int", "file size when indexed [bytes]"),
    "mtime": ("float", "file modification time when indexed [s since 1970, UTC]"),
    "specimen": ("text", "specimen id"), "protocol": ("text", "protocol name"),
    "protocol_kind": ("text", "protocol kind"), "backend": ("text", "twin, rig or import"),
    "origin": ("text", "where the data come from: twin, emulator, rig, import or unknown"),
    "model": ("text", "the twin's model ('-' for none)"), "status": ("text", "complete, aborted, interrupted"),
    "status_reason": ("text", "why the run ended so"), "created": ("time", "start of the run (UTC)"),
    "finished": ("time", "end of the run (UTC)"), "samples": ("int", "samples in the file"),
    "duration_s": ("float", "last time minus first [s]"), "sample_rate": ("float", "planned sample rate [Hz]"),
    "peak_force": ("float", "largest |force| [N]"), "peak_stretch": ("float", "largest stretch [-]"),
    "peak_voltage": ("float", "largest |voltage| [V]"),
    "params_hash": ("text", "sha256 of the twin's parameter set (its ``parameters`` attribute), '' if none"),
    "rdea_lab_version": ("text", "rdea-lab version that wrote the run"), "indexed_at": ("time", "when indexed (UTC)"),
}

_TABLES = None


def _tables():
    """The ``runs`` and ``run_metadata`` tables (made on first use: importing this module needs no SQLAlchemy)."""
    global _TABLES
    if _TABLES is None:
        from sqlalchemy import BigInteger, Column, DateTime, Float, Index, MetaData, String, Table, Text

        kinds = {"text": Text, "int": BigInteger, "float": Float, "time": DateTime}
        meta = MetaData()
        runs = Table("runs", meta, *(Column(name, String(64) if name == "run_id" else kinds[kind](),
                                            primary_key=name == "run_id", nullable=name not in ("run_id", "file"))
                                     for name, (kind, _) in RUN_COLUMNS.items()),
                     Index("runs_file", "file"), Index("runs_created", "created"))
        md = Table("run_metadata", meta, Column("run_id", String(64), primary_key=True),
                   Column("key", String(64), primary_key=True), Column("value", Text, nullable=False),
                   Index("run_metadata_key_value", "key", "value"))
        _TABLES = (meta, runs, md)
    return _TABLES


class CatalogUnavailable(UserError):
    """The catalogue cannot be reached or written (locked too long, a server down): one line saying so."""


def _url_problem(text: str) -> str:
    return (f"{show(text)} is not a catalogue; allowed: a SQLite file (path or sqlite:///PATH) or "
            "postgresql://USER@HOST[:PORT]/DATABASE")


def catalog_url(text: str, source: str = "--catalog") -> str:
    """A catalogue given by the user as the URL SQLAlchemy opens: a path or ``sqlite:///PATH`` (a SQLite file),
    ``postgresql://...`` (through psycopg: ``postgresql+psycopg://...``).

    Parameters
    ----------
    text : str
        What ``--catalog`` or ``RDEA_LAB_CATALOG`` holds.
    source : str
        Where it came from, for the message.

    Returns
    -------
    str
        The URL.

    Raises
    ------
    SpecError
        Anything else (another scheme, a URL that does not parse).
    """
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    text = str(text).strip()
    if not text:
        raise SpecError(source, DOCUMENT, _url_problem(text))
    if "://" not in text:  # a path: a SQLite file
        return f"sqlite:///{os.path.abspath(text)}"
    try:
        url = make_url(text)
    except ArgumentError:
        raise SpecError(source, DOCUMENT, _url_problem(text)) from None
    if url.drivername in ("postgresql", "postgres", "postgresql+psycopg"):
        if not url.database:
            raise SpecError(source, DOCUMENT, f"{show(text)} names no database; allowed: "
                            "postgresql://USER@HOST[:PORT]/DATABASE")
        return url.set(drivername="postgresql+psycopg").render_as_string(hide_password=False)
    if url.drivername in ("sqlite", "sqlite+pysqlite") and url.database and url.database != ":memory:":
        return f"sqlite:///{os.path.abspath(url.database)}"
    raise SpecError(source, DOCUMENT, _url_problem(text))


def resolve_catalog(folder=".", url=None) -> str:
    """Where the catalogue of the runs in ``folder`` is (a URL; nothing is created).

    Parameters
    ----------
    folder : str or path-like
        A run's folder (or the folder ``ls`` lists).
    url : str, optional
        ``--catalog``: wins over everything.

    Returns
    -------
    str
        ``url``, else ``RDEA_LAB_CATALOG``, else ``sqlite:///<nearest folder at or above with an
        rdea-lab-catalog.sqlite>/rdea-lab-catalog.sqlite``, else that file in ``folder``.

    Raises
    ------
    SpecError
        A ``url`` or ``RDEA_LAB_CATALOG`` that is no catalogue (`catalog_url`).
    """
    if url:
        return catalog_url(url, "--catalog")
    if os.environ.get(ENV, "").strip():
        return catalog_url(os.environ[ENV], ENV)
    here = Path(os.path.abspath(folder))
    for place in (here, *here.parents):
        if (place / CATALOG_FILE).is_file():
            return f"sqlite:///{place / CATALOG_FILE}"
    return f"sqlite:///{here / CATALOG_FILE}"


def shown_url(url: str) -> str:
    """A catalogue URL for a message: no password, a SQLite file by its path."""
    if url.startswith("sqlite:///"):
        return url[len("sqlite:///"):]
    from sqlalchemy.engine import make_url

    return make_url(url).set(drivername="postgresql").render_as_string(hide_password=True)


class Catalog:
    """A catalogue database: the engine, its tables made if missing.

    Parameters
    ----------
    url : str
        As `resolve_catalog` gives it. A SQLite file runs in WAL mode (readers never wait for the writer)
        with a busy timeout of `BUSY_TIMEOUT` seconds, so processes can write one after the other; a
        PostgreSQL URL is opened through psycopg.

    Raises
    ------
    CatalogUnavailable
        The database cannot be opened, created or reached.

    Notes
    -----
    Use as a context manager (``with Catalog(url) as cat:``) or call `close`.
    """

    def __init__(self, url: str):
        from sqlalchemy import create_engine, event

        self.url = url
        self.meta, self.runs, self.md = _tables()
        self.sqlite = url.startswith("sqlite")
        memory = url == "sqlite://"
        self.root = Path(url[len("sqlite:///"):]).parent if self.sqlite and not memory else None
        self.host = socket.gethostname()
        if memory:  # one connection for the life of the catalogue (a scratch copy of the tables)
            from sqlalchemy.pool import StaticPool

            self.engine = create_engine(url, poolclass=StaticPool)
        elif self.sqlite:
            # connections are pooled for the life of this object; `close` closes them, and with the last one
            # SQLite folds the -wal file back in and removes it (none outlives a command)
            self.engine = create_engine(url)
            event.listen(self.engine, "connect", _sqlite_connect)
            event.listen(self.engine, "begin", _sqlite_begin)
        else:
            self.engine = create_engine(url, connect_args={"connect_timeout": CONNECT_TIMEOUT})
        self._create()

    def _create(self):
        from sqlalchemy.exc import SQLAlchemyError

        try:
            if self.root is not None:
                self.root.mkdir(parents=True, exist_ok=True)
            for attempt in range(3):  # two processes creating the tables at once: the second finds them made
                try:  # under the write lock (SQLite's BEGIN IMMEDIATE): the check and the creation are one step
                    with self.engine.connect().execution_options(sqlite_write=True) as conn, conn.begin():
                        self.meta.create_all(conn, checkfirst=True)
                    break
                except SQLAlchemyError:
                    if attempt == 2:
                        raise
        except (SQLAlchemyError, OSError) as exc:
            self.engine.dispose()
            raise self.unavailable(exc) from None

    def unavailable(self, exc) -> CatalogUnavailable:
        """The one-line error of a database that failed: which catalogue, and the driver's reason."""
        reason = getattr(exc, "orig", None) or exc
        detail = " ".join(str(reason).split())[:200]
        return CatalogUnavailable(f"catalogue {shown_url(self.url)}: {type(reason).__name__}: {detail}")

    def close(self):
        self.engine.dispose()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---- paths as stored ----

    def stored(self, path) -> str:
        """A file as the catalogue stores it: relative to a SQLite catalogue's folder when below it (posix),
        else absolute."""
        text = os.path.abspath(path)  # text, not pathlib: ls stores 1e4 names in a few milliseconds
        if self.root is not None:
            root = str(self.root)
            if text == root:
                return "."
            if text.startswith(root.rstrip(os.sep) + os.sep):
                return text[len(root.rstrip(os.sep)) + 1:].replace(os.sep, "/")
        return text.replace(os.sep, "/")

    def located(self, text: str) -> Path:
        """A stored file as a path here."""
        return Path(text) if os.path.isabs(text) or self.root is None else self.root / text

    def is_local(self, row) -> bool:
        """Whether this machine can check the row's file (stored relative, or indexed here)."""
        return not os.path.isabs(row["file"]) or row.get("host") == self.host

    # ---- writing ----

    def write(self, rows) -> None:
        """Upsert ``[(row, metadata), ...]`` in one transaction: each row by ``run_id`` (``INSERT .. ON CONFLICT
        DO UPDATE``), its metadata replaced, and rows of another run that named the same file removed.

        Raises
        ------
        CatalogUnavailable
            The transaction failed (rolled back: nothing of it is written).
        """
        from sqlalchemy.exc import SQLAlchemyError

        if not rows:
            return
        upsert, stale_md, stale_runs, drop_md = self._statements()
        # a non-finite number is stored as NULL on both engines (SQLite makes NaN NULL, PostgreSQL keeps it,
        # and the same query would then answer differently)
        rows = [({k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()}, m)
                for r, m in rows]
        try:
            with self.engine.connect().execution_options(sqlite_write=True) as conn:
                with conn.begin():
                    conn.execute(upsert, [r for r, _ in rows])
                    # another run's row on this file: that run's file was replaced (by a run with --force)
                    same = [{"f": r["file"], "h": r["host"], "i": r["run_id"]} for r, _ in rows]
                    conn.execute(stale_md, same)
                    conn.execute(stale_runs, same)
                    conn.execute(drop_md, [{"i": r["run_id"]} for r, _ in rows])
                    values = [{"run_id": r["run_id"], "key": k, "value": v} for r, m in rows for k, v in m.items()]
                    if values:
                        conn.execute(self.md.insert(), values)
        except SQLAlchemyError as exc:
            raise self.unavailable(exc) from None

    def _statements(self):
        """The statements `write` runs (made once per catalogue: building them costs more than running them)."""
        if getattr(self, "_write_statements", None) is None:
            from sqlalchemy import and_, bindparam, delete, select

            if self.sqlite:
                from sqlalchemy.dialects.sqlite import insert
            else:
                from sqlalchemy.dialects.postgresql import insert
            runs, md = self.runs, self.md
            upsert = insert(runs)
            upsert = upsert.on_conflict_do_update(index_elements=[runs.c.run_id],
                                                  set_={c: upsert.excluded[c] for c in RUN_COLUMNS if c != "run_id"})
            other = and_(runs.c.file == bindparam("f"), runs.c.host == bindparam("h"), runs.c.run_id != bindparam("i"))
            self._write_statements = (upsert, delete(md).where(md.c.run_id.in_(select(runs.c.run_id).where(other))),
                                      delete(runs).where(other), delete(md).where(md.c.run_id == bindparam("i")))
        return self._write_statements

    def remove(self, run_ids) -> None:
        """Delete the rows (and metadata) of ``run_ids`` in one transaction."""
        from sqlalchemy import delete
        from sqlalchemy.exc import SQLAlchemyError

        run_ids = list(run_ids)
        if not run_ids:
            return
        try:
            with self.engine.connect().execution_options(sqlite_write=True) as conn:
                with conn.begin():
                    for i in range(0, len(run_ids), 500):
                        part = run_ids[i:i + 500]
                        conn.execute(delete(self.runs).where(self.runs.c.run_id.in_(part)))
                        conn.execute(delete(self.md).where(self.md.c.run_id.in_(part)))
        except SQLAlchemyError as exc:
            raise self.unavailable(exc) from None

    # ---- reading ----

    def field(self, runs=None, md=None):
        """The resolver `rdea_lab.store.query.where_clause` takes: a column of ``runs`` by name, ``md.<key>``
        as a scalar subquery of the run's metadata value; `KeyError` for anything else."""
        from sqlalchemy import and_, select

        runs = self.runs if runs is None else runs
        md = self.md if md is None else md

        def field(name: str):
            if name.startswith("md."):
                return (select(md.c.value).where(and_(md.c.run_id == runs.c.run_id, md.c.key == name[3:]))
                        .scalar_subquery())
            if name not in RUN_COLUMNS:
                raise KeyError(name)
            return runs.c[name]

        field.fields = list(RUN_COLUMNS)
        return field

    def column(self, stmt) -> list:
        """The first column of a read statement's rows.

        Raises
        ------
        CatalogUnavailable
        """
        from sqlalchemy.exc import SQLAlchemyError

        try:
            with self.engine.connect() as conn:
                return list(conn.execute(stmt).scalars())
        except SQLAlchemyError as exc:
            raise self.unavailable(exc) from None

    def execute(self, stmt):
        """Rows of a read statement, as dicts.

        Raises
        ------
        CatalogUnavailable
        """
        from sqlalchemy.exc import SQLAlchemyError

        try:
            with self.engine.connect() as conn:
                return [dict(r._mapping) for r in conn.execute(stmt)]
        except SQLAlchemyError as exc:
            raise self.unavailable(exc) from None


def _sqlite_connect(dbapi_conn, record):
    dbapi_conn.isolation_level = None  # the driver's own BEGIN off: `_sqlite_begin` issues it
    cur = dbapi_conn.cursor()
    cur.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT * 1000)}")
    cur.execute("PRAGMA journal_mode = WAL")
    cur.execute("PRAGMA synchronous = NORMAL")  # WAL keeps the file whole; the runs' files are the truth anyway
    cur.close()


def _sqlite_begin(conn):
    # a writer takes the write lock at BEGIN (waiting up to the busy timeout), never half-way through
    conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.get_execution_options().get("sqlite_write") else "BEGIN")


# ---- a run's row, from its file ----

def file_sha256(path) -> str:
    """sha256 of a file, read in 1 MiB pieces (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for piece in iter(lambda: fh.read(1 << 20), b""):
            h.update(piece)
    return h.hexdigest()


def _when(text) -> datetime | None:
    """An ISO 8601 attribute as a naive UTC datetime (None when it is none)."""
    try:
        value = datetime.fromisoformat(str(text).strip().replace("Z", "+00:00"))
    except ValueError:
        return None
    return value.astimezone(timezone.utc).replace(tzinfo=None) if value.tzinfo else value


def _peak(var, absolute: bool) -> float | None:
    """Largest value (``absolute``: largest magnitude) of a variable's finite values: from its
    ``actual_range`` if it has one, else read chunk by chunk; None when none is finite."""
    if "actual_range" in var.ncattrs():
        lo, hi = (float(x) for x in np.ravel(var.getncattr("actual_range"))[:2])
        return max(abs(lo), abs(hi)) if absolute else hi
    best = None
    for start in range(0, var.shape[0], CHUNK):
        v = np.asarray(var[start:start + CHUNK], dtype=float)
        v = np.abs(v) if absolute else v
        v = v[np.isfinite(v)]
        if v.size:
            best = float(v.max()) if best is None else max(best, float(v.max()))
    return best


def read_row(path) -> tuple[dict, dict]:
    """A dataset's row of ``runs`` and its metadata, from its attributes (variables only where a peak has
    no ``actual_range``). ``file`` is the absolute path; `Catalog.stored` makes it the stored form.

    Raises
    ------
    OSError, ValueError
        A file that cannot be read, or is not an rdea-lab run (no ``run_id``).
    """
    import netCDF4
    from xarray.backends.locks import HDF5_LOCK  # HDF5 is not thread-safe: one call at a time, as xarray's

    from .catalog import user_metadata
    from .schema import origin_kind

    path = Path(os.path.abspath(path))
    st = path.stat()
    sha = file_sha256(path)
    with HDF5_LOCK, netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        a = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in ((k, nc.getncattr(k)) for k in nc.ncattrs())}
        if not str(a.get("run_id", "")).strip():
            raise ValueError("not an rdea-lab run (no run_id attribute)")
        n = len(nc.dimensions["time"]) if "time" in nc.dimensions else 0
        duration = float(nc.variables["time"][n - 1] - nc.variables["time"][0]) if n and "time" in nc.variables else 0.0
        peaks = {f"peak_{name}": _peak(nc.variables[name], name != "stretch") if name in nc.variables else None
                 for name in ("force", "stretch", "voltage")}
    params = str(a.get("parameters", "") or "")
    try:
        rate = float(a.get("sample_rate", "nan"))
    except (TypeError, ValueError):
        rate = float("nan")
    row = {"run_id": str(a["run_id"]).strip()[:64], "file": path.as_posix(), "host": socket.gethostname(),
           "sha256": sha, "size": int(st.st_size), "mtime": float(st.st_mtime),
           "specimen": str(a.get("specimen_id", "?")), "protocol": str(a.get("protocol_name", "?")),
           "protocol_kind": str(a.get("protocol_kind", "?")), "backend": str(a.get("backend", "?")),
           "origin": origin_kind(a), "model": str(a.get("model", "-")), "status": str(a.get("status", "?")),
           "status_reason": str(a.get("status_reason", "")), "created": _when(a.get("created", "")),
           "finished": _when(a.get("finished", "")), "samples": int(n), "duration_s": duration,
           "sample_rate": rate if np.isfinite(rate) else None, **peaks,
           "params_hash": hashlib.sha256(params.encode()).hexdigest() if params else "",
           "rdea_lab_version": str(a.get("rdea_lab_version", "?")),
           "indexed_at": datetime.now(timezone.utc).replace(tzinfo=None, microsecond=0)}
    return row, user_metadata(a)


def index_run(path, url=None) -> dict:
    """Index one finished dataset: its row written (or replaced) in the catalogue, in one transaction.

    Parameters
    ----------
    path : str or path-like
        A run's netCDF file.
    url : str, optional
        The catalogue (`resolve_catalog` of the file's folder by default).

    Returns
    -------
    dict
        The row written (`RUN_COLUMNS`, ``file`` as stored) and ``metadata`` (a dict).

    Raises
    ------
    OSError, ValueError
        The file cannot be read or is not an rdea-lab run.
    CatalogUnavailable
        The catalogue cannot be written (locked longer than `BUSY_TIMEOUT`, a server down).
    """
    row, md = read_row(path)
    with Catalog(resolve_catalog(Path(path).parent, url)) as cat:
        row["file"] = cat.stored(path)
        cat.write([(row, md)])
    return {**row, "metadata": md}


def index_quietly(path, url=None, stream=None) -> dict | None:
    """`index_run`, never failing: a catalogue that cannot be written leaves the run unindexed and says so
    in one line on ``stream`` (stderr), with the command that indexes it later. The dataset is untouched."""
    try:
        return index_run(path, url)
    except Exception as exc:  # noqa: BLE001 (the run is safe in its file; the index is a convenience)
        folder = Path(path).parent
        detail = " ".join(str(exc).split())[:240]
        print(f"rdea-lab: warning: {path} is not in the catalogue ({detail}); index it later with: "
              f"rdea-lab catalog rebuild {folder}", file=stream or sys.stderr)
        return None


__all__ = ["BUSY_TIMEOUT", "CATALOG_FILE", "Catalog", "CatalogUnavailable", "ENV", "RUN_COLUMNS", "catalog_url",
           "file_sha256", "index_quietly", "index_run", "read_row", "resolve_catalog", "shown_url"]

#: The answers live beside, in `rdea_lab.store.listing`; found here too (loaded on first use). The CLI's
#: names (``rdea_lab.api._cli``): ``rebuild_catalog``, ``check_catalog``.
_LISTING = {"Rebuild": "Rebuild", "check": "check", "query": "query", "rebuild": "rebuild",
            "rebuild_catalog": "rebuild", "check_catalog": "check"}


def __getattr__(name):
    if name not in _LISTING:
        raise AttributeError(f"module 'rdea_lab.store.index' has no attribute {name!r}")
    from . import listing

    return getattr(listing, _LISTING[name])
