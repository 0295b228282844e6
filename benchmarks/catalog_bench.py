"""The catalogue with 1e4 synthetic runs: a filtered query, `ls` of 100 rows, a rebuild; SQLite and PostgreSQL.

The runs are real netCDF files: one short twin run (specimen 2, a 4-second tensile ramp-sine at 10 Hz) written
once, copied ``--runs`` times, and each copy's attributes changed in place with netCDF4: ``run_id`` (a fresh
uuid4), ``specimen_id`` (specimen-1 .. specimen-5), ``status`` (90 % complete, 6 % aborted, 4 % interrupted),
``created``/``finished`` (spread over 2025-06 .. 2026-06), ``protocol_name``/``protocol_kind`` (two kinds), the
user's ``metadata`` (batch B1 .. B20, four operators; 5 % without a batch) and the force's ``actual_range`` (the
peak the index reads; the samples themselves are the template's). The files sit in ten folders (rig-0 .. rig-9).

Timed (the median of ``--repeat`` calls after one warm-up, with the fastest and slowest; the machine may be
shared):

- ``rebuild``: `rdea_lab.store.index.rebuild` of the whole folder into an empty catalogue (every file read and
  hashed), then again with nothing changed (each file read and hashed, nothing written); once each.
- ``query``: the issue's question, ``specimen == 'specimen-2' and status == 'complete' and md.batch == 'B7'``
  since 2026-03-01 with the columns file, peak_force, through `rdea_lab.store.index.query` (opening the
  catalogue, the SQL, each listed file stat-ed) and as the SQL alone on an open catalogue (`select_rows`).
- ``ls_100``: `rdea_lab.catalog(folder, limit=100)` (the folder walked for files the index lacks, 100 rows
  stat-ed), and the command ``rdea-lab ls FOLDER --limit 100`` as a process (its start-up included).

Given ``--postgresql URL`` (an empty database; ``auto`` starts a throwaway server as the tests do, from
tests/pg_server.py) the same rebuild and queries run there, and every query's answer (run ids, files, peaks) is
compared with SQLite's: the script exits 1 when one differs.

    python3 benchmarks/catalog_bench.py [--runs 10000] [--repeat 21] [--postgresql auto|URL] [--keep DIR]
                                        [--out results.json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WHERE = "specimen == 'specimen-2' and status == 'complete' and md.batch == 'B7'"
SINCE = "2026-03-01"
#: Queries (where, since) whose answers must agree between the engines (the issue's question first).
COMPARED = [(WHERE, SINCE), (WHERE, None), ("status != 'complete'", None),
            ("md.operator in ['ana', 'ben'] and peak_force > 3.5", "2025-12-24T18:00:00+01:00"),
            ("specimen like 'specimen-1%' and not (md.batch == null)", None),
            ("md.batch == null or protocol_kind == 'tensile'", None),
            ("created >= '2026-01-01' and created < '2026-02-01'", None), ("md.batch > 'B5' and samples >= 10", None)]
PROTOCOL = """\
name: bench_tensile
kind: tensile
description: a short tensile ramp-sine for the catalogue benchmark
sample_rate: 10 Hz
measure: [force]
limits: {max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}
preset: tensile_ramp_sine
settings: {voltage: 2.6 kV, min_stretch: 1.0, max_stretch: 1.3, frequency: 0.5 Hz, cycles: 1, settle: 2 s}
"""


def template(folder: Path) -> Path:
    """One short twin run (written in ``folder``, its own catalogue beside it)."""
    from rdea_lab.api import run_protocol

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "bench_tensile.yaml").write_text(PROTOCOL)
    out = folder / "template.nc"
    run_protocol(folder / "bench_tensile.yaml", ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml", "twin",
                 out=out, metadata={"batch": "B0"})
    return out


def synthetic_runs(tpl: Path, folder: Path, n: int, seed: int = 0) -> list[dict]:
    """``n`` copies of ``tpl`` below ``folder`` with their attributes varied (module docstring); what each got."""
    import netCDF4

    rng = np.random.default_rng(seed)
    start = datetime(2025, 6, 1, tzinfo=timezone.utc)
    operators = ["ana", "ben", "chi", "dev"]
    made = []
    for i in range(n):
        sub = folder / f"rig-{i % 10}"
        sub.mkdir(parents=True, exist_ok=True)
        path = sub / f"run-{i:05d}.nc"
        shutil.copyfile(tpl, path)
        created = start + timedelta(seconds=float(rng.uniform(0, 365 * 86400)))
        u = rng.uniform()
        status = "complete" if u < 0.90 else "aborted" if u < 0.96 else "interrupted"
        md = {"operator": operators[int(rng.integers(4))]}
        if rng.uniform() >= 0.05:
            md["batch"] = f"B{int(rng.integers(1, 21))}"
        kind = "tensile" if rng.uniform() < 0.7 else "blocking"
        peak = float(rng.uniform(0.5, 5.0))
        attrs = {"run_id": uuid.UUID(int=int(rng.integers(2**62)) << 64 | i, version=4).hex,
                 "specimen_id": f"specimen-{int(rng.integers(1, 6))}", "status": status,
                 "status_reason": "" if status == "complete" else "synthetic",
                 "created": created.strftime("%Y-%m-%dT%H:%M:%SZ"),
                 "finished": (created + timedelta(seconds=4)).strftime("%Y-%m-%dT%H:%M:%SZ"),
                 "protocol_name": f"bench_{kind}", "protocol_kind": kind, "metadata": json.dumps(md)}
        with netCDF4.Dataset(path, "a") as nc:
            for k, v in attrs.items():
                nc.setncattr(k, v)
            if "force" in nc.variables:
                nc.variables["force"].setncattr("actual_range", np.array([-0.1, peak]))
        made.append({**attrs, "file": str(path), "peak_force": peak, "md": md})
    return made


def timed(fn, repeat: int) -> dict:
    """Median, fastest and slowest of ``repeat`` calls of ``fn`` after one warm-up [s], and its last answer."""
    answer = fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        answer = fn()
        times.append(time.perf_counter() - t0)
    return {"median_s": statistics.median(times), "min_s": min(times), "max_s": max(times), "n": repeat,
            "answer": answer}


def once(fn) -> tuple[float, object]:
    t0 = time.perf_counter()
    answer = fn()
    return time.perf_counter() - t0, answer


def engine_figures(url: str, folder: Path, repeat: int, ls_too: bool) -> dict:
    """Rebuild into the (empty) catalogue at ``url`` and time the queries there."""
    from rdea_lab.store import index
    from rdea_lab.store.listing import select_rows

    out = {}
    out["rebuild_s"], first = once(lambda: index.rebuild(folder, url))
    out["rebuild_counts"] = first.counts
    out["rebuild_again_s"], again = once(lambda: index.rebuild(folder, url))
    out["rebuild_again_counts"] = again.counts
    q = timed(lambda: index.query(WHERE, SINCE, ["file", "peak_force"], url=url), repeat)
    out["query"] = {k: v for k, v in q.items() if k != "answer"} | {"rows": len(q["answer"])}
    with index.Catalog(index.resolve_catalog(folder, url)) as cat:
        s = timed(lambda: select_rows(cat, WHERE, SINCE)[0], repeat)
    out["query_sql_only"] = {k: v for k, v in s.items() if k != "answer"} | {"rows": len(s["answer"])}
    if ls_too:
        import rdea_lab

        ls = timed(lambda: rdea_lab.catalog(folder, limit=100, catalog=url), repeat)
        out["ls_100"] = {k: v for k, v in ls.items() if k != "answer"} | {"rows": len(ls["answer"])}
        here = Path(rdea_lab.__file__).resolve().parents[1]  # the process lists with the same rdea-lab as this one
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(here), os.environ.get("PYTHONPATH", "")])}
        cmd = [sys.executable, "-m", "rdea_lab.cli", "ls", str(folder), "--limit", "100", "--catalog", url]

        def cli():
            done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
            if done.returncode != 0:
                raise RuntimeError(f"{' '.join(cmd)}: exit {done.returncode}: {done.stderr.strip()}")
            return done.stdout.count("\n")

        c = timed(cli, max(3, repeat // 4))
        out["ls_100_cli"] = {k: v for k, v in c.items() if k != "answer"} | {"lines": c["answer"]}
    out["answers"] = {q: index.query(q[0], q[1], columns=["run_id", "file", "peak_force", "status"], url=url)
                      for q in COMPARED}
    return out


def expected(made):
    """The issue's question over the synthetic runs in plain Python (a check of the catalogue's answer)."""
    return sorted(r["run_id"] for r in made if r["specimen_id"] == "specimen-2" and r["status"] == "complete"
                  and r["md"].get("batch") == "B7" and r["created"] >= "2026-03-01")


def same(a, b) -> bool:
    """Two engines' answers to one query: the same runs, files and peaks (and statuses)."""
    cols = ["run_id", "file", "peak_force", "status"]
    a = a[cols].sort_values("run_id").reset_index(drop=True)
    b = b[cols].sort_values("run_id").reset_index(drop=True)
    return a.equals(b)


