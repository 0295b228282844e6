"""``rdea-lab design``: a design study (sweep, sensitivity, optimization) on a dask cluster."""

from __future__ import annotations

import json
import sys

import click

from ..api import _cli as api
from .errors import EXIT_HELP


@click.command("design", epilog=EXIT_HELP)
@click.argument("study_path", metavar="STUDY.yaml", type=click.Path(dir_okay=False))
@click.option("--out", default=None, type=click.Path(file_okay=False),
              help="Folder for study.nc, pareto.csv, sobol.csv, card.yaml, summary.json and the figures "
                   "[default: designs/<study name>].")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
              help="A running dask scheduler [default: $DASK_SCHEDULER_ADDRESS, else a local cluster].")
@click.option("--workers", default=None, type=click.IntRange(1, 1024),
              help="Worker processes of the local cluster [default: one per core].")
@click.option("--synchronous", is_flag=True, help="Run every task in this process (no cluster; for debugging).")
@click.option("--run", "backend", type=click.Choice(("emulator", "twin")), default=None,
              help="Also run the study's protocol on the best design's card (needs optimize and protocol).")
@click.option("--force", "overwrite", is_flag=True, help="Replace the outputs of an earlier study in --out.")
@click.option("--no-figures", is_flag=True, help="Skip the PNG figures.")
@click.option("--quiet", is_flag=True, help="No progress bar or cluster line on stderr.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def design(study_path, out, scheduler, workers, synchronous, backend, overwrite, no_figures, quiet, as_json):
    """Evaluate a design study: roll geometry, bias and operating point against objectives and constraints.

    Samples the variables (grid, Latin hypercube or Sobol), evaluates every
    design (and its Monte Carlo rolls) in large tasks on dask.distributed,
    ranks them (constraints, Pareto front, Sobol indices), refines the best
    with SLSQP and writes the best design's specimen card.

    \b
    Examples:
      rdea-lab design studies/stroke_spring.yaml --out designs/stroke_spring --run emulator
      rdea-lab design STUDY.yaml --scheduler tcp://10.0.0.5:8786
    """
    study = api.load_study(study_path)
    if backend:
        api.check_card_run(study)  # before hours of work, not after
    out = out or f"designs/{study.name}"
    api.check_study_out(out, overwrite)
    try:
        result = api.run_study(study, scheduler=scheduler, workers=workers, synchronous=synchronous,
                               progress=not quiet, quiet=quiet)
    except api.StudyAborted as exc:  # the cluster lost the work: ended by the environment, as a run's abort
        click.echo(f"rdea-lab: {exc}", err=True)
        sys.exit(3)
    paths = {name: str(path) for name, path in result.write(out, overwrite=overwrite, figures=not no_figures).items()}
    summary = result.summary()
    summary["outputs"] = paths
    text = result.lines()
    if backend:
        summary["run"] = run = api.run_card(result, paths["card.yaml"], backend, f"{out}/{backend}.nc", overwrite)
        text.append(f"{backend} run of card.yaml: {run['dataset']}, peak force {run['peak_force']:.4g} N (the "
                    f"study's twin for the card {run['predicted_peak_force']:.4g} N, "
                    f"{run['peak_force'] / run['predicted_peak_force'] - 1:+.1%})")
    if as_json:
        click.echo(json.dumps(summary, indent=2, default=float))
    else:
        for line in text:
            click.echo(line)
        click.echo(f"outputs: {out}/ ({', '.join(sorted(p.split('/')[-1] for p in paths.values()))})")
