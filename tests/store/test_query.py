"""The catalogue's query language: parsed (never eval'ed), compiled to SQL, the same answers on SQLite and PostgreSQL.

The reference for every query is a predicate written by hand in plain Python over the rows as dicts (not derived
from the parser); random trees are checked against a small interpreter of the tree written here, independently of
the SQL compiler. PostgreSQL runs where a server can start (tests/pg_server.py), else those cases skip.
"""

import operator
import re
from datetime import datetime, timedelta, timezone

import pg_server
import pytest
import sqlalchemy as sa
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sqlalchemy.dialects import sqlite

from rdea_lab.specs import SpecError
from rdea_lab.store.query import (And, Compare, Field, Match, Member, Not, Or, QueryError, Value, format_where,
                                  parse_since, parse_where, where_clause)

META = sa.MetaData()
RUNS = sa.Table("runs", META, sa.Column("run_id", sa.String(64), primary_key=True), sa.Column("specimen", sa.Text),
                sa.Column("status", sa.Text), sa.Column("samples", sa.Integer), sa.Column("peak_force", sa.Float),
                sa.Column("created", sa.Text))
MD = sa.Table("run_metadata", META, sa.Column("run_id", sa.String(64), primary_key=True),
              sa.Column("key", sa.String(64), primary_key=True), sa.Column("value", sa.Text))

# Twelve runs: empty fields, mixed case, the wildcard and escape characters of GLOB and LIKE, non-ASCII text.
ROWS = [
    dict(run_id="r01", specimen="specimen-2", status="complete", samples=1000, peak_force=1.25,
         created="2026-03-01T09:00:00Z", md={"batch": "B7", "operator": "ana"}),
    dict(run_id="r02", specimen="specimen-2", status="complete", samples=86_400_000, peak_force=2.5,
         created="2026-02-28T23:59:59Z", md={"batch": "B7"}),
    dict(run_id="r03", specimen="specimen-2", status="aborted", samples=10, peak_force=None,
         created="2026-03-02T00:00:00Z", md={"batch": "B8", "note": "50% done"}),
    dict(run_id="r04", specimen="Specimen-2", status="complete", samples=0, peak_force=0.0,
         created="2026-04-10T12:00:00Z", md={"batch": "b7"}),
    dict(run_id="r05", specimen="specimen_3", status="complete", samples=500, peak_force=-3.0,
         created="2025-12-31T23:00:00Z", md={}),
    dict(run_id="r06", specimen="specimenX3", status="interrupted", samples=None, peak_force=1e-4,
         created=None, md={"operator": "Ana", "note": "a*b?[c]"}),
    dict(run_id="r07", specimen="vhb4910 strip", status="complete", samples=20000, peak_force=12.0,
         created="2026-03-15T08:30:00Z", md={"batch": "B7", "glob": "it's \\ here"}),
    dict(run_id="r08", specimen="élastomère", status="complete", samples=3, peak_force=0.5,
         created="2026-03-01T00:00:00Z", md={"batch": "Ä1", "operator": "zoë"}),
    dict(run_id="r09", specimen=None, status="unreadable (OSError)", samples=None, peak_force=None,
         created=None, md={}),
    dict(run_id="r10", specimen="a", status="complete", samples=-1, peak_force=7.5,
         created="2026-03-01", md={"batch": "B10", "note": "line1\nline2"}),
    dict(run_id="r11", specimen="B", status="complete", samples=2, peak_force=2.5,
         created="2026-05-01T00:00:00Z", md={"batch": "", "operator": "ana"}),
    dict(run_id="r12", specimen="b", status="complete", samples=4, peak_force=1.0,
         created="2026-03-01T09:00:00Z", md={"batch": "B7", "operator": "ANA", "note": "100%"}),
]


def md(row, key):
    return row["md"].get(key)


class Resolver:
    """The fields of the table above, as the catalogue's resolver gives them."""

    fields = ["run_id", "specimen", "status", "samples", "peak_force", "created"]

    def __call__(self, name):
        if name.startswith("md."):
            return (sa.select(MD.c.value).where(MD.c.run_id == RUNS.c.run_id, MD.c.key == name[3:])
                    .scalar_subquery())
        if name not in self.fields:
            raise KeyError(name)
        return RUNS.c[name]


