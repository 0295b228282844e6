"""Fixtures for every test.

No backend is chosen here: without a DISPLAY matplotlib picks Agg by itself.
"""

import os
import signal
import sys
import threading
from pathlib import Path

import pytest
import pg_server
from vhb_data import LOADING_UNLOADING, MISSING

ROOT = Path(__file__).resolve().parents[1]

# The test run puts a worker on each core (pytest-xdist): a call that took the other core for numba's threads
# would only take it from the other worker, and compile the threaded variants, some 30 s of CPU with an empty
# numba cache, wherever a large call happened to meet an idle moment. The tests of the threaded variants say
# so themselves (they set `kernels._other_load`); the processes the tests start inherit this.
os.environ.setdefault("RDEA_LAB_THREADS", "1")


@pytest.fixture(autouse=True)
def _close_figures():
    """Close every pyplot figure a test left open (pyplot imported only if the test did)."""
    yield
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")


@pytest.fixture(autouse=True)
def _signals_as_found():
    """A test leaves this process's SIGINT and SIGTERM handlers as it found them and blocks no signal it did not:
    one left changed changes every later test in the process, and every process a later test starts (a child
    inherits an ignored or blocked signal). Put back, and the test fails at teardown naming what it left."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    wanted = (signal.SIGINT, signal.SIGTERM)
    handlers = {sig: signal.getsignal(sig) for sig in wanted}
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, set())
    yield
    left = [f"{sig.name} handler {signal.getsignal(sig)!r} (was {handler!r})" for sig, handler in handlers.items()
            if signal.getsignal(sig) is not handler]
    # newly blocked only: multiprocessing's resource tracker unblocks both signals when it starts, whatever the
    # mask was (CPython 3.11 `resource_tracker.ensure_running`), which no later test minds
    now = signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    if now - mask:
        left.append(f"signal mask {sorted(s.name for s in now)} (was {sorted(s.name for s in mask)})")
    for sig, handler in handlers.items():
        if handler is not None:  # None: a handler not installed from Python, which cannot be put back
            signal.signal(sig, handler)
    if left:
        pytest.fail("the test left this process's signal handling changed: " + "; ".join(left), pytrace=False)


@pytest.fixture(scope="session")
def imported(tmp_path_factory):
    """A folder of the five VHB files as datasets, imported as the README shows (calibration and report tests)."""
    if not LOADING_UNLOADING:
        pytest.skip(MISSING)
    from rdea_lab.cli.errors import run as run_cli
    from rdea_lab.cli.main import cli

    out = tmp_path_factory.mktemp("vhb")
    rc = run_cli(cli, ["import", *map(str, LOADING_UNLOADING), "--format", "csv", "--map",
                       "time=0,position=1,force=2", "--protocol-kind", "tensile", "--specimen",
                       str(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml"), "--credit",
                       "Chongran-Zhao/VHB4910_data (GitHub)", "--out", str(out)])
    assert rc == 0
    return out


@pytest.fixture(scope="session")
def postgresql_server():
    """A PostgreSQL server for this session (or xdist worker): `RDEA_LAB_TEST_POSTGRESQL`'s, else a throwaway one
    started on first use and stopped at the end (tests/pg_server.py); skips, saying why in one line, without one."""
    if url := os.environ.get(pg_server.ENV):
        server = pg_server.Server(url)
    else:
        # where the server must be there (CI installs it: RDEA_LAB_REQUIRE_POSTGRESQL=1) a missing one fails
        give_up = pytest.fail if os.environ.get("RDEA_LAB_REQUIRE_POSTGRESQL") == "1" else pytest.skip
        if reason := pg_server.unavailable():
            give_up(reason)
        try:
            server = pg_server.Server.start()
        except (OSError, RuntimeError) as exc:
            give_up(f"PostgreSQL tests skipped: the throwaway server did not start ({exc})")
    yield server
    server.stop()


@pytest.fixture
def postgresql_url(postgresql_server):
    """A fresh, empty PostgreSQL database: ``postgresql://postgres@127.0.0.1:PORT/NAME``."""
    return postgresql_server.new_database()
