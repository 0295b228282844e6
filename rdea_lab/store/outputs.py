"""Where a dataset, a figure or a record is to be written: checked before anything is measured or computed."""

from __future__ import annotations

import tempfile
from pathlib import Path

from ..specs import SpecError


class OutputError(SpecError):
    """A dataset cannot be written where asked (a folder that is not writable, not a folder, ...)."""


def check_writable(path, what="out") -> None:
    """Raise `OutputError` unless the file ``path`` can be created: its nearest existing folder is a
    writable folder (the missing ones below it are made when the run writes)."""
    path = Path(path)
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(str(path), what, f"{folder} is not a folder")
    try:  # a probe file: permissions, read-only mounts and pseudo file systems alike (root passes os.access)
        with tempfile.TemporaryFile(dir=folder, prefix=".rdea-lab-probe-"):
            pass
    except OSError as exc:
        raise OutputError(str(path), what, f"cannot write in the folder {folder} "
                          f"({exc.strerror or type(exc).__name__})") from None
