"""``rdea-lab monitor``: a live view of runs in the browser (a Bokeh server started in this process).

Above the runs and the store: it follows every run in progress below a folder by reading its journal
(`tail`: new whole rows, new and vanished journals), whatever started the run (the CLI, Python, a campaign),
since every run writes one; no change to a run is needed and a viewer changes nothing for it. `feed` turns a
run's rows into display points (decimated, with the twin's prediction), `hub` shares them between viewers,
`access` says who may look (loopback, or a token) and who may pause, resume and abort (the control URL's
secret, checked on the server), `app` is the page and `server` the Bokeh server.

`Monitor` and `monitor` need Bokeh (``pip install "rdea-lab[monitor]"``); `tail`, `feed` and `access` do not.
"""

from __future__ import annotations

from ..extras import require


def _server():
    require("bokeh", "rdea-lab monitor", extra="monitor")
    from . import server

    return server


def __getattr__(name):
    if name in ("Monitor", "monitor", "MODELS"):
        return getattr(_server(), name)
    raise AttributeError(f"module 'rdea_lab.monitor' has no attribute {name!r}")


__all__ = ["MODELS", "Monitor", "monitor"]
