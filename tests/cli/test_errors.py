"""rdea_lab.cli.errors: an unknown option that is another tool's name for one of ours points at ours."""

import click
import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli


def _commands(group=cli, path=()):
    """(command path, command) of every command below the group, subcommands included."""
    for name in group.list_commands(None):
        command = group.get_command(None, name)
        if isinstance(command, click.Group):
            yield from _commands(command, (*path, name))
        else:
            yield (*path, name), command


def _has_force(command) -> bool:
    return any("--force" in p.opts for p in command.params if isinstance(p, click.Option))


WITH_FORCE = sorted(path for path, command in _commands() if _has_force(command))
WITHOUT_FORCE = sorted(path for path, command in _commands() if not _has_force(command))


def test_the_commands_that_write_have_force():
    # the commands whose outputs may exist already: each has --force (so the suggestion below is tested on them)
    assert {("reproduce",), ("run",), ("import",), ("campaign", "run"), ("design",), ("plan",),
            ("selfsense",), ("calibrate",), ("report", "validation"),
            ("report", "speed")} <= set(WITH_FORCE)


@pytest.mark.parametrize("path", WITH_FORCE, ids=" ".join)
@pytest.mark.parametrize("spelling", ["--overwrite", "--overwrite=yes"])
def test_overwrite_points_at_force(path, spelling, capsys):
    assert run_cli(cli, [*path, spelling]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert (err.startswith(f"rdea-lab {' '.join(path)}: ") and "'--overwrite'" in err
            and "Did you mean '--force'?" in err)


@pytest.mark.parametrize("path", WITHOUT_FORCE, ids=" ".join)
def test_overwrite_suggests_no_force_where_there_is_none(path, capsys):
    assert run_cli(cli, [*path, "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No such option '--overwrite'" in err and "--force" not in err


def test_clicks_own_guess_stays_for_other_options(capsys):
    assert run_cli(cli, ["run", "--output", "x.nc"]) == 2
    assert "Did you mean '--out'?" in capsys.readouterr().err
