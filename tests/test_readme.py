"""The README: short, the two set-up lines exactly, its notebook cell and every command of its table run.

The table's examples run in the order written, in one empty folder (later rows use what earlier rows
wrote), in process through `rdea_lab.cli.errors.run`; the rows that keep running (`rig serve`, a paced
`run --realtime`, `monitor`) as processes of their own, for the rows after them. Left out here: the install
and test lines and `rdea-lab reproduce` (tests/reports cover reproduce). The longer examples (a whole
campaign, the speed study, a design study, bench) run alone, each in its own folder: none of them uses another row's
output; those over about 15 s on a loaded 2-core machine (design, bench: 20-30 s) are marked slow. The
`import` example needs the VHB 4910 files beside the checkout (docs/vhb4910.md); without them it skips
and says where.
"""

import contextlib
import io
import os
import re
import shlex
import socket
import subprocess
import sys
import time
from glob import glob
from pathlib import Path

import pytest
from terminal import as_at_a_terminal
from vhb_data import MISSING, VHB

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SETUP = ['python3 -m pip install -e ".[test]" && rdea-lab reproduce       # install, then the main job',
         'python3 -m pip install -e ".[test]" && python3 -m pytest -q     # install, then the tests']
#: Examples that run alone, each in a folder of its own (first words after ``rdea-lab``) ...
ALONE = {("campaign", "run"), ("report", "speed"), ("design",), ("bench",)}
#: ... and those of them over ~10 s here (marked slow).
SLOW = {("design",), ("bench",), ("campaign", "run"), ("report", "speed")}
NOT_RUN = {("reproduce",)}


def _text():
    return README.read_text(encoding="utf-8")


def table_examples():
    """The examples of the README's command table, in order, as argument lists (without ``rdea-lab``)."""
    section = _text().split("\n## Commands\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    examples = []
    for row in rows:
        cells = [c.strip() for c in row.strip().strip("|").split(" | ")]
        assert len(cells) == 3, f"a table row of three cells: {row}"
        command = re.fullmatch(r"`(rdea-lab [^`]+)`", cells[2])
        assert command, f"the example is one command in backticks: {row}"
        argv = shlex.split(command[1])
        assert argv[0] == "rdea-lab"
        examples.append(argv[1:])
    return examples


def _key(argv):
    for n in (2, 1):
        if tuple(argv[:n]) in ALONE | NOT_RUN:
            return tuple(argv[:n])
    return None


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _run(argv, cwd):
    from rdea_lab.cli.errors import run
    from rdea_lab.cli.main import cli

    argv = [m for a in argv for m in (sorted(glob(a, root_dir=cwd)) or [a] if "*" in a else [a])]
    err = io.StringIO()
    started = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = run(cli, argv)
    took = time.perf_counter() - started
    assert rc == 0, f"rdea-lab {shlex.join(argv)} exited {rc} after {took:.1f} s: {err.getvalue().strip()}"


def test_readme_is_short_and_holds_the_setup_lines():
    lines = _text().splitlines()
    assert len(lines) <= 200
    for line in SETUP:
        assert line in lines
    assert "```bash\n" + "\n".join(SETUP) + "\n```" in _text()


def test_readme_table_covers_every_command():
    from rdea_lab.cli.main import cli

    named = {argv[0] for argv in table_examples()}
    assert named == set(cli.list_commands(None))  # the lazy group: every command, loaded or not


def test_readme_commands(tmp_path, monkeypatch):
    """Every fast example, in order, in one folder; the rig server as a process of its own."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    port, viewer = str(_free_port()), str(_free_port())
    servers, paced, codes = [], None, []
    try:
        for argv in table_examples():
            if _key(argv) or argv[0] == "import":
                continue
            argv = [a.replace("5025", port) for a in argv]
            if argv[:2] == ["rig", "serve"] or argv[0] == "monitor":
                argv = [a.replace("5006", viewer) for a in argv]
                servers.append(_background(argv, work))
                _wait_listening(int(viewer if argv[0] == "monitor" else port), servers[-1])
                continue
            if argv[0] == "run" and "--realtime" in argv:  # a paced run, operated by the rows after it
                paced = _background(argv, work)
                _wait_running(work / argv[argv.index("--out") + 1], paced)
                continue
            _run(argv, work)
        if paced is not None:  # the rows after it ended it (abort): exit 3, its dataset whole
            assert paced.wait(60) == 3, paced.communicate()[1]
    finally:
        for process in [*servers, *([paced] if paced is not None else [])]:
            if process.poll() is None:
                process.terminate()
            codes.append((process.args, process.wait(30), process.communicate()[1]))
    for args, code, stderr in codes[:len(servers)]:  # a server ends cleanly on SIGTERM
        assert code == 0, (args, stderr)


def _background(argv, cwd):
    """A row that keeps running (a server, a paced run), as a process of its own, ended by SIGTERM."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen([sys.executable, "-m", "rdea_lab.cli.main", *argv], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, preexec_fn=as_at_a_terminal)


def _wait_running(out, process, timeout=120.0):
    from rdea_lab.runs.control import read_state

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()[1]
        if (read_state(out) or {}).get("samples", 0) > 0:
            return
        time.sleep(0.1)
    pytest.fail(f"the paced run {out} did not start within {timeout} s")


def _wait_listening(port, process, timeout=60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()[1]
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), timeout=1):
            return
        time.sleep(0.2)
    pytest.fail(f"rig serve did not listen on port {port} within {timeout} s")


def test_readme_import(tmp_path, monkeypatch):
    """The import example reads ../shared/data/vhb4910 beside the working folder (the checkout's own, linked)."""
    if not VHB.is_dir():
        pytest.skip(MISSING)
    (tmp_path / "shared" / "data").mkdir(parents=True)
    (tmp_path / "shared" / "data" / "vhb4910").symlink_to(VHB, target_is_directory=True)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    examples = [argv for argv in table_examples() if argv[0] == "import"]
    assert examples
    for argv in examples:
        _run(argv, work)


@pytest.mark.parametrize("argv", [pytest.param(a, marks=[pytest.mark.slow] if _key(a) in SLOW else [],
                                               id=" ".join(_key(a))) for a in table_examples() if _key(a) in ALONE])
def test_readme_commands_alone(argv, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _run(argv, tmp_path)


def test_readme_notebook_cell(tmp_path):
    """The notebook cell runs as written (in an empty folder) and prints what the README says it prints."""
    section = _text().split("## The library: a notebook cell", 1)[1]
    cell = re.search(r"```python\n(.*?)```", section, re.DOTALL)[1]
    claimed = re.search(r"print\(.*\)\s+# (.*)", cell)[1].strip()
    cell = cell.replace('rdea_lab.catalog(".")', 'table = rdea_lab.catalog(".")')
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        out = io.StringIO()
        scope = {}
        with contextlib.redirect_stdout(out):
            exec(compile(cell, "README.md", "exec"), scope)  # noqa: S102 (the README's own cell)
    finally:
        os.chdir(here)
    assert out.getvalue().strip() == claimed
    assert list(scope["table"]["md.operator"]) == ["ana"]
    assert scope["fig"].axes  # a Figure was drawn