def _filled(engine):
    META.create_all(engine)
    with engine.begin() as conn:
        conn.execute(RUNS.insert(), [{k: v for k, v in r.items() if k != "md"} for r in ROWS])
        conn.execute(MD.insert(), [{"run_id": r["run_id"], "key": k, "value": v} for r in ROWS
                                   for k, v in r["md"].items()])
    return engine


@pytest.fixture(scope="module")
def sqlite_engine():
    engine = _filled(sa.create_engine("sqlite://"))
    yield engine
    engine.dispose()


@pytest.fixture(scope="module")
def postgresql_engine(postgresql_server):
    engine = _filled(sa.create_engine(pg_server.sqlalchemy_url(postgresql_server.new_database())))
    yield engine
    engine.dispose()


@pytest.fixture(params=["sqlite", "postgresql"])
def engine(request):
    return request.getfixturevalue(f"{request.param}_engine")


def selected(engine, text):
    clause = where_clause(parse_where(text), Resolver())
    with engine.connect() as conn:
        return sorted(conn.execute(sa.select(RUNS.c.run_id).where(clause)).scalars())


def gt(a, b):
    return a is not None and a > b


# (query, the same question as a plain Python predicate on a row), written independently of each other
VALID = [
    ("specimen == 'specimen-2' and status == 'complete' and md.batch == 'B7'",
     lambda r: r["specimen"] == "specimen-2" and r["status"] == "complete" and md(r, "batch") == "B7"),
    ("status != 'complete'", lambda r: r["status"] != "complete"),
    ("specimen != 'specimen-2'", lambda r: r["specimen"] != "specimen-2"),  # empty specimen included
    ("samples > 100", lambda r: gt(r["samples"], 100)),
    ("samples >= 1000 and samples <= 20000", lambda r: r["samples"] is not None and 1000 <= r["samples"] <= 20000),
    ("samples < 3", lambda r: r["samples"] is not None and r["samples"] < 3),
    ("peak_force >= 2.5", lambda r: gt(r["peak_force"], 2.4999999)),
    ("peak_force < 1.5e-3", lambda r: r["peak_force"] is not None and r["peak_force"] < 0.0015),
    ("peak_force > -4 and peak_force < 0", lambda r: r["peak_force"] is not None and -4 < r["peak_force"] < 0),
    ("peak_force == 2.5", lambda r: r["peak_force"] == 2.5),
    ("samples == 86400000", lambda r: r["samples"] == 86_400_000),
    # a float against an integer column, a list starting with an integer against a float column (bound as written)
    ("samples > 2.5", lambda r: gt(r["samples"], 2.5)),
    ("samples < 3.5 and samples >= 2.0", lambda r: r["samples"] is not None and 2 <= r["samples"] < 3.5),
    ("peak_force in [0, 0.5]", lambda r: r["peak_force"] in (0.0, 0.5)),
    ("samples in [2, 3.0, 3.5]", lambda r: r["samples"] in (2, 3)),
    ("peak_force == null", lambda r: r["peak_force"] is None),
    ("samples != null and created == NULL", lambda r: r["samples"] is not None and r["created"] is None),
    ("md.batch == null", lambda r: md(r, "batch") is None),
    ("md.batch != null", lambda r: md(r, "batch") is not None),
    ("md.batch == ''", lambda r: md(r, "batch") == ""),
    ("md.batch != 'B7'", lambda r: md(r, "batch") != "B7"),
    ("not md.batch == 'B7'", lambda r: not md(r, "batch") == "B7"),
    ("not (md.batch == 'B7' or md.batch == 'B8')", lambda r: md(r, "batch") not in ("B7", "B8")),
    ("md.batch in ['B7', 'B8']", lambda r: md(r, "batch") in ("B7", "B8")),
    ("md.batch not in ['B7', 'B8']", lambda r: md(r, "batch") not in ("B7", "B8")),
    ("samples in [0, 2, 4, 5]", lambda r: r["samples"] in (0, 2, 4, 5)),
    ("status not in ['complete']", lambda r: r["status"] != "complete"),
    ("md.operator == 'ana'", lambda r: md(r, "operator") == "ana"),  # case-sensitive
    ("md.operator contains 'na'", lambda r: "na" in (md(r, "operator") or "")),
    ("md.operator not contains 'n'", lambda r: "n" not in (md(r, "operator") or "")),
    ("md.note contains '%'", lambda r: "%" in (md(r, "note") or "")),
    ("md.note contains '*b?['", lambda r: "*b?[" in (md(r, "note") or "")),
    ("md.note contains '\\n'", lambda r: "\n" in (md(r, "note") or "")),
    ("md.glob contains \"it's \\\\\"", lambda r: "it's \\" in (md(r, "glob") or "")),
    ("specimen like 'specimen_3'", lambda r: r["specimen"] in ("specimen_3", "specimenX3")),
    ("specimen like 's%'", lambda r: (r["specimen"] or "").startswith("s")),
    ("specimen like 'S%'", lambda r: (r["specimen"] or "").startswith("S")),  # same shape, another value
    ("specimen like '%-2'", lambda r: (r["specimen"] or "").endswith("-2")),
    ("specimen like '_'", lambda r: r["specimen"] is not None and len(r["specimen"]) == 1),
    ("specimen like '%'", lambda r: r["specimen"] is not None),
    ("specimen not like '%men%'", lambda r: "men" not in (r["specimen"] or "")),
    ("specimen like 'élast%'", lambda r: (r["specimen"] or "").startswith("élast")),
    ("specimen contains 'è'", lambda r: "è" in (r["specimen"] or "")),
    ("md.batch == 'Ä1'", lambda r: md(r, "batch") == "Ä1"),
    ("md.batch == '\\u00c41'", lambda r: md(r, "batch") == "Ä1"),
    # text in code-point order on both engines: 'B' < 'a' < 'b' (a lab server's en-US collation says otherwise)
    ("specimen < 'a'", lambda r: r["specimen"] is not None and r["specimen"] < "a"),
    ("specimen >= 'b' and specimen <= 'specimen-2'",
     lambda r: r["specimen"] is not None and "b" <= r["specimen"] <= "specimen-2"),
    ("md.batch > 'B7'", lambda r: md(r, "batch") is not None and md(r, "batch") > "B7"),
    # ISO times as text: --since's comparison
    ("created >= '2026-03-01'", lambda r: r["created"] is not None and r["created"] >= "2026-03-01"),
    ("created >= '2026-03-01' and created < '2026-03-02'",
     lambda r: r["created"] is not None and r["created"][:10] == "2026-03-01"),
    ("created < \"2026\"", lambda r: r["created"] is not None and r["created"][:4] < "2026"),
    # precedence: not > and > or; parentheses
    ("status == 'aborted' or specimen == 'a' and samples < 0",
     lambda r: r["status"] == "aborted" or (r["specimen"] == "a" and r["samples"] is not None and r["samples"] < 0)),
    ("(status == 'aborted' or specimen == 'a') and samples < 0",
     lambda r: (r["status"] == "aborted" or r["specimen"] == "a") and r["samples"] is not None and r["samples"] < 0),
    ("not status == 'complete' and not samples == null",
     lambda r: r["status"] != "complete" and r["samples"] is not None),
    ("not not (md.operator == 'ana')", lambda r: md(r, "operator") == "ana"),
    ("run_id == 'r01' or run_id == 'r12' or run_id == 'r99'", lambda r: r["run_id"] in ("r01", "r12")),
    ("  md.batch=='B7'and(samples>=4)  ", lambda r: md(r, "batch") == "B7" and gt(r["samples"], 3)),
]


