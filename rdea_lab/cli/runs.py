"""CLI commands for runs and datasets: run, recover, ls, show, protocol show, campaign run."""

from __future__ import annotations

import contextlib
import os
import shlex
import sys
from pathlib import Path

import click

from ..api import _cli as api
from ..specs import MODEL_CHOICES, UserError
from .errors import EXIT_HELP, die, headless

LIVE_HELP = ("Live view of the samples: 'table' (a line a second), 'plot' (a matplotlib window) "
             "or FILE.png (a PNG redrawn every second).")


def _command_line() -> str:
    return "rdea-lab " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def parse_metadata(items) -> dict:
    """``("operator=ana", "batch=B7")`` -> ``{"operator": "ana", "batch": "B7"}``."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            die(f"--md: {item!r} is not KEY=VALUE (e.g. --md operator=ana)")
        if key.strip() in out:
            die(f"--md: {key.strip()!r} given twice")
        out[key.strip()] = value.strip()
    return api.check_metadata(out, source="--md")


class _Bar:
    """A click progress bar as a run subscriber."""

    def __init__(self, total, label):
        self.bar = click.progressbar(length=total, label=label, file=sys.stderr, show_eta=True, show_percent=True)

    def __enter__(self):
        self.bar.__enter__()
        return self

    def __exit__(self, *exc):
        return self.bar.__exit__(*exc)

    def __call__(self, block):
        self.bar.update(len(block))


def subscribers(live, quiet, total, label, seconds, stack) -> list:
    """The CLI's subscribers: a live view (--live) or a progress bar (runs over a second, on a terminal)."""
    if live:
        if live == "table":
            return [api.LiveTable()]
        if live == "plot":
            import matplotlib

            if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo", "template"):
                die("--live plot: no display for a window here; give --live FILE.png instead")
            return [api.LivePlot()]
        if not live.lower().endswith(".png"):
            die(f"--live: {live!r}; allowed: table, plot or a FILE.png")
        api.check_figure(live, "--live")  # a folder it can be written in, before the run
        headless()
        return [api.LivePlot(Path(live))]
    if quiet or not (sys.stdout.isatty() and sys.stderr.isatty()) or (seconds is not None and seconds <= 1.0):
        return []
    return [stack.enter_context(_Bar(total, label))]


@click.command(epilog=EXIT_HELP)
@click.argument("protocol", type=click.Path(dir_okay=False))
@click.option("--specimen", "card_path", required=True, type=click.Path(dir_okay=False), help="Specimen card (YAML).")
@click.option("--backend", type=click.Choice(["twin", "rig", "emulator"], case_sensitive=False), default="twin",
              show_default=True,
              help="twin: the physics model; rig: a rig server (--rig); emulator: a built-in emulated rig.")
@click.option("--rig", "rig_address", metavar="tcp://HOST:PORT", help="Rig server, for --backend rig.")
@click.option("--token-file", type=click.Path(dir_okay=False), help="Token presented to the rig server.")
@click.option("--truth", "truth_path", type=click.Path(dir_okay=False),
              help="For --backend emulator: truth file [default: truth/paper2021.yaml].")
@click.option("--fault", "faults", multiple=True, metavar="KIND-at=SECONDS[:DURATION]",
              help="For --backend emulator: disconnect-at=, breakdown-at=, stall-at=, interlock-at=, "
                   "overheat-at=, drift-at= (repeatable; see docs/rig-protocol.md).")
@click.option("--stall-timeout", type=click.FloatRange(0.1, 3600), default=5.0, show_default=True,
              help="Seconds without a new sample before a rig run is aborted as stalled.")
@click.option("--params", "params_path", type=click.Path(dir_okay=False),
              help="Parameter set for the twin [default: params/paper2021_table3.yaml].")
@click.option("--model", type=click.Choice(MODEL_CHOICES, case_sensitive=False), default="auto",
              show_default=True,
              help="Twin model; auto = cheapest within --tolerance of CR (the continuum model) on this run.")
@click.option("--tolerance", type=click.FloatRange(0.0, 1.0, min_open=True, max_open=True), default=0.01,
              show_default=True,
              help="For --model auto: allowed deviation from CR, relative to the peak stress.")
@click.option("--out", "out_path", type=click.Path(dir_okay=False),
              help="Dataset to write [default: datasets/<specimen>/<protocol>-<UTC time>.nc].")
