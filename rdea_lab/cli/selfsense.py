"""``rdea-lab selfsense``: the stretch from the amplifier current beside the encoder's."""

from __future__ import annotations

import click

from ..api import _cli as api
from ..specs import MODELS
from .errors import EXIT_HELP, headless


@click.command(epilog=EXIT_HELP)
@click.argument("run_path", metavar="RUN.nc", type=click.Path(dir_okay=False))
@click.option("--params", "params_path", required=True, type=click.Path(dir_okay=False),
              help="Parameter set (YAML): eps_r gives C0; 1R, 3R and CR use the whole material.")
@click.option("--model", type=click.Choice(MODELS, case_sensitive=False), default="su", show_default=True,
              help="Capacitance model C(lambda1, v) inverted.")
@click.option("--tare", type=click.Choice(("rest", "reference", "none")), default="rest", show_default=True,
              help="rest: one factor on C0 from the run's first rest (encoder stretch, 0 V); reference: gain and "
                   "offset from --reference; none: nothing fitted.")
@click.option("--reference", "reference", type=click.Path(dir_okay=False),
              help="A 0 V run of the same specimen with current and probe (protocols/selfsense_0V.yaml): the "
                   "model's capacitance is fitted to it (implies --tare reference).")
@click.option("--estimator", type=click.Choice(("secant", "small-signal")), default="secant", show_default=True,
              help="secant: charge over voltage (what the models' C is); small-signal: dq/dv at the probe.")
@click.option("--out", "out_path", type=click.Path(dir_okay=False),
              help="Dataset to write [default: RUN.selfsense.nc beside the run].")
@click.option("--force", "overwrite", is_flag=True, help="Overwrite an existing --out.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Write a PNG (or .pdf, .svg, ...): both stretches and the error against time.")
def selfsense(run_path, params_path, model, tare, reference, estimator, out_path, overwrite, plot_path):
    """Self-sensing: the stretch estimated from the amplifier current, beside the encoder's.

    The run must have recorded the current with a probe on the voltage (a
    protocol with `measure: [force, current]` and `probe: {amplitude: 20 V,
    frequency: 200 Hz}`, e.g. protocols/selfsense_2.6kV.yaml). Writes the
    estimated capacitance and stretch, the error (absolute and in % of the
    run's stretch range) and prints one line: the max and rms error over the
    samples where the estimate is valid and the roll taut.

    \b
    Example:
      rdea-lab run protocols/selfsense_2.6kV.yaml --specimen specimens/specimen2.yaml --backend emulator \\
          --out runs/sense2.nc
      rdea-lab selfsense runs/sense2.nc --params params/paper2021_table3.yaml --out runs/sense2.selfsense.nc
      rdea-lab selfsense runs/sense2.nc --params params/paper2021_table3.yaml --reference runs/sense2-0V.nc
    """
    if plot_path:
        api.check_figure(plot_path)
    if out_path is None:
        out_path = str(run_path)[:-3] + ".selfsense.nc" if str(run_path).endswith(".nc") else str(run_path) + \
            ".selfsense.nc"
    result = api.selfsense_run(run_path, params_path, model.lower(), tare=tare, estimator=estimator, out=out_path,
                               overwrite=overwrite, reference=reference)
    click.echo(f"{result.summary()}; written {out_path}")
    if plot_path:
        headless()
        api.plot_selfsense(result.dataset, plot_path)
