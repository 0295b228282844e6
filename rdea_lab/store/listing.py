"""The catalogue's answers: `query` (a DataFrame, each listed file stat-ed), `listing` (what
`rdea_lab.store.catalog.catalog` and ``rdea-lab ls`` show: the index refreshed from a folder, its journals),
`rebuild` and `check` (every file re-read). The tables and writers are `rdea_lab.store.index`'s."""

from __future__ import annotations

import json
import os
import socket
from dataclasses import dataclass, field as _field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..specs.errors import DOCUMENT, SpecError
from .journal import walk_runs as walk
from .index import RUN_COLUMNS, Catalog, CatalogUnavailable, _when, read_row, resolve_catalog, shown_url

#: `catalog`'s columns by default (what ``rdea-lab ls`` showed before the index), then ``md.<key>``.
DEFAULT_COLUMNS = ["file", "specimen", "protocol", "backend", "model", "status", "duration_s", "samples", "created",
                   "metadata"]
#: The extra columns a listing may ask for: ``metadata`` (``key=value; ...``) and ``file_state``.
EXTRA_COLUMNS = ("metadata", "file_state")
#: `query`'s marks of a listed file (``file_state``).
OK, CHANGED, MISSING, ELSEWHERE = "ok", "changed since indexed", "missing", "not checked (indexed on another host)"


def _stat_state(cat: Catalog, row: dict) -> str:
    if not cat.is_local(row):
        return ELSEWHERE
    try:
        st = cat.located(row["file"]).stat()
    except OSError:
        return MISSING
    same = st.st_size == row["size"] and abs(st.st_mtime - (row["mtime"] or 0.0)) < 1e-6
    return OK if same else CHANGED


def _check_columns(columns) -> list[str] | None:
    if columns is None:
        return None
    if isinstance(columns, str):
        columns = [c.strip() for c in columns.split(",") if c.strip()]
    allowed = [*RUN_COLUMNS, *EXTRA_COLUMNS]
    for c in columns:
        if c not in allowed and not (c.startswith("md.") and len(c) > 3):
            raise SpecError("--columns", c, f"unknown column; allowed: {', '.join(allowed)} or md.<key>")
    if not columns:
        raise SpecError("--columns", DOCUMENT, "no column named; allowed: a comma-separated list, e.g. file,status")
    return list(columns)


def _filters(cat, runs, md, where, since, folder):
    from sqlalchemy import and_, or_

    clauses = []
    if where is not None:
        from .query import parse_where, where_clause  # the query language (rdea_lab.store.query)

        node = parse_where(where) if isinstance(where, str) else where
        clauses.append(where_clause(node, cat.field(runs, md)))
    if since is not None:
        from .query import parse_since

        when = parse_since(since) if isinstance(since, str) else since
        when = when.astimezone(timezone.utc).replace(tzinfo=None) if when.tzinfo else when
        clauses.append(and_(runs.c.created.is_not(None), runs.c.created >= when))
    if folder is not None:
        prefix = cat.stored(folder)
        if prefix != "" and prefix != ".":
            under = runs.c.file.startswith(prefix.rstrip("/") + "/", autoescape=True)
            clauses.append(under if not os.path.isabs(prefix) else and_(under, runs.c.host == cat.host))
        elif cat.root is None:
            clauses.append(or_(runs.c.host == cat.host))
    return clauses


def select_rows(cat: Catalog, where=None, since=None, folder=None, limit=None, runs=None, md=None):
    """The rows (dicts, by file) and their metadata that a query selects, and how many match without ``limit``."""
    from sqlalchemy import and_, func, select

    runs = cat.runs if runs is None else runs
    md = cat.md if md is None else md
    clauses = _filters(cat, runs, md, where, since, folder)
    stmt = select(runs).where(and_(*clauses)) if clauses else select(runs)
    stmt = stmt.order_by(runs.c.file, runs.c.run_id)
    total = None
    if limit is not None:
        counted = select(func.count()).select_from(runs)
        total = cat.execute(counted.where(and_(*clauses)) if clauses else counted)[0]["count_1"]
        stmt = stmt.limit(int(limit))
    rows = cat.execute(stmt)
    metadata = {r["run_id"]: {} for r in rows}
    ids = list(metadata)
    for i in range(0, len(ids), 500):
        for m in cat.execute(select(md).where(md.c.run_id.in_(ids[i:i + 500])).order_by(md.c.run_id, md.c.key)):
            metadata[m["run_id"]][m["key"]] = m["value"]
    return rows, metadata, len(rows) if total is None else total