@click.option("--force", "overwrite", is_flag=True, help="Overwrite an existing dataset.")
@click.option("--realtime", is_flag=True, help="Pace the twin at wall-clock speed, as a rig runs.")
@click.option("--dry-run", is_flag=True, help="Check the protocol against the specimen and limits; print the plan.")
@click.option("--live", metavar="table|plot|FILE.png", help=LIVE_HELP)
@click.option("--md", "md", multiple=True, metavar="KEY=VALUE",
              help="User metadata stored with the run (operator, batch, notes; repeatable).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed (recorded), 0 to 2**63 - 1.")
@click.option("--on-ctrl-c", "on_ctrl_c", type=click.Choice(["ask", "interrupt"]), default=None,
              help="A first Ctrl-C pauses the run and asks resume or abort (ask; the default on a terminal), or "
                   "interrupts it at once (interrupt; the default otherwise). A second Ctrl-C always interrupts.")
@click.option("--trust-card", is_flag=True,
              help="With --backend rig: run although the rig names another specimen than --specimen (recorded).")
def run(protocol, card_path, backend, rig_address, token_file, truth_path, faults, stall_timeout, params_path,
        model, tolerance, out_path, overwrite, realtime, dry_run, live, md, quiet, seed, on_ctrl_c, trust_card):
    """Run a protocol on a specimen and store the run as one netCDF file.

    \b
    Examples:
      rdea-lab run protocols/tensile_ramp_sine_0V.yaml --specimen specimens/specimen2.yaml \\
          --backend twin --model auto --out datasets/demo.nc --md operator=ana --live table
      rdea-lab run protocols/blocking_force.yaml --specimen specimens/specimen1.yaml \\
          --backend rig --rig tcp://127.0.0.1:5025
      rdea-lab run protocols/blocking_force.yaml --specimen specimens/specimen1.yaml \\
          --backend emulator --fault breakdown-at=12
    """
    from ..specs import read_token  # here: the module loads for --help too

    metadata = parse_metadata(md)
    executor = api.backend_from_choice(backend, params=params_path, model=model, tolerance=tolerance,
                                       realtime=realtime, address=rig_address,
                                       token=read_token(token_file, "--token-file") if token_file else None,
                                       truth=truth_path, faults=faults, stall_timeout=stall_timeout,
                                       trust_card=trust_card)
    setup = api.prepare_run(protocol, card_path, executor, out=out_path, seed=seed)
    if dry_run:
        click.echo(setup.describe())
        return
    api.check_outputs([setup.out], overwrite)
    plan = setup.plan
    # wall time: the plan's duration when paced (a rig always is), else about 1e5 samples/s
    paced = realtime or backend == "rig"
    with contextlib.ExitStack() as stack:
        subs = subscribers(live, quiet, plan.samples, f"{plan.name} on {setup.card.id}",
                           plan.duration if paced else plan.samples / 1e5, stack)
        from .operate import AskOnCtrlC

        control = api.RunControl()
        ask = on_ctrl_c == "ask" or (on_ctrl_c is None and sys.stdin.isatty() and sys.stderr.isatty())
        result = api.execute_setup(setup, callbacks=subs, metadata=metadata, command=_command_line(),
                                   control=control, on_interrupt=AskOnCtrlC(control) if ask else None)
    what = ""
    if backend == "twin":
        what = f", model {api.open_run(result.path).attrs.get('model', '?')}"
    click.echo(f"{result.path}: {result.samples} samples, status {result.status}"
               + (f" ({result.reason})" if result.reason else "") + what)
    if result.exit_code:
        sys.exit(result.exit_code)


#: `recover`'s exit status when it left a live run's journal alone (BSD's EX_TEMPFAIL: try again later).
LIVE_LEFT_ALONE = 75


@click.command(epilog=EXIT_HELP + f" recover: {LIVE_LEFT_ALONE} a journal left alone because its run is still going.")
@click.argument("paths", nargs=-1, required=True, type=click.Path())
@click.option("--out", "out_path", type=click.Path(dir_okay=False),
              help="Write the dataset here instead (one journal only), e.g. on another disk.")
