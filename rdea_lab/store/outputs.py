"""Where a dataset, a figure or a record is to be written: checked before anything is measured or computed.

The one rule of every writer (`check_new`): an existing output is refused unless ``overwrite`` (the CLI's
``--force``), before any work; then the place must be writable (`check_writable`).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..specs import SpecError


class OutputError(SpecError):
    """A dataset cannot be written where asked (a folder that is not writable, not a folder, ...)."""


#: The longest suffix a writer adds to an output's name (the journal folder ``<out>.part``; ``.tmp`` is shorter).
LONGEST_SUFFIX = ".part"


def shown(path) -> str:
    """A path as a message can print it, whatever bytes it holds (undecodable ones as ``\\xNN``)."""
    return str(path).encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


def check_dataset_name(path, what="out") -> None:
    """Raise `OutputError` unless ``path`` names a netCDF file (``.nc``): a dataset written under another
    suffix (``run.csv``) is netCDF all the same, and misleads every program that opens it by its name.
    For dataset outputs only (reports and figures have their own suffixes)."""
    suffix = Path(path).suffix
    if suffix.lower() != ".nc":
        given = f"the suffix {suffix!r}" if suffix else "no suffix"
        raise OutputError(shown(path), what, f"{given}; allowed: a .nc file name (a dataset is written as "
                          "netCDF)")


def check_writable(path, what="out") -> None:
    """Raise `OutputError` unless the file ``path`` can be created: a name in UTF-8 (netCDF and the
    dataset's attributes store it as text), each part of it (and the journal's ``<name>.part``) no longer
    than the file system takes, and its nearest existing folder a writable folder (the missing ones below
    it are made when the run writes)."""
    path = Path(path)
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        raise OutputError(shown(path), what, "is not valid UTF-8; allowed: a name of UTF-8 characters (netCDF "
                          "stores it as text)") from None
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(str(path), what, f"{folder} is not a folder")
    try:
        name_max = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    below = path.relative_to(folder).parts if path.is_absolute() == folder.is_absolute() else path.parts
    for i, part in enumerate(below):
        size = len((part + (LONGEST_SUFFIX if i == len(below) - 1 else "")).encode("utf-8"))
        if size > name_max:
            raise OutputError(str(path)[:120] + ("..." if len(str(path)) > 120 else ""), what,
                              f"the name {part[:40]!r}... is {len(part.encode('utf-8'))} bytes; allowed: at most "
                              f"{name_max - (len(LONGEST_SUFFIX) if i == len(below) - 1 else 0)} bytes here "
                              f"(the file system takes {name_max}"
                              + (f", and the run's journal adds {LONGEST_SUFFIX!r})" if i == len(below) - 1 else ")"))
    try:  # a probe file: permissions, read-only mounts and pseudo file systems alike (root passes os.access)
        with tempfile.TemporaryFile(dir=folder, prefix=".rdea-lab-probe-"):
            pass
    except OSError as exc:
        raise OutputError(str(path), what, f"cannot write in the folder {folder} "
                          f"({exc.strerror or type(exc).__name__})") from None


#: What a refused output tells the user to do (the same words for every writer).
FORCE_HINT = "give --force (overwrite=True) to replace it, or another output"


def check_new(path, overwrite: bool = False, what="out", *, folder: bool = False, error=OutputError) -> None:
    """Raise ``error`` (an `OutputError`) if the output ``path`` exists and not ``overwrite``, or cannot be
    written (`check_writable`): the one rule of every command that writes, checked before any work.

    Parameters
    ----------
    path : path
        A file to be written, or with ``folder`` a folder to be written into.
    overwrite : bool
        Replace what is there (``--force``).
    what : str
        The field the path came from, for the message (``out``, ``--out``, ...).
    folder : bool
        ``path`` is a folder: refused when it holds anything (a file is refused as not a folder, even with
        ``overwrite``); otherwise a folder at ``path`` is refused as not a file.
    """
    path = Path(path)
    if folder:
        if path.exists() and not path.is_dir():
            raise error(shown(path), what, "is a file; give a folder")
        if not overwrite and path.is_dir() and any(path.iterdir()):
            raise error(shown(path), what, "exists and holds files; give --force (overwrite=True) to write "
                        "over it, or another folder")
        check_writable(path / "x", what)
        return
    if path.is_dir():
        raise error(shown(path), what, "is a folder; give the path of a file")
    if path.exists() and not overwrite:
        raise error(shown(path), what, f"exists; {FORCE_HINT}")
    check_writable(path, what)


def figure_formats() -> tuple[str, ...]:
    """The file suffixes matplotlib writes (``png``, ``pdf``, ``svg``, ...), from its canvas alone: no pyplot, no
    backend chosen."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted(FigureCanvasBase.get_supported_filetypes()))


def check_figure(path, what="--plot") -> None:
    """Raise `OutputError` unless matplotlib can write a figure to ``path``: a suffix among its formats
    (`figure_formats`), and a place `check_writable` accepts; before the work the figure shows."""
    path = Path(path)
    suffix = path.suffix.lower().lstrip(".")
    formats = figure_formats()
    if suffix not in formats:
        given = f"the suffix {path.suffix!r}" if path.suffix else "no suffix"
        raise OutputError(shown(path), what, f"{given} is not a figure format matplotlib writes; allowed: "
                          + ", ".join(f".{f}" for f in formats))
    if path.is_dir():
        raise OutputError(shown(path), what, "is a folder; give the path of a file")
    check_writable(path, what)