def _postgresql(spec: str):
    """The URL of an empty database, and what stops it (None for a server of the user's)."""
    if spec != "auto":
        return spec, None
    sys.path.insert(0, str(ROOT / "tests"))
    import pg_server

    if reason := pg_server.unavailable():
        raise SystemExit(reason)
    server = pg_server.Server.start()
    return server.new_database(), server


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=21)
    ap.add_argument("--postgresql", metavar="URL", help="an empty PostgreSQL database, or 'auto'")
    ap.add_argument("--keep", type=Path, help="build the runs in this folder and keep them (reused if there)")
    ap.add_argument("--out", type=Path, help="JSON results")
    args = ap.parse_args(argv)
    os.environ.pop("RDEA_LAB_CATALOG", None)
    tmp = tempfile.TemporaryDirectory() if args.keep is None else None
    base = Path(tmp.name) if tmp else args.keep
    folder, made_json = base / "runs", base / "made.json"
    try:
        if made_json.exists():
            made = json.loads(made_json.read_text())
            print(f"{len(made)} synthetic runs reused from {folder}")
        else:
            t_make, made = once(lambda: synthetic_runs(template(base / "template"), folder, args.runs))
            made_json.write_text(json.dumps(made))
            size = sum(p.stat().st_size for p in folder.rglob("*.nc"))
            print(f"{len(made)} synthetic runs written in {t_make:.1f} s ({size / 1e6:.0f} MB) in {folder}")
        results = {"runs": len(made), "repeat": args.repeat}
        sqlite_url = f"sqlite:///{base / 'catalog.sqlite'}"
        Path(sqlite_url[len("sqlite:///"):]).unlink(missing_ok=True)
        results["sqlite"] = engine_figures(sqlite_url, folder, args.repeat, ls_too=True)
        ok = sorted(results["sqlite"]["answers"][WHERE, SINCE]["run_id"]) == expected(made)
        results["issue_query_rows"] = len(expected(made))
        results["sqlite_answer_as_expected"] = ok
        server = None
        if args.postgresql:
            url, server = _postgresql(args.postgresql)
            try:
                results["postgresql"] = engine_figures(url, folder, args.repeat, ls_too=True)
            finally:
                if server is not None:
                    server.stop()
            differ = [q for q in COMPARED if not same(results["sqlite"]["answers"][q],
                                                      results["postgresql"]["answers"][q])]
            results["postgresql_answers_differ"] = differ
            ok = ok and not differ
        report(results)
        if args.out:
            args.out.write_text(json.dumps(_plain(results), indent=2))
        return 0 if ok else 1
    finally:
        if tmp:
            tmp.cleanup()


