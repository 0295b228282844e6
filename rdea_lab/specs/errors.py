"""Errors at the edge: `UserError` and `SpecError`.

Every mistake a user can make in a specimen card or a parameter file ends as
one `SpecError` whose ``str`` is a single line
``"{source}: {field}: {message}"`` (``"{source}: {message}"`` for the document as a whole), e.g.
``specimens/x.yaml: membrane.L3: '48 kg' is not a length; give it with a
length unit, e.g. '48 um'``.

This module imports neither YAML nor pydantic (a command line's errors cost nothing): the safe YAML
reader is `rdea_lab.specs.yamlio`, the base model and the translation of pydantic's errors
`rdea_lab.specs.base`. Their names are still found here (loaded on first use) for older imports.
"""

from __future__ import annotations

import importlib as _importlib
from typing import Any

#: Field name used for problems with the document as a whole (file missing,
#: not YAML, top level not a mapping).
DOCUMENT = "<document>"


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def show(value: object, limit: int = 60) -> str:
    """Short, one-line ``repr`` of a user value for an error message."""
    text = _one_line(repr(value))
    return text if len(text) <= limit else text[: limit - 3] + "..."


class UserError(ValueError):
    """A user's mistake (input, options, a rig refusing a run): the CLI gives it exit status 2 and one line.

    Every such error of the package derives from it; anything else reaching the
    CLI is a bug (exit status 1).
    """


class SpecError(UserError):
    """A user mistake in a spec (specimen card, parameter set, ...).

    Parameters
    ----------
    source : str
        Where the input came from: a file path, ``"<string>"``,
        ``"<mapping>"`` or ``"<python>"``.
    field : str
        Dotted path of the offending field, e.g. ``membrane.L3``,
        ``yeoh.C10``, ``viscoelastic.branches[0].eta``; `DOCUMENT` for the
        document as a whole.
    message : str
        What is wrong and what is allowed.
    """

    def __init__(self, source: str, field: str, message: str):
        self.source = _one_line(source)
        self.field = _one_line(field)
        self.message = _one_line(message)
        # a problem of the file as a whole names no field ("x.yaml: file not found")
        where = self.source if self.field == DOCUMENT else f"{self.source}: {self.field}"
        super().__init__(f"{where}: {self.message}")

    def __reduce__(self):
        return (type(self), (self.source, self.field, self.message))

    def with_source(self, source: str) -> "SpecError":
        """The same error, attributed to another `source`.

        Parameters
        ----------
        source : str
            The new source (e.g. the file a mapping was read from).

        Returns
        -------
        SpecError
            Of the same type, with the same field and message.
        """
        return type(self)(source, self.field, self.message)


#: The largest noise seed: numpy's generators take any integer >= 0, but the rig's protocol and the
#: dataset attributes hold a signed 64-bit integer.
MAX_SEED = 2**63 - 1


def seed_problem(value: Any) -> str | None:
    """What is wrong with `value` as a noise seed (one rule everywhere: an integer 0 to 2**63 - 1), or None."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SEED:
        return f"{show(value)} is not an integer from 0 to 2**63 - 1; allowed: 0 to {MAX_SEED}"
    return None


#: Names that moved to `yamlio` and `base`, still importable from here (PEP 562).
_MOVED = {
    "yamlio": ("HugeInteger", "MAX_DEPTH", "MAX_NODES", "MAX_SPEC_BYTES", "check_file_size", "megabytes",
               "parse_yaml_mapping", "read_yaml_mapping", "read_yaml_text"),
    "base": ("Identifier", "MAX_IDENTIFIER", "SpecModel", "empty_value_error", "format_loc",
             "spec_error_from_validation", "units_required"),
}
_MODULE_OF = {name: module for module, names in _MOVED.items() for name in names}


def __getattr__(name):
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(_importlib.import_module(f"{__package__}.{module}"), name)


__all__ = ["DOCUMENT", "MAX_SEED", "SpecError", "UserError", "seed_problem", "show"]
