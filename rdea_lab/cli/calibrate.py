"""``rdea-lab calibrate``."""

from __future__ import annotations

import sys

import click

from .. import api
from ..specs import MODEL_CHOICES
from .errors import headless


@click.command()
@click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=False))
@click.option("--model", type=click.Choice(MODEL_CHOICES, case_sensitive=False), default="su",
              show_default=True, help="Quasi-static model of the twin.")
@click.option("--init", "init_path", type=click.Path(dir_okay=False),
              help="Start values (a parameter file); default: estimated from the data.")
@click.option("--free", "free_text", help="Parameters to fit, e.g. C10,C20,C30,k_v1,eta_v1 "
                                          "[default: every Yeoh and viscoelastic parameter].")
@click.option("--viscous-branches", "M", type=click.IntRange(0, 6),
              help="Maxwell branches M [default: those of --init, or 1]; without --init they are fitted "
                   "one at a time, each from the previous optimum.")
@click.option("--eps-r", type=float, default=None, help="Relative permittivity, fixed [default: --init's, or 2.8].")
@click.option("--protocol-kind", "kinds_text", default="tensile", show_default=True,
              help="For folders: which runs, comma-separated from tensile, blocking, capacitance, custom.")
@click.option("--metric", type=click.Choice(["rms", "max"], case_sensitive=False), default="rms", show_default=True,
              help="Error metric on the peak-normalized force.")
@click.option("--max-evals", type=click.IntRange(10, 10**7), default=20000, show_default=True)
@click.option("--max-time", type=click.FloatRange(0.1, 86400), default=300.0, show_default=True,
              help="Wall-time budget [s].")
@click.option("--name", help="Name of the calibrated parameter set [default: from --out].")
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False),
              help="Record to write (a parameter file with a calibration section).")
@click.option("--quiet", is_flag=True, help="No progress line.")
def calibrate(inputs, model, init_path, free_text, M, eps_r, kinds_text, metric, max_evals, max_time, name,
              out_path, quiet):
    """Fit the Yeoh and viscoelastic parameters to measured runs with Nelder-Mead.

    INPUTS are datasets or folders of datasets (a folder gives its complete
    runs of --protocol-kind, by default the tensile tests, as in the paper).

    \b
    Example:
      rdea-lab calibrate datasets/paper2021/specimen-2 --model su --out params/calibrated.yaml
    """
    headless()
    show = not quiet and sys.stderr.isatty()

    def progress(n, best, elapsed):
        if show:
            click.echo(f"\r  evaluations {n:6d}  best {best:.6e}  elapsed {elapsed:6.1f} s", nl=False, err=True)

    def announce(runs, chosen, reason, free, skipped):
        for s in skipped:
            click.echo(f"skipped {s['file']}: {s['reason']}")
        if reason:
            click.echo(f"model auto: {chosen} ({reason})")
        click.echo(f"calibrating {', '.join(free)} ({chosen}, {metric}) on {len(runs)} runs: "
                   + ", ".join(f"{r.specimen}/{r.protocol}" for r in runs))

    kinds = [k.strip() for k in kinds_text.split(",") if k.strip()]
    result = api.calibrate_runs(list(inputs), model=model.lower(), init=init_path, free=free_text, branches=M,
                                eps_r=eps_r, kinds=kinds, metric=metric, max_evals=max_evals, max_time=max_time,
                                out=out_path, name=name, progress=progress, announce=announce)
    if show:
        click.echo("", err=True)
    click.echo(api.format_result(result))
    files = result.record_files
    click.echo(f"wrote {files['params']}, {files['history']}, {files['plot']}")