def query(where=None, since=None, columns=None, folder=None, url=None, limit=None):
    """The runs of a catalogue that a query selects, as a DataFrame; each listed file is stat-ed.

    Parameters
    ----------
    where : str or Node, optional
        A query (`rdea_lab.store.query.parse_where`), e.g. ``"status == 'complete' and md.batch == 'B7'"``.
    since : str or datetime, optional
        Runs created at or after this (ISO 8601, UTC unless an offset is given).
    columns : sequence of str or str, optional
        Columns to return (`RUN_COLUMNS`, ``metadata``, ``file_state``, ``md.<key>``); default
        `DEFAULT_COLUMNS`, ``file_state`` and one ``md.<key>`` per metadata key of the runs listed.
    folder : path-like, optional
        Only the runs below it (of this host); default every run of the catalogue.
    url : str, optional
        The catalogue (`resolve_catalog` of ``folder`` or ``.``).
    limit : int, optional
        At most this many rows (by file); ``df.attrs["total"]`` says how many matched.

    Returns
    -------
    pandas.DataFrame
        One row per run, by file. ``file`` as a path here (below ``folder`` as given, when it is);
        ``created``/``finished`` ISO 8601 text; ``file_state`` `OK`, `CHANGED` (size or mtime differ
        from the indexed ones), `MISSING`, or `ELSEWHERE`.

    Raises
    ------
    SpecError
        A bad query (`~rdea_lab.store.query.QueryError`, with the position), ``since``, column or URL.
    CatalogUnavailable
        The catalogue cannot be read.
    """
    with Catalog(resolve_catalog(folder if folder is not None else ".", url)) as cat:
        columns = _check_columns(columns)
        rows, metadata, total = select_rows(cat, where, since, folder, limit)
        for r in rows:
            r["file_state"] = _stat_state(cat, r)
            r["file"] = _shown_file(cat, r["file"], folder)
        return frame(rows, metadata, columns, total)


def _shown_file(cat: Catalog, stored: str, folder) -> str:
    path = cat.located(stored)
    if folder is not None:
        try:
            return str(Path(folder) / path.relative_to(os.path.abspath(folder)))
        except ValueError:
            pass
    return str(path)


def _text(value) -> str:
    if isinstance(value, datetime):
        return value.strftime("%Y-%m-%dT%H:%M:%SZ")
    return "?" if value is None else value


def frame(rows, metadata, columns=None, total=None):
    """Rows (dicts) and their metadata as `query`'s DataFrame."""
    import pandas as pd

    from .catalog import metadata_text

    keys = list(dict.fromkeys(k for r in rows for k in metadata.get(r["run_id"], {}))) if columns is None else []
    names = columns if columns is not None else [*DEFAULT_COLUMNS, "file_state", *(f"md.{k}" for k in keys)]
    out = []
    for r in rows:
        m = metadata.get(r["run_id"], {})
        full = {**r, "metadata": metadata_text(m), "created": _text(r.get("created")),
                "finished": _text(r.get("finished")), "indexed_at": _text(r.get("indexed_at"))}
        if full.get("origin") == "emulator" and columns is None:
            full["backend"] = f"{full['backend']} (emulator)"  # as ls showed it
        out.append({c: m.get(c[3:], "") if c.startswith("md.") else full.get(c) for c in names})
    table = pd.DataFrame(out, columns=names)
    table.attrs["total"] = len(rows) if total is None else total
    return table


# ---- rebuild and check ----

