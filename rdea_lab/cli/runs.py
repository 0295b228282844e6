"""CLI commands for runs and datasets: run, recover, ls, show, protocol show."""

from __future__ import annotations

import contextlib
import math
import shlex
import sys
from datetime import datetime, timezone
from pathlib import Path

import click

from ..specs import load_params, load_specimen
from .errors import die, project_file

DEFAULT_PARAMS = "params/paper2021_table3.yaml"


def _plans():
    from .. import protocols  # the protocol layer, loaded when a command needs it
    return protocols


def _default_out(card_id: str, plan_name: str) -> Path:
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    return Path("datasets") / card_id / f"{plan_name}-{stamp}.nc"


def _clear_outputs(paths, overwrite: bool) -> None:
    """Check every dataset to be written before any run starts: an unfinished run's
    journal in the way, or an existing file without ``--force``, is refused; with
    ``--force`` the existing files are removed."""
    from ..store import journal_path

    for out in paths:
        if journal_path(out).exists():
            die(f"{out}: an unfinished run's journal {journal_path(out)} is in the way; "
                "rdea-lab recover it, or remove it")
        if out.exists() and not overwrite:
            die(f"{out}: exists; give --force to overwrite, or choose another --out")
    for out in paths:
        if out.exists():
            out.unlink()


def _progress(total: int, quiet: bool, label: str, seconds: float | None = None):
    """A progress bar on stderr, for runs expected to last over a second (``seconds``,
    when known), unless ``--quiet`` or stdout is not a terminal."""
    if quiet or not (sys.stdout.isatty() and sys.stderr.isatty()):
        return None
    if seconds is not None and seconds <= 1.0:
        return None
    return click.progressbar(length=total, label=label, file=sys.stderr, show_eta=True, show_percent=True)


def register(cli: click.Group) -> None:
    """Add the commands of this module to ``cli``."""

    @cli.command()
    @click.argument("protocol", type=click.Path(dir_okay=False))
    @click.option("--specimen", "card_path", required=True, type=click.Path(dir_okay=False), help="Specimen card (YAML).")
    @click.option("--backend", type=click.Choice(["twin", "rig", "emulator"]), default="twin", show_default=True,
                  help="twin: the physics model; rig: a rig server (--rig); emulator: a built-in emulated rig.")
    @click.option("--rig", "rig_address", metavar="tcp://HOST:PORT", help="Rig server, for --backend rig.")
    @click.option("--token-file", type=click.Path(dir_okay=False), help="Token presented to the rig server.")
    @click.option("--truth", "truth_path", type=click.Path(dir_okay=False),
                  help="For --backend emulator: truth file [default: truth/paper2021.yaml].")
    @click.option("--fault", "faults", multiple=True, metavar="KIND-at=SECONDS",
                  help="For --backend emulator: disconnect-at=, breakdown-at= or stall-at= (repeatable).")
    @click.option("--stall-timeout", type=click.FloatRange(0.1, 3600), default=5.0, show_default=True,
                  help="Seconds without a new sample before a rig run is aborted as stalled.")
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
    def run(protocol, card_path, backend, rig_address, token_file, truth_path, faults, stall_timeout, params_path,
            model, tolerance, out_path, overwrite, realtime, dry_run, quiet, seed):
        """Run a protocol on a specimen and store the run as one netCDF file.

        \b
        Examples:
          rdea-lab run protocols/tensile_ramp_sine_0V.yaml --specimen specimens/specimen2.yaml \\
              --backend twin --model auto --out datasets/demo.nc
          rdea-lab run protocols/blocking_force.yaml --specimen specimens/specimen1.yaml \\
              --backend rig --rig tcp://127.0.0.1:5025
          rdea-lab run protocols/blocking_force.yaml --specimen specimens/specimen1.yaml \\
              --backend emulator --fault breakdown-at=12
        """
        from ..backends import TwinBackend
        from ..runs import execute
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
        if backend != "emulator" and (faults or truth_path):
            die("--fault and --truth: only with --backend emulator")
        if backend != "rig" and (rig_address or token_file):
            die("--rig and --token-file: only with --backend rig")
        if backend == "twin":
            params = load_params(project_file(params_path, DEFAULT_PARAMS, "--params"))
            executor = TwinBackend(card, params, model=model.lower(), tolerance=tolerance, realtime=realtime,
                                   seed=seed)
        elif params_path:
            die("--params: the twin's parameters; a rig measures, it takes none")
        elif backend == "rig":
            if not rig_address:
                die("--rig: required with --backend rig (e.g. --rig tcp://127.0.0.1:5025)")
            from ..backends.rig import RigBackend, parse_address
            from .rig import _read_token
            try:
                parse_address(rig_address)
            except ValueError as exc:
                die(f"--rig: {exc}")
            executor = RigBackend(rig_address, card, token=_read_token(token_file) if token_file else None,
                                  stall_timeout=stall_timeout, seed=seed)
        else:
            from ..emulator.controller import check_faults
            from .rig import DEFAULT_TRUTH, parse_fault
            parsed = [parse_fault(f) for f in faults]
            try:
                check_faults(parsed)
            except ValueError as exc:
                die(f"--fault: {exc}")
            from ..specs.truth import load_truth
            truth = load_truth(project_file(truth_path, DEFAULT_TRUTH, "--truth"))
        if dry_run:
            click.echo(plan.describe())
            click.echo(f"limits: ok for {card.id} (L3 = {geom.L3 * 1e6:g} um)")
            if backend == "twin":
                executor.start(plan)
                sel = executor.attrs().get("model_selection")
                click.echo(f"twin: model {executor.model}" + (f" ({executor.choice.reason})" if sel else "")
                           + f", parameters {params.name}")
            elif backend == "rig":
                click.echo(f"rig {rig_address}: not contacted (dry run)")
            else:
                click.echo(f"emulator: truth {truth.name}" + (f", faults {', '.join(faults)}" if faults else ""))
            return
        out = Path(out_path) if out_path else _default_out(card.id, plan.name)
        _clear_outputs([out], overwrite)
        # wall time: the plan's duration when paced (a rig always is), else about 1e5 samples/s
        paced = realtime or backend == "rig"
        bar = _progress(plan.time.size, quiet, f"{plan.name} on {card.id}",
                        seconds=plan.duration if paced else plan.time.size / 1e5)
        command = "rdea-lab " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        with contextlib.ExitStack() as stack:
            if backend == "emulator":
                from ..runs.campaign import _emulator
                from ..backends.rig import RigBackend
                address = stack.enter_context(_emulator(card, truth, realtime, faults=parsed))
                executor = RigBackend(address, card, stall_timeout=stall_timeout, seed=seed)
            if bar is not None:
                stack.enter_context(bar)
            result = execute(plan, card, executor, out, seed=seed, command=command,
                             progress=bar.update if bar is not None else None)
        what = f", model {executor.model}" if backend == "twin" else ""
        click.echo(f"{result.path}: {result.samples} samples, status {result.status}"
                   + (f" ({result.reason})" if result.reason else "") + what)
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


