"""Errors at the edge: `SpecError`, and the translation of YAML and pydantic
problems into it.

Every mistake a user can make in a specimen card or a parameter file ends as
one `SpecError` whose ``str`` is a single line
``"{source}: {field}: {message}"`` (``"{source}: {message}"`` for the document as a whole), e.g.
``specimens/x.yaml: membrane.L3: '48 kg' is not a length; give it with a
length unit, e.g. '48 um'``.
"""

from __future__ import annotations

import contextvars
import os
import re
import typing
from typing import Annotated, Any

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, ValidationError, model_validator

from ..paths import resolve

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
        """The same error, attributed to another `source`."""
        return type(self)(source, self.field, self.message)


# --------------------------------------------------------------------- YAML
class _UniqueKeyLoader(yaml.SafeLoader):
    """Safe loader that refuses duplicate keys instead of keeping the last."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
                seen.add(key)
            except TypeError:  # unhashable key: SafeLoader reports it below
                continue
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {show(key)}", key_node.start_mark
                )
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        try:
            return super().construct_yaml_int(node)
        except ValueError:  # more digits than Python converts (sys.get_int_max_str_digits): no spec's number
            return HugeInteger(self.construct_scalar(node))


class HugeInteger(str):
    """A YAML integer too long for Python to convert: kept as its text, so the field's own check refuses it
    (naming the field and its allowed range) instead of the loader failing without a field."""

    def __repr__(self) -> str:
        return f"{str.__str__(self)[:12]}... (an integer of {len(self)} digits)"


_UniqueKeyLoader.add_constructor("tag:yaml.org,2002:int", _UniqueKeyLoader.construct_yaml_int)


#: The most values a spec may expand to (aliases counted as often as they are used) and the deepest
#: nesting: far above any real card, protocol or parameter file, far below a "billion laughs" bomb.
MAX_NODES = 100_000
MAX_DEPTH = 64
#: The largest spec file [bytes] read: a spec holds at most `MAX_NODES` values (a table of 100000 numbers
#: is about 2 MB), so 10 MB is far above any real file; checked before reading (a 100 MB file would take
#: minutes and gigabytes to parse, only to be refused).
MAX_SPEC_BYTES = 10_000_000


def megabytes(n: int) -> str:
    """A byte count in MB for messages (``"10 MB"``, ``"12.5 MB"``)."""
    return f"{n / 1e6:.3g} MB"


def check_file_size(source: str, limit: int, allowed: str = "") -> None:
    """Refuse a file larger than `limit` bytes before reading it (a missing one is left to the reader).

    Raises
    ------
    SpecError
        Naming `source`, its size and the limit; `allowed` adds why the limit is what it is.
    """
    try:
        size = os.stat(source).st_size
    except OSError:
        return
    if size > limit:
        why = f" ({allowed})" if allowed else ""
        raise SpecError(source, DOCUMENT, f"the file is {megabytes(size)}; allowed: at most {megabytes(limit)}{why}")


def _check_size(data, source: str) -> None:
    """Refuse a document that expands past `MAX_NODES` values or `MAX_DEPTH` levels, or that refers to
    itself, counting each alias as often as it is used, in time linear in the document as written."""
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    busy: set[int] = set()

    def walk(node) -> tuple[int, int]:
        if not isinstance(node, (dict, list)):
            return 1, 0
        key = id(node)
        if key in size:
            return size[key], depth[key]
        if key in busy:
            raise SpecError(source, DOCUMENT, "an alias refers to the node that holds it (a recursive document)")
        busy.add(key)
        children = list(node.values()) if isinstance(node, dict) else node
        n, d = 1 + len(node) if isinstance(node, dict) else 1, 0
        for child in children:
            cn, cd = walk(child)
            n, d = n + cn, max(d, cd + 1)
            if n > MAX_NODES:
                raise SpecError(source, DOCUMENT, f"expands to more than {MAX_NODES} values (aliases included); "
                                "a spec is far smaller")
            if d > MAX_DEPTH:
                raise SpecError(source, DOCUMENT, f"nested more than {MAX_DEPTH} levels deep")
        busy.discard(key)
        size[key], depth[key] = n, d
        return n, d

    try:
        walk(data)
    except RecursionError:
        raise SpecError(source, DOCUMENT, f"nested more than {MAX_DEPTH} levels deep") from None


def parse_yaml_mapping(text: str, source: str = "<string>") -> dict:
    """Parse YAML `text` whose top level must be a mapping.

    Raises
    ------
    SpecError
        If `text` is not valid YAML (with line and column), has a duplicate
        key, or its top level is not a mapping.
    """
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)
    except RecursionError:
        raise SpecError(source, DOCUMENT, f"nested too deeply (a spec needs at most {MAX_DEPTH} levels)") from None
    except yaml.YAMLError as exc:
        parts = [p for p in (getattr(exc, "context", None), getattr(exc, "problem", None)) if p]
        what = "; ".join(parts) or _one_line(exc)
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        raise SpecError(source, DOCUMENT, f"not valid YAML: {what}{where}") from None
    _check_size(data, source)
    if data is None:
        raise SpecError(source, DOCUMENT, "the document is empty; expected a mapping of keys")
    if not isinstance(data, dict):
        raise SpecError(
            source, DOCUMENT,
            f"top level is a {type(data).__name__} ({show(data)}); expected a mapping of keys",
        )
    return data


def read_yaml_mapping(path: str | os.PathLike, kind: str | None = None) -> tuple[dict, str]:
    """Read a YAML file whose top level is a mapping.

    With ``kind`` (``"specimens"``, ``"params"``, ...; see `rdea_lab.paths.KINDS`), a path
    that does not exist may name a packaged reference file (`rdea_lab.paths.resolve`).

    Returns
    -------
    mapping : dict
    source : str
        `path` as a string, for error messages.
    """
    if kind is not None:
        path = resolve(path, kind)
    source = os.fspath(path)
    if os.path.isfile(source):
        check_file_size(source, MAX_SPEC_BYTES, f"a spec holds at most {MAX_NODES} values")
    try:
        with open(source, encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise SpecError(source, DOCUMENT, "file not found") from None
    except IsADirectoryError:
        raise SpecError(source, DOCUMENT, "is a directory; expected a YAML file") from None
    except UnicodeDecodeError as exc:
        raise SpecError(source, DOCUMENT, f"not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise SpecError(source, DOCUMENT, f"cannot read file: {exc.strerror}") from None
    return parse_yaml_mapping(text, source), source


# ----------------------------------------------------------------- pydantic
def _unwrap_model(annotation: Any) -> type[BaseModel] | None:
    """The pydantic model inside ``X | None``, ``tuple[X, ...]``, ``Annotated``."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _unwrap_model(arg)
        if found is not None:
            return found
    return None


