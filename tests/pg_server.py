"""A throwaway PostgreSQL server for the catalogue's tests (fixtures ``postgresql_server``, ``postgresql_url``).

``RDEA_LAB_TEST_POSTGRESQL`` (a URL of a server where the user may create databases) is used if set. Otherwise
Debian's binaries (``/usr/lib/postgresql/<version>/bin``, package ``postgresql``) start a server of the test
session's own: data and unix socket in a temporary folder, listening on 127.0.0.1 on a free port, ``trust``
authentication, no fsync (a test's data need not survive a crash). As root it runs as the ``postgres`` user
(``runuser``); as anyone else, as that user. Each pytest-xdist worker starts its own (about a second); the
database's default collation is ICU's ``en-US`` where ICU is there, as on a lab's server, so the tests see
what a non-C collation does to text order. Every test gets a fresh database (`new_database`).
"""

from __future__ import annotations

import glob
import itertools
import os
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path

ENV = "RDEA_LAB_TEST_POSTGRESQL"


def sqlalchemy_url(url: str) -> str:
    """`url` with SQLAlchemy's psycopg (3) driver named (``postgresql://`` alone means psycopg2 to SQLAlchemy)."""
    from sqlalchemy.engine import make_url

    u = make_url(url)
    return u.set(drivername="postgresql+psycopg").render_as_string(hide_password=False) if u.drivername == \
        "postgresql" else url


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _binaries() -> Path | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"), key=lambda p: int(Path(p).parts[-3]))
    return Path(found[-1]).parent if found else None


def unavailable() -> str | None:
    """Why no server can start here (one line), or None."""
    try:
        import psycopg  # noqa: F401
    except ImportError:
        return "PostgreSQL tests skipped: psycopg is not installed (pip install 'rdea-lab[postgresql]')"
    if _binaries() is None:
        return (f"PostgreSQL tests skipped: no server binaries (/usr/lib/postgresql/*/bin; apt install postgresql) "
                f"and {ENV} not set")
    if os.geteuid() == 0:
        try:
            import pwd

            pwd.getpwnam("postgres")
        except KeyError:
            return "PostgreSQL tests skipped: running as root and there is no 'postgres' user to run the server"
        if shutil.which("runuser") is None:
            return "PostgreSQL tests skipped: running as root without runuser to start the server as 'postgres'"
    return None


class Server:
    """A server (started here, or the one `ENV` names) that hands out fresh databases."""

    def __init__(self, url: str, data: Path | None = None, as_postgres: bool = False):
        self.url, self.data, self.as_postgres = url, data, as_postgres
        self._names = (f"rdea_{os.environ.get('PYTEST_XDIST_WORKER', 'main')}_{os.getpid()}_{i}"
                       for i in itertools.count())
        self.created: list[str] = []

    @classmethod
    def start(cls) -> "Server":
        bin_dir, as_postgres = _binaries(), os.geteuid() == 0
        folder = Path(tempfile.mkdtemp(prefix="rdea-lab-pg-"))
        if as_postgres:
            import pwd

            user = pwd.getpwnam("postgres")
            os.chown(folder, user.pw_uid, user.pw_gid)
        data = folder / "data"
        prefix = ["runuser", "-u", "postgres", "--"] if as_postgres else []
        init = [*prefix, str(bin_dir / "initdb"), "-D", str(data), "-A", "trust", "-U", "postgres", "-E", "UTF8",
                "--no-sync", "--no-instructions"]
        done = subprocess.run([*init, "--locale-provider=icu", "--icu-locale=en-US", "--locale=C.UTF-8"],
                              capture_output=True, text=True)
        if done.returncode != 0:  # an older server or no ICU: the C collation
            shutil.rmtree(data, ignore_errors=True)
            done = subprocess.run([*init, "--locale=C.UTF-8"], capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"initdb failed: {done.stderr.strip().splitlines()[-1:]}")
        for _attempt in range(3):  # the free port may be taken by another worker between the look and the start
            port = _free_port()
            options = (f"-h 127.0.0.1 -p {port} -k {folder} -F -c full_page_writes=off -c synchronous_commit=off "
                       "-c max_connections=50 -c shared_buffers=16MB")
            started = subprocess.run([*prefix, str(bin_dir / "pg_ctl"), "-D", str(data), "-o", options, "-l",
                                      str(folder / "log"), "-w", "-t", "30", "start"], capture_output=True, text=True)
            if started.returncode == 0:
                server = cls(f"postgresql://postgres@127.0.0.1:{port}/postgres", data, as_postgres)
                server._bin, server._prefix = bin_dir, prefix
                return server
        raise RuntimeError(f"pg_ctl start failed: {(folder / 'log').read_text()[-300:]!r}")

    def new_database(self) -> str:
        """A fresh, empty database: its URL ``postgresql://postgres@127.0.0.1:PORT/NAME``."""
        import psycopg
        from sqlalchemy.engine import make_url

        name = next(self._names)
        base = make_url(self.url)
        with psycopg.connect(base.set(drivername="postgresql").render_as_string(hide_password=False),
                             autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        self.created.append(name)
        return base.set(database=name).render_as_string(hide_password=False)

    def stop(self) -> None:
        if self.data is None:  # the server of RDEA_LAB_TEST_POSTGRESQL: drop the databases made here
            self._drop_created()
            return
        subprocess.run([*self._prefix, str(self._bin / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w",
                        "stop"], capture_output=True)
        shutil.rmtree(self.data.parent, ignore_errors=True)

    def _drop_created(self) -> None:
        import psycopg
        from sqlalchemy.engine import make_url

        try:
            with psycopg.connect(make_url(self.url).render_as_string(hide_password=False), autocommit=True) as conn:
                for name in self.created:
                    conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        except psycopg.Error:
            pass
