"""``rdea-lab geometry`` and ``rdea-lab curve``: what a specimen card and a parameter set give, without a run.

numpy and the spec loaders are imported where used, so that ``rdea-lab curve --help`` loads neither.
"""

from __future__ import annotations

import csv
import io
import json
import math

import click

from ..api import _cli as api
from ..specs import MODELS
from .errors import EXIT_HELP, die

#: Table 1 of [1]: the datasheet permittivity of the silicone.
DEFAULT_EPS_R = 2.8


def _jsonable(value):
    import numpy as np

    def convert(value):
        if isinstance(value, np.ndarray):
            return [convert(v) for v in value.tolist()]
        if isinstance(value, float) and not math.isfinite(value):
            return None  # JSON has no NaN: null marks a sample without equilibrium
        if isinstance(value, list):
            return [convert(v) for v in value]
        if isinstance(value, dict):
            return {k: convert(v) for k, v in value.items()}
        return value

    return convert(value)


@click.command(epilog=EXIT_HELP)
@click.argument("card", type=click.Path(dir_okay=False))
@click.option("--params", "params_path", type=click.Path(dir_okay=False),
              help="Parameter set whose eps_r gives C0 (default: eps_r = 2.8, Table 1).")
@click.option("--eps-r", type=float, default=None, help="Relative permittivity for C0 [-].")
@click.option("--json", "as_json", is_flag=True, help="Print JSON (SI units).")
def geometry(card, params_path, eps_r, as_json):
    """Ring radii, volume fractions and C0 of a specimen card (Appendix of the paper).

    \b
    Example:
      rdea-lab geometry specimens/specimen2.yaml --json
    """
    from ..specs import load_params, load_specimen

    spec = load_specimen(card)
    if params_path and eps_r is not None:
        die("geometry: give --params or --eps-r, not both")
    if params_path:
        eps_r = load_params(params_path).eps_r
    elif eps_r is None:
        eps_r = DEFAULT_EPS_R
    elif not (eps_r >= 1.0 and math.isfinite(eps_r)):
        die(f"--eps-r: {eps_r} is not a relative permittivity; allowed: a finite number >= 1")
    values = api.geometry(card).as_dict(eps_r)
    if spec.kind == "strip":
        if as_json:
            click.echo(json.dumps({"id": spec.id, "kind": "strip", **values}, indent=2))
            return
        click.echo(f"{spec.id} (strip, eps_r = {eps_r:g})")
        for k in ("length", "width", "thickness", "electrode_length", "electrode_width"):
            click.echo(f"  {k:<17}{values[k] * 1e3:10.4f} mm")
        click.echo(f"  {'C0':<17}{values['C0'] * 1e12:10.2f} pF")
        return
    keys = ("Ri", "Rie", "Roe", "Ro", "eta_a", "eta_b", "eta_c", "alpha_e1", "C0")
    if as_json:
        click.echo(json.dumps({"id": spec.id, **{k: values[k] for k in keys}, "eps_r": eps_r}, indent=2))
        return
    click.echo(f"{spec.id} ({spec.form} form, eps_r = {eps_r:g})")
    for k in ("Ri", "Rie", "Roe", "Ro"):
        click.echo(f"  {k:<9}{values[k] * 1e3:10.4f} mm")
    for k in ("eta_a", "eta_b", "eta_c", "alpha_e1"):
        click.echo(f"  {k:<9}{values[k]:10.4f}")
    click.echo(f"  {'C0':<9}{values['C0'] * 1e12:10.2f} pF")


def _parse_stretch(text: str):
    import numpy as np

    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        die(f"--stretch: {text!r} is not START:STOP:N (e.g. 1:1.5:51)")
    if not (math.isfinite(start) and math.isfinite(stop)) or start < 1.0 or stop < start:
        die(f"--stretch: {text!r}: need 1 <= START <= STOP (the roll stays in tension)")
    if not 1 <= n <= 10_000_000:
        die(f"--stretch: {text!r}: N = {n} must be between 1 and 10000000")
    return np.linspace(start, stop, n)


