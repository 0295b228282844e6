"""The hub every viewer shares: runs found as they start, marked finished when their journal goes."""

import shutil

import numpy as np
from journals import append, make_journal, rows

from rdea_lab.monitor.hub import Hub


def test_runs_are_followed_from_their_start_to_their_end(tmp_path):
    hub = Hub(tmp_path)
    try:
        hub.update(force=True)
        assert hub.runs() == []
        j = make_journal(tmp_path / "day1" / "a.nc.part")
        append(j, rows(np.arange(50) * 0.01))
        hub.update(force=True)
        assert hub.runs() == [(str(j), "day1/a.nc")]
        assert hub.feeds[str(j)].samples == 50 and hub.feeds[str(j)].measured >= {"force", "stretch"}
        version = hub.runs_version
        shutil.rmtree(j)
        hub.update(force=True)
        assert hub.runs() == [(str(j), "day1/a.nc (finished)")] and hub.runs_version > version
    finally:
        hub.close()
