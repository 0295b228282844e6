"""The safe YAML reader of every spec file: duplicate keys refused, integers too long kept as text for
the field's own check, and limits on size (bytes, values with aliases counted, depth) that a real spec
never meets and a "billion laughs" bomb always does."""

from __future__ import annotations

import os

import yaml

from ..paths import resolve
from .errors import DOCUMENT, SpecError, _one_line, show

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


def read_yaml_text(path: str | os.PathLike, kind: str | None = None) -> tuple[str, str]:
    """Read the text of a spec file (at most `MAX_SPEC_BYTES`, UTF-8).

    With ``kind`` (``"specimens"``, ``"params"``, ...; see `rdea_lab.paths.KINDS`), a path
    that does not exist may name a packaged reference file (`rdea_lab.paths.resolve`).

    Returns
    -------
    text : str
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
            return fh.read(), source
    except FileNotFoundError:
        raise SpecError(source, DOCUMENT, "file not found") from None
    except IsADirectoryError:
        raise SpecError(source, DOCUMENT, "is a directory; expected a YAML file") from None
    except UnicodeDecodeError as exc:
        raise SpecError(source, DOCUMENT, f"not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise SpecError(source, DOCUMENT, f"cannot read file: {exc.strerror}") from None


def read_yaml_mapping(path: str | os.PathLike, kind: str | None = None) -> tuple[dict, str]:
    """Read a YAML file whose top level is a mapping (`read_yaml_text`, then `parse_yaml_mapping`).

    Returns
    -------
    mapping : dict
    source : str
        `path` as a string, for error messages.
    """
    text, source = read_yaml_text(path, kind)
    return parse_yaml_mapping(text, source), source

def dump_yaml(data: dict, dumper: type = yaml.SafeDumper) -> str:
    """`data` as the YAML text every spec is written in: keys in their order, unicode as is, no line folding."""
    return yaml.dump(data, Dumper=dumper, sort_keys=False, allow_unicode=True, width=1000)


__all__ = ["HugeInteger", "MAX_DEPTH", "MAX_NODES", "MAX_SPEC_BYTES", "check_file_size", "dump_yaml", "megabytes",
           "parse_yaml_mapping", "read_yaml_mapping", "read_yaml_text"]