@pytest.mark.parametrize("text,predicate", VALID, ids=[v[0][:60] for v in VALID])
def test_a_query_selects_the_rows_its_plain_python_predicate_selects(engine, text, predicate):
    expected = sorted(r["run_id"] for r in ROWS if predicate(r))
    assert selected(engine, text) == expected


def test_keywords_in_any_case_and_fields_as_written(sqlite_engine):
    assert selected(sqlite_engine, "NOT (samples > 5 OR peak_force > 5) AND status == 'complete'") == sorted(
        r["run_id"] for r in ROWS if r["status"] == "complete" and not (gt(r["samples"], 5) or gt(r["peak_force"], 5)))
    with pytest.raises(QueryError, match="position 41: unknown field 'Status'; allowed: run_id, specimen, "
                                         "status, samples, peak_force, created, md.<key>"):  # a field as written
        selected(sqlite_engine, "NOT (samples > 5 OR peak_force > 5) AND Status == 'complete'")


# (query, 1-based column of the mistake, what the message says there), the columns counted by hand
BAD = [
    ("", 1, "the end of the query"),
    ("   ", 4, "the end of the query"),
    ("specimen", 9, "the end of the query; allowed: an operator"),
    ("specimen ==", 12, "the end of the query; allowed: a value"),
    ("specimen = 'a'", 10, "unexpected character '='"),
    ("specimen === 'a'", 12, "unexpected character '='"),
    ("specimen == 'a", 13, "not closed"),
    ('specimen == "a\\"', 13, "not closed"),
    ("specimen == 'a\\q'", 15, "unknown escape"),
    ("specimen == '\\u12'", 14, "unknown escape"),
    ("specimen == '\\ud800'", 14, "is not a character"),
    ("(specimen == 'a'", 17, "allowed: ')'"),
    ("specimen == 'a')", 16, "a ')' without its '('"),
    ("specimen == 'a' and", 20, "the end of the query"),
    ("specimen == 'a' or or samples > 1", 20, "'or'"),
    ("specimen == 'a' samples > 1", 17, "'samples'; allowed: and, or"),
    ("and specimen == 'a'", 1, "'and'"),
    ("samples > 12abc", 13, "'a' after the number 12"),
    ("samples > 1.5.3", 14, "'.' after the number 1.5"),
    ("samples > 1e999", 11, "not a finite number"),
    ("samples > 99999999999999999999", 11, "out of range"),
    ("samples in 1, 2", 12, "'[' opening"),
    ("samples in [1, 2", 17, "',' or ']'"),
    ("samples in []", 13, "']'; allowed: a value"),
    ("samples in [1, null]", 16, "null in a list"),
    ("samples not == 1", 13, "'in', 'contains' or 'like' after 'not'"),
    ("specimen contains 5", 19, "a quoted string after 'contains'"),
    ("md. == 'a'", 4, "metadata key ''"),
    ("md.9a == 'a'", 4, "metadata key '9a'"),
    ("md." + "k" * 65 + " == 'a'", 4, "at most 64"),
    ("specimen == 'a' ; drop table runs", 17, "unexpected character ';'"),
    ("__import__('os') == 1", 11, "'('"),
    ("specimen == 'a' && samples > 1", 17, "unexpected character '&'"),
    ("specimen == true_ish", 13, "'true_ish'; allowed: a value"),
    # limits: 200 conditions (the 201st starts at 1 + 200 * len("samples == 1 or ")), 50 levels of nesting
    ("samples == 1 or " * 200 + "samples == 2", 1 + 200 * 16, "at most 200 conditions"),
    ("(" * 50 + "not samples == 1" + ")" * 50, 51, "at most 50 levels of parentheses and 'not' (this is level 51)"),
    ("not " * 51 + "samples == 1", 201, "at most 50 levels"),
    # compile-time: fields and types
    ("speciman == 'a'", 1, "unknown field 'speciman'; allowed: run_id, specimen,"),
    ("status == 'complete' and peak == 1", 26, "unknown field 'peak'"),
    ("specimen == 2", 13, "a number (2) for specimen, which holds text; allowed: a quoted string, e.g. '2'"),
    ("md.batch == 7", 13, "e.g. '7'"),
    ("samples == '7'", 12, "text ('7') for samples, which holds numbers; allowed: a number"),
    ("samples in [1, 'x']", 16, "text ('x') for samples"),
    ("peak_force > true", 14, "a boolean (true) for peak_force"),
    ("samples < null", 11, "null after <; allowed: == null or != null"),
    ("samples contains '1'", 1, "contains on samples, which holds numbers"),
    ("peak_force not like '1%'", 1, "like on peak_force"),
]


