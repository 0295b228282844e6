"""Operating a run while it goes: pause, resume and abort requests, from this process or another.

`RunControl` is what the run engine reads between two blocks of samples: requests put in from Python
(``control.pause("look at the specimen")``, from any thread: a callback, a notebook, the live view) and
requests that other processes put in the run's journal folder (``rdea-lab pause RUN``, ``rdea-lab monitor``).
The engine answers each request by publishing the run's state in the same folder, so whoever asked can see
it acted on.

The files, in ``<out>.part/`` (the run's journal, which exists exactly while the run goes):

- ``control/<id>.json``: one request, ``{"id", "action", "reason", "by", "sent"}``, written whole (a temporary
  name, then a rename) by `request`; the engine reads and removes it.
- ``state.json``: ``{"state", "reason", "run_id", "pid", "samples", "time", "updated", "handled"}``, replaced
  whole by the engine at every change; ``handled`` lists the ids of the last requests it acted on (or refused,
  with ``refused`` saying why).

Who may write the journal folder may control the run: the operating system's permissions are the control
(the run's own user, by default). The live view adds its own controller check on top (`rdea_lab.monitor`).
"""

from __future__ import annotations

import collections
import json
import os
import secrets
import threading
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

from ..specs import SpecError

#: What a request can ask.
ACTIONS = ("pause", "resume", "abort")
#: The run states `RunControl.publish` writes: a run goes ``running`` -> ``pausing`` (voltage ramping down)
#: -> ``paused`` (held) -> ``resuming`` (ramping back) -> ``running``, and ends ``ended``.
STATES = ("starting", "running", "pausing", "paused", "resuming", "ended")
REQUESTS = "control"
STATE_FILE = "state.json"
#: Request ids remembered in ``handled``.
HANDLED = 32


class ControlError(SpecError):
    """A request that cannot reach a run: no run in progress there, or one that does not answer."""

    def __init__(self, run, message):
        super().__init__(str(run), "RUN", message)


@dataclass(frozen=True)
class Request:
    """One request to a run."""

    action: str
    reason: str = ""
    by: str = "python"
    id: str = field(default_factory=lambda: secrets.token_hex(8))


def _write_whole(path: Path, data: dict) -> None:
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    with open(tmp, "w", encoding="utf-8") as fh:
        json.dump(data, fh)
    os.replace(tmp, path)


class RunControl:
    """Requests to one run (thread-safe), and the run's published state.

    The engine makes one for every run (or takes the caller's: ``run_protocol(..., control=ctl)``), attaches
    the run's journal folder (`attach`), reads the requests between blocks (`poll`) and publishes the state
    (`publish`).
    """

    def __init__(self):
        self._lock = threading.Lock()
        self._queue: collections.deque = collections.deque()
        self.folder: Path | None = None
        self.state = "starting"
        self.reason = ""
        self._handled: collections.deque = collections.deque(maxlen=HANDLED)
        self._published: dict = {}

    # ------------------------------------------------------------ asking
    def _put(self, action, reason, by) -> Request:
        req = Request(action, reason, by)
        with self._lock:
            self._queue.append(req)
        return req

    def pause(self, reason: str = "paused by the user", by: str = "python") -> Request:
        """Ask the run to pause (voltage ramped to 0, stretch held) from its next block."""
        return self._put("pause", reason, by)

    def resume(self, reason: str = "resumed by the user", by: str = "python") -> Request:
        """Ask a paused run to go back to its plan."""
        return self._put("resume", reason, by)

    def abort(self, reason: str = "aborted by the user", by: str = "python") -> Request:
        """Ask the run to end now, ``aborted``, voltage off, every sample kept."""
        return self._put("abort", reason, by)

    # ----------------------------------------------------------- the run
    def attach(self, folder) -> None:
        """The run's journal folder: requests from other processes are read from it, the state written to it."""
        self.folder = Path(folder)
        (self.folder / REQUESTS).mkdir(exist_ok=True)

    def poll(self, folder: bool = True) -> list[Request]:
        """Every request not yet read, oldest first (this process's, then the folder's by the time sent;
        ``folder=False``: this process's only, without a look at the folder)."""
        out = []
        if self._queue:  # (read without the lock: a request put in meanwhile is read next time)
            with self._lock:
                out = list(self._queue)
                self._queue.clear()
        if self.folder is None or not folder:
            return out
        found = []
        try:
            entries = list(os.scandir(self.folder / REQUESTS))
        except OSError:
            return out
        for entry in entries:
            if not entry.name.endswith(".json") or entry.name.startswith("."):
                continue
            try:
                with open(entry.path, encoding="utf-8") as fh:
                    data = json.load(fh)
                os.unlink(entry.path)
            except (OSError, ValueError):
                continue
            if isinstance(data, dict) and data.get("action") in ACTIONS:
                found.append((float(data.get("sent", 0.0)), Request(str(data["action"]), str(data.get("reason", "")),
                                                                    str(data.get("by", "another process")),
                                                                    str(data.get("id", "")))))
        return out + [req for _, req in sorted(found, key=lambda x: x[0])]

    def outcome(self, request: Request) -> dict | None:
        """How the run answered `request` (``{"id", "action", "refused"}``), or None while it has not."""
        for done in list(self._handled):
            if done["id"] == request.id:
                return done
        return None

    def handled(self, request: Request, refused: str = "") -> None:
        """`request` was acted on (or refused, saying why); published with the next `publish`."""
        self._handled.append({"id": request.id, "action": request.action, "refused": refused})

    def publish(self, state: str, reason: str = "", **extra) -> None:
        """The run's state for other processes (``state.json``), written whole; also kept in `state`."""
        if state not in STATES:
            raise ValueError(f"state {state!r}; allowed: {', '.join(STATES)}")
        self.state, self.reason = state, reason
        data = {"state": state, "reason": reason, "pid": os.getpid(), "updated": _time.time(),
                "handled": list(self._handled), **extra}
        self._published = data
        if self.folder is not None and self.folder.is_dir():
            try:
                _write_whole(self.folder / STATE_FILE, data)
            except OSError:
                pass  # the run goes on; a request from elsewhere then waits in vain and says so


