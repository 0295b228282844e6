"""A click group that imports a command's module only when the command is asked for."""

from __future__ import annotations

import importlib

import click
from click.utils import make_default_short_help


class LazyGroup(click.Group):
    """A `click.Group` whose commands may live in modules imported on first use.

    ``rdea-lab --help`` lists every command with its short help from `lazy_commands`
    alone; ``rdea-lab calibrate ...`` imports only ``rdea_lab.cli.calibrate``. Commands
    added with `add_command` work as in any group.

    Parameters
    ----------
    lazy_commands : dict
        name -> (module, attribute, short help): the module that defines the command,
        the command's name there, and the first sentence of its help (what
        ``--help`` lists; click shortens it to the width, as it does a loaded
        command's).
    """

    def __init__(self, *args, lazy_commands: dict[str, tuple[str, str, str]] | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.lazy_commands = dict(lazy_commands or {})

    def list_commands(self, ctx):
        return sorted(set(self.commands) | set(self.lazy_commands))

    def get_command(self, ctx, name):
        if name not in self.commands and name in self.lazy_commands:
            module, attribute, _ = self.lazy_commands[name]
            self.add_command(getattr(importlib.import_module(module), attribute), name)
        return self.commands.get(name)

    def format_commands(self, ctx, formatter):
        """The "Commands" section as click writes it, a command not loaded yet shown from the table."""
        names = [n for n in self.list_commands(ctx) if n in self.lazy_commands or not self.commands[n].hidden]
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = [(n, self.commands[n].get_short_help_str(limit) if n in self.commands
                 else make_default_short_help(self.lazy_commands[n][2], limit)) for n in names]
        with formatter.section("Commands"):
            formatter.write_dl(rows)
