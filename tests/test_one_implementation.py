"""One implementation of each thing, found by reading the package's source (ast), not by running it.

- eq. (44) of [1] is composed in one function, `physics.viscoelastic.overstress_step`;
- nothing outside `physics` reaches into its private names;
- no library module picks a matplotlib backend (only the CLI may);
- the twin's force composition, `carried_force`, is called in one place outside physics.
"""

import ast
import functools
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "rdea_lab"
VISCOELASTIC = Path("physics") / "viscoelastic.py"


def modules():
    return sorted(PKG.rglob("*.py"))


def rel(path: Path) -> Path:
    return path.relative_to(PKG)


@functools.lru_cache(maxsize=None)
def parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), filename=str(path))


@functools.lru_cache(maxsize=None)
def walk(tree) -> tuple:
    """Every node below ``tree`` (``ast.walk``), listed once per tree: the tests walk each module many times."""
    return tuple(ast.walk(tree))


def called_name(call: ast.Call) -> str | None:
    """``f`` of ``f(...)`` and ``m.f(...)``."""
    func = call.func
    if isinstance(func, ast.Name):
        return func.id
    if isinstance(func, ast.Attribute):
        return func.attr
    return None


@functools.lru_cache(maxsize=None)
def functions(tree):
    """Every function (and method) with its qualified name."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = f"{prefix}{child.name}"
                out.append((name, child))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(tree, "")
    return tuple(out)


@functools.lru_cache(maxsize=None)
def own_calls(fn) -> frozenset[str]:
    """Names called in the body of ``fn`` itself (not in functions nested in it)."""
    names = set()
    stack = list(fn.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(node, ast.Call):
            names.add(called_name(node))
        stack.extend(ast.iter_child_nodes(node))
    return frozenset(names)


def calls_anywhere(name: str):
    """``(module, line)`` of every call of ``name`` (plain or as an attribute) in the package."""
    for path in modules():
        for node in walk(parse(path)):
            if isinstance(node, ast.Call) and called_name(node) == name:
                yield rel(path), node.lineno


def resolve(node: ast.ImportFrom, module: Path) -> list[str]:
    """The absolute module of ``from ... import`` in ``module`` (a path below rdea_lab/), as parts."""
    if node.level:  # relative: against this module's package (as tests/test_layers.py does)
        parts = list(module.parts[:-1])
        base = parts[: len(parts) - (node.level - 1)] if node.level > 1 else parts
        return ["rdea_lab", *base, *(node.module.split(".") if node.module else [])]
    return node.module.split(".") if node.module else []


def imported_modules(path: Path):
    """``(absolute module parts, imported names, line)`` of every import in a module."""
    for node in walk(parse(path)):
        if isinstance(node, ast.ImportFrom):
            yield resolve(node, rel(path)), [alias.name for alias in node.names], node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name.split("."), [], node.lineno


def references(tree, name: str):
    """Lines where the function ``name`` is used at all: called, passed, imported, bare or as ``module.name``
    of an imported module. A data attribute of the same name (``spec.stretch_rate``, a pause's rate) or a
    field declared under it is not the function."""
    modules = {(a.asname or a.name).split(".")[0] for node in walk(tree)
               if isinstance(node, (ast.Import, ast.ImportFrom)) for a in node.names}
    # a name the module binds itself (a local variable, an argument: a pause's ``stretch_rate``) is not the
    # function, unless the module imports it
    bound = {n.id for n in walk(tree) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
    bound |= {a.arg for a in walk(tree) if isinstance(a, ast.arg)}
    local = name in bound and name not in modules
    for node in walk(tree):
        if (isinstance(node, ast.Name) and node.id == name and isinstance(node.ctx, ast.Load) and not local) or (
                isinstance(node, ast.Attribute) and node.attr == name and isinstance(node.value, ast.Name)
                and node.value.id in modules):
            yield node.lineno
        elif isinstance(node, (ast.Import, ast.ImportFrom)) and any(
                a.name.split(".")[-1] == name or a.asname == name for a in node.names):
            yield node.lineno


# ---------------------------------------------------------------- eq. (44)
def test_helpers_find_what_is_there():
    # an empty result below means something: the helpers do find the known uses
    tree = parse(PKG / VISCOELASTIC)
    assert list(references(tree, "branch_strains"))
    names = {name for name, _ in functions(parse(PKG / "twin" / "simulate.py"))}
    assert {"compose", "TwinStream.step"} <= names
    assert "compose" in own_calls(dict(functions(parse(PKG / "twin" / "simulate.py")))["TwinStream.step"])


def test_eq44_is_composed_in_overstress_step_only():
    composers = []
    for path in modules():
        for name, fn in functions(parse(path)):
            if {"branch_strains", "stretch_rate"} <= own_calls(fn):
                composers.append((rel(path), name))
    assert composers == [(VISCOELASTIC, "overstress_step")]


@pytest.mark.parametrize("name", ["branch_strains", "stretch_rate"])
def test_eq44_pieces_are_used_only_inside_viscoelastic(name):
    outside = [f"{rel(path)}:{line}" for path in modules() if rel(path) != VISCOELASTIC
               for line in references(parse(path), name)]
    assert outside == []
    inside = {fn for fn, node in functions(parse(PKG / VISCOELASTIC)) if name in own_calls(node)}
    assert inside == {"overstress_step"}


# ---------------------------------------------------- physics private names
def private_physics_imports(path: Path):
    for target, names, line in imported_modules(path):
        if target[:2] != ["rdea_lab", "physics"]:
            continue
        private = [p for p in target[2:] if p.startswith("_") and p != "__init__"]
        private += [n for n in names if n.startswith("_")]
        if private:
            yield f"{rel(path)}:{line} imports {'.'.join(target)}: {', '.join(private)}"


def test_no_private_physics_names_outside_physics():
    # inside physics the models share physics/models/_common.py: the scan sees that
    assert list(private_physics_imports(PKG / "physics" / "models" / "su.py"))
    bad = [found for path in modules() if rel(path).parts[0] != "physics" for found in private_physics_imports(path)]
    assert bad == []


@pytest.mark.parametrize("source, module, target", [
    ("from ..physics.models._common import kappa", "twin/x.py", "rdea_lab.physics.models._common"),
    ("from ...physics import _x", "store/sub/y.py", "rdea_lab.physics"),
    ("from .geometry import RollGeometry", "physics/models/su.py", "rdea_lab.physics.models.geometry"),
    ("from rdea_lab.physics._private import k", "runs/z.py", "rdea_lab.physics._private"),
])
def test_imports_are_resolved_to_absolute_modules(source, module, target):
    assert ".".join(resolve(ast.parse(source).body[0], Path(module))) == target


# ---------------------------------------------------------- matplotlib.use
def backend_choices(tree):
    """Lines of ``matplotlib.use(...)`` / ``mpl.use(...)`` (any alias of matplotlib) in a module."""
    aliases = {"matplotlib"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            aliases |= {a.asname or a.name for a in node.names if a.name == "matplotlib"}
    aliases.add("mpl")
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "use"
                and isinstance(node.func.value, ast.Name) and node.func.value.id in aliases):
            yield node.lineno
        elif isinstance(node, ast.ImportFrom) and node.module == "matplotlib" and any(
                a.name == "use" for a in node.names):
            yield node.lineno


def test_backend_check_sees_both_spellings():
    tree = ast.parse("import matplotlib\nimport matplotlib as m2\nmatplotlib.use('Agg')\nmpl.use('Agg')\n"
                     "m2.use('Agg')\nfrom matplotlib import use\nplt.use('x')\n")
    assert sorted(backend_choices(tree)) == [3, 4, 5, 6]


def test_only_the_cli_picks_a_matplotlib_backend():
    bad = [f"{rel(path)}:{line}" for path in modules() if rel(path).parts[0] != "cli"
           for line in backend_choices(parse(path))]
    assert bad == []


# ------------------------------------------------------------ carried_force
def test_carried_force_is_called_once_outside_physics():
    callers = []
    for path in modules():
        if rel(path).parts[0] == "physics":
            continue
        for name, fn in functions(parse(path)):
            if "carried_force" in own_calls(fn):
                callers.append((rel(path), name))
    assert callers == [(Path("twin") / "simulate.py", "compose")]


def test_one_list_of_model_names():
    """The models the physics implements are the names every layer accepts (specs.MODELS)."""
    from rdea_lab.physics.models import MODELS as IMPLEMENTED
    from rdea_lab.physics.selection import ORDER
    from rdea_lab.specs import MODEL_CHOICES, MODELS

    assert tuple(IMPLEMENTED) == MODELS == ORDER and MODEL_CHOICES == (*MODELS, "auto")
    # no other module spells out its own list of allowed names
    offenders = []
    for path in modules():
        for node in walk(parse(path)):
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Tuple) and any(
                    isinstance(t, ast.Name) and t.id in ("MODELS", "MODEL_CHOICES", "ORDER") for t in node.targets):
                offenders.append(rel(path))
    assert set(offenders) == {Path("specs") / "names.py"}