def _plain(results):
    """The results as JSON (the answers as their row counts)."""
    out = json.loads(json.dumps({k: v for k, v in results.items() if k not in ("sqlite", "postgresql")}))
    for engine in ("sqlite", "postgresql"):
        if engine in results:
            out[engine] = {k: v for k, v in results[engine].items() if k != "answers"}
            out[engine]["answer_rows"] = {f"{w} (since {s})": len(t)
                                          for (w, s), t in results[engine]["answers"].items()}
    return out


def report(results):
    def ms(d):
        return f"{1e3 * d['median_s']:8.1f} ms (min {1e3 * d['min_s']:.1f}, max {1e3 * d['max_s']:.1f}, n={d['n']})"

    print(f"catalogue of {results['runs']} runs")
    for engine in ("sqlite", "postgresql"):
        if engine not in results:
            continue
        r = results[engine]
        print(f"  {engine}:")
        print(f"    rebuild (empty catalogue)   {r['rebuild_s']:8.1f} s   {r['rebuild_counts']}")
        print(f"    rebuild (nothing changed)   {r['rebuild_again_s']:8.1f} s")
        print(f"    filtered query              {ms(r['query'])}  {r['query']['rows']} rows")
        print(f"    filtered query, SQL only    {ms(r['query_sql_only'])}")
        if "ls_100" in r:
            print(f"    catalog(folder, limit=100)  {ms(r['ls_100'])}  {r['ls_100']['rows']} rows")
            print(f"    rdea-lab ls --limit 100     {ms(r['ls_100_cli'])}  (a process: start-up included)")
    print(f"  SQLite's answer to the issue's query ({results['issue_query_rows']} runs, as computed from what was "
          "written): "
          f"{'the same' if results['sqlite_answer_as_expected'] else 'DIFFERS'}")
    if "postgresql_answers_differ" in results:
        differ = results["postgresql_answers_differ"]
        print(f"  PostgreSQL's answers to {len(COMPARED)} queries equal SQLite's: {not differ}"
              + (f" (differ: {differ})" if differ else ""))


if __name__ == "__main__":
    sys.exit(main())
