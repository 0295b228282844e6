"""The shared secret a rig client presents (``SYST:AUTH``), read from a file."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import SpecError


#: The shortest token accepted [characters].
MIN_TOKEN = 16


#: The characters a token may hold: printable ASCII without the space (and not '#', which starts a block).
TOKEN_FIRST, TOKEN_LAST = "!", "~"


def check_token(token) -> str:
    """``token`` if a server can use it (a string of printable ASCII without space or '#'), else ValueError."""
    if not isinstance(token, str) or not token or any(not (TOKEN_FIRST <= c <= TOKEN_LAST) or c == "#" for c in token):
        raise ValueError("the token must be a non-empty string of printable ASCII letters, digits and punctuation, "
                         "without spaces or '#'")
    return token


def read_token(path: str | os.PathLike, field: str = "token", warn=None) -> str:
    """The one word in the file ``path``: a shared secret of at least 16 characters.

    A file that others may write is refused (anyone could change the secret);
    one that others may read is accepted with a warning (``warn(message)``).

    Raises
    ------
    SpecError
        The file cannot be read, is group or world writable, or holds nothing,
        more than one word, or fewer than 16 characters.
    """
    try:
        mode = os.stat(path).st_mode
        token = Path(path).read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(str(path), field, f"cannot read the token file ({type(exc).__name__})") from None
    if mode & (stat.S_IWGRP | stat.S_IWOTH):
        raise SpecError(str(path), field, "the token file is writable by others; chmod 600 it")
    if not token or any(c.isspace() for c in token):
        raise SpecError(str(path), field, "the token file must hold one token: a single word, no spaces")
    bad = next((c for c in token if not (TOKEN_FIRST <= c <= TOKEN_LAST) or c == "#"), None)
    if bad is not None:
        raise SpecError(str(path), field, f"the token holds {bad!r}; allowed: printable ASCII letters, digits and "
                        "punctuation except '#' (e.g. python3 -c 'import secrets; print(secrets.token_hex(16))')")
    if len(token) < MIN_TOKEN:
        raise SpecError(str(path), field, f"the token has {len(token)} characters; give at least {MIN_TOKEN} "
                        "(e.g. python3 -c 'import secrets; print(secrets.token_hex(16))')")
    if mode & stat.S_IROTH and warn is not None:
        warn(f"{path}: the token file is readable by everyone; chmod 600 it")
    return token
