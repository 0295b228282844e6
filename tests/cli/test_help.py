"""Every command's and subcommand's --help ends with the exit statuses (issue 25)."""

import click
import pytest

from rdea_lab.cli.errors import EXIT_HELP
from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import COMMANDS, cli


def _walk(group, path=()):
    """Every command path below ``group``, groups included; a lazily loaded command is loaded by get_command."""
    ctx = click.Context(group)
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        yield (*path, name)
        if isinstance(command, click.Group):
            yield from _walk(command, (*path, name))


PATHS = list(_walk(cli))


def test_the_walk_reaches_every_lazy_command_and_the_subcommands():
    top = {p[0] for p in PATHS}
    assert set(COMMANDS) <= top and {"reproduce", "bench"} <= top
    assert {("report", "validation"), ("report", "speed"), ("protocol", "show"), ("campaign", "run"),
            ("rig", "serve")} <= set(PATHS)


@pytest.mark.parametrize("path", [(), *PATHS], ids=lambda p: " ".join(p) or "rdea-lab")
def test_help_carries_the_exit_statuses(path, capsys):
    assert run_cli(cli, [*path, "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())  # click wraps the epilog to the width
    assert " ".join(EXIT_HELP.split()) in help_text