def recover(paths, out_path):
    """Rebuild the dataset of a run whose process died (SIGKILL, power loss) from its journal.

    PATHS are journals (``<run>.nc.part``), the datasets they were writing, or
    folders searched for journals.

    \b
    Example:
      rdea-lab recover datasets/specimen-2/
    """
    targets = []
    for p in map(Path, paths):
        if p.is_dir() and not p.name.endswith(".part"):
            targets += sorted(p.rglob("*.nc.part"))
        else:
            targets.append(p)
    if not targets:
        click.echo("no unfinished runs found")
        return
    if out_path and len(targets) > 1:
        die(f"--out: {len(targets)} journals found; --out takes one (name the journal)")
    live = 0
    for t in targets:
        try:
            out = api.recover(t, out_path)
        except api.RunInProgress as exc:  # a live run's journal: left alone
            click.echo(str(exc))
            live += 1
            continue
        except api.EmptyJournal as exc:  # a run that never began
            click.echo(str(exc))
            continue
        except (FileNotFoundError, FileExistsError, ValueError) as exc:
            die(str(exc))
        ds = api.open_run(out)
        click.echo(f"{out}: {ds.sizes['time']} samples recovered, status {ds.attrs['status']}")
    if live:  # a script can tell "nothing to do yet" from "done"
        click.echo(f"rdea-lab: {live} of {len(targets)} journals belong to runs still going and were left alone; "
                   f"run recover again once they end (exit {LIVE_LEFT_ALONE})", err=True)
        sys.exit(LIVE_LEFT_ALONE)


CATALOG_HELP = ("The catalogue: a SQLite file or postgresql://USER@HOST[:PORT]/DATABASE [default: env "
                "RDEA_LAB_CATALOG, else rdea-lab-catalog.sqlite at or above FOLDER].")


@click.command(name="ls", epilog=EXIT_HELP)
@click.argument("folder", required=False, type=click.Path(file_okay=False))
@click.option("--where", metavar="QUERY", help="Only the runs the query selects, e.g. \"specimen == 'specimen-2' and "
              "status == 'complete' and md.batch == 'B7'\" (docs/catalogue.md).")