def _parse_voltages(text: str) -> list[float]:
    from ..specs import parse_quantity

    out = []
    for item in text.split(","):
        item = item.strip()
        try:
            value = float(item)  # a bare number is in volts
        except ValueError:
            value = parse_quantity(item, "voltage", source="command line", field="--voltage")
        if not math.isfinite(value):
            die(f"--voltage: {item!r} is not a finite voltage")
        out.append(value)
    return out


@click.command(epilog=EXIT_HELP)
@click.option("--specimen", "card", required=True, type=click.Path(dir_okay=False), help="Specimen card (YAML).")
@click.option("--params", "params_path", required=True, type=click.Path(dir_okay=False), help="Parameter set (YAML).")
@click.option("--model", type=click.Choice(MODELS, case_sensitive=False), default="su",
              show_default=True, help="Quasi-static model.")
@click.option("--stretch", "stretch_text", default="1:1.5:51", show_default=True,
              help="Stretches START:STOP:N.")
@click.option("--voltage", "voltage_text", default="0", show_default=True,
              help="Voltages, comma-separated; bare numbers in V, or with a unit ('2.6 kV').")
@click.option("--json", "as_json", is_flag=True, help="Print JSON (SI units; null where no equilibrium).")
@click.option("--csv", "as_csv", is_flag=True, help="Print CSV, one row per (voltage, stretch).")
@click.option("--no-field-check", is_flag=True,
              help="Compute past a field estimate of 300 V/um (where any real membrane has broken down).")
def curve(card, params_path, model, stretch_text, voltage_text, as_json, as_csv, no_field_check):
    """Quasi-static stress and force against stretch at fixed voltages.

    \b
    Example:
      rdea-lab curve --specimen specimens/passive_core.yaml --params params/rizzello2020.yaml \\
          --model 3r --stretch 1:1.75:76 --voltage 0,3.5kV --json
    """
    from ..specs import load_params, load_specimen

    if as_json and as_csv:
        die("curve: give --json or --csv, not both")
    stretch = _parse_stretch(stretch_text)
    voltages = _parse_voltages(voltage_text)
    result = api.quasi_static_curves(load_specimen(card), load_params(params_path), model.lower(), stretch, voltages,
                                     max_field=None if no_field_check else api.CURVE_MAX_FIELD)
    if as_json:
        out = {"model": result.model, "specimen": result.specimen, "parameters": result.parameters,
               "curves": [{k: getattr(c, k) for k in ("voltage", *api.CURVE_FIELDS, "summary")} for c in result.curves]}
        click.echo(json.dumps(_jsonable(out)))
        return
    if as_csv:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["voltage_V", "stretch", "sigma1_Pa", "force_N", "lambda2b", "capacitance_F", "converged"])
        for c in result.curves:
            for i in range(stretch.size):
                w.writerow([c.voltage, repr(float(c.stretch[i])), repr(float(c.sigma1[i])),
                            repr(float(c.force[i])), repr(float(c.lambda2b[i])),
                            repr(float(c.capacitance[i])), int(c.converged[i])])
        click.echo(buf.getvalue(), nl=False)
        return
    click.echo(f"{result.specimen}, {result.parameters}, model {model.lower()}")
    for c in result.curves:
        click.echo(f"voltage {c.voltage:g} V: {c.summary}")
        click.echo(f"  {'stretch':>8} {'sigma1/MPa':>11} {'force/N':>9} {'lambda2b':>9} {'C/pF':>9}")
        step = max(1, stretch.size // 10)
        for i in list(range(0, stretch.size, step)) + ([stretch.size - 1] if (stretch.size - 1) % step else []):
            click.echo(f"  {c.stretch[i]:8.4f} {c.sigma1[i] / 1e6:11.5f} {c.force[i]:9.4f} "
                       f"{c.lambda2b[i]:9.5f} {c.capacitance[i] * 1e12:9.2f}")
