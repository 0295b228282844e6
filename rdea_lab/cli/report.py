"""``rdea-lab report validation`` (the Table 4 analogue) and ``rdea-lab report speed``."""

from __future__ import annotations

import click

from ..api import _cli as api
from ..specs import MODEL_CHOICES
from .errors import EXIT_HELP, headless

MODELS = MODEL_CHOICES


class _ReportGroup(click.Group):
    """``report`` holds two commands; options given to the group itself were ``report validation``'s."""

    def parse_args(self, ctx, args):
        if args and args[0].startswith("--") and args[0] not in ("--help", "-h"):
            raise click.UsageError(f"{args[0]} belongs to a subcommand: 'rdea-lab report validation --params P "
                                   "--datasets D' (the Table 4 analogue) or 'rdea-lab report speed'", ctx)
        return super().parse_args(ctx, args)


@click.group(cls=_ReportGroup, epilog=EXIT_HELP)
def report():
    """Reports: the twin against measured runs (validation), and speed against error (speed).

    \b
    Examples:
      rdea-lab report validation --params params/calibrated.yaml --datasets datasets/paper2021 --out reports/paper2021
      rdea-lab report speed --out reports/speed
    """


@report.command(epilog=EXIT_HELP)
@click.option("--params", "params_path", required=True, type=click.Path(dir_okay=False),
              help="Parameter set (YAML), e.g. a calibration record.")
@click.option("--datasets", "datasets", required=True, type=click.Path(file_okay=False),
              help="Folder of runs (searched recursively for complete *.nc runs).")
@click.option("--out", "out_dir", default="reports/validation", show_default=True,
              type=click.Path(file_okay=False), help="Folder for the table, figures and index.html.")
@click.option("--model", type=click.Choice(MODELS, case_sensitive=False), default="su", show_default=True,
              help="Twin model; auto = cheapest within --tolerance of CR (the continuum model), per run.")
@click.option("--tolerance", type=click.FloatRange(min=0.0, min_open=True), default=0.01, show_default=True,
              help="For --model auto: allowed deviation from CR, relative to the peak stress.")
@click.option("--bands", type=float, default=None, metavar="LEVEL",
              help="Prediction bands of the force at this nominal level (0.9: 90 %), from the calibration record "
                   "in --params (covariance and cross-validated misfit): each row gets the band's coverage of the "
                   "measured samples, the figures shade it.")
@click.option("--no-figures", is_flag=True, help="Tables and index.html only.")
@click.option("--force", "overwrite", is_flag=True, help="Write into an --out that holds files.")
def validation(params_path, datasets, out_dir, model, tolerance, bands, no_figures, overwrite):
    """The twin against measured runs: the Table 4 analogue, figures 11-16, index.html.

    Runs the twin on every complete run's own stretch and voltage history
    and writes table4.md / .csv / .tex, figures (PNG at 200 dpi and PDF)
    and index.html into --out. Each row names its run, protocol, rate and
    maximum stretch, where its data come from (import and its credit,
    emulator, twin, rig), its role (calibration run, held out (same
    specimen), other specimen: from the calibration record in --params) and
    where it leaves the calibration envelope. With --bands, the band's
    coverage, half-width and status (bounded, parameter-only, widened or
    unbounded beyond the calibration) beside the errors.

    \b
    Example:
      rdea-lab report validation --params params/calibrated.yaml --datasets datasets/paper2021 \\
          --out reports/paper2021
      rdea-lab report validation --params params/vhb4910.yaml --datasets datasets/vhb4910 --model 1r \\
          --out reports/vhb4910
      rdea-lab report validation --params params/vhb4910.yaml --datasets datasets/vhb4910 --bands 0.9
    """
    headless()
    click.echo(f"evaluating the twin ({model.lower()}) on the runs in {datasets} ...")
    api.check_validation_inputs(params_path, datasets, model.lower())  # the inputs first, then --out,
    api.check_new(out_dir, overwrite, "out", folder=True)  # both before the work
    report = api.validation_report(params_path, datasets, model=model.lower(), tolerance=tolerance, bands=bands)
    files = report.write(out_dir, figures=not no_figures, overwrite=overwrite)
    click.echo(report.caption)
    click.echo(report.markdown, nl=False)
    click.echo(report.legend)
    for line in report.repeat_lines:
        click.echo(f"Repeats: {line}")
    for s in report.skipped:
        click.echo(f"skipped {s['file']}: {s['reason']}")
    click.echo(f"wrote {files['html']} (tables table4.md, table4.csv, table4.tex; "
               f"{len(api.figure_files(files))} figures) in {out_dir}")


@report.command(epilog=EXIT_HELP)
@click.option("--out", "out_dir", default="reports/speed", show_default=True, type=click.Path(file_okay=False),
              help="Folder for speed.md, speed.csv, pareto.png and the Figure 8 sweep.")
@click.option("--repeats", type=click.IntRange(1, 50), default=3, show_default=True,
              help="Timing repeats per model and scene (the best is kept).")
@click.option("--tolerance", type=click.FloatRange(min=0.0, min_open=True), default=0.01, show_default=True,
              help="For auto: allowed deviation from CR, relative to the peak stress.")
@click.option("--force", "overwrite", is_flag=True, help="Write into an --out that holds files.")
def speed(out_dir, repeats, tolerance, overwrite):
    """SU, 1R, 3R, CR and auto: time per sample against stress error from CR, per scene.

    Scenes: the three paper specimens under the paper's protocols, and the
    hollow, active and passive cores of Section 3.4 at 3.5 kV.

    \b
    Example:
      rdea-lab report speed --out reports/speed
    """
    headless()
    click.echo(f"timing SU, 1R, 3R, CR and auto (best of {repeats}) ...")
    result = api.speed_study(out_dir, repeats=repeats, tolerance=tolerance, overwrite=overwrite)
    for a in result["auto"]:
        click.echo(f"  {a['scene']}: auto picks {a['model_used']} ({a['auto_reason']})")
    for c in result["reference_check"]:
        if "max_rel_error" in c:
            click.echo(f"  3R check on {c['scene']}: 3R vs fsolve within "
                       f"{c['max_rel_error']:.2g} of the peak stress ({c['converged']}/{c['samples']} samples)")
    for c in result["quadrature_check"]:
        click.echo(f"  reference check on {c['scene']}: CR quadrature ({c['nodes']} nodes) within "
                   f"{c['max_rel_error']:.2g} of the peak stress of {c['check_nodes']} nodes")
    click.echo(f"wrote {result['files']['markdown']}, {result['files']['csv']}, {result['files']['pareto']}, "
               f"{result['files']['figure8']}")