def _keys(model: type[BaseModel]) -> list[str]:
    return [f.alias or name for name, f in model.model_fields.items()]


def _model_at(root: type[BaseModel], loc: tuple) -> type[BaseModel] | None:
    """The model class that validates the mapping found at `loc`."""
    model: type[BaseModel] | None = root
    for part in loc:
        if model is None:
            return None
        if isinstance(part, int):
            continue  # element of a tuple of models: same model
        by_key = {f.alias or name: f for name, f in model.model_fields.items()}
        if part not in by_key:
            return None
        model = _unwrap_model(by_key[part].annotation)
    return model


def format_loc(loc: tuple | list, rename: dict[str, str] | None = None) -> str:
    """``("viscoelastic", "branches", 0, "eta")`` -> ``viscoelastic.branches[0].eta``."""
    out = ""
    for i, part in enumerate(loc):
        if isinstance(part, int):
            out += f"[{part}]"
            continue
        if i == 0 and rename:
            part = rename.get(part, part)
        out += f".{part}" if out else str(part)
    return out


def _message(err: dict, root: type[BaseModel]) -> str:
    kind, loc, value = err["type"], tuple(err["loc"]), err.get("input")
    if kind == "extra_forbidden":
        model = _model_at(root, loc[:-1])
        allowed = ", ".join(_keys(model)) if model else "?"
        return f"unknown key {show(loc[-1])}; allowed keys: {allowed}"
    if kind == "invalid_key":
        return f"key {show(value)} is not a text string"
    if kind == "missing":
        return f"missing required key {show(loc[-1]) if loc else ''}".rstrip()
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        model = _model_at(root, loc)
        keys = f" with keys {', '.join(_keys(model))}" if model else ""
        return f"expected a mapping{keys}, got {show(value)}"
    if kind in ("tuple_type", "list_type"):
        return f"expected a list, got {show(value)}"
    if kind == "string_type":
        return f"expected a text string, got {show(value)}"
    text = err["msg"].removeprefix("Value error, ")
    return f"{text}, got {show(value)}"


