"""The reference inputs shipped inside the package, and how a name or a path finds one.

The paper's specimen cards, parameter sets, protocols, the emulator's truth, the
campaign, the targets and the design studies are package data under
``rdea_lab/data/<kind>/`` (read through `importlib.resources`), so an installed
wheel runs ``rdea-lab reproduce`` from any folder. A user's path always wins:
`resolve` returns it unchanged when it exists; otherwise a packaged file of that
name (``specimen2``, ``specimen2.yaml`` or ``specimens/specimen2.yaml``) answers
for it, and else the path comes back as given, for the loader to say it is missing.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

#: The kinds of packaged input, each a folder of ``rdea_lab/data``.
KINDS = ("specimens", "params", "protocols", "truth", "campaigns", "targets", "studies")
_SUFFIXES = (".yaml", ".yml", ".csv")


def data_dir() -> Path:
    """The folder of the packaged reference inputs (``rdea_lab/data``), as a filesystem path."""
    return Path(os.fspath(resources.files("rdea_lab") / "data"))


def packaged(kind: str, name: str) -> Path | None:
    """The packaged file ``name`` of ``kind`` (with or without its suffix), or None."""
    if kind not in KINDS:
        raise ValueError(f"unknown kind of input {kind!r}; allowed: {', '.join(KINDS)}")
    folder = data_dir() / kind
    for candidate in (name, *(name + s for s in _SUFFIXES)):
        path = folder / candidate
        if path.is_file() and path.parent == folder:
            return path
    return None


def names(kind: str) -> list[str]:
    """The packaged files of ``kind``, by name without suffix (``specimen2``, ...)."""
    folder = data_dir() / kind
    return sorted(p.stem for p in folder.iterdir() if p.suffix in _SUFFIXES) if folder.is_dir() else []


def resolve(ref: str | os.PathLike, kind: str) -> Path:
    """A user's file reference as a path: the path itself when it exists, else the packaged file it names.

    ``"specimen2"``, ``"specimen2.yaml"`` and ``"specimens/specimen2.yaml"`` all name
    ``rdea_lab/data/specimens/specimen2.yaml`` when no such file exists where the user is.
    A reference that names nothing comes back unchanged (the loader reports it missing).
    """
    path = Path(ref)
    if path.exists() or path.is_absolute():
        return path
    parts = path.parts
    if len(parts) == 2 and parts[0] in KINDS:
        kind, name = parts
    elif len(parts) == 1:
        name = parts[0]
    else:
        return path
    return packaged(kind, name) or path


def portable(path) -> str | None:
    """A packaged file's name relative to the data folder (``specimens/specimen2.yaml``), else None."""
    try:
        return Path(path).resolve().relative_to(data_dir().resolve()).as_posix()
    except (ValueError, OSError):
        return None


def benchmarks_dir() -> Path | None:
    """The source checkout's ``benchmarks/`` (holding ``bench_models.py``) beside this package, or None
    (an installed wheel has no benchmarks)."""
    folder = Path(__file__).resolve().parents[1] / "benchmarks"
    return folder if (folder / "bench_models.py").is_file() else None