@click.option("--since", metavar="DATE", help="Only runs created at or after DATE (ISO 8601, UTC), e.g. 2026-03-01.")
@click.option("--columns", metavar="A,B,md.X", help="The columns to show (e.g. file,status,peak_force,md.batch).")
@click.option("--catalog", "catalog_url", metavar="URL", help=CATALOG_HELP)
@click.option("--limit", type=click.IntRange(1), metavar="N", help="At most N runs (by file).")
def ls_(folder, where, since, columns, catalog_url, limit):
    """A table of the runs below FOLDER, from their attributes (with the user's metadata).

    The catalogue index answers (a run's row is written when it ends); a file
    changed or gone since it was indexed is marked so, not trusted (rdea-lab
    catalog rebuild FOLDER re-reads them). FOLDER defaults to datasets/, or, with
    --catalog (or RDEA_LAB_CATALOG), to every run of that catalogue.

    \b
    Examples:
      rdea-lab ls datasets/
      rdea-lab ls datasets/ --where "status == 'complete' and md.batch == 'B7'" --since 2026-03-01
      rdea-lab ls --catalog postgresql://lab@dbhost/rdea --columns file,host,status,peak_force
    """
    if folder is None and not (catalog_url or os.environ.get("RDEA_LAB_CATALOG", "").strip()):
        folder = "datasets"
    if folder is not None and not Path(folder).is_dir():
        die(f"{folder}: no such folder")
    table = api.catalog(Path(folder) if folder is not None else None, where=where, since=since,
                        columns=columns.split(",") if columns is not None else None, catalog=catalog_url, limit=limit)
    if table.empty:
        click.echo(f"no runs below {folder}" if folder is not None else "no runs in the catalogue"
                   + (" match" if where or since else ""))
        return
    if columns is not None:
        head = list(table.columns)
        rows = [[_cell(v) for v in r] for r in table.itertuples(index=False)]
    else:
        head = ["file", "specimen", "protocol", "backend", "model", "status", "duration", "samples"]
        rows = [[r.file, r.specimen, r.protocol, r.backend, r.model, _status(r.status, r.file_state),
                 f"{r.duration_s:.1f} s", str(r.samples)] for r in table.itertuples()]
        if table["metadata"].astype(bool).any():
            head.append("metadata")
            for row, md in zip(rows, table["metadata"]):
                row.append(md)
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]
    click.echo("  ".join(h.ljust(w) for h, w in zip(head, widths)).rstrip())
    for row in rows:
        click.echo("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip())
    total = table.attrs.get("total", len(table))
    if total > len(table):
        click.echo(f"({len(table)} of {total} runs: --limit {limit})")


def _status(status, state) -> str:
    """A run's status as ls shows it: with the file's state when it is not as indexed."""
    return f"{status} (file {state})" if state in ("changed since indexed", "missing") else status


def _cell(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return "" if value is None else str(value)


@click.command(epilog=EXIT_HELP)
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Write a PNG of the run (or .pdf, .svg, ...: matplotlib's formats).")
def show(file, plot_path):
    """Summary of one run (with the user's metadata), and optionally a plot.

    \b
    Example:
      rdea-lab show datasets/demo.nc --plot demo.png
    """
    if plot_path:
        api.check_figure(plot_path)
    if not Path(file).is_file():
        die(f"{file}: no such file")
    try:
        ds = api.open_run(file)
    except UserError:  # a dataset from elsewhere: the attribute or variable that is not rdea-lab's
        raise
    except (OSError, ValueError) as exc:
        die(f"{file}: not a readable netCDF dataset ({type(exc).__name__})")
    if "time" not in ds or "force" not in ds:
        die(f"{file}: not an rdea-lab run (no time/force variables)")
    click.echo(api.describe_run(ds))
    if plot_path:
        headless()
        api.plot_run(ds, plot_path)
        click.echo(f"plot: {plot_path}")


@click.group(epilog=EXIT_HELP)
def protocol():
    """Inspect protocols."""


@protocol.command(name="show", epilog=EXIT_HELP)
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--specimen", "card_path", type=click.Path(dir_okay=False),
              help="Also check the field limit against this specimen's layer thickness.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Write a PNG of the setpoints (or .pdf, .svg, ...: matplotlib's formats).")
def protocol_show(file, card_path, plot_path):
    """Print the expanded plan of a protocol (duration, samples, envelope), and draw it.

    \b
    Example:
      rdea-lab protocol show protocols/blocking_force.yaml --plot blocking.png
    """
    if plot_path:
        api.check_figure(plot_path)
    plan = api.load_plan(file)
    L3 = api.geometry(card_path).L3 if card_path else None
    click.echo(plan.describe())
    api.check_plan(plan, L3)
    click.echo("limits: ok" + (f" (field checked with L3 = {L3 * 1e6:g} um)" if L3 else ""))
    if plot_path:
        headless()
        api.plot_plan(plan, plot_path)
        click.echo(f"plot: {plot_path}")


@click.group(epilog=EXIT_HELP)
def campaign():
    """Run a whole campaign of experiments (campaigns/*.yaml)."""


@campaign.command(name="run", epilog=EXIT_HELP)
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", type=click.Path(file_okay=False),
              help="Folder for the datasets [default: the campaign's 'out' in the working folder, "
              "e.g. datasets/paper2021].")
@click.option("--force", "overwrite", is_flag=True, help="Overwrite existing datasets.")
@click.option("--realtime", is_flag=True, help="Pace the runs at wall-clock speed.")
@click.option("--live", metavar="table|plot|FILE.png", help=LIVE_HELP)
@click.option("--md", "md", multiple=True, metavar="KEY=VALUE",
              help="User metadata stored with every run (operator, batch, notes; repeatable).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def campaign_run(file, out_dir, overwrite, realtime, live, md, quiet):
    """Run every protocol on every specimen of a campaign, into <out>/<specimen_id>/<protocol_name>.nc.

    \b
    Example:
      rdea-lab campaign run campaigns/paper2021.yaml --md operator=ana
    """
    metadata = parse_metadata(md)
    spec, root = api.load_campaign(file)
    runs = api.experiments(spec, root, out_dir)
    api.check_outputs([r.out for r in runs], overwrite, names=[r.name for r in runs])
    total = sum(r.plan.samples for r in runs)
    click.echo(f"campaign {spec.name}: {len(runs)} runs, {total} samples, backend {spec.backend}")
    lines = []
    with contextlib.ExitStack() as stack:
        subs = subscribers(live, quiet, total, spec.name, None, stack)
        quietly = bool(subs)  # a bar or a live view owns the terminal: the lines come after it
        results = api.run_campaign(spec, root, out_dir=out_dir, overwrite=overwrite, realtime=realtime,
                                   callbacks=subs, metadata=metadata, command=_command_line(), runs=runs,
                                   on_result=lambda r: lines.append(r) if quietly else
                                   click.echo(f"  {r.path}: {r.samples} samples, {r.status}"))
    for r in lines:
        click.echo(f"  {r.path}: {r.samples} samples, {r.status}")
    bad = [r for r in results if r.status != "complete"]
    if bad:
        click.echo(f"{len(bad)} of {len(results)} runs did not complete: "
                   + "; ".join(f"{r.path.name}: {r.reason}" for r in bad), err=True)
        sys.exit(max(r.exit_code for r in bad))
