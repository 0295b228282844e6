"""CLI command ``rdea-lab monitor``: a live view of runs in the browser."""

from __future__ import annotations

import click

from ..api import _cli as api
from ..specs import MODEL_CHOICES
from .errors import EXIT_HELP, die


@click.command(epilog=EXIT_HELP)
@click.argument("folder", default=".", required=False, metavar="[DIR]", type=click.Path(file_okay=False))
@click.option("--port", default=5006, show_default=True, type=click.IntRange(1, 65535), help="TCP port.")
@click.option("--bind", default="127.0.0.1", show_default=True,
              help="Address to listen on; anything but loopback needs --token-file.")
@click.option("--token-file", "token_file", type=click.Path(dir_okay=False),
              help="File holding the token every page must carry (?token=); needed for a non-loopback --bind.")
@click.option("--params", "params_path", type=click.Path(dir_okay=False),
              help="Parameter set: the twin's predicted force beside every run's measured force.")
@click.option("--model", type=click.Choice(MODEL_CHOICES), default="su", show_default=True,
              help="The twin's model for --params (auto: the cheapest within 1 % of CR on the run's plan).")
@click.option("--no-browser", is_flag=True, help="Do not open a browser; only print the URLs.")
def monitor(folder, port, bind, token_file, params_path, model, no_browser):
    """A live view of the runs in progress below DIR in the browser, and the catalogue of finished ones.

    Follows every run below DIR (default: here) by reading its journal, however the run was started, and
    streams force, stretch, voltage (capacitance, current where recorded) to every page; with --params the
    twin's prediction beside the measurement. Prints a view URL and a control URL: only a page opened with
    the control URL may pause, resume or abort a run. Closing a page changes nothing for a run (its heartbeat
    is the rig's, not the page's). Runs until Ctrl-C.

    \b
    Example:
      rdea-lab monitor datasets --params paper2021_table3 --no-browser
    """
    from pathlib import Path

    from ..specs import read_token  # here: the module loads for --help too

    if not Path(folder).is_dir():
        die(f"DIR {folder}: no such folder; give the folder the runs write to (default: .)")
    token = read_token(token_file, "--token-file", warn=lambda m: click.echo(f"rdea-lab: warning: {m}", err=True)) \
        if token_file else None
    if token is None and not api.is_loopback(bind):
        die(f"--bind {bind}: not a loopback address; give --token-file so that only pages with ?token= can "
            "see the runs (the default 127.0.0.1 needs none)")
    params = None
    if params_path:
        params = api.load_params(params_path)
    serve = api.monitor  # needs bokeh: a missing extra is refused here (exit 2, naming rdea-lab[monitor])
    try:
        serve(folder, port=port, bind=bind, token=token, params=params, model=model, open_browser=not no_browser,
              echo=lambda line: click.echo(line))
    except KeyboardInterrupt:
        click.echo("rdea-lab monitor: stopped (the runs go on)")