@pytest.mark.parametrize("text,position,says", BAD, ids=[b[0][:40] + str(len(b[0])) for b in BAD])
def test_a_bad_query_names_its_position_in_one_line(text, position, says):
    with pytest.raises(QueryError) as caught:
        where_clause(parse_where(text), Resolver())
    message = str(caught.value)
    assert caught.value.position == position
    assert message.startswith(f"--where: position {position}: ") and "\n" not in message
    assert says in message and "allowed: " in message
    assert isinstance(caught.value, SpecError)


def test_queries_at_the_limits_compile():
    many = " or ".join(f"samples == {i}" for i in range(200))  # 200 conditions, left-nested 199 deep
    deep = "(" * 25 + "not " * 25 + "samples < 5" + ")" * 25
    for text in (many, deep):
        str(sa.select(RUNS.c.run_id).where(where_clause(parse_where(text), Resolver())).compile(
            dialect=sqlite.dialect()))
    assert format_where(parse_where(deep)) == "not " * 25 + "samples < 5"


def test_an_unknown_field_without_a_list_of_fields_and_another_source():
    with pytest.raises(QueryError, match=r"^catalog\(where=\): position 1: unknown field 'x'; allowed: a catalogue "
                                         r"column or md.<key>$"):
        where_clause(parse_where("x == 1", "catalog(where=)"), lambda name: {}[name])


