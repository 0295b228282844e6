"""The shape of the library as a user meets it, from the source (issue 26): no import, only the AST.

Counts: the public names of ``rdea_lab`` (its ``__all__``, or the export table it forwards to); the public
functions (module-level, no leading underscore, in modules without one) and how many return a ``dict``
(annotated ``-> dict``/``dict[...]``, or a ``return {...}``/``return dict(...)``); the longest argument lists;
the call sites of ``geometry_from_card`` (a card becoming geometry).

    python3 benchmarks/api_shape.py            # a table
    python3 benchmarks/api_shape.py --json
"""

from __future__ import annotations

import argparse
import ast
import json
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "rdea_lab"


def _modules():
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG)
        yield rel, ast.parse(path.read_text(), str(path))


def _string_list(node) -> list[str] | None:
    if isinstance(node, (ast.List, ast.Tuple)) and all(isinstance(e, ast.Constant) for e in node.elts):
        return [e.value for e in node.elts]
    return None


def public_names() -> list[str]:
    """``rdea_lab.__all__``: literal names plus those of the export table it forwards to (``*_api.__all__``)."""
    names = []
    tree = ast.parse((PKG / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "__all__" for t in node.targets):
            value = node.value
            for element in getattr(value, "elts", []):
                if isinstance(element, ast.Constant):
                    names.append(element.value)
                elif isinstance(element, ast.Starred):  # *_api.__all__: the api package's table
                    names += _api_names()
    return sorted(set(names))


def _api_names() -> list[str]:
    tree = ast.parse((PKG / "api" / "__init__.py").read_text())
    for node in tree.body:
        target = node.targets[0] if isinstance(node, ast.Assign) else getattr(node, "target", None)
        if getattr(target, "id", "") == "_EXPORTS" and isinstance(node.value, ast.Dict):
            return [k.value for k in node.value.keys]
        if getattr(target, "id", "") == "__all__":
            names = _string_list(node.value)
            if names is not None:
                return names
    return []


def _own_returns(fn):
    """The return statements of ``fn`` itself, not of the functions and classes defined inside it."""
    stack = list(fn.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda)):
            continue
        if isinstance(node, ast.Return):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def _returns_dict(fn: ast.FunctionDef) -> bool:
    if fn.returns is not None:
        text = ast.unparse(fn.returns)
        if text == "dict" or text.startswith("dict["):
            return True
    for ret in _own_returns(fn):
        v = ret.value
        if isinstance(v, (ast.Dict, ast.DictComp)) or (isinstance(v, ast.Call) and getattr(v.func, "id", "") == "dict"):
            return True
    return False


def _arg_count(fn) -> int:
    a = fn.args
    bound = 1 if a.args and a.args[0].arg in ("self", "cls") else 0
    return len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) - bound


def scan() -> dict:
    functions, dict_returning, geometry_calls = [], [], []
    for rel, tree in _modules():
        private_module = any(part.startswith("_") and part != "__init__.py" for part in rel.parts)
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_") \
                    and not private_module:
                where = f"{rel}:{node.lineno} {node.name}"
                functions.append((where, _arg_count(node)))
                if _returns_dict(node):
                    dict_returning.append(where)
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and (getattr(node.func, "id", "") == "geometry_from_card"
                                               or getattr(node.func, "attr", "") == "geometry_from_card"):
                geometry_calls.append(f"{rel}:{node.lineno}")
    longest = sorted(functions, key=lambda f: -f[1])[:10]
    names = public_names()
    return {"public_names": len(names), "names": names, "public_functions": len(functions),
            "returning_dict": len(dict_returning), "returning_dict_where": dict_returning,
            "longest_argument_lists": longest, "geometry_from_card_calls": len(geometry_calls),
            "geometry_from_card_where": geometry_calls}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    result = scan()
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f"public names of rdea_lab: {result['public_names']}")
    print(f"public functions: {result['public_functions']}, returning a dict: {result['returning_dict']}")
    print("longest argument lists: " + ", ".join(f"{w.split(' ')[1]} {n}" for w, n in
                                                   result["longest_argument_lists"][:6]))
    print(f"geometry_from_card call sites: {result['geometry_from_card_calls']}")


if __name__ == "__main__":
    main()