@dataclass(frozen=True)
class Rebuild:
    """What `rebuild` (or `check`) found below a folder.

    Attributes
    ----------
    catalog : str
        The catalogue (as shown).
    added, updated, unchanged, changed, missing : tuple of str
        Files newly indexed; indexed already with the same content but another path or row (moved, or
        indexed by an older rdea-lab); as indexed; whose content changed since they were indexed (sha256
        differs; re-indexed, reported); indexed but gone (their rows removed).
    unreadable : tuple of (str, str)
        Files that could not be indexed, and why.
    duplicates : tuple of str
        Files holding a run id an earlier file (by path) holds already (a copy): not indexed.
    written : bool
        False for `check` (nothing written).
    """

    catalog: str
    added: tuple = ()
    updated: tuple = ()
    unchanged: tuple = ()
    changed: tuple = ()
    missing: tuple = ()
    unreadable: tuple = ()
    duplicates: tuple = ()
    written: bool = True
    counts: dict = _field(default=None, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "counts", {k: len(getattr(self, k)) for k in
                                            ("added", "updated", "unchanged", "changed", "missing", "unreadable",
                                             "duplicates")})

    @property
    def consistent(self) -> bool:
        """The catalogue matched the files (nothing to add, update, report)."""
        return not (self.added or self.updated or self.changed or self.missing or self.unreadable or self.duplicates)

    def describe(self) -> str:
        """The counts, then one line per file that was not as indexed."""
        verb = "" if self.written else "would be "
        lines = [f"catalogue {self.catalog}: " + ", ".join(
            f"{n} {verb if k in ('added', 'updated') else ''}{k}" for k, n in self.counts.items())]
        notes = {"changed": "changed since indexed" + ("; re-indexed" if self.written else ""),
                 "missing": "missing" + ("; its row removed" if self.written else " (indexed, file gone)"),
                 "duplicates": "holds a run id another file holds; not indexed",
                 "added": "not indexed" if not self.written else None}
        for kind, note in notes.items():
            if note:
                lines += [f"  {f}: {note}" for f in getattr(self, kind)]
        lines += [f"  {f}: unreadable ({why})" for f, why in self.unreadable]
        return "\n".join(lines)


def _compare_keys():
    return [c for c in RUN_COLUMNS if c not in ("indexed_at", "mtime")]


def rebuild(folder, url=None, write=True) -> Rebuild:
    """Re-index every dataset below ``folder`` from its file (the files are the truth).

    Every ``*.nc`` below ``folder`` is read (attributes, ``actual_range``, sha256) and written; a row whose
    file's sha256 differs from the one indexed is re-indexed and reported as changed; a row below ``folder``
    (of this host) whose file is gone is removed and reported as missing; a file that cannot be read is
    reported as unreadable. A rebuild into an empty catalogue gives the rows the runs wrote as they ended.

    Parameters
    ----------
    folder : str or path-like
    url : str, optional
        The catalogue (`resolve_catalog` of ``folder``).
    write : bool
        False: only compare (`check`).

    Returns
    -------
    Rebuild

    Raises
    ------
    SpecError
        ``folder`` is no folder; a bad ``url``.
    CatalogUnavailable
        The catalogue cannot be read or written.
    """
    if not Path(folder).is_dir():
        raise SpecError(str(folder), DOCUMENT, "no such folder")
    datasets, _ = walk(folder)
    with Catalog(resolve_catalog(folder, url)) as cat:
        old, old_md, _ = select_rows(cat, folder=folder)
        by_id = {r["run_id"]: r for r in old}
        found = {k: [] for k in ("added", "updated", "unchanged", "changed", "unreadable", "duplicates")}
        seen, batch = set(), []
        held = {os.path.abspath(cat.located(r["file"])) for r in old}
        datasets = sorted(datasets, key=lambda p: os.path.abspath(p) not in held)  # a run's indexed file first
        for path in datasets:
            try:
                row, md = read_row(path)
            except Exception as exc:  # noqa: BLE001 (a foreign or broken file: reported)
                found["unreadable"].append((str(path), f"{type(exc).__name__}: {' '.join(str(exc).split())[:120]}"))
                continue
            row["file"] = cat.stored(path)
            if row["run_id"] in seen:
                found["duplicates"].append(str(path))
                continue
            seen.add(row["run_id"])
            before = by_id.get(row["run_id"])
            if before is None:
                kind = "added"
            elif before["sha256"] != row["sha256"]:
                kind = "changed"
            elif any(before[k] != row[k] for k in _compare_keys()) or old_md.get(row["run_id"]) != md:
                kind = "updated"
            else:
                kind = "unchanged"
            found[kind].append(str(path))
            if write and (kind != "unchanged" or abs((before["mtime"] or 0) - row["mtime"]) > 1e-6):
                batch.append((row, md))
                if len(batch) >= 500:
                    cat.write(batch)
                    batch = []
        if write:
            cat.write(batch)
        gone = [r for r in old if r["run_id"] not in seen and cat.is_local(r)]
        if write:
            cat.remove(r["run_id"] for r in gone)
        return Rebuild(shown_url(cat.url), missing=tuple(str(cat.located(r["file"])) for r in gone), written=write,
                       **{k: tuple(v) for k, v in found.items()})