def test_a_time_column_takes_an_iso_string():
    table = sa.Table("t", sa.MetaData(), sa.Column("created", sa.DateTime), sa.Column("t_utc",
                                                                                      sa.DateTime(timezone=True)))
    engine = sa.create_engine("sqlite://")
    table.metadata.create_all(engine)
    with engine.begin() as conn:
        conn.execute(table.insert(), [{"created": datetime(2026, 3, 1, 12)}, {"created": datetime(2026, 2, 1)}])
        clause = where_clause(parse_where("created >= '2026-03-01T11:00:00Z'"), lambda name: table.c[name])
        assert conn.execute(sa.select(table.c.created).where(clause)).scalars().all() == [datetime(2026, 3, 1, 12)]
    with pytest.raises(QueryError, match="position 12: 'March' for created; allowed: an ISO 8601"):
        where_clause(parse_where("created >= 'March'"), lambda name: table.c[name])
    with pytest.raises(QueryError, match="position 12: a number"):
        where_clause(parse_where("created >= 2026"), lambda name: table.c[name])
    engine.dispose()


def test_the_sql_is_parameters_not_text():
    clause = where_clause(parse_where("specimen == 'x\\' or 1 == 1 --'"), Resolver())
    sql = str(clause.compile(dialect=sqlite.dialect()))
    assert "1 == 1" not in sql and "?" in sql


@pytest.mark.parametrize("text,expected", [
    ("2026-03-01", datetime(2026, 3, 1, tzinfo=timezone.utc)),
    (" 2026-03-01 ", datetime(2026, 3, 1, tzinfo=timezone.utc)),
    ("2026-03-01T14:30", datetime(2026, 3, 1, 14, 30, tzinfo=timezone.utc)),
    ("2026-03-01T14:30:05Z", datetime(2026, 3, 1, 14, 30, 5, tzinfo=timezone.utc)),
    ("2026-03-01 14:30:05.250", datetime(2026, 3, 1, 14, 30, 5, 250000, tzinfo=timezone.utc)),
    ("2026-03-01T01:30:00+02:00", datetime(2026, 2, 28, 23, 30, tzinfo=timezone.utc)),
    ("2026-03-01T01:30:00-05:30", datetime(2026, 3, 1, 7, 0, tzinfo=timezone.utc)),
])
def test_since_is_an_iso_date_or_time_in_utc(text, expected):
    when = parse_since(text)
    assert when == expected and when.utcoffset() == timedelta(0)


@pytest.mark.parametrize("text", ["", "March", "2026-13-01", "2026-02-30", "01.03.2026", "2026-03-01T25:00",
                                  "2026-W09", "20260301", "yesterday", None])
def test_since_refuses_anything_else(text):
    with pytest.raises(SpecError, match=r"^--since: .* is not an ISO 8601 date or date-time; allowed: e\.g\. "
                                        r"2026-03-01"):
        parse_since(text)


# ---- random input ----

PIECES = ["specimen", "samples", "md.batch", "md.", "==", "!=", "<", "<=", ">", ">=", "=", "in", "not", "and", "or",
          "contains", "like", "(", ")", "[", "]", ",", "'a'", "'", '"x"', "\\", "1", "-2.5e3", "1e999", "null",
          "true", "nope", "md.9", ";", " ", "'\\u00e9'", "'\\x'"]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.text(max_size=30), st.lists(st.sampled_from(PIECES), max_size=12).map(" ".join),
                 st.lists(st.sampled_from(PIECES), max_size=12).map("".join)))
