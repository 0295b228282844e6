"""The layers of DESIGN.md import one way: lower layers never import upper ones."""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "rdea_lab"
#: Bottom to top. DESIGN.md's order, plus the emulator (below the backends that
#: drive it) and the run engine (above backends and store: it couples the two).
LAYERS = ["specs", "physics", "twin", "protocols", "emulator", "backends", "store", "runs", "calibration",
          "design", "reports", "monitor", "api", "cli"]
# the package root, the version, the path and extras helpers
ANYWHERE = {"", "__version__", "_version", "paths", "extras", "signals"}


def imported_layers(path: Path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against this module's package
                parts = path.relative_to(PKG).parts[:-1]
                base = list(parts[: len(parts) - (node.level - 1)]) if node.level > 1 else list(parts)
                target = base + (node.module.split(".") if node.module else [])
            elif node.module and node.module.startswith("rdea_lab"):
                target = node.module.split(".")[1:]
            else:
                continue
            if target:
                yield target[0], node.lineno
            else:  # `from .. import api`: the names imported are the modules
                for alias in node.names:
                    yield alias.name, node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("rdea_lab."):
                    yield alias.name.split(".")[1], node.lineno


def test_lower_layers_never_import_upper_ones():
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        own = path.relative_to(PKG).parts[0]
        if own not in LAYERS:
            continue
        for layer, line in imported_layers(path):
            if layer in ANYWHERE or layer == own or layer.endswith(".py"):
                continue
            if layer in LAYERS and LAYERS.index(layer) > LAYERS.index(own):
                bad.append(f"{path.relative_to(PKG)}:{line} ({own}) imports {layer}")
    assert not bad, "\n".join(bad)


def test_every_package_is_placed_in_a_layer():
    packages = {p.name for p in PKG.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert packages <= set(LAYERS), packages - set(LAYERS)


#: What the CLI may import: the application layer, the specs, and the process-level helpers.
CLI_MAY_IMPORT = ("api", "specs", "cli", "", "__version__", "_version", "signals")


def test_the_cli_imports_only_the_application_layer_and_specs():
    """The CLI parses arguments and calls the public application layer (``rdea_lab.api``); it holds no
    physics, I/O policy or limit logic, so it imports nothing else of the package but the specs."""
    bad = []
    for path in sorted((PKG / "cli").rglob("*.py")):
        for layer, line in imported_layers(path):
            if layer not in CLI_MAY_IMPORT and not layer.endswith(".py"):
                bad.append(f"{path.relative_to(PKG)}:{line} imports {layer}")
    assert not bad, "\n".join(bad)


def test_cli_commands_are_module_level_and_thin():
    """Every click command is a module-level function (importable, reusable), none defined inside another."""
    nested = []
    for path in sorted((PKG / "cli").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef):
                for inner in ast.walk(node):
                    if inner is not node and isinstance(inner, ast.FunctionDef) and any(
                            "command" in ast.unparse(d) or "group" in ast.unparse(d) for d in inner.decorator_list):
                        nested.append(f"{path.relative_to(PKG)}:{inner.lineno} {inner.name} inside {node.name}")
    assert not nested, "\n".join(nested)


def _root_imports(path: Path):
    """Imports of the package root itself (``import rdea_lab``, ``from rdea_lab import name``, ``from ..
    import name`` for a name that is not a module): its public names are the api layer's."""
    modules = {p.stem for p in PKG.glob("*.py")} | {p.name for p in PKG.iterdir() if (p / "__init__.py").exists()}
    tree = ast.parse(path.read_text())
    depth = len(path.relative_to(PKG).parts) - 1  # packages between the root and this module
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(a.name == "rdea_lab" for a in node.names):
            yield node.lineno, "import rdea_lab"
        elif isinstance(node, ast.ImportFrom):
            root = (node.level == 0 and node.module == "rdea_lab") or (node.level == depth + 1 and not node.module)
            if root:
                names = [a.name for a in node.names if a.name not in modules]
                if names:
                    yield node.lineno, f"from the root: {', '.join(names)}"


def test_no_module_below_the_api_imports_the_package_root():
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        own = path.relative_to(PKG).parts[0]
        if own in LAYERS and LAYERS.index(own) < LAYERS.index("api"):
            bad += [f"{path.relative_to(PKG)}:{line} {what}" for line, what in _root_imports(path)]
    assert not bad, "\n".join(bad)


def test_the_public_names_are_few_and_each_documented():
    import importlib

    import rdea_lab

    assert len(rdea_lab.__all__) <= 30, len(rdea_lab.__all__)
    text = (PKG.parent / "docs" / "api.md").read_text()
    undocumented = []
    for name in rdea_lab.__all__:
        if name == "__version__":
            continue
        obj = getattr(rdea_lab, name)
        doc = (getattr(obj, "__doc__", None) or "").strip()
        if len(doc.split()) < 8 or f".{name}\n" not in text:
            undocumented.append(name)
        importlib.import_module(obj.__module__)
    assert not undocumented, undocumented


def test_the_rig_driver_imports_nothing_of_the_emulator():
    """The driver and the emulator share the wire protocol (``rdea_lab.specs.rigwire``), not each other's code:
    a lab's own rig server and the built-in emulator are driven alike."""
    bad = [f"{path.relative_to(PKG)}:{line} imports emulator"
           for path in sorted((PKG / "backends").rglob("*.py"))
           for layer, line in imported_layers(path) if layer == "emulator"]
    assert not bad, "\n".join(bad)
