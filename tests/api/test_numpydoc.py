"""numpydoc on every public name of `rdea_lab` (its ``__all__``) and on the ``ds.rdea`` accessor.

The docstrings are parsed by hand (a section is a title underlined with dashes, an entry a line
``name : type`` with its description indented below) and checked for what the API reference needs:

- a summary line;
- ``Parameters`` naming every parameter of the signature (of a class: its constructor's, in the class
  docstring), none that does not exist, each with a type (``*args`` and ``**kwargs`` need none);
- ``Returns`` (or ``Yields``) where the function's body returns a value;
- ``Raises`` naming each user error (`rdea_lab.specs.errors.UserError` and its kinds) that the body
  raises itself (a ``raise SomeError(...)`` statement; errors raised by the functions it calls are not
  traced: the docstrings name those by hand);
- a ``References`` section citing [1] (Prechtl et al. 2021) for the names that implement the paper
  (`PAPER`);
- a unit in brackets (``[V]``, ``[s]``, ``[-]``) in the description of each parameter or return whose name
  is one of the physical quantities in `PHYSICAL`.

A class's public methods (defined on the class itself) are checked as functions; its properties need a
summary line only (numpydoc documents them as attributes).
"""

from __future__ import annotations

import ast
import inspect
import textwrap

import pytest

import rdea_lab
from rdea_lab.specs.errors import SpecError, UserError

#: Names being rewritten by the other parts of issue 26 (backends as objects and typed results: runs/*,
#: calibration/*, reports/*, design/*); the lead empties this set when that work is merged.

#: Parameter (and return) names that are physical quantities: their descriptions carry a unit in brackets.
PHYSICAL = {
    "t", "time", "stretch", "voltage", "force", "capacitance", "current", "L3", "tolerance", "duration",
    "rate", "thickness", "sample_rate", "frequency", "interval", "seconds", "window_seconds", "timeout",
    "stall_timeout", "heartbeat", "auth_timeout", "idle_timeout", "block_timeout", "line_timeout", "send_timeout",
    "max_voltage", "max_stretch", "max_force", "max_field",
}

#: The public names that implement the paper's physics: their References cite it as [1].
PAPER = {"predict", "simulate", "TwinStep", "geometry", "plan_target"}
#: The paper's DOI, which each of their References gives.
DOI = "10.1088/1361-665X/ac34be"

NAMES = sorted(name for name in rdea_lab.__all__ if name != "__version__")


# ------------------------------------------------------------------ the parser
def parse(doc: str | None) -> tuple[str, dict[str, list[tuple[str, str | None, str]]]]:
    """``(summary, {section: [(head names, type or None, description), ...]})`` of a numpydoc docstring."""
    lines = inspect.cleandoc(doc or "").splitlines()
    titles = [i for i in range(len(lines) - 1)
              if lines[i].strip() and set(lines[i + 1].strip()) == {"-"} and len(lines[i + 1].strip()) >= 3]
    summary = " ".join(line.strip() for line in lines[:titles[0] if titles else len(lines)] if line.strip())
    sections = {}
    for k, i in enumerate(titles):
        end = titles[k + 1] if k + 1 < len(titles) else len(lines)
        entries = []
        for line in lines[i + 2:end]:
            if line.strip() and not line[0].isspace():
                head, _, kind = line.partition(" : ")
                entries.append([head.strip(), kind.strip() or None, ""])
            elif entries:
                entries[-1][2] += " " + line.strip()
        sections[lines[i].strip()] = [(head, kind, text.strip()) for head, kind, text in entries]
    return summary, sections


def names_of(head: str) -> list[str]:
    """``"max_evals, max_time"`` -> both; ``"**kwargs"`` -> ``kwargs``."""
    return [part.strip().lstrip("*") for part in head.split(",") if part.strip()]


# ------------------------------------------------------------------ what the body does
def _body(func) -> ast.AST | None:
    try:
        source = textwrap.dedent(inspect.getsource(func))
    except (OSError, TypeError):
        return None
    return ast.parse(source).body[0]