def check(folder, url=None) -> Rebuild:
    """`rebuild` without writing: how the catalogue differs from the files below ``folder`` (full sha256)."""
    return rebuild(folder, url, write=False)


def refresh(cat: Catalog, datasets) -> list[tuple[str, str]]:
    """Index the datasets the catalogue does not hold by path (copied in, written by an older rdea-lab or
    into another catalogue); the others are not read. A copy of a run indexed at a file that is still there
    is not indexed (its run id is the other file's). Returns the (file, reason) of those not indexed."""
    from sqlalchemy import select

    known = set(cat.column(select(cat.runs.c.file))) if datasets else set()
    batch, bad, pending = [], [], {}
    for path in datasets:
        if cat.stored(path) in known:
            continue
        try:
            row, md = read_row(path)
        except Exception as exc:  # noqa: BLE001
            bad.append((str(path), type(exc).__name__))
            continue
        row["file"] = cat.stored(path)
        held = cat.column(select(cat.runs.c.file).where(cat.runs.c.run_id == row["run_id"]))
        if held and cat.located(held[0]).exists() and held[0] != row["file"]:
            bad.append((str(path), f"a copy: run id {row['run_id']} is {cat.located(held[0])}'s"))
            continue
        if row["run_id"] in pending:  # two files of one run found in this pass: the first (by path) is indexed
            bad.append((str(path), f"a copy: run id {row['run_id']} is {cat.located(pending[row['run_id']])}'s"))
            continue
        pending[row["run_id"]] = row["file"]
        batch.append((row, md))
    cat.write(batch)
    return bad


def journal_row(folder: Path) -> tuple[dict, dict, str]:
    """An unfinished journal as a row of ``runs`` (status ``running`` or ``unfinished``), its metadata, and
    the status as listed (``running (pid N on HOST)``, ``unfinished (rdea-lab recover)``).

    Raises
    ------
    OSError, ValueError
        Not a journal of this rdea-lab.
    """
    from .catalog import user_metadata
    from .journal import FORMAT, journal_writer
    from .schema import origin_kind

    header = json.loads((folder / "header.json").read_text())
    if not isinstance(header, dict) or header.get("format") != FORMAT or not isinstance(header.get("attrs"), dict):
        raise ValueError("not a journal")
    a = header["attrs"]
    size = (folder / "samples.f8").stat().st_size if (folder / "samples.f8").exists() else 0
    n = size // (8 * len(header["columns"]))
    try:
        rate = float(a.get("sample_rate", 0.0)) or float("nan")
    except (TypeError, ValueError):
        rate = float("nan")
    writer = journal_writer(folder)
    status, shown = (("running", f"running (pid {writer.get('pid', '?')} on {writer.get('host', '?')})")
                     if writer is not None else ("unfinished", "unfinished (rdea-lab recover)"))
    row = {c: None for c in RUN_COLUMNS}
    row.update({"run_id": str(a.get("run_id") or folder.name)[:64], "file": str(folder), "host": socket.gethostname(),
                "specimen": str(a.get("specimen_id", "?")), "protocol": str(a.get("protocol_name", "?")),
                "protocol_kind": str(a.get("protocol_kind", "?")), "backend": str(a.get("backend", "?")),
                "origin": origin_kind(a), "model": str(a.get("model", "-")), "status": status, "status_reason": "",
                "created": _when(a.get("created", "")), "samples": int(n),
                "duration_s": (n - 1) / rate if n and np.isfinite(rate) else 0.0,
                "sample_rate": rate if np.isfinite(rate) else None,
                "rdea_lab_version": str(a.get("rdea_lab_version", "?"))})
    return row, user_metadata(a), shown


