"""The query tree (`rdea_lab.store.query`) compiled to SQLAlchemy Core: one expression, the same answers on SQLite
and PostgreSQL.

Two constructs render per dialect, because the engines' defaults differ: text order (PostgreSQL orders by the
database's collation, e.g. ``en_US``; here it is ``COLLATE "C"``, code-point order as in SQLite and Python) and
pattern matching (SQLite's ``LIKE`` ignores ASCII case, PostgreSQL's does not; here SQLite uses ``GLOB``, which
is case-sensitive, PostgreSQL ``LIKE``). Both carry their values as bound parameters, so compiled statements
are cached safely.
"""

from __future__ import annotations

from sqlalchemy import and_, literal, not_, or_
from sqlalchemy import types as T
from sqlalchemy.ext.compiler import compiles
from sqlalchemy.sql.functions import FunctionElement

from ..specs.errors import SpecError, show
from .query import And, Compare, Match, Member, Not, Or, QueryError, Value, parse_since

ANY, ONE = object(), object()


class _InCodePointOrder(FunctionElement):
    """A text expression compared in code-point order (``COLLATE "C"`` on PostgreSQL, the default elsewhere)."""
    inherit_cache = True
    name = "rdea_code_point_order"

    def __init__(self, expr):
        super().__init__(expr)
        self.type = expr.type


class _Matches(FunctionElement):
    """``expr`` matched in full, case-sensitively, by a pattern given both as a GLOB and as a LIKE pattern."""
    inherit_cache = True
    name = "rdea_matches"
    type = T.Boolean()


@compiles(_InCodePointOrder)
def _order_default(element, compiler, **kw):
    return compiler.process(list(element.clauses)[0], **kw)


@compiles(_InCodePointOrder, "postgresql")
def _order_postgresql(element, compiler, **kw):
    return f'({compiler.process(list(element.clauses)[0], **kw)}) COLLATE "C"'


@compiles(_Matches)
def _matches_like(element, compiler, **kw):
    expr, _glob, like = element.clauses
    return f"({compiler.process(expr, **kw)} LIKE {compiler.process(like, **kw)} ESCAPE '\\')"


@compiles(_Matches, "sqlite")
def _matches_glob(element, compiler, **kw):
    expr, glob, _like = element.clauses
    return f"({compiler.process(expr, **kw)} GLOB {compiler.process(glob, **kw)})"


def pattern_parts(op: str, text: str) -> list:
    """``contains``/``like`` text as a list of literal characters and the wildcards `ANY` (any text) and `ONE`."""
    if op == "contains":
        return [ANY, *text, ANY]
    return [ANY if c == "%" else ONE if c == "_" else c for c in text]


def glob_pattern(parts) -> str:
    """As SQLite's GLOB writes it (``*``, ``?``; a literal ``*``, ``?`` or ``[`` in brackets)."""
    return "".join("*" if p is ANY else "?" if p is ONE else f"[{p}]" if p in "*?[" else p for p in parts)


def like_pattern(parts) -> str:
    """As LIKE ... ESCAPE '\\' writes it (``%``, ``_``; a literal ``%``, ``_`` or ``\\`` escaped)."""
    return "".join("%" if p is ANY else "_" if p is ONE else f"\\{p}" if p in "%_\\" else p for p in parts)


def _kind(expr) -> str | None:
    """The kind of a column's values: "bool", "number", "text", "time", or None (unknown: any literal)."""
    t = getattr(expr, "type", None)
    if isinstance(t, T.Boolean):
        return "bool"
    if isinstance(t, (T.Integer, T.Numeric, T.Float)):  # (Float is no Numeric in SQLAlchemy 2.1)
        return "number"
    if isinstance(t, T.String):
        return "text"
    if isinstance(t, (T.DateTime, T.Date)):
        return "time"
    return None


_WHAT = {"str": "text", "int": "a number", "float": "a number", "bool": "a boolean", "null": "null"}
_ALLOWED = {"text": "a quoted string", "number": "a number", "bool": "true or false",
            "time": "an ISO 8601 date or date-time in quotes"}
_NUMBER_TYPES = {"int": T.BigInteger, "float": T.Float}
_HOLDS = {"text": "text", "number": "numbers", "bool": "booleans", "time": "times"}
_FITS = {"text": ("str",), "number": ("int", "float"), "bool": ("bool",), "time": ("str",)}