def _own_nodes(node: ast.AST):
    """The nodes of a function's body, not of the functions or classes defined inside it."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        yield child
        yield from _own_nodes(child)


def returns_a_value(func) -> bool:
    node = _body(func)
    return node is not None and any(
        isinstance(n, (ast.Yield, ast.YieldFrom))
        or (isinstance(n, ast.Return) and n.value is not None
            and not (isinstance(n.value, ast.Constant) and n.value.value is None))
        for n in _own_nodes(node))


def user_errors_raised(func) -> set[type]:
    """The `UserError` classes a ``raise X(...)`` (or ``raise X``) statement of the body names."""
    node, found = _body(func), set()
    namespace = getattr(inspect.unwrap(func), "__globals__", {})
    for n in _own_nodes(node) if node is not None else ():
        if not isinstance(n, ast.Raise) or n.exc is None:
            continue
        target = n.exc.func if isinstance(n.exc, ast.Call) else n.exc
        value = None
        if isinstance(target, ast.Name):
            value = namespace.get(target.id)
        elif isinstance(target, ast.Attribute) and isinstance(target.value, ast.Name):
            value = getattr(namespace.get(target.value.id), target.attr, None)
        if isinstance(value, type) and issubclass(value, UserError):
            found.add(value)
    return found


# ------------------------------------------------------------------ the checks
def problems_of_function(func, where: str, *, doc_of=None, signature_of=None, needs_returns=True) -> list[str]:
    doc = inspect.getdoc(doc_of if doc_of is not None else func)
    summary, sections = parse(doc)
    out = [] if summary else [f"{where}: no summary line"]
    signature = inspect.signature(signature_of if signature_of is not None else func)
    wanted = [p.name for p in signature.parameters.values() if p.name not in ("self", "cls")]
    entries = sections.get("Parameters", [])
    documented = [name for head, _, _ in entries for name in names_of(head)]
    out += [f"{where}: parameter {name!r} is not in Parameters" for name in wanted if name not in documented]
    out += [f"{where}: Parameters names {name!r}, which the signature does not have"
            for name in documented if name not in wanted]
    out += [f"{where}: parameter {head!r} has no type (write '{head} : type')"
            for head, kind, _ in entries if kind is None and not head.startswith("*")]  # numpydoc: **kwargs untyped
    out += [f"{where}: parameter {name!r} is a physical quantity: give its unit in brackets in its description"
            for head, _, text in entries for name in names_of(head) if name in PHYSICAL and "[" not in text]
    if needs_returns and returns_a_value(func) and not ({"Returns", "Yields"} & set(sections)):
        out.append(f"{where}: returns a value but has no Returns section")
    for head, kind, text in sections.get("Returns", []) + sections.get("Yields", []):
        name = head if kind is not None else ""
        if name in PHYSICAL and "[" not in text:
            out.append(f"{where}: return {name!r} is a physical quantity: give its unit in brackets")
    raised = {head for head, _, _ in sections.get("Raises", [])}
    for error in sorted(user_errors_raised(func), key=lambda e: e.__name__):
        if not {c.__name__ for c in error.__mro__} & {h.lstrip("~").rsplit(".", 1)[-1] for h in raised}:
            out.append(f"{where}: raises {error.__name__} but its Raises section does not name it")
    return out


def _public_members(cls):
    for name, value in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(value, property):
            yield name, value, "property"
        elif inspect.isfunction(value) or isinstance(value, (staticmethod, classmethod)):
            yield name, getattr(cls, name), "method"


def problems_of_members(cls, where: str) -> list[str]:
    out = []
    for name, member, kind in _public_members(cls):
        if kind == "property":
            if not parse(inspect.getdoc(member))[0]:
                out.append(f"{where}.{name}: no summary line")
        else:
            out += problems_of_function(member, f"{where}.{name}")
    return out


def problems_of(obj, where: str) -> list[str]:
    if not inspect.isclass(obj):
        return problems_of_function(obj, where)
    init = obj.__init__ if "__init__" in vars(obj) else None
    out = problems_of_function(init or obj, where, doc_of=obj, signature_of=obj, needs_returns=False)
    return out + problems_of_members(obj, where)


# ------------------------------------------------------------------ the tests
@pytest.mark.parametrize("name", NAMES)
def test_public_name_has_a_complete_numpydoc_docstring(name):
    problems = problems_of(getattr(rdea_lab, name), name)
    if name in PAPER:
        references = " ".join(" ".join(filter(None, e)) for e in parse(inspect.getdoc(getattr(rdea_lab, name)))[1]
                              .get("References", []))
        if not all(w in references for w in ("[1]", "Prechtl", "Smart Mater. Struct.", DOI)):
            problems.append(f"{name}: implements [1] but has no References section citing Prechtl et al. "
                            f"(Smart Mater. Struct., doi:{DOI})")
    assert not problems, "\n".join(problems)


def test_the_accessor_methods_have_complete_numpydoc_docstrings():
    from rdea_lab.api.accessor import RdeaAccessor

    summary = parse(inspect.getdoc(RdeaAccessor))[0]
    problems = ([] if summary else ["ds.rdea: no summary line"]) + problems_of_members(RdeaAccessor, "ds.rdea")
    assert not problems, "\n".join(problems)


# ------------------------------------------------------------------ the checker can fail
def _bad(stretch, voltage, *, rate=1.0):
    """Returns the force.

    Parameters
    ----------
    stretch : float
        Axial stretch.
    voltage
        Voltage [V].
    ghost : int
        Not a parameter.
    """
    if stretch < 1:
        raise SpecError("<python>", "stretch", "below 1")
    return stretch * voltage * rate


def test_the_checker_finds_each_kind_of_problem():
    problems = "\n".join(problems_of_function(_bad, "_bad"))
    for expected in ("'rate' is not in Parameters", "'ghost', which the signature does not have",
                     "'voltage' has no type", "'stretch' is a physical quantity", "no Returns section",
                     "raises SpecError"):
        assert expected in problems, expected
    assert "'voltage' is a physical quantity" not in problems  # it has its [V]


def test_the_parser_reads_sections_and_combined_entries():
    summary, sections = parse("""One line.

    More text.

    Parameters
    ----------
    a, b : float
        Two [s].

    Returns
    -------
    int
    """)
    assert summary == "One line. More text."
    assert sections["Parameters"] == [("a, b", "float", "Two [s].")]
    assert names_of("a, b") == ["a", "b"] and names_of("**kwargs") == ["kwargs"]
    assert sections["Returns"] == [("int", None, "")]


# ------------------------------------------------------------------ the API reference's summary table
def test_the_api_reference_table_gives_each_name_its_docstring_summary():
    """docs/api.md's table: one row per public name (and ``ds.rdea``), linked to its entry, with the
    summary of its docstring (its first paragraph) as written there."""
    import importlib
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "api.md").read_text(encoding="utf-8")
    entries = [line.split()[1] for line in text.splitlines() if line.startswith("::: ")]
    rows = re.findall(r"^\| \[`([\w.]+)`\]\(#([\w.]+)\) \| (.*) \|$", text, flags=re.MULTILINE)
    shown = {name: (anchor, summary) for name, anchor, summary in rows}
    assert len(shown) == len(rows) and set(shown) == set(NAMES) | {"ds.rdea"}
    for name, (anchor, summary) in shown.items():
        assert anchor in entries, f"{name}: its row links to {anchor}, which has no ::: entry"
        assert anchor.rsplit(".", 1)[1] == (name if name != "ds.rdea" else "RdeaAccessor"), name
        module, attr = anchor.rsplit(".", 1)
        doc = inspect.cleandoc(getattr(importlib.import_module(module), attr).__doc__ or "")
        first = " ".join(line.strip() for line in doc.split("\n\n")[0].splitlines())
        assert summary == first.replace("|", "\\|"), name