def register_campaign(cli: click.Group) -> None:
    """The ``campaign`` group."""

    @cli.group()
    def campaign():
        """Run a whole campaign of experiments (campaigns/*.yaml)."""

    @campaign.command(name="run")
    @click.argument("file", type=click.Path(dir_okay=False))
    @click.option("--out", "out_dir", type=click.Path(file_okay=False),
                  help="Folder for the datasets [default: the campaign's 'out', e.g. datasets/paper2021].")
    @click.option("--force", "overwrite", is_flag=True, help="Overwrite existing datasets.")
    @click.option("--realtime", is_flag=True, help="Pace the runs at wall-clock speed.")
    @click.option("--quiet", is_flag=True, help="No progress bar.")
    def campaign_run(file, out_dir, overwrite, realtime, quiet):
        """Run every protocol on every specimen of a campaign, into <out>/<specimen_id>/<protocol_name>.nc.

        \\b
        Example:
          rdea-lab campaign run campaigns/paper2021.yaml
        """
        from ..runs.campaign import experiments, run_campaign
        from ..specs.campaign import load_campaign

        spec, root = load_campaign(file)
        runs = experiments(spec, root, out_dir)
        _clear_outputs([r.out for r in runs], overwrite)
        total = sum(r.plan.time.size for r in runs)
        click.echo(f"campaign {spec.name}: {len(runs)} runs, {total} samples, backend {spec.backend}")
        bar = _progress(total, quiet, spec.name)
        lines = []
        with contextlib.ExitStack() as stack:
            if bar is not None:
                stack.enter_context(bar)
            results = run_campaign(spec, root, out_dir=out_dir, realtime=realtime,
                                   progress=bar.update if bar is not None else None,
                                   on_result=lambda r: lines.append(r) if bar is not None else
                                   click.echo(f"  {r.path}: {r.samples} samples, {r.status}"))
        for r in lines:
            click.echo(f"  {r.path}: {r.samples} samples, {r.status}")
        bad = [r for r in results if r.status != "complete"]
        if bad:
            click.echo(f"{len(bad)} of {len(results)} runs did not complete: "
                       + "; ".join(f"{r.path.name}: {r.reason}" for r in bad), err=True)
            sys.exit(1)
