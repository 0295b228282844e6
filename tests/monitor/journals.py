"""Journals written by hand, as `rdea_lab.store.journal.JournalWriter` lays them out (tests of the monitor)."""

import json

import numpy as np

COLUMNS = ["time", "stretch", "position", "voltage", "force", "capacitance", "stretch_setpoint",
           "voltage_setpoint"]


def make_journal(folder, columns=COLUMNS, attrs=None):
    """``folder`` (``<out>.nc.part``) with a header and an empty ``samples.f8``."""
    folder.mkdir(parents=True)
    header = {"format": "rdea-lab-journal-1", "columns": list(columns), "attrs": attrs or {"protocol_name": "p"},
              "writer": {"pid": 1, "host": "h", "started": "2026-01-01T00:00:00Z"}}
    (folder / "header.json").write_text(json.dumps(header))
    (folder / "samples.f8").write_bytes(b"")
    return folder


def rows(t, columns=COLUMNS, **values):
    """Rows at times ``t`` [s]: each column ``values[name]`` (default: the time itself, for checking)."""
    t = np.asarray(t, float)
    return np.column_stack([t] + [np.broadcast_to(values.get(c, t), t.shape) for c in columns[1:]]).astype("<f8")


def append(folder, block, torn_bytes=0):
    """Append ``block``'s rows, then ``torn_bytes`` of a row being written (a torn last row)."""
    with open(folder / "samples.f8", "ab") as fh:
        fh.write(block.tobytes())
        fh.write(b"\x01" * torn_bytes)
