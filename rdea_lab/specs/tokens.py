"""The shared secret a rig client presents (``SYST:AUTH``), read from a file."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import SpecError


def read_token(path: str | os.PathLike, field: str = "token") -> str:
    """The one word in the file ``path``.

    Raises
    ------
    SpecError
        The file cannot be read, or holds nothing or more than one word.
    """
    try:
        token = Path(path).read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(str(path), field, f"cannot read the token file ({type(exc).__name__})") from None
    if not token or any(c.isspace() for c in token):
        raise SpecError(str(path), field, "the token file must hold one token: a single word, no spaces")
    return token