def _journals(journals, where, since, limit):
    """The journals' rows that the query selects: the same SQL, on an in-memory copy of the tables."""
    rows, metadata, shown = [], {}, {}
    for folder in journals:
        try:
            row, md, text = journal_row(folder)
        except Exception:  # noqa: BLE001 (a foreign or torn folder: not a run)
            continue
        rows.append(row)
        metadata[row["run_id"]] = md
        shown[row["run_id"]] = text
    if not rows or (where is None and since is None):
        return rows, metadata, shown
    mem = Catalog("sqlite://")
    try:
        with mem.engine.begin() as conn:
            conn.execute(mem.runs.insert(), rows)
            values = [{"run_id": i, "key": k, "value": v} for i, m in metadata.items() for k, v in m.items()]
            if values:
                conn.execute(mem.md.insert(), values)
        picked, _, _ = select_rows(mem, where, since, None, None)
    finally:
        mem.close()
    ids = {r["run_id"] for r in picked}
    return [r for r in rows if r["run_id"] in ids], metadata, shown


def listing(folder=".", where=None, since=None, columns=None, url=None, limit=None):
    """`rdea_lab.store.catalog.catalog`'s work (documented there): the index refreshed with the datasets
    below ``folder`` it lacks, queried, each listed file stat-ed, then the folder's journals."""
    columns = _check_columns(columns)
    if folder is not None and not Path(folder).is_dir():
        return frame([], {}, columns, 0)
    datasets, journals = walk(folder) if folder is not None else ([], [])
    url = resolve_catalog(folder if folder is not None else ".", url)
    rows, metadata, total, bad = [], {}, 0, []
    fresh = url.startswith("sqlite:///") and not Path(url[len("sqlite:///"):]).exists()
    if datasets or not fresh:  # no catalogue made where there is nothing to index
        try:
            cat = Catalog(url)
        except CatalogUnavailable:
            if not fresh:
                raise
            cat = Catalog("sqlite://")  # a folder the catalogue cannot be made in (read-only): indexed in memory
        with cat:
            bad = refresh(cat, datasets)
            rows, metadata, total = select_rows(cat, where, since, folder, limit)
            for r in rows:
                r["file_state"] = _stat_state(cat, r)
                r["file"] = _shown_file(cat, r["file"], folder)
    if where is None and since is None:  # files no query can select: listed as they are
        for path, why in bad:
            rows.append({**{c: None for c in RUN_COLUMNS}, "run_id": f"unreadable:{path}", "file": str(path),
                         "specimen": "?", "protocol": "?", "backend": "?", "model": "-", "samples": 0,
                         "duration_s": 0.0, "file_state": "not indexed",
                         "status": f"{'not indexed' if why.startswith('a copy') else 'unreadable'} ({why})"})
        total += len(bad)
    more, md_more, shown = _journals(journals, where, since, limit)
    for r in more:
        r["status"] = shown[r["run_id"]]
        r["file_state"] = "journal"
    return frame(rows + more, {**metadata, **md_more}, columns, total + len(more))


__all__ = ["CHANGED", "DEFAULT_COLUMNS", "ELSEWHERE", "MISSING", "OK", "Rebuild", "check", "frame", "journal_row",
           "listing", "query", "rebuild", "refresh", "select_rows", "walk"]
