"""A disk that fills during a run (issue 25): exit 2 in one line, every sample kept in the journal, and
`recover --out` elsewhere gives them all back with how the run ended.

On a real 1 MiB file system (tmpfs, where this machine lets the suite mount one; skipped with the reason
otherwise), and in-process with the journal's writes failing with ENOSPC part-way through a block.
The samples are counted from the journal's file size, not from what the code reports.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.store import journal_path, open_run

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml"
RATE = 1000.0
PROTOCOL = """\
name: long
kind: custom
sample_rate: 1000 Hz
stretch:
  - {kind: ramp, duration: 30 s, to: 1.3}
  - {kind: ramp, duration: 30 s, to: 1.0}
voltage:
  - {kind: hold, duration: 60 s}
"""  # 60001 samples: about 4 MB of journal, four times the file system


def cli(*args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "rdea_lab.cli", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def journal_rows(folder: Path) -> int:
    columns = len(json.loads((folder / "header.json").read_text())["columns"])
    return (folder / "samples.f8").stat().st_size // (8 * columns)


@pytest.fixture
def tiny_disk(tmp_path):
    mount = tmp_path / "tiny"
    mount.mkdir()
    if shutil.which("mount") is None or os.geteuid() != 0:
        pytest.skip("a 1 MiB file system needs `mount -t tmpfs` as root; not available here")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)], capture_output=True,
                          text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a 1 MiB tmpfs here: {done.stderr.strip()[:120]}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def test_a_disk_that_fills_mid_run_is_exit_2_and_recover_elsewhere_gets_every_sample(tmp_path, tiny_disk):
    protocol = tmp_path / "long.yaml"
    protocol.write_text(PROTOCOL)
    out = tiny_disk / "run.nc"
    done = cli("run", protocol, "--specimen", CARD, "--quiet", "--out", out, cwd=tmp_path)
    lines = done.stderr.splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert "disk full" in lines[0] and "recover" in lines[0] and str(journal_path(out)) in lines[0], lines
    folder = journal_path(out)
    safe = journal_rows(folder)
    assert 1000 < safe < 60001  # the disk took part of the run, and the journal holds it
    assert f"{safe} samples are safe" in lines[0]

    again = cli("recover", tiny_disk, cwd=tmp_path)  # on the same, still full, disk: says so, the journal kept
    assert again.returncode == 2 and len(again.stderr.splitlines()) == 1 and "--out" in again.stderr, again.stderr
    assert journal_rows(folder) == safe

    elsewhere = tmp_path / "elsewhere" / "run.nc"
    rec = cli("recover", folder, "--out", elsewhere, cwd=tmp_path)
    assert rec.returncode == 0, rec.stderr
    ds = open_run(elsewhere)
    assert ds.sizes["time"] == safe
    np.testing.assert_array_equal(ds["time"].values, np.arange(safe) / RATE)  # none lost, none duplicated
    assert ds.attrs["status"] == "aborted" and "the disk filled up" in ds.attrs["status_reason"]
    ds.close()
    assert not folder.exists()


def test_enospc_part_way_through_a_block_keeps_the_whole_rows(tmp_path, monkeypatch):
    """The journal's write fails after a torn row: the rows that got out whole are counted and kept,
    the run ends aborted with the reason, and its dataset holds exactly those rows."""
    import rdea_lab
    from rdea_lab.store import journal as journal_module

    real_write = os.write
    total = 200_013  # bytes the disk takes: not a whole number of rows
    budget = {"bytes": total, "columns": None}

    def write(fd, data):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            target = ""
        if not target.endswith("samples.f8"):
            return real_write(fd, data)
        header = json.loads((Path(target).parent / "header.json").read_text())
        budget["columns"] = len(header["columns"])
        if budget["bytes"] <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        n = real_write(fd, bytes(memoryview(data)[: budget["bytes"]]))
        budget["bytes"] -= n
        return n

    monkeypatch.setattr(journal_module.os, "write", write)
    protocol = tmp_path / "long.yaml"
    protocol.write_text(PROTOCOL)
    out = tmp_path / "run.nc"
    result = rdea_lab.run_protocol(protocol, rdea_lab.load_specimen(CARD), "twin", out=out)
    monkeypatch.undo()
    ds = open_run(out)
    assert ds.attrs["status"] == "aborted" and "the disk filled up" in ds.attrs["status_reason"], ds.attrs
    whole = total // (8 * budget["columns"])  # the rows that reached the disk whole; the torn one is dropped
    assert result.samples == ds.sizes["time"] == whole
    np.testing.assert_array_equal(ds["time"].values, np.arange(whole) / RATE)
    ds.close()