def test_garbage_raises_nothing_but_a_query_error(text):
    try:
        where_clause(parse_where(text), Resolver())
    except QueryError as exc:
        assert str(exc).startswith("--where: position ") and "\n" not in str(exc)
        assert 1 <= exc.position <= len(text) + 1


ALPHABET = st.sampled_from(list("aBb-_%*?[]\\'\"é\n 7"))
TEXT = st.text(ALPHABET, max_size=6) | st.sampled_from(["B7", "specimen-2", "ana", "complete", "2026-03-01", ""])
FIELDS = {"specimen": "text", "status": "text", "created": "text", "md.batch": "text", "md.operator": "text",
          "md.note": "text", "samples": "int", "peak_force": "float"}


def _value(kind):
    if kind == "text":
        return TEXT.map(lambda s: Value("str", s))
    return st.one_of(st.integers(-30_000, 100_000_000).map(lambda i: Value("int", i)),
                     st.floats(-20, 20, allow_nan=False).map(lambda x: Value("float", x)))


@st.composite
def _predicate(draw):
    name = draw(st.sampled_from(sorted(FIELDS)))
    kind, fld = FIELDS[name], Field(name)
    shape = draw(st.sampled_from(["compare", "null", "member"] + (["match"] if kind == "text" else [])))
    if shape == "compare":
        return Compare(fld, draw(st.sampled_from(["==", "!=", "<", "<=", ">", ">="])), draw(_value(kind)))
    if shape == "null":
        return Compare(fld, draw(st.sampled_from(["==", "!="])), Value("null", None))
    if shape == "member":
        return Member(fld, tuple(draw(st.lists(_value(kind), min_size=1, max_size=3))), draw(st.booleans()))
    return Match(fld, draw(st.sampled_from(["contains", "like"])), draw(TEXT.map(lambda s: Value("str", s))),
                 draw(st.booleans()))


TREES = st.recursive(_predicate(), lambda inner: st.one_of(
    inner.map(Not), st.tuples(inner, inner).map(lambda p: And(*p)), st.tuples(inner, inner).map(lambda p: Or(*p))),
    max_leaves=6)


def _get(row, name):
    return md(row, name[3:]) if name.startswith("md.") else row[name]


def _like(pattern):
    return re.compile("".join(".*" if c == "%" else "." if c == "_" else re.escape(c) for c in pattern), re.DOTALL)


def interpret(node, row) -> bool:
    """The tree's meaning on one row, in plain Python (the module docstring's rules for empty fields)."""
    if isinstance(node, (And, Or)):
        left, right = interpret(node.left, row), interpret(node.right, row)
        return left and right if isinstance(node, And) else left or right
    if isinstance(node, Not):
        return not interpret(node.operand, row)
    x = _get(row, node.field.name)
    if isinstance(node, Compare):
        if node.value.kind == "null":
            return (x is None) == (node.op == "==")
        if x is None:
            return node.op == "!="
        ops = {"==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le, ">": operator.gt,
               ">=": operator.ge}
        return ops[node.op](x, node.value.value)
    if x is None:
        return node.negated
    if isinstance(node, Member):
        return (x in [v.value for v in node.values]) != node.negated
    hit = node.value.value in x if node.op == "contains" else bool(_like(node.value.value).fullmatch(x))
    return hit != node.negated


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(TREES)
def test_a_random_tree_round_trips_and_selects_what_the_interpreter_selects(sqlite_engine, tree):
    text = format_where(tree)
    assert parse_where(text) == tree
    assert format_where(parse_where(text)) == text
    assert selected(sqlite_engine, text) == sorted(r["run_id"] for r in ROWS if interpret(tree, r))


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(TREES)
def test_postgresql_answers_random_trees_as_sqlite_does(sqlite_engine, postgresql_engine, tree):
    text = format_where(tree)
    assert parse_where(text) == tree
    assert selected(postgresql_engine, text) == selected(sqlite_engine, text) == sorted(
        r["run_id"] for r in ROWS if interpret(tree, r))
