"""The dataset schema: one run = one netCDF file (DESIGN.md, "Data")."""

from __future__ import annotations

from pathlib import Path, PurePath

from ..paths import portable
from ..specs.variables import (FLAGS, MODEL_VARIABLES, NO_INSTITUTION, OPTIONAL_RUN_VARIABLES, PAUSE_VARIABLES,
                               REFERENCES, RUN_VARIABLES, TIME_ENCODING, TIME_LONG_NAME, global_attrs, time_attrs,
                               variable_attrs)

#: Variables of every run, in journal column order after ``time``: name -> (units, long_name).
#: The one table is `rdea_lab.specs.variables` (below the store and the twin, which writes datasets too).
VARIABLES: dict[str, tuple[str, str]] = RUN_VARIABLES

#: Optional variables: per backend (``model_status``), recorded when the protocol measures them
#: (``current``), or by a run that can pause (``paused``, the phase of each sample: `rdea_lab.store.pauses`):
#: name -> (units, long_name, netCDF dtype).
EXTRA_VARIABLES: dict[str, tuple[str, str, str]] = {"model_status": MODEL_VARIABLES["model_status"],
                                                    **OPTIONAL_RUN_VARIABLES, "paused": PAUSE_VARIABLES["paused"]}

#: Text variables of a run (the pause table's, along ``pause``); every other variable holds numbers.
TEXT_VARIABLES = tuple(name for name, (_, _, dtype) in PAUSE_VARIABLES.items() if dtype == "S1")

#: ``(units, long_name)`` of ``time`` as a reader gets it from `open_run`: float seconds since the
#: run's start (the file's ``units`` say since when: `time_attrs`).
TIME = ("s", TIME_LONG_NAME)

#: Values of the ``status`` attribute.
STATUSES = ("running", "complete", "aborted", "interrupted")

#: Attributes every dataset carries (DESIGN.md); none may be None.
REQUIRED_ATTRS = (
    "Conventions", "title", "rdea_lab_version", "run_id", "backend", "specimen_id", "specimen",
    "protocol_name", "protocol_kind", "protocol", "sample_rate", "seed", "created", "status",
    "status_reason", "history", "institution", "source", "references",
)


def is_emulated(attrs) -> bool:
    """Whether a dataset's attributes say it comes from the rig emulator.

    Reads ``emulated`` as written now (the integer 1; 0 for a physical rig)
    and as written by rdea-lab 0.1 (a sentence starting with ``yes``).
    """
    value = attrs.get("emulated", 0)
    if isinstance(value, str):
        return value.strip().lower().startswith("yes") or value.strip() == "1"
    try:
        return int(value) == 1
    except (TypeError, ValueError):
        return False


def origin_kind(attrs) -> str:
    """Where a run's data come from, as its attributes say: ``import``, ``emulator``, ``twin``, ``rig`` or
    ``unknown`` (the catalogue's ``origin``; `rdea_lab.reports.provenance.run_origin` says more)."""
    backend = str(attrs.get("backend", ""))
    if backend == "import":
        return "import"
    if is_emulated(attrs):
        return "emulator"
    return backend if backend in ("twin", "rig") else "unknown"


def portable_path(path) -> str:
    """A path as a shipped file may hold it: a packaged input by its name under ``rdea_lab/data``
    (``protocols/blocking_force.yaml``, which `rdea_lab.paths.resolve` finds again), a path below the
    working directory relative to it, else the bare file name (no machine's absolute path); text that
    is not a path (``<string>``) as it is."""
    text = str(path)
    if not text or text.startswith("<") or not PurePath(text).is_absolute():
        return text
    p = Path(text)
    name = portable(p)
    if name is not None:
        return name
    try:
        return p.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except (ValueError, OSError):
        return p.name


def portable_command(command: str) -> str:
    """A command line for ``history``: each absolute path in it (also after ``--opt=``) made portable."""
    def one(word: str) -> str:
        key, eq, value = word.rpartition("=") if "=" in word and not word.startswith("/") else ("", "", word)
        return key + eq + portable_path(value) if value.startswith("/") else word

    return " ".join(one(w) for w in str(command).split(" "))


__all__ = ["EXTRA_VARIABLES", "FLAGS", "NO_INSTITUTION", "OPTIONAL_RUN_VARIABLES", "PAUSE_VARIABLES", "REFERENCES",
           "REQUIRED_ATTRS", "STATUSES", "TEXT_VARIABLES", "TIME", "TIME_ENCODING", "VARIABLES", "global_attrs",
           "is_emulated", "origin_kind", "portable_command", "portable_path", "time_attrs", "variable_attrs"]
