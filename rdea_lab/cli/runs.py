"""CLI commands for runs and datasets: run, recover, ls, show, protocol show."""

from __future__ import annotations

import math
import shlex
import sys
from datetime import datetime, timezone
from pathlib import Path

import click

from ..paths import project_root
from ..specs import load_params, load_specimen
from .errors import die

DEFAULT_PARAMS = "params/paper2021_table3.yaml"


def _plans():
    from .. import protocols  # the protocol layer, loaded when a command needs it
    return protocols


def _default_out(card_id: str, plan_name: str) -> Path:
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    return Path("datasets") / card_id / f"{plan_name}-{stamp}.nc"


def _progress(total: int, quiet: bool, label: str):
    if quiet or not sys.stderr.isatty():
        return None
    return click.progressbar(length=total, label=label, file=sys.stderr, show_eta=True, show_percent=True)


def register(cli: click.Group) -> None:
    """Add the commands of this module to ``cli``."""

    @cli.command()
    @click.argument("protocol", type=click.Path(dir_okay=False))
    @click.option("--specimen", "card_path", required=True, type=click.Path(dir_okay=False), help="Specimen card (YAML).")
    @click.option("--backend", type=click.Choice(["twin"]), default="twin", show_default=True, help="Executor.")
    @click.option("--params", "params_path", type=click.Path(dir_okay=False),
                  help=f"Parameter set for the twin [default: {DEFAULT_PARAMS}].")
    @click.option("--model", type=click.Choice(["su", "1r", "3r", "auto"], case_sensitive=False), default="auto",
                  show_default=True, help="Twin model; auto = cheapest within --tolerance of 3R on this run.")
    @click.option("--tolerance", type=float, default=0.01, show_default=True,
                  help="For --model auto: allowed deviation from 3R, relative to the peak stress.")
    @click.option("--out", "out_path", type=click.Path(dir_okay=False),
                  help="Dataset to write [default: datasets/<specimen>/<protocol>-<UTC time>.nc].")
    @click.option("--force", "overwrite", is_flag=True, help="Overwrite an existing dataset.")
    @click.option("--realtime", is_flag=True, help="Pace the twin at wall-clock speed, as a rig runs.")
    @click.option("--dry-run", is_flag=True, help="Check the protocol against the specimen and limits; print the plan.")
    @click.option("--quiet", is_flag=True, help="No progress bar.")
    @click.option("--seed", type=int, default=0, show_default=True, help="Random seed (recorded).")
    def run(protocol, card_path, backend, params_path, model, tolerance, out_path, overwrite, realtime, dry_run,
            quiet, seed):
        """Run a protocol on a specimen and store the run as one netCDF file.

        \b
        Example:
          rdea-lab run protocols/tensile_ramp_sine_0V.yaml --specimen specimens/specimen2.yaml \\
              --backend twin --model auto --out datasets/demo.nc
        """
        from ..backends import TwinBackend, execute
        from ..physics.geometry import geometry_from_card

        P = _plans()
        plan = P.load_plan(protocol)
        card = load_specimen(card_path)
        try:
            geom = geometry_from_card(card)
        except ValueError as exc:
            die(f"{card_path}: {exc}")
        P.first_violation(plan, L3=geom.L3)
        if not (0.0 < tolerance < 1.0 and math.isfinite(tolerance)):
            die(f"--tolerance: {tolerance} is not a relative deviation; allowed: 0 < tolerance < 1")
        if params_path is None:
            root = project_root()
            if root is None or not (root / DEFAULT_PARAMS).is_file():
                die("--params: required here (no params/paper2021_table3.yaml to default to)")
            params_path = str(root / DEFAULT_PARAMS)
        params = load_params(params_path)
        twin = TwinBackend(card, params, model=model.lower(), tolerance=tolerance, realtime=realtime, seed=seed)
        if dry_run:
            click.echo(plan.describe())
            twin.start(plan)
            click.echo(f"limits: ok for {card.id} (L3 = {geom.L3 * 1e6:g} um)")
            sel = twin.attrs().get("model_selection")
            click.echo(f"twin: model {twin.model}" + (f" ({twin.choice.reason})" if sel else "")
                       + f", parameters {params.name}")
            return
        out = Path(out_path) if out_path else _default_out(card.id, plan.name)
        from ..store import journal_path
        if journal_path(out).exists():
            die(f"{out}: an unfinished run's journal {journal_path(out)} is in the way; "
                "rdea-lab recover it, or remove it")
        if out.exists() and not overwrite:
            die(f"{out}: exists; give --force to overwrite or choose --out")
        if out.exists():
            out.unlink()
        bar = _progress(plan.time.size, quiet, f"{plan.name} on {card.id}")
        command = "rdea-lab " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        if bar is not None:
            with bar:
                result = execute(plan, card, twin, out, seed=seed, command=command, progress=bar.update)
        else:
            result = execute(plan, card, twin, out, seed=seed, command=command)
        click.echo(f"{result.path}: {result.samples} samples, status {result.status}"
                   + (f" ({result.reason})" if result.reason else "") + f", model {twin.model}")
        if result.status == "interrupted":
            sys.exit(130)
        if result.status != "complete":
            sys.exit(1)

    @cli.command()
    @click.argument("paths", nargs=-1, required=True, type=click.Path())
    def recover(paths):
        """Rebuild the dataset of a run whose process died (SIGKILL, power loss) from its journal.

        PATHS are journals (``<run>.nc.part``), the datasets they were writing, or
        folders searched for journals.

        \b
        Example:
          rdea-lab recover datasets/specimen-2/
        """
        from ..store import recover as recover_run
        targets = []
        for p in map(Path, paths):
            if p.is_dir() and not p.name.endswith(".part"):
                targets += sorted(p.rglob("*.nc.part"))
            else:
                targets.append(p)
        if not targets:
            click.echo("no unfinished runs found")
            return
        for t in targets:
            try:
                out = recover_run(t)
            except (FileNotFoundError, FileExistsError, ValueError) as exc:
                die(str(exc))
            from ..store import open_run
            ds = open_run(out)
            click.echo(f"{out}: {ds.sizes['time']} samples recovered, status {ds.attrs['status']}")

    @cli.command(name="ls")
    @click.argument("folder", default="datasets", type=click.Path(file_okay=False))
    def ls_(folder):
        """A table of the runs below FOLDER, from their attributes.

        \b
        Example:
          rdea-lab ls datasets/
        """
        from ..store import catalog
        if not Path(folder).is_dir():
            die(f"{folder}: no such folder")
        rows = catalog(Path(folder))
        if not rows:
            click.echo(f"no runs below {folder}")
            return
        head = ("file", "specimen", "protocol", "backend", "model", "status", "duration", "samples")
        table = [(r["file"], r["specimen"], r["protocol"], r["backend"], r["model"], r["status"],
                  f"{r['duration_s']:.1f} s", str(r["samples"])) for r in rows]
        widths = [max(len(h), *(len(row[i]) for row in table)) for i, h in enumerate(head)]
        click.echo("  ".join(h.ljust(w) for h, w in zip(head, widths)))
        for row in table:
            click.echo("  ".join(c.ljust(w) for c, w in zip(row, widths)))

    @cli.command()
    @click.argument("file", type=click.Path(dir_okay=False))
    @click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Write a PNG of the run.")
    def show(file, plot_path):
        """Summary of one run, and optionally a plot.

        \b
        Example:
          rdea-lab show datasets/demo.nc --plot demo.png
        """
        from ..store import describe_run, open_run
        if not Path(file).is_file():
            die(f"{file}: no such file")
        try:
            ds = open_run(file)
        except (OSError, ValueError) as exc:
            die(f"{file}: not a readable netCDF dataset ({type(exc).__name__})")
        if "time" not in ds or "force" not in ds:
            die(f"{file}: not an rdea-lab run (no time/force variables)")
        click.echo(describe_run(ds))
        if plot_path:
            from ..reports.plots import plot_run
            click.echo(f"plot: {plot_run(ds, plot_path)}")

    @cli.group()
    def protocol():
        """Inspect protocols."""

    @protocol.command(name="show")
    @click.argument("file", type=click.Path(dir_okay=False))
    @click.option("--specimen", "card_path", type=click.Path(dir_okay=False),
                  help="Also check the field limit against this specimen's layer thickness.")
    @click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Write a PNG of the setpoints.")
    def protocol_show(file, card_path, plot_path):
        """Print the expanded plan of a protocol (duration, samples, envelope), and draw it.

        \b
        Example:
          rdea-lab protocol show protocols/blocking_force.yaml --plot blocking.png
        """
        P = _plans()
        plan = P.load_plan(file)
        L3 = None
        if card_path:
            from ..physics.geometry import geometry_from_card
            L3 = geometry_from_card(load_specimen(card_path)).L3
        click.echo(plan.describe())
        P.first_violation(plan, L3=L3)
        click.echo("limits: ok" + (f" (field checked with L3 = {L3 * 1e6:g} um)" if L3 else ""))
        if plot_path:
            from ..reports.plots import plot_plan
            click.echo(f"plot: {plot_plan(plan, plot_path)}")
