"""The base of every spec model (`SpecModel`) and the translation of pydantic's errors into `SpecError`.

One idiom for every input kind: ``Kind.load(path)``, ``Kind.from_yaml(text, source=...)``,
``Kind.from_mapping(mapping, source=...)`` and ``spec.dump()`` (YAML text), implemented here once; a
kind says only how its YAML form maps to the model (`SpecModel._from_form`, `SpecModel._form`).
"""

from __future__ import annotations

import contextvars
import re
import typing
from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, ValidationError, model_validator

from .errors import DOCUMENT, SpecError, show
import yaml

from .yamlio import dump_yaml, parse_yaml_mapping, read_yaml_text

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

    Every kind is read and written the same way, by the methods defined here once:
    ``Kind.load(path)``, ``Kind.from_yaml(text, source)``, ``Kind.from_mapping(mapping, source)``
    and ``spec.dump()``. A kind says only what differs: `spec_kind` (the folder of packaged files
    `load` falls back to), `_from_form` (its YAML form to the model, when the file is not the model's
    fields), `_form` (the model to its YAML form) and `yaml_dumper`.

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

    # ------------------------------------------------------ the one idiom
    #: The folder of packaged reference files (`rdea_lab.paths.KINDS`) that `load` falls back to, if any
    spec_kind: typing.ClassVar[str | None] = None
    #: The YAML dumper `dump` writes with (a kind may write some mappings on one line)
    yaml_dumper: typing.ClassVar[type] = yaml.SafeDumper

    @classmethod
    def load(cls, path, **context):
        """Read and validate a YAML file of this kind.

        A path that does not exist may name a packaged reference file (`rdea_lab.paths.resolve`).

        Raises
        ------
        SpecError
            The file is missing, too large, not YAML, not a mapping, or a value is invalid; the message
            names the file and the field.
        """
        text, source = read_yaml_text(path, cls.spec_kind)
        return cls.from_yaml(text, source, **context)

    @classmethod
    def from_yaml(cls, text: str, source: str = "<string>", **context):
        """Validate YAML text of this kind (e.g. a dataset attr); `source` names it in messages."""
        return cls.from_mapping(parse_yaml_mapping(text, source), source, **context)._read_from(text)

    @classmethod
    def from_mapping(cls, mapping: Any, source: str = "<mapping>", **context):
        """Validate a mapping in this kind's YAML form (quantities as strings with units).

        Raises
        ------
        SpecError
            Attributed to `source`.
        """
        if not isinstance(mapping, Mapping):
            raise SpecError(source, DOCUMENT, f"expected a mapping of keys, got {show(mapping)}")
        return cls._from_form(dict(mapping), source, **context)

    def dump(self) -> str:
        """This spec as YAML text with units; `from_yaml` reads it back equal."""
        return dump_yaml(self._form(), type(self).yaml_dumper)

    @classmethod
    def _from_form(cls, mapping: dict, source: str):
        """The model from its YAML form (a kind whose file is not its fields overrides this)."""
        return cls.from_yaml_mapping(mapping, source)

    def _read_from(self, text: str):
        """This spec, read from the YAML `text` (a kind that keeps its text overrides this)."""
        return self

    def _form(self) -> dict:
        """The YAML form of this spec (quantities as strings with units), for `dump`."""
        raise NotImplementedError(f"{type(self).__name__} is not written as a file of its own")


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


__all__ = ["Identifier", "MAX_IDENTIFIER", "SpecModel", "empty_value_error", "format_loc", "spec_error_from_validation",
           "units_required"]