def _literal(source, name, kind, v: Value, aware=False):
    """The Python value to bind for `v` against a field of `kind`, after checking that they fit."""
    if kind is not None and v.kind not in _FITS[kind]:
        hint = f", e.g. '{v.value}'" if kind == "text" and v.kind in ("int", "float") else ""
        raise QueryError(source, f"position {v.pos + 1}", f"{_WHAT[v.kind]} ({_format(v)}) for {name}, which holds "
                         f"{_HOLDS[kind]}; allowed: {_ALLOWED[kind]}{hint}")
    if kind == "time":
        try:
            when = parse_since(v.value, source)
        except SpecError:
            raise QueryError(source, f"position {v.pos + 1}", f"{show(v.value)} for {name}; allowed: "
                             f"{_ALLOWED['time']}") from None
        return when if aware else when.replace(tzinfo=None)
    if v.kind in _NUMBER_TYPES:
        # typed as written, not as the column: SQLAlchemy would bind 2.5 against an integer column (or a list that
        # starts with an integer) as ::INTEGER on PostgreSQL, i.e. 3
        return literal(v.value, _NUMBER_TYPES[v.kind]())
    return v.value


def _aware(col) -> bool:
    return bool(getattr(getattr(col, "type", None), "timezone", False))


def _format(v: Value) -> str:
    from .query import _format_value

    return _format_value(v)


def _column(node, field):
    name = node.field.name
    try:
        return field(name)
    except LookupError:
        fields = list(getattr(field, "fields", ()) or ())
        allowed = ", ".join([*fields, "md.<key>"]) if fields else "a catalogue column or md.<key>"
        raise QueryError(node.source, f"position {node.field.pos + 1}",
                         f"unknown field {show(name)}; allowed: {allowed}") from None


def _compare(node: Compare, field):
    col, v = _column(node, field), node.value
    kind = _kind(col)
    if v.kind == "null":
        if node.op not in ("==", "!="):
            raise QueryError(node.source, f"position {v.pos + 1}", f"null after {node.op}; allowed: == null "
                             "or != null (is the field empty)")
        return col.is_(None) if node.op == "==" else col.is_not(None)
    value = _literal(node.source, node.field.name, kind, v, _aware(col))
    if node.op == "==":
        return and_(col.is_not(None), col == value)
    if node.op == "!=":
        return or_(col.is_(None), col != value)
    ordered = _InCodePointOrder(col) if kind == "text" or (kind is None and v.kind == "str") else col
    test = {"<": ordered.__lt__, "<=": ordered.__le__, ">": ordered.__gt__, ">=": ordered.__ge__}[node.op]
    return and_(col.is_not(None), test(value))


def _member(node: Member, field):
    col = _column(node, field)
    values = [_literal(node.source, node.field.name, _kind(col), v, _aware(col)) for v in node.values]
    if node.negated:
        return or_(col.is_(None), col.not_in(values))
    return and_(col.is_not(None), col.in_(values))


def _match(node: Match, field):
    col = _column(node, field)
    kind = _kind(col)
    if kind not in ("text", None):
        raise QueryError(node.source, f"position {node.field.pos + 1}", f"{node.op} on {node.field.name}, which "
                         f"holds {_HOLDS[kind]}; allowed: {node.op} on a text field")
    parts = pattern_parts(node.op, node.value.value)
    test = _Matches(col, literal(glob_pattern(parts), T.String()), literal(like_pattern(parts), T.String()))
    if node.negated:
        return or_(col.is_(None), not_(test))
    return and_(col.is_not(None), test)


def compile_node(node, field):
    """`rdea_lab.store.query.where_clause`'s work (documented there)."""
    if isinstance(node, Compare):
        return _compare(node, field)
    if isinstance(node, Member):
        return _member(node, field)
    if isinstance(node, Match):
        return _match(node, field)
    if isinstance(node, Not):
        return not_(compile_node(node.operand, field))
    if isinstance(node, And):
        return and_(compile_node(node.left, field), compile_node(node.right, field))
    if isinstance(node, Or):
        return or_(compile_node(node.left, field), compile_node(node.right, field))
    raise TypeError(f"not a query node: {node!r}")

