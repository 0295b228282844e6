"""``rdea-lab suggest``: the next experiment to run."""

from __future__ import annotations

import click

from ..api import _cli as api
from .errors import EXIT_HELP


def _numbers(text: str, option: str) -> tuple[float, ...]:
    from ..specs import SpecError

    try:
        values = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise SpecError("arguments", option, f"{text!r}; allowed: comma-separated numbers") from None
    if not values:
        raise SpecError("arguments", option, "none given; allowed: comma-separated numbers")
    return values


@click.command("suggest", epilog=EXIT_HELP)
@click.option("--params", "params_path", required=True, type=click.Path(dir_okay=False),
              help="Calibration record (a parameter file written by rdea-lab calibrate --out): set, model, covariance.")
@click.option("--specimen", "card", required=True, type=click.Path(dir_okay=False), help="Specimen card (YAML).")
@click.option("--target", "scene", type=click.Path(dir_okay=False), default=None,
              help="The scene to predict better: a protocol YAML [default: none, D-optimal].")
@click.option("--out", type=click.Path(dir_okay=False), default=None,
              help="Write the winning candidate here as a protocol YAML.")
@click.option("--force", "overwrite", is_flag=True, help="Overwrite an existing --out.")
@click.option("--stretches", default="1.5,2,2.5,3", show_default=True, help="Peak stretches of the candidates.")
@click.option("--rates", default="0.01,0.05,0.25", show_default=True,
              help="Stretch rates of the loading-unloading candidates [1/s].")
@click.option("--holds", default="60,300,1200", show_default=True, help="Hold durations of the step-and-holds [s].")
@click.option("--sample-rate", type=click.FloatRange(min=0.01, max=1e5), default=10.0, show_default=True,
              help="Sample rate of the candidates [Hz].")
@click.option("--max-stretch", default=None,
              help="The rig's stretch limit [default: the target's limits, or rdea-lab's default 2].")
@click.option("--max-voltage", default=None, help="The rig's voltage limit, e.g. '3 kV' [default: as --max-stretch].")
@click.option("--max-field", default=None, help="The rig's field limit, e.g. '80 V/um' [default: as --max-stretch].")
@click.option("--top", type=click.IntRange(min=1), default=10, show_default=True, help="Candidates shown.")
def suggest(params_path, card, scene, out, overwrite, stretches, rates, holds, sample_rate, max_stretch, max_voltage,
            max_field, top):
    """Propose the next experiment: the candidate protocol that would shrink a target's prediction band most.

    The candidates are loading-unloading ramps at --rates and step-and-holds of --holds (ramps at
    0.25 /s) to each of --stretches, those the rig's limits allow (checked as rdea-lab run checks a
    plan). Ranked by the linearized (Fisher information) shrink of the --target's prediction band, or
    without a target of the parameter covariance's determinant (D-optimal); see docs/guide/suggest.md.

    \b
    Example:
      rdea-lab suggest --params vhb.yaml --specimen specimens/vhb4910_strip.yaml \\
          --target hold_2.5.yaml --max-stretch 3 --out next.yaml
    """
    from ..specs.limits import Limits

    if out is not None:
        api.check_new(out, overwrite, "--out")  # before the ranking
    given = {k: v for k, v in (("max_stretch", max_stretch), ("max_voltage", max_voltage),
                                ("max_field", max_field)) if v is not None}
    limits = None
    if given:
        base = Limits() if scene is None else api.load_scene(scene).limits
        limits = Limits.from_options({**base.model_dump(), **given})
    result = api.suggest(params_path, card, scene=scene, limits=limits, stretches=_numbers(stretches, "--stretches"),
                  rates=_numbers(rates, "--rates"), holds=_numbers(holds, "--holds"), sample_rate=sample_rate)
    click.echo(result.table(top))
    best = result.rows[0]
    if result.criterion == "scene":
        why = (f"it shrinks the predicted band of {result.scene} by {100 * best['shrink']:.1f} % "
               f"(sd {best['band_before_N']:.3g} N -> {best['band_after_N']:.3g} N)")
    else:
        why = f"it shrinks the parameter standard deviations by {100 * best['shrink']:.1f} % (geometric mean)"
    click.echo(f"suggested: {result.best.name} ({result.best.spec.description}): {why}")
    if result.refused:
        click.echo(f"outside the limits: {len(result.refused)} candidates (e.g. {result.refused[0]})")
    if out is not None:
        click.echo(f"wrote {api.write_suggestion(result, out, overwrite)}")
