"""Tests of rdea_lab.cli.rig: ``rdea-lab rig serve``, in process for bad input, as a real process for serving."""

import json
import os
import select
import signal
import subprocess
import sys

import numpy as np
import pytest

from rdea_lab.cli.errors import run
from rdea_lab.cli.main import cli
from terminal import as_at_a_terminal

from .helpers import ROOT, Client

CARD = str(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")
#: the CLI with the rig group, as a process
LAUNCH = ("import sys; from rdea_lab.cli.main import cli; "
          "from rdea_lab.cli.errors import run; sys.exit(run(cli, sys.argv[1:]))")


def rig_cli(capsys, *args):
    code = run(cli, ["rig", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_help_has_an_example(capsys):
    code, out, _ = rig_cli(capsys, "serve", "--help")
    assert code == 0 and "Example:" in out and "rdea-lab rig serve --specimen" in out


@pytest.mark.parametrize("args, words", [
    (["--fault", "melt-at=1"], "--fault: 'melt-at=1' is not one of disconnect-at=SECONDS"),
    (["--fault", "stall=1"], "is not one of"),
    (["--fault", "stall-at=soon"], "'soon' is not a number of seconds"),
    (["--fault", "stall-at=-1"], "finite number of seconds >= 0"),
    (["--fault", "stall-at=nan"], "finite number of seconds >= 0"),
    (["--fault", "stall-at=1", "--fault", "stall-at=2"], "stall-at given 2 times"),
    (["--host", "0.0.0.0"], "--host 0.0.0.0: not a loopback address; give --token-file"),
    (["--token-file", "/nonexistent/token"], "--token-file: cannot read"),
])
def test_bad_input_exits_2_with_one_line(capsys, args, words):
    code, out, err = rig_cli(capsys, "serve", "--specimen", CARD, "--port", "0", *args)
    assert code == 2 and out == ""
    assert words in err and err.count("\n") == 1


@pytest.mark.parametrize("text, mode, words", [
    ("short-token\n", 0o600, "the token has 11 characters; give at least 16"),
    ("a-long-enough-token-0123\n", 0o622, "writable by others"),
    ("a-long-enough-token-0123\n", 0o660, "writable by others"),
])
def test_weak_or_exposed_token_files_are_refused(capsys, tmp_path, text, mode, words):
    token = tmp_path / "token"
    token.write_text(text)
    token.chmod(mode)
    code, _, err = rig_cli(capsys, "serve", "--specimen", CARD, "--token-file", token, "--port", "0")
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1


def test_a_world_readable_token_file_is_taken_with_a_warning(capsys, tmp_path):
    from rdea_lab.specs import read_token

    token = tmp_path / "token"
    token.write_text("a-long-enough-token-0123\n")
    token.chmod(0o644)
    said = []
    assert read_token(token, warn=said.append) == "a-long-enough-token-0123"
    assert len(said) == 1 and "readable by everyone" in said[0]


@pytest.mark.parametrize("option, value, words", [
    ("--max-voltage", "3 kg", "--max-voltage: '3 kg' is not a voltage"),
    ("--max-field", "-1 V/um", "--max-field"),
])
def test_bad_hard_limits_exit_2(capsys, option, value, words):
    code, _, err = rig_cli(capsys, "serve", "--specimen", CARD, option, value, "--port", "0")
    assert code == 2 and words in err, err


def test_empty_token_file(capsys, tmp_path):
    token = tmp_path / "token"
    token.write_text("  \n")
    code, _, err = rig_cli(capsys, "serve", "--specimen", CARD, "--token-file", token)
    assert code == 2 and "must hold one token" in err


def test_bad_truth_file_names_file_and_field(capsys, tmp_path):
    bad = tmp_path / "truth.yaml"
    text = ((ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml").read_text()
            .replace("force_noise: 4 mN", "force_noise: -4 mN"))
    bad.write_text(text)
    code, _, err = rig_cli(capsys, "serve", "--specimen", CARD, "--truth", bad, "--port", "0")
    assert code == 2 and f"{bad}: instrument.force_noise: must be >= 0" in err and err.count("\n") == 1


def serve(*args, launch=LAUNCH):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-c", launch, "rig", "serve", "--specimen", CARD, "--port", "0", *args],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=as_at_a_terminal)
    ready, _, _ = select.select([proc.stdout], [], [], 60)
    assert ready, "the server printed nothing"
    line = proc.stdout.readline()
    assert " listening on tcp://127.0.0.1:" in line, (line, proc.stderr.read() if proc.poll() is not None else "")
    port = int(line.rsplit(":", 1)[1])
    return proc, ("127.0.0.1", port)


def stop(proc):
    """Kill the server if a test left it running, and close its pipes."""
    if proc.poll() is None:
        proc.kill()
        proc.wait()
    proc.stdout.close()
    proc.stderr.close()


#: The launch, saying on stderr, as the server hands its heap back to the collector (`gc.unfreeze`, once it
#: stopped serving), how many objects it had frozen and how many the collector tracked beside them
#: (`test_serve_until_a_signal_then_exit_0`)
COUNTING = ("import gc, sys; thaw = gc.unfreeze; gc.unfreeze = lambda: (print('frozen', gc.get_freeze_count(), "
            "'tracked', len(gc.get_objects()), file=sys.stderr, flush=True), thaw())[1]; " + LAUNCH)


@pytest.mark.parametrize("sig", [signal.SIGTERM, pytest.param(signal.SIGINT, marks=pytest.mark.slow)])
def test_serve_until_a_signal_then_exit_0(sig):
    """Served until the signal, then exit 0 with nothing on stderr. And the process keeps the heap it held once
    listening out of the collector (`dedicate_process`), so that a full collection, which holds the
    interpreter lock, scans only what serving made since and cannot delay an ABOR past its 50 ms (CI once saw
    63 ms; a full collection of the heap unfrozen took 80-95 ms here), and hands it back when it stops:
    `COUNTING` reads both."""
    proc, address = serve(launch=COUNTING)
    try:
        client = Client(address)
        assert client.q("*IDN?").startswith("rdea-lab,rig-emulator,specimen-2,")
        assert json.loads(client.q("SYST:TRUTH?"))["name"] == "paper2021-emulator"
        client.configure(rate=1000.0)
        client.start(np.array([1.0, 1.1, 1.2]), np.array([0.0, 500.0, 1000.0]))
        assert client.q("ABOR") == "OK"
        proc.send_signal(sig)
        assert proc.wait(timeout=20) == 0
        assert client.closed()      # the server closed the connection on its way out
        client.close()
        said = proc.stderr.read().split()
        assert len(said) == 4 and said[0::2] == ["frozen", "tracked"], said  # nothing else
        frozen, tracked = int(said[1]), int(said[3])
        assert frozen > 20_000  # the imports, the card, the truth: without the freeze, 0
        assert tracked < frozen / 10  # what a collection still scans, after a run was served
        # (no line at all: the heap was never handed back)
    finally:
        stop(proc)


def test_serve_with_a_token_file(tmp_path):
    token = tmp_path / "token"
    token.write_text("letmein-42-and-more\n")
    token.chmod(0o600)
    proc, address = serve("--token-file", str(token))
    try:
        c = Client(address)
        assert c.q("*IDN?").startswith('ERR -300,"token required') and c.closed()
        c = Client(address)
        assert c.auth("letmein-42-and-more") == "OK" and c.q("*IDN?").startswith("rdea-lab,rig-emulator,")
        c.close()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=20) == 0
    finally:
        stop(proc)
