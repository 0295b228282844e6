"""``rdea-lab``: the command line. Thin wrappers: parse, call the library, print."""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path

import click
import numpy as np

from .. import api
from .._version import __version__
from ..specs import MODELS, load_params, load_specimen, parse_quantity
from . import calibrate as calibrate_cmd
from . import design as design_cmd, importer, plan as plan_cmd, report, rig, runs, selfsense
from .errors import EXIT_HELP, die, run

#: Table 1 of [1]: the datasheet permittivity of the silicone.
DEFAULT_EPS_R = 2.8


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100}, epilog=EXIT_HELP)
@click.version_option(__version__, prog_name="rdea-lab")
def cli():
    """rdea-lab: rolled dielectric elastomer actuators, from protocol to validated model.

    \b
    Example:
      rdea-lab geometry specimens/specimen2.yaml
    """


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()]
    if isinstance(value, float) and not math.isfinite(value):
        return None  # JSON has no NaN: null marks a sample without equilibrium
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    return value


@click.command()
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


def _parse_stretch(text: str) -> np.ndarray:
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


@click.command()
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
    if as_json and as_csv:
        die("curve: give --json or --csv, not both")
    stretch = _parse_stretch(stretch_text)
    voltages = _parse_voltages(voltage_text)
    result = api.quasi_static_curves(load_specimen(card), load_params(params_path), model.lower(), stretch, voltages,
                                     max_field=None if no_field_check else api.CURVE_MAX_FIELD)
    if as_json:
        out = {"model": result["model"], "specimen": result["specimen"], "parameters": result["parameters"],
               "curves": [{k: c[k] for k in ("voltage", *api.CURVE_FIELDS, "summary")} for c in result["curves"]]}
        click.echo(json.dumps(_jsonable(out)))
        return
    if as_csv:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["voltage_V", "stretch", "sigma1_Pa", "force_N", "lambda2b", "capacitance_F", "converged"])
        for c in result["curves"]:
            for i in range(stretch.size):
                w.writerow([c["voltage"], repr(float(c["stretch"][i])), repr(float(c["sigma1"][i])),
                            repr(float(c["force"][i])), repr(float(c["lambda2b"][i])),
                            repr(float(c["capacitance"][i])), int(c["converged"][i])])
        click.echo(buf.getvalue(), nl=False)
        return
    click.echo(f"{result['specimen']}, {result['parameters']}, model {model.lower()}")
    for c in result["curves"]:
        click.echo(f"voltage {c['voltage']:g} V: {c['summary']}")
        click.echo(f"  {'stretch':>8} {'sigma1/MPa':>11} {'force/N':>9} {'lambda2b':>9} {'C/pF':>9}")
        step = max(1, stretch.size // 10)
        for i in list(range(0, stretch.size, step)) + ([stretch.size - 1] if (stretch.size - 1) % step else []):
            click.echo(f"  {c['stretch'][i]:8.4f} {c['sigma1'][i] / 1e6:11.5f} {c['force'][i]:9.4f} "
                       f"{c['lambda2b'][i]:9.5f} {c['capacitance'][i] * 1e12:9.2f}")


@click.command(epilog=EXIT_HELP)
@click.option("--out", "out_dir", default="rdea-lab-reproduce", show_default=True,
              type=click.Path(file_okay=False), help="Folder for everything reproduce writes (refused if it "
              "holds files, unless --force).")
@click.option("--datasets", "datasets_dir", type=click.Path(file_okay=False),
              help="Folder for the campaign's datasets [default: OUT/datasets].")
@click.option("--campaign", "campaign_path", type=click.Path(dir_okay=False),
              help="Campaign file [default: the packaged paper2021]; must include specimen 2's tensile tests.")
@click.option("--force", "overwrite", is_flag=True, help="Write over an output folder that holds files.")
@click.option("--no-speed", is_flag=True, help="Skip the speed-against-error study.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--pdf", is_flag=True, help="A PDF beside every PNG figure (vector, for a paper).")
@click.option("--workers", type=click.IntRange(1, 64), default=None,
              help="Processes [default: the cores, at most 4]; 1 runs every stage in this process in turn.")
def reproduce(out_dir, datasets_dir, campaign_path, overwrite, no_speed, quiet, pdf, workers):
    """The paper's campaign end to end, on the built-in emulated rig.

    Runs the experiments of Section 4.2 on the three specimens (emulator), stores
    the datasets, calibrates the SU model on specimen 2, writes the Table 4
    analogue with its figures, the speed-against-error study, and Table 2 and
    Section 3.4 (Figures 5-8); prints the table, where everything is and the
    time of each stage. It reads only the packaged inputs and writes only OUT.

    \b
    Example:
      rdea-lab reproduce
      rdea-lab reproduce --out reports/paper2021 --datasets datasets/paper2021 --pdf --force   # the reference report
    """
    from .errors import headless

    headless()
    out = Path(out_dir)

    def bar(total, label):
        if quiet or not sys.stderr.isatty():
            import contextlib
            return contextlib.nullcontext(type("NoBar", (), {"update": staticmethod(lambda n: None)})())
        return click.progressbar(length=total, label=label, file=sys.stderr)

    result = api.reproduce(out, datasets=datasets_dir, campaign=campaign_path, speed=not no_speed,
                           overwrite=overwrite, echo=click.echo, progress_factory=bar, pdf=pdf, workers=workers)
    v = result["validation"]
    click.echo("")
    click.echo(f"Table 4 analogue ({v['origin']})")
    click.echo(v["markdown"], nl=False)
    click.echo(v["legend"] + "\n")
    click.echo("outputs:")
    click.echo(f"  index           {result['index']} (links to everything below)")
    click.echo(f"  datasets        {result['datasets']}/<specimen>/<protocol>.nc")
    click.echo(f"  parameters      {result['calibration']['params']} (+ .history.csv, .history.png)")
    click.echo(f"  validation      {v['files']['html']} (table4.md/.csv/.tex, figures)")
    if "speed" in result:
        click.echo(f"  speed vs error  {out / 'speed'}/speed.md, pareto.png, figure8_sweep.png")
    click.echo(f"  models          {out / 'models'}/models.md, figure5-8*.png")
    click.echo("time by stage:" + (f" ({result['workers']} processes: the campaign, calibration and models "
                                   "overlap)" if result["workers"] > 1 else ""))
    for name, seconds in result["stages"]:
        click.echo(f"  {name:<15} {seconds:6.1f} s")
    click.echo(f"  {'total':<15} {result['seconds']:6.1f} s")


@click.command()
@click.option("--samples", default=100_000, show_default=True, type=click.IntRange(1000, 10_000_000),
              help="Samples per model.")
@click.option("--baseline-samples", default=1000, show_default=True, type=click.IntRange(10, 100_000),
              help="Samples for the per-sample fsolve baseline of 3R.")
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(1, 100),
              help="Timing repeats (the median and the spread are reported).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@click.option("--no-vhb", is_flag=True, help="Leave out the calibrations on the shared VHB 4910 files (about a minute).")
@click.option("--steps", default=20_000, show_default=True, type=click.IntRange(100, 10_000_000),
              help="Timed calls of the per-sample step (step_latency_us).")
@click.option("--no-compile-probe", is_flag=True,
              help="Leave out numba's cold start (compile_s: two fresh processes, about 30 s).")
@click.option("--reproduce", "reproduce_", is_flag=True,
              help="Instead: rdea-lab reproduce's wall and stage times, warm (--repeat runs after a warm-up) and "
              "cold (one run, empty numba cache and byte code), each in a fresh process (benchmarks/bench_reproduce.py).")
def bench(samples, baseline_samples, repeat, as_json, no_vhb, steps, no_compile_probe, reproduce_):
    """Speed of the SU, 1R, 3R and CR solvers, of 3R against an fsolve baseline, of calibration, of the
    compiled kernels against the numpy reference and of the per-sample step.

    \b
    Example:
      rdea-lab bench --json
    """
    folder = api.benchmarks_dir()
    if folder is None:
        die("bench: benchmarks/bench_models.py not found; run from a source checkout (pip install -e .)")
    sys.path.insert(0, str(folder))
    if reproduce_:
        import bench_reproduce  # noqa: E402  (lives in benchmarks/, outside the package)

        result = bench_reproduce.run(repeat=repeat, cold=0 if no_compile_probe else 1)
        click.echo(json.dumps(result, indent=2) if as_json else bench_reproduce.format_text(result))
        return
    import bench_models  # noqa: E402  (lives in benchmarks/, outside the package)

    result = bench_models.run(samples=samples, baseline_samples=baseline_samples, repeat=repeat, vhb=not no_vhb,
                              steps=steps, compile_probe=not no_compile_probe)
    if as_json:
        click.echo(json.dumps(result, indent=2))
    else:
        click.echo(bench_models.format_text(result))


for command in (geometry, curve, reproduce, bench, runs.run, runs.recover, runs.ls_, runs.show, runs.protocol,
                runs.campaign, rig.rig, calibrate_cmd.calibrate, report.report, importer.import_, plan_cmd.plan,
                selfsense.selfsense, design_cmd.design):
    cli.add_command(command)


def main(argv=None):
    """Console entry point."""
    sys.exit(run(cli, argv))


if __name__ == "__main__":
    main()