def spec_error_from_validation(
    exc: ValidationError,
    *,
    source: str,
    model: type[BaseModel],
    rename: dict[str, str] | None = None,
) -> SpecError:
    """Turn the first problem of a pydantic `ValidationError` into a `SpecError`.

    Unknown keys are reported before missing ones: a misspelt key produces
    both, and the unknown one explains the missing one.

    Parameters
    ----------
    exc : pydantic.ValidationError
    source : str
        File path or ``"<string>"``.
    model : type
        The root model that was validated (to list the allowed keys).
    rename : dict, optional
        Maps a top-level field name to its dotted path in the YAML form
        (``{"C10": "yeoh.C10"}``).
    """
    errors = exc.errors(include_url=False)
    errors.sort(key=lambda e: e["type"] != "extra_forbidden")
    err = errors[0]
    inner = (err.get("ctx") or {}).get("error")
    where = format_loc(err["loc"], rename)
    if isinstance(inner, SpecError):  # raised by our own validators
        relative = "" if inner.field == DOCUMENT else inner.field
        field = ".".join(p for p in (where, relative) if p)
        return SpecError(source, field or DOCUMENT, inner.message)
    return SpecError(source, where or DOCUMENT, _message(err, model))


_DECIMAL_TAIL = re.compile(r"\d+(?:[eE][+-]?\d+)?(?:\s+\S.*)?")


def empty_value_error(data: dict, key: Any) -> SpecError:
    """The error for ``key:`` with nothing after it in `data`. A key such as ``6 kV`` right after a key with a
    number is a decimal comma inside ``{...}`` (``{voltage: 2,6 kV}`` reads as ``voltage: 2`` and ``6 kV:``)."""
    keys = list(data)
    i = keys.index(key) if key in keys else -1
    before = keys[i - 1] if i > 0 else None
    if (isinstance(key, str) and _DECIMAL_TAIL.fullmatch(key) and before is not None
            and isinstance(data[before], (int, float)) and not isinstance(data[before], bool)):
        written = f"{data[before]},{key}"
        return SpecError("", str(before), f"'{written}' reads as '{data[before]}' and a key '{key}' (a comma "
                         f"separates entries in {{...}}); use a decimal point, e.g. '{data[before]}.{key}'")
    return SpecError("", str(key), "no value given")


#: True while validating a mapping read from a file: quantities then need units
_FROM_YAML: contextvars.ContextVar[bool] = contextvars.ContextVar("rdea_lab_specs_from_yaml", default=False)


def units_required() -> bool:
    """True while validating YAML input: a bare number for a dimensional
    quantity is then an error; from Python it is taken as SI."""
    return _FROM_YAML.get()


def _check_keys(data: Any, loc: tuple, source: str) -> None:
    """Refuse non-text keys anywhere (YAML allows ``1: x``; a spec does not)."""
    if isinstance(data, dict):
        keys = list(data)
        for i, (key, value) in enumerate(data.items()):
            if not isinstance(key, str):
                before = keys[i - 1] if i > 0 else None
                if (value is None and isinstance(key, (int, float)) and isinstance(before, str)
                        and isinstance(data[before], (int, float)) and not isinstance(data[before], bool)):
                    raise SpecError(source, format_loc(loc + (before,)), f"a number with a decimal comma reads as "
                                    f"two entries inside {{...}} ('{data[before]}' and a key {show(key)}); use a "
                                    f"decimal point, e.g. '{data[before]}.5', not '{data[before]},5'")
                raise SpecError(source, format_loc(loc + (str(key),)), f"key {show(key)} is not a text string")
            _check_keys(value, loc + (key,), source)
    elif isinstance(data, list):
        for i, value in enumerate(data):
            _check_keys(value, loc + (i,), source)


