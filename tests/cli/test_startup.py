"""``rdea-lab --help`` stays light: the group loads a command's module only when asked for it.

What is checked is the import graph, in a fresh interpreter (what a user's ``rdea-lab``
pays for), never a wall time; `benchmarks/bench_cli_startup.py` measures the time.
"""

import importlib
import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import click
import pytest

import rdea_lab.cli
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import COMMANDS, cli

ROOT = Path(__file__).resolve().parents[2]
#: Slow to import (pint builds its registry, the others are large) and needed by no --help.
HEAVY = ("pint", "scipy", "dask", "distributed", "xarray", "numba", "matplotlib", "netCDF4", "h5netcdf", "pandas")


def loaded_after(code: str) -> dict:
    """The top-level packages and the rdea_lab modules a fresh interpreter holds after running `code`."""
    probe = (f"import sys\n{code}\nimport json\n"
             "print(json.dumps({'top': sorted({m.split('.')[0] for m in sys.modules}), "
             "'rdea_lab': sorted(m for m in sys.modules if m.startswith('rdea_lab'))}))")
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=120,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def test_importing_the_cli_loads_no_heavy_package_and_no_layer_below_it():
    loaded = loaded_after("import rdea_lab.cli.main")
    assert not set(loaded["top"]) & set(HEAVY)
    # nor numpy, pydantic or YAML: the command line itself is click and a table
    assert not set(loaded["top"]) & {"numpy", "pydantic", "yaml"}
    assert set(loaded["rdea_lab"]) <= {"rdea_lab", "rdea_lab._version", "rdea_lab.api", "rdea_lab.api._cli",
                                       "rdea_lab.cli",
                                       "rdea_lab.cli.main", "rdea_lab.cli.errors", "rdea_lab.cli.lazy"}


@pytest.mark.parametrize("argv", [["--help"], [], ["--version"]])
def test_the_groups_help_loads_no_command_module(argv):
    loaded = loaded_after("from rdea_lab.cli.main import cli\nfrom rdea_lab.cli.errors import run\n"
                          f"assert run(cli, {argv!r}) == 0")
    assert not set(loaded["top"]) & set(HEAVY + ("numpy", "pydantic"))
    assert not [m for m in loaded["rdea_lab"] if m.startswith("rdea_lab.cli.") and m.split(".")[-1] in
                {module.rsplit(".", 1)[-1] for module, _, _ in COMMANDS.values()}]


def test_each_commands_help_loads_no_heavy_package():
    """``rdea-lab <cmd> --help`` imports that command's module (and the specs' plain vocabularies), no physics."""
    names = sorted(cli.list_commands(None))
    loaded = loaded_after("from rdea_lab.cli.main import cli\nfrom rdea_lab.cli.errors import run\n"
                          f"for name in {names!r}:\n    assert run(cli, [name, '--help']) == 0, name")
    assert not set(loaded["top"]) & set(HEAVY)
    below = [m for m in loaded["rdea_lab"] if m != "rdea_lab" and m.split(".")[1] not in
             ("cli", "api", "_version", "specs", "paths", "signals")]
    assert not below, below


def _defined_commands():
    """Every module-level click command of rdea_lab.cli that is not a subcommand of one of its groups."""
    found, children = {}, set()
    for info in pkgutil.iter_modules(rdea_lab.cli.__path__):
        if info.name == "__main__":  # `python -m rdea_lab.cli`: importing it runs the command
            continue
        module = importlib.import_module(f"rdea_lab.cli.{info.name}")
        for value in vars(module).values():
            if isinstance(value, click.Command) and value is not cli:
                found[id(value)] = value
                if isinstance(value, click.Group):
                    children.update(id(c) for c in value.commands.values())
    return {c.name: c for i, c in found.items() if i not in children}


def test_the_table_reaches_every_command_of_the_package():
    reachable = {name: cli.get_command(None, name) for name in cli.list_commands(None)}
    defined = _defined_commands()
    assert set(reachable) == set(defined)
    for name, command in reachable.items():
        assert command is defined[name], name


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_the_tables_short_help_is_the_commands_own(name):
    module, attribute, _ = COMMANDS[name]
    command = getattr(importlib.import_module(module), attribute)
    assert command.name == name
    for limit in (20, 45, 60, 80, 120, 400):  # click shortens to the terminal's width: any width agrees
        assert click.utils.make_default_short_help(COMMANDS[name][2], limit) == command.get_short_help_str(limit)


@pytest.mark.parametrize("width", [60, 100])
def test_the_groups_help_is_what_click_writes_for_the_loaded_commands(width, monkeypatch):
    """The lazy group's --help, from the table, against a plain click group holding every command."""
    import rdea_lab.cli.main as main

    plain = click.Group(name="cli", help=cli.help, epilog=cli.epilog, context_settings=cli.context_settings,
                        params=cli.params)
    for name in cli.list_commands(None):
        plain.add_command(cli.get_command(None, name), name)
    lazy = main.LazyGroup(name="cli", help=cli.help, epilog=cli.epilog, context_settings=cli.context_settings,
                          params=cli.params, lazy_commands=COMMANDS)
    for name in ("reproduce", "bench"):
        lazy.add_command(cli.commands[name], name)
    monkeypatch.setenv("COLUMNS", str(width))
    texts = []
    for group in (lazy, plain):
        with click.Context(group, info_name="rdea-lab", terminal_width=width, max_content_width=width) as ctx:
            texts.append(group.get_help(ctx))
    assert texts[0] == texts[1]
    assert all(f"\n  {name} " in texts[0] for name in cli.list_commands(None))


def test_an_unknown_command_is_a_usage_error(capsys):
    assert run_cli(cli, ["calibrat"]) == 2
    assert "No such command 'calibrat'" in capsys.readouterr().err