# ------------------------------------------------------------- other processes
def journal_folder(run) -> Path:
    """The journal folder of a run in progress: ``RUN`` is its dataset (``out.nc``) or its ``out.nc.part``."""
    path = Path(run)
    if path.name.endswith(".part"):
        return path
    return path.with_name(path.name + ".part")


def read_state(run) -> dict | None:
    """The state a run in progress published (`RunControl.publish`), or None (no run there, or not yet)."""
    try:
        with open(journal_folder(run) / STATE_FILE, encoding="utf-8") as fh:
            data = json.load(fh)
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def request(run, action: str, reason: str = "", *, by: str = "another process", wait: float = 5.0,
            clock=_time.monotonic, sleep=_time.sleep) -> dict:
    """Ask the run in progress at ``run`` to ``pause``, ``resume`` or ``abort``; wait until it says it acted.

    Parameters
    ----------
    run : path
        The run's dataset (``out.nc``) or its journal folder (``out.nc.part``).
    action : {"pause", "resume", "abort"}
    reason : str
        Recorded in the dataset with the pause (or as the abort's reason).
    by : str
        Who asks, recorded too (``rdea-lab pause``, ``monitor``).
    wait : float
        Longest wait for the run's answer [s]; 0 sends and returns at once.

    Returns
    -------
    dict
        The run's state after it acted (`read_state`), with ``refused`` set when it would not (e.g. resume
        of a run that is not paused).

    Raises
    ------
    ControlError
        No run in progress at ``run``, or none that answered within ``wait``.
    """
    if action not in ACTIONS:
        raise SpecError("arguments", "action", f"{action!r}; allowed: {', '.join(ACTIONS)}")
    if not Path(run).name:
        raise ControlError(run, "not a run: give the run's dataset (RUN.nc, as rdea-lab run --out named it) or "
                                "its journal folder (RUN.nc.part)")
    folder = journal_folder(run)
    if not (folder / REQUESTS).is_dir():
        raise ControlError(run, f"no run in progress there (no {folder / REQUESTS}); a run that has ended "
                                f"cannot {action}")
    req = Request(action, reason, by)
    _write_whole(folder / REQUESTS / f"{req.id}.json",
                 {"id": req.id, "action": action, "reason": reason, "by": by, "sent": _time.time()})
    if wait <= 0:
        return read_state(run) or {}
    end = clock() + wait
    while clock() < end:
        state = read_state(run)
        if state is not None:
            for done in state.get("handled", ()):
                if done.get("id") == req.id:
                    return {**state, "refused": done.get("refused", "")}
        if not folder.is_dir():
            raise ControlError(run, f"the run ended before it acted on the {action}")
        sleep(0.02)
    try:
        os.unlink(folder / REQUESTS / f"{req.id}.json")  # not taken: withdrawn, so it does not act later
    except OSError:
        pass
    raise ControlError(run, f"the run did not answer the {action} within {wait:g} s (its process may be stopped "
                            "or of an older rdea-lab)")


__all__ = ["ACTIONS", "ControlError", "Request", "RunControl", "STATES", "journal_folder", "read_state", "request"]