class SpecModel(BaseModel):
    """Base of every spec model: frozen, unknown keys refused.

    Constructing a model in Python raises `SpecError` (source
    ``"<python>"``), never a raw pydantic ``ValidationError``. Quantities
    given as numbers are taken as SI; strings with units are parsed.

    Notes
    -----
    pydantic calls an overridden ``__init__`` for nested models too, so a
    nested model's problem reaches the parent as a `SpecError` whose field is
    relative to the nested model; `spec_error_from_validation` prefixes it
    with the nested model's location. A `contextvars.ContextVar` (not
    pydantic's validation context, which an overridden ``__init__`` drops)
    says whether the input came from YAML.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    #: top-level field -> dotted path in the YAML form, for error messages
    _yaml_paths: typing.ClassVar[dict[str, str]] = {}

    def __init__(self, /, **data: Any):
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise spec_error_from_validation(
                exc, source="<python>", model=type(self), rename=self._yaml_paths
            ) from None

    @model_validator(mode="before")
    @classmethod
    def _no_empty_values(cls, data: Any) -> Any:
        # ``key:`` with nothing after it is a mistake in a file, not "use the
        # default"; from Python, None is the ordinary way to leave out an option
        if units_required() and isinstance(data, dict):
            for key, value in data.items():
                if value is None:
                    raise empty_value_error(data, key)
        return data

    @classmethod
    def from_yaml_mapping(cls, mapping: dict, source: str):
        """Validate a mapping read from YAML (quantities must carry units).

        Raises
        ------
        SpecError
            Attributed to `source`.
        """
        _check_keys(mapping, (), source)
        token = _FROM_YAML.set(True)
        try:
            return cls(**mapping)
        except SpecError as err:
            raise err.with_source(source) from None
        finally:
            _FROM_YAML.reset(token)


#: The largest noise seed: numpy's generators take any integer >= 0, but the rig's protocol and the
#: dataset attributes hold a signed 64-bit integer.
MAX_SEED = 2**63 - 1


def seed_problem(value: Any) -> str | None:
    """What is wrong with `value` as a noise seed (one rule everywhere: an integer 0 to 2**63 - 1), or None."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SEED:
        return f"{show(value)} is not an integer from 0 to 2**63 - 1; allowed: 0 to {MAX_SEED}"
    return None


_IDENTIFIER = re.compile(r"[A-Za-z0-9._-]+")
#: The longest name or id: ids name folders and files (``datasets/<id>/<protocol>.nc``, and the journal's
#: ``.part``), which a file system takes up to 255 bytes; 200 leaves room, and is far above any real name.
MAX_IDENTIFIER = 200


def _check_identifier(value: str) -> str:
    if len(value) > MAX_IDENTIFIER:
        raise SpecError("", "", f"{show(value)} is {len(value)} characters long; allowed: at most "
                        f"{MAX_IDENTIFIER} letters, digits, '-', '_' and '.' (ids name files and folders)")
    if value in (".", "..") or value.startswith("."):
        raise SpecError("", "", f"{show(value)} is not a valid name: it may not start with '.' (ids name files "
                        "and folders, e.g. datasets/<id>/); use letters, digits, '-', '_' and '.'")
    if not _IDENTIFIER.fullmatch(value):
        raise SpecError(
            "", "", f"{show(value)} is not a valid name; use letters, digits, '-', '_' and '.' only, "
            "at least one character (e.g. 'specimen-2')",
        )
    return value


#: A name or id: a non-empty string of letters, digits, ``-``, ``_``, ``.``.
Identifier = Annotated[str, AfterValidator(_check_identifier)]


__all__ = [
    "DOCUMENT", "Identifier", "MAX_IDENTIFIER", "MAX_SEED", "MAX_SPEC_BYTES", "check_file_size", "empty_value_error",
    "seed_problem",
    "SpecError", "SpecModel", "format_loc", "parse_yaml_mapping",
    "read_yaml_mapping", "show", "spec_error_from_validation", "units_required",
]
