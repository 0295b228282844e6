"""The CLI's edge: each outcome to an exit status and at most one line on stderr.

Exit status: 0 done; 1 internal error (a bug: say so, traceback with
RDEA_LAB_DEBUG=1); 2 bad input (one line naming the file, the field and what
is allowed); 3 a run ended by the rig or a limit (aborted: breakdown, force
limit, lost connection, stall); 130 interrupted (Ctrl-C, SIGTERM).
"""

from __future__ import annotations

import os
import sys
import traceback

import click

EXIT_HELP = ("Exit status: 0 done, 1 internal error, 2 bad input (one line naming the file, the field and what is "
             "allowed), 3 a run ended by the rig or a limit (aborted), 130 interrupted.")


#: The library's argument names (in its messages: "arguments: seed: ...") as the CLI spells them.
OPTIONS = {"address": "--rig", "token": "--token-file", "address/token": "--rig/--token-file",
           "address/token/trust_card": "--rig/--token-file/--trust-card", "faults": "--fault",
           "faults/truth": "--fault/--truth", "truth": "--truth", "seed": "--seed", "params": "--params",
           "model": "--model", "tolerance": "--tolerance", "backend": "--backend", "stall_timeout": "--stall-timeout",
           "protocol_kind": "--protocol-kind", "free": "--free", "eps_r": "--eps-r", "branches": "--viscous-branches",
           "metric": "--metric", "init": "--init", "cv": "--cv", "holdout": "--holdout",
           "method": "--method", "tare": "--tare", "estimator": "--estimator", "tau": "--tau",
           "reference": "--reference", "hyperelastic": "--hyperelastic", "stretches": "--stretches",
           "rates": "--rates", "holds": "--holds", "bands": "--bands",
           "candidates": "--stretches/--rates/--holds/--max-stretch", "bind": "--bind", "port": "--port"}


#: Options a user reaches for by another name (other tools', or rdea-lab's before): the name -> ours.
SYNONYMS = {"--overwrite": "--force"}


def _suggest_synonym(exc: click.NoSuchOption) -> None:
    """Point an unknown option at the command's option of that meaning, if the command has one
    (click's own guess goes by spelling: ``--overwrite`` is not close to ``--force``)."""
    ours = SYNONYMS.get(exc.option_name)
    command = exc.ctx.command if exc.ctx is not None else None
    if ours and command is not None and any(ours in p.opts for p in command.params if isinstance(p, click.Option)):
        exc.possibilities = [ours]


def user_message(exc) -> str:
    """One line for a user's mistake; the library's argument names become the CLI's options."""
    source, field = getattr(exc, "source", None), getattr(exc, "field", None)
    if source == "arguments" and field is not None:
        return f"{OPTIONS.get(field, field)}: {exc.message}"
    return str(exc)


class UserInputError(click.ClickException):
    """A user mistake found by the CLI itself: exit status 2, one line."""

    exit_code = 2


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _interrupted(exc: BaseException) -> int:
    detail = _one_line(exc)
    click.echo(f"rdea-lab: interrupted ({detail})" if detail else "rdea-lab: interrupted", err=True)
    return 130


def run(group: click.Group, argv=None, *, process=False) -> int:
    """Run ``group`` and map every outcome to an exit status and at most one line on stderr.

    ``process``: this is the whole process (the console entry point): a signal after the command has ended is
    still exit 130, and the handlers stay in place until the interpreter exits (no KeyboardInterrupt while it
    shuts down). Otherwise (tests, a caller's own loop) the caller's handlers are put back.
    """
    from ..signals import Signals  # the command's start-up and end (a run's own are the engine's)

    signals = Signals().install()
    try:
        code = _run(group, argv)
    except KeyboardInterrupt as exc:  # between the command's end and the return
        code = _interrupted(exc)
    finally:
        signals.closing = True
        if process:
            signals.hold()
        else:
            signals.restore()
    if signals.pending and code != 130:
        click.echo(f"rdea-lab: interrupted ({signals.pending} as the command ended)", err=True)
        code = 130
    return code


def _run(group: click.Group, argv) -> int:
    try:
        # the command, without click's own main(): it would turn Ctrl-C into Abort after an empty line
        args = list(sys.argv[1:] if argv is None else argv)
        with group.make_context("rdea-lab", args) as ctx:
            group.invoke(ctx)
        return 0
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except SystemExit as exc:  # a command's own sys.exit(status)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except KeyboardInterrupt as exc:
        return _interrupted(exc)
    except click.exceptions.Abort:  # a prompt answered with end of input
        click.echo("rdea-lab: aborted", err=True)
        return 130
    except click.exceptions.NoArgsIsHelpError as exc:  # bare `rdea-lab`: show the help
        click.echo(exc.ctx.get_help() if exc.ctx is not None else "rdea-lab --help")
        return 0
    except click.UsageError as exc:
        if isinstance(exc, click.NoSuchOption):
            _suggest_synonym(exc)
        where = exc.ctx.command_path if exc.ctx is not None else "rdea-lab"
        click.echo(f"{where}: {_one_line(exc.format_message())} (see --help)", err=True)
        return 2
    except click.ClickException as exc:
        click.echo(f"rdea-lab: {_one_line(exc.format_message())}", err=True)
        return exc.exit_code
    except BrokenPipeError:
        return 0
    except Exception as exc:
        from ..specs import UserError  # here, not at the top: `rdea-lab --help` needs no specs

        if isinstance(exc, UserError):  # SpecError, LimitError, a rig refusing, a model that does not apply, ...
            click.echo(f"rdea-lab: {_one_line(user_message(exc))}", err=True)
            return 2
        # an internal error: say so, traceback on request
        if os.environ.get("RDEA_LAB_DEBUG"):
            traceback.print_exc()
        detail = _one_line(exc)
        detail = detail if len(detail) <= 300 else detail[:297] + "..."  # never a whole huge value
        click.echo(f"rdea-lab: internal error: {type(exc).__name__}: {detail} "
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


def headless() -> None:
    """Figures go to files: the CLI (only the CLI) picks the non-interactive backend."""
    import matplotlib

    matplotlib.use("Agg")
