"""The catalogue's query language: ``--where`` text parsed into a small tree, compiled to SQL, never eval'ed.

Grammar (keywords in any case; ``not`` binds tighter than ``and``, ``and`` tighter than ``or``)::

    query      := and_expr ("or" and_expr)*
    and_expr   := not_expr ("and" not_expr)*
    not_expr   := "not" not_expr | "(" query ")" | predicate
    predicate  := field ("==" | "!=" | "<" | "<=" | ">" | ">=") value
                | field ["not"] "in" "[" value ("," value)* "]"
                | field ["not"] ("contains" | "like") string
    field      := identifier | "md." key
    value      := string | integer | float | "true" | "false" | "null"

A field is a catalogue column (letters, digits, ``_``) or ``md.<key>``, a run's metadata value (a key is a
letter, then letters, digits, ``_``, ``.``, ``-``). Strings are single- or double-quoted with the escapes
``\\\\ \\' \\" \\n \\t \\r \\uXXXX``; numbers are integers or floats (``2.6``, ``1e3``, ``-4``). Dates and times
are quoted ISO 8601 text (``created >= '2026-03-01'``): against a date-time column they are read as a time (UTC
unless an offset is given, `parse_since`), against a text column compared as text (ISO 8601 UTC text orders as
time). ``== null`` / ``!= null`` ask whether a field is empty (a run without that metadata key, a peak not
measured).

Every predicate is true or false, never unknown: a comparison, ``in``, ``contains`` or ``like`` on an empty
field is false and its negation (``!=``, ``not in``, ``not contains``, ``not like``, ``not (...)``) true, so
``not (md.batch == 'B7')`` includes the runs without a batch. ``contains`` is a case-sensitive substring test,
``like`` a case-sensitive match of the whole text where ``%`` is any text and ``_`` any one character; text
orders by code point. `where_clause` gives one SQLAlchemy expression for both engines (text order and pattern
matching render per dialect, `rdea_lab.store._querysql`), so SQLite and PostgreSQL give the same answers.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field as _dc_field
from datetime import datetime, timezone
from typing import Callable, Union

from ..specs.errors import SpecError, show

__all__ = ["And", "Compare", "Field", "Match", "Member", "Not", "Or", "QueryError", "Value", "format_where",
           "parse_since", "parse_where", "where_clause"]

#: A metadata key, as `rdea_lab.runs.engine.check_metadata` allows it.
MD_KEY = re.compile(r"[A-Za-z][A-Za-z0-9_.\-]{0,63}\Z")
COMPARISONS = ("==", "!=", "<=", ">=", "<", ">")
KEYWORDS = ("and", "or", "not", "in", "contains", "like", "true", "false", "null")
#: The most conditions (predicates) in one query, and the deepest nesting of parentheses and ``not``: the tree,
#: its SQL and their compilers recurse, and a query of a lab's catalogue needs far fewer.
MAX_CONDITIONS, MAX_DEPTH = 200, 50
#: The literals an integer may take (a signed 64-bit integer, as both databases store one).
MAX_INT = 2**63 - 1
_ESCAPES = {"\\": "\\", "'": "'", '"': '"', "n": "\n", "t": "\t", "r": "\r"}
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_MD_TAIL = re.compile(r"[A-Za-z0-9_.\-]*")
_ALLOWED_START = "a field (a catalogue column or md.<key>), 'not' or '('"


class QueryError(SpecError):
    """A query that cannot be parsed or compiled: ``"<source>: position N: <what was found>; allowed: ..."``.

    ``position`` is the 1-based column of the offending text (None if the field is not a position).
    """

    def __init__(self, source: str, field: str, message: str):
        super().__init__(source, field, message)
        found = re.fullmatch(r"position (\d+)", self.field)
        self.position = int(found[1]) if found else None


def _error(source, pos, message) -> QueryError:
    return QueryError(source, f"position {pos + 1}", message)


# ---- the tree: positions (0-based offsets into the text) and the source do not take part in equality ----

@dataclass(frozen=True)
class Field:
    """A field: a catalogue column or ``md.<key>``."""
    name: str
    pos: int = _dc_field(default=0, compare=False, repr=False)


@dataclass(frozen=True)
class Value:
    """A literal: ``kind`` is ``"str"``, ``"int"``, ``"float"``, ``"bool"`` or ``"null"``."""
    kind: str
    value: Union[str, int, float, bool, None]
    pos: int = _dc_field(default=0, compare=False, repr=False)


@dataclass(frozen=True)
class Compare:
    field: Field
    op: str
    value: Value
    source: str = _dc_field(default="--where", compare=False, repr=False)


@dataclass(frozen=True)
class Member:
    """``field in [...]`` (``negated``: ``not in``)."""
    field: Field
    values: tuple
    negated: bool = False
    source: str = _dc_field(default="--where", compare=False, repr=False)


@dataclass(frozen=True)
class Match:
    """``field contains 'text'`` or ``field like 'pattern'`` (``negated``: ``not contains`` / ``not like``)."""
    field: Field
    op: str
    value: Value
    negated: bool = False
    source: str = _dc_field(default="--where", compare=False, repr=False)


@dataclass(frozen=True)
class Not:
    operand: "Node"


@dataclass(frozen=True)
class And:
    left: "Node"
    right: "Node"


@dataclass(frozen=True)
class Or:
    left: "Node"
    right: "Node"


Node = Union[Compare, Member, Match, Not, And, Or]


# ---- tokens ----

@dataclass(frozen=True)
class _Token:
    kind: str  # "name", "field", "op", "punct", "str", "int", "float", "keyword", "end"
    text: str
    pos: int
    value: object = None


def _string(text, pos, source):
    quote, out, i = text[pos], [], pos + 1
    while i < len(text):
        c = text[i]
        if c == quote:
            return "".join(out), i + 1
        if c == "\\":
            e = text[i + 1:i + 2]
            if e in _ESCAPES:
                out.append(_ESCAPES[e])
                i += 2
                continue
            if e == "u" and re.fullmatch(r"[0-9A-Fa-f]{4}", text[i + 2:i + 6]):
                code = int(text[i + 2:i + 6], 16)
                if 0xD800 <= code <= 0xDFFF or code == 0:
                    raise _error(source, i, f"escape {text[i:i + 6]!r} is not a character; allowed: \\u0001 to "
                                 "\\uFFFF outside the surrogates D800-DFFF")
                out.append(chr(code))
                i += 6
                continue
            raise _error(source, i, f"unknown escape {text[i:i + 2]!r}; allowed: \\\\ \\' \\\" \\n \\t \\r "
                         "\\uXXXX")
        if c == "\x00" or 0xD800 <= ord(c) <= 0xDFFF:
            raise _error(source, i, "a NUL or a lone surrogate in a string; allowed: text characters")
        out.append(c)
        i += 1
    raise _error(source, pos, f"a string opened with {quote} and not closed; allowed: {quote}text{quote}")


def _number(match, source):
    text, pos = match[0], match.start()
    if re.fullmatch(r"[+-]?\d+", text):
        value = int(text)
        if abs(value) > MAX_INT:
            raise _error(source, pos, f"the integer {show(text)} is out of range; allowed: -{MAX_INT} to {MAX_INT}")
        return _Token("int", text, pos, value)
    value = float(text)
    if not math.isfinite(value):
        raise _error(source, pos, f"{show(text)} is not a finite number; allowed: a float up to 1.8e308")
    return _Token("float", text, pos, value)


def _tokens(text: str, source: str) -> list[_Token]:
    out, i = [], 0
    while i < len(text):
        c = text[i]
        if c.isspace():
            i += 1
        elif text.startswith(("==", "!=", "<=", ">="), i):
            out.append(_Token("op", text[i:i + 2], i))
            i += 2
        elif c in "<>":
            out.append(_Token("op", c, i))
            i += 1
        elif c in "()[],":
            out.append(_Token("punct", c, i))
            i += 1
        elif c in "'\"":
            value, end = _string(text, i, source)
            out.append(_Token("str", text[i:end], i, value))
            i = end
        elif m := _NUMBER.match(text, i):
            if (after := text[m.end():m.end() + 1]) and (after.isalnum() or after in "_."):
                raise _error(source, m.end(), f"{show(after)} after the number {m[0]}; allowed: a space, "
                             "an operator or a bracket")
            out.append(_number(m, source))
            i = m.end()
        elif m := _NAME.match(text, i):
            out.append(_name(text, m, source))
            i = i + len(out[-1].text)
        else:
            raise _error(source, i, f"unexpected character {show(c)}; allowed: a field, a value, an operator "
                         "(== != < <= > >= in contains like and or not), '(' ')' '[' ']' ','")
    out.append(_Token("end", "", len(text)))
    return out


def _name(text, m, source) -> _Token:
    name, pos = m[0], m.start()
    if name == "md" and text[m.end():m.end() + 1] == ".":
        key = _MD_TAIL.match(text, m.end() + 1)[0]
        if not MD_KEY.match(key):
            raise _error(source, m.end() + 1, f"metadata key {show(key)}; allowed: a letter, then letters, digits, "
                         "'_', '.' or '-' (at most 64)")
        return _Token("field", f"md.{key}", pos)
    if name.lower() in KEYWORDS:
        return _Token("keyword", name, pos, name.lower())
    return _Token("field", name, pos)


# ---- the parser ----

class _Parser:
    def __init__(self, text, source):
        self.source = source
        self.tokens = _tokens(text, source)
        self.i = 0
        self.depth = self.conditions = 0

    @property
    def tok(self) -> _Token:
        return self.tokens[self.i]

    def keyword(self, *words) -> bool:
        return self.tok.kind == "keyword" and self.tok.value in words

    def take(self) -> _Token:
        tok = self.tok
        self.i += 1
        return tok

    def fail(self, allowed, tok=None):
        tok = tok or self.tok
        found = "the end of the query" if tok.kind == "end" else show(tok.text)
        raise _error(self.source, tok.pos, f"{found}; allowed: {allowed}")

    def query(self):
        node = self.and_expr()
        while self.keyword("or"):
            self.take()
            node = Or(node, self.and_expr())
        return node

    def and_expr(self):
        node = self.not_expr()
        while self.keyword("and"):
            self.take()
            node = And(node, self.not_expr())
        return node

    def not_expr(self):
        if self.keyword("not") or (self.tok.text == "(" and self.tok.kind == "punct"):
            self.depth += 1
            if self.depth > MAX_DEPTH:
                self.fail(f"at most {MAX_DEPTH} levels of parentheses and 'not' (this is level {self.depth})")
            node = self.nested()
            self.depth -= 1
            return node
        if self.tok.kind != "field":
            self.fail(_ALLOWED_START)
        self.conditions += 1
        if self.conditions > MAX_CONDITIONS:
            self.fail(f"at most {MAX_CONDITIONS} conditions in a query (this is condition {self.conditions})")
        return self.predicate(Field(self.tok.text, self.take().pos))

    def nested(self):
        if self.take().text == "(":
            node = self.query()
            if self.tok.text != ")":
                self.fail("')' or and/or")
            self.take()
            return node
        return Not(self.not_expr())

    def predicate(self, fld):
        src = self.source
        if self.tok.kind == "op":
            op = self.take().text
            return Compare(fld, op, self.value(), src)
        negated = self.keyword("not")
        if negated:
            self.take()
        if self.keyword("in"):
            self.take()
            return Member(fld, self.values(), negated, src)
        if self.keyword("contains", "like"):
            op = self.take().value
            if self.tok.kind != "str":
                self.fail(f"a quoted string after '{op}'")
            tok = self.take()
            return Match(fld, op, Value("str", tok.value, tok.pos), negated, src)
        self.fail("'in', 'contains' or 'like' after 'not'" if negated else
                  "an operator after the field: == != < <= > >= in, not in, contains, like")

    def values(self):
        if self.tok.text != "[" or self.tok.kind != "punct":
            self.fail("'[' opening a list of values")
        self.take()
        out = [self.value()]
        while self.tok.text == "," and self.tok.kind == "punct":
            self.take()
            out.append(self.value())
        if self.tok.text != "]":
            self.fail("',' or ']'")
        self.take()
        for v in out:
            if v.kind == "null":
                raise _error(self.source, v.pos, "null in a list; allowed: text or numbers (test emptiness "
                             "with == null)")
        return tuple(out)

    def value(self):
        tok = self.tok
        if tok.kind in ("str", "int", "float"):
            self.take()
            return Value(tok.kind, tok.value, tok.pos)
        if self.keyword("true", "false", "null"):
            self.take()
            return Value("null", None, tok.pos) if tok.value == "null" else Value("bool", tok.value == "true",
                                                                                    tok.pos)
        self.fail("a value: 'text', a number, true, false or null")


def parse_where(text: str, source: str = "--where") -> Node:
    """Parse a query (syntax only: fields are checked when it is compiled, `where_clause`).

    Parameters
    ----------
    text : str
        The query, e.g. ``"specimen == 'specimen-2' and status == 'complete' and md.batch == 'B7'"``
        (the grammar is in this module's docstring).
    source : str
        Where the text came from, for the error message (the option, ``--where``).

    Returns
    -------
    Node
        The query's tree (`Compare`, `Member`, `Match`, `Not`, `And`, `Or`); ``format_where`` writes it back.

    Raises
    ------
    QueryError
        ``"<source>: position N: <what was found>; allowed: ..."`` with N the 1-based column.
    """
    if not isinstance(text, str):
        raise QueryError(source, "<document>", f"{show(text)} is not text; allowed: a query string")
    parser = _Parser(text, source)
    if parser.tok.kind == "end":
        parser.fail(_ALLOWED_START)
    node = parser.query()
    if parser.tok.kind != "end":
        parser.fail("and, or, or the end of the query" + (" (a ')' without its '(')" if parser.tok.text == ")"
                                                          else ""))
    return node


# ---- writing a tree back ----

def _escape(c: str) -> str:
    if c in "\\'\n\t\r":
        return "\\" + {"\n": "n", "\t": "t", "\r": "r"}.get(c, c)
    return c if c.isprintable() or ord(c) > 0xFFFF else f"\\u{ord(c):04x}"


def _format_value(v: Value) -> str:
    if v.kind == "str":
        return "'" + "".join(map(_escape, v.value)) + "'"
    if v.kind == "bool":
        return "true" if v.value else "false"
    if v.kind == "null":
        return "null"
    return repr(v.value)


def format_where(node: Node) -> str:
    """A tree as query text (parenthesized where needed, so ``parse_where(format_where(n)) == n``).

    Parameters
    ----------
    node : Node
        As `parse_where` returns it.

    Returns
    -------
    str
        The query.
    """
    if isinstance(node, Compare):
        return f"{node.field.name} {node.op} {_format_value(node.value)}"
    if isinstance(node, Member):
        values = ", ".join(_format_value(v) for v in node.values)
        return f"{node.field.name} {'not in' if node.negated else 'in'} [{values}]"
    if isinstance(node, Match):
        return f"{node.field.name} {'not ' if node.negated else ''}{node.op} {_format_value(node.value)}"
    if isinstance(node, Not):
        inner = format_where(node.operand)
        return f"not ({inner})" if isinstance(node.operand, (And, Or)) else f"not {inner}"
    if isinstance(node, And):
        left, right = format_where(node.left), format_where(node.right)
        left = f"({left})" if isinstance(node.left, Or) else left
        right = f"({right})" if isinstance(node.right, (And, Or)) else right
        return f"{left} and {right}"
    if isinstance(node, Or):
        right = format_where(node.right)
        return f"{format_where(node.left)} or " + (f"({right})" if isinstance(node.right, Or) else right)
    raise TypeError(f"not a query node: {node!r}")


# ---- compiling a tree to SQL ----

def where_clause(node: Node, field: Callable[[str], object]):
    """A parsed query as a SQLAlchemy Core boolean expression (the same SQL on SQLite and PostgreSQL).

    Parameters
    ----------
    node : Node
        From `parse_where`.
    field : callable
        ``field(name)`` gives the SQLAlchemy column expression of a field (a column of the runs table, or for
        ``md.<key>`` a scalar subquery of the run's metadata value) and raises `LookupError` (e.g. KeyError)
        for a field the catalogue does not have; its attribute ``fields`` (if any) lists the allowed names
        for the message. The column's type is checked against the literal: text against a quoted string,
        numbers against a number, booleans against true/false, dates and times against an ISO string.

    Returns
    -------
    sqlalchemy.sql.ColumnElement
        A boolean expression, never NULL (the module docstring: empty fields). Numbers are bound typed as
        written (``2.5`` as a float against an integer column).

    Raises
    ------
    QueryError
        An unknown field (naming the allowed ones), a value of the wrong type for its field, null with an
        operator other than == and !=; with the 1-based position of the field or the value.
    """
    from . import _querysql

    return _querysql.compile_node(node, field)


# ---- --since ----

def parse_since(text: str, source: str = "--since") -> datetime:
    """An ISO 8601 date or date-time as an aware UTC datetime (a time without an offset is UTC).

    Parameters
    ----------
    text : str
        ``2026-03-01`` (midnight UTC), ``2026-03-01T14:30``, ``2026-03-01T14:30:00Z`` or with an offset
        (``+02:00``, converted to UTC).
    source : str
        Where the text came from, for the error message.

    Returns
    -------
    datetime.datetime
        With ``tzinfo=timezone.utc``.

    Raises
    ------
    SpecError
        Text that is not an ISO 8601 date or date-time.
    """
    value = None
    if isinstance(text, str) and re.fullmatch(r"\d{4}-\d{2}-\d{2}([T ][0-9:.,]+(Z|[+-][0-9:]+)?)?", text.strip()):
        try:
            value = datetime.fromisoformat(text.strip())
        except ValueError:
            value = None
    if value is None:
        raise SpecError(source, "<document>", f"{show(text)} is not an ISO 8601 date or date-time; allowed: e.g. "
                        "2026-03-01 or 2026-03-01T14:30:00Z (UTC unless an offset is given)")
    return value.replace(tzinfo=timezone.utc) if value.tzinfo is None else value.astimezone(timezone.utc)
