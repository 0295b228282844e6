"""CLI commands for the catalogue index: catalog rebuild, catalog check."""

from __future__ import annotations

import sys

import click

from ..api import _cli as api
from .errors import EXIT_HELP, die
from .runs import CATALOG_HELP

#: `catalog check`'s exit status when the catalogue differs from the files (a report, not an error).
DIFFERS = 4


@click.group(epilog=EXIT_HELP)
def catalog():
    """The catalogue index of runs: rebuild it from the files, check it against them."""


@catalog.command(name="rebuild", epilog=EXIT_HELP + " A file changed, missing or unreadable is reported, with "
                 "exit 0: the catalogue is rebuilt from what the files hold.")
@click.argument("folder", type=click.Path(file_okay=False))
@click.option("--catalog", "catalog_url", metavar="URL", help=CATALOG_HELP)
def rebuild(folder, catalog_url):
    """Re-index every run below FOLDER from its file (the files are the truth).

    Prints the counts (added, updated, unchanged, changed, missing,
    unreadable, duplicates), then each file that was not as indexed: changed
    since indexed (re-indexed), missing (its row removed), unreadable.

    \b
    Example:
      rdea-lab catalog rebuild datasets/
    """
    from pathlib import Path

    if not Path(folder).is_dir():
        die(f"{folder}: no such folder")
    click.echo(api.rebuild_catalog(folder, catalog_url).describe())


@catalog.command(name="check", epilog=EXIT_HELP + f" check: {DIFFERS} the catalogue differs from the files.")
@click.argument("folder", type=click.Path(file_okay=False))
@click.option("--catalog", "catalog_url", metavar="URL", help=CATALOG_HELP)
def check(folder, catalog_url):
    """Compare the catalogue with the runs below FOLDER (full sha256), writing nothing.

    \b
    Example:
      rdea-lab catalog check datasets/
    """
    from pathlib import Path

    if not Path(folder).is_dir():
        die(f"{folder}: no such folder")
    result = api.check_catalog(folder, catalog_url)
    click.echo(result.describe())
    if not result.consistent:
        sys.exit(DIFFERS)
