"""The CLI's edge: user mistakes exit 2 with one line, internal errors exit 1."""

from __future__ import annotations

import os
import sys
import traceback

import click

from ..backends.rig import RigRefused
from ..physics.result import ModelNotApplicable, StretchBelowOneError
from ..specs import SpecError


class UserInputError(click.ClickException):
    """A user mistake found by the CLI itself: exit status 2, one line."""

    exit_code = 2


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def run(group: click.Group, argv=None) -> int:
    """Run ``group`` and map every outcome to an exit status and at most one line on stderr."""
    try:
        group.main(args=argv, prog_name="rdea-lab", standalone_mode=False)
        return 0
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except SystemExit as exc:  # a command's own sys.exit(status)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except click.exceptions.Abort:
        click.echo("rdea-lab: aborted", err=True)
        return 130
    except click.exceptions.NoArgsIsHelpError as exc:  # bare `rdea-lab`: show the help
        click.echo(exc.ctx.get_help() if exc.ctx is not None else "rdea-lab --help")
        return 0
    except click.UsageError as exc:
        where = exc.ctx.command_path if exc.ctx is not None else "rdea-lab"
        click.echo(f"{where}: {_one_line(exc.format_message())} (see --help)", err=True)
        return 2
    except click.ClickException as exc:
        click.echo(f"rdea-lab: {_one_line(exc.format_message())}", err=True)
        return exc.exit_code
    except (SpecError, StretchBelowOneError, ModelNotApplicable, RigRefused) as exc:
        click.echo(f"rdea-lab: {_one_line(exc)}", err=True)
        return 2
    except KeyboardInterrupt:
        click.echo("rdea-lab: interrupted", err=True)
        return 130
    except BrokenPipeError:
        return 0
    except Exception as exc:  # an internal error: say so, traceback on request
        if os.environ.get("RDEA_LAB_DEBUG"):
            traceback.print_exc()
        click.echo(f"rdea-lab: internal error: {type(exc).__name__}: {_one_line(exc)} "
                   "(set RDEA_LAB_DEBUG=1 for a traceback)", err=True)
        return 1


def die(message: str) -> None:
    """Stop with a user-input error (exit status 2)."""
    raise UserInputError(message)


def flush_stdout():
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        pass


def project_file(given: str | None, default: str, option: str) -> str:
    """``given``, or the project's ``default`` file (e.g. ``params/paper2021_table3.yaml``) when absent."""
    if given is not None:
        return given
    from ..paths import project_root

    root = project_root()
    if root is None or not (root / default).is_file():
        die(f"{option}: required here (no {default} to default to)")
    return str(root / default)
