"""``rdea-lab plan``: a voltage setpoint protocol from a target (the inverse twin)."""

from __future__ import annotations

import json

import click

from ..api import _cli as api
from ..specs import MODELS
from .errors import EXIT_HELP, die


def _tracking_lines(t: dict) -> list[str]:
    lines = [f"tracking over {t['samples']} samples: force error max {t['force_error_max_N'] * 1e3:.3g} mN, "
             f"rms {t['force_error_rms_N'] * 1e3:.3g} mN, mean {t['force_error_mean_N'] * 1e3:+.3g} mN "
             f"({t['relative_max']:.2%} / {t['relative_rms']:.2%} of the peak target force)"]
    if "stretch_error_max" in t:
        lines.append(f"equivalent stretch error against the bias: max {t['stretch_error_max']:.3g}, "
                     f"rms {t['stretch_error_rms']:.3g} ({t['stretch_error_max_of_stroke']:.1%} of the stroke "
                     f"{t['stroke']:.3g})")
    return lines


@click.command("plan", epilog=EXIT_HELP)
@click.option("--target", "target_path", required=True, type=click.Path(dir_okay=False),
              help="Target: YAML (settings and samples) or CSV ('time [s],force [N]' or 'time [s],stretch [-]').")
@click.option("--specimen", "card", required=True, type=click.Path(dir_okay=False), help="Specimen card (YAML).")
@click.option("--params", "params_path", required=True, type=click.Path(dir_okay=False),
              help="The twin's parameter set (YAML).")
@click.option("--model", type=click.Choice(MODELS), default="su", show_default=True,
              help="Quasi-static model of the twin that is inverted.")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Protocol YAML to write.")
@click.option("--force", "overwrite", is_flag=True, help="Overwrite existing outputs.")
@click.option("--stretch", default=None, help="CSV force target only: the fixed stretch (e.g. 1.5).")
@click.option("--bias", default=None,
              help="CSV stretch target only: the bias, e.g. '{kind: spring, stiffness: 200 N/m, preload: 1 N}'.")
@click.option("--sample-rate", default=None, help="CSV target only: the protocol's sample rate [default: 1 kHz].")
@click.option("--approach", default=None, help="CSV target only: the stretch ramp to the target at 0 V [default: 5 s].")
@click.option("--settle", default=None,
              help="CSV target only: the hold before the target, the voltage ramping to its start [default: 2 s].")
@click.option("--run", "backend", type=click.Choice(("twin", "emulator")), default=None,
              help="Also run the plan (twin or the built-in emulated rig) and report its tracking error.")
@click.option("--run-out", type=click.Path(dir_okay=False), default=None,
              help="Dataset of the --run [default: datasets/<specimen>/<plan>-<UTC time>.nc].")
@click.option("--check", "check_run", type=click.Path(dir_okay=False), default=None,
              help="A finished run of this plan (any backend): report its tracking error.")
@click.option("--seed", default=0, show_default=True, type=int, help="Noise seed of the --run.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def plan(target_path, card, params_path, model, out, overwrite, stretch, bias, sample_rate, approach, settle,
         backend, run_out, check_run, seed, as_json):
    """Plan the voltage that drives the twin along a target force (blocking) or stretch (against a bias).

    Past the twin's fold (pull-in, 1R/3R) or the voltage and field limits a
    target is out of reach: refused, naming the sample's time and the range
    the twin reaches there.

    \b
    Examples:
      rdea-lab plan --target targets/spring_stroke.yaml --specimen specimens/specimen2.yaml \\
          --params params/paper2021_table3.yaml --out spring_stroke-plan.yaml --run emulator
      rdea-lab plan --target targets/blocking_ramp.csv --stretch 1.5 --specimen specimens/specimen2.yaml \\
          --params params/paper2021_table3.yaml --out blocking-plan.yaml
    """
    if backend and check_run:
        die("plan: give --run or --check, not both")
    if run_out and not backend:
        die("--run-out: only with --run")
    api.check_new(out, overwrite, "--out")  # before the planning; the --run's dataset too
    if backend and run_out:
        api.check_outputs([run_out], overwrite)
    target = api.load_target(target_path, stretch=stretch, bias=bias, sample_rate=sample_rate, approach=approach,
                             settle=settle)
    tp = api.plan_target(target, card, params_path, model)
    api.write_protocol(tp, out, overwrite)
    result = {"protocol": out, **tp.summary()}
    if backend:
        tracked = api.track_target(tp, card, params_path, model, backend=backend, out=run_out, overwrite=overwrite,
                                   seed=seed, command="rdea-lab plan")
        result.update(run=str(tracked["run"].encoding.get("source", "")), backend=backend,
                      tracking=tracked["tracking"])
    elif check_run:
        result.update(run=check_run, tracking=api.tracking_error(check_run, tp))
    if as_json:
        click.echo(json.dumps(result, indent=2))
        return
    click.echo(f"{out}: {tp.describe()}")
    if "tracking" in result:
        click.echo(f"run {result['run']}" + (f" ({backend})" if backend else ""))
        for line in _tracking_lines(result["tracking"]):
            click.echo("  " + line)
