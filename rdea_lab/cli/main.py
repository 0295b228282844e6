"""``rdea-lab``: the command line. Thin wrappers: parse, call the library, print.

The group imports a command's module only when that command is run or its help shown, so
``rdea-lab --help`` loads click and this file, not numpy, pydantic, pint or xarray.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from ..api import _cli as api
from .._version import __version__
from .errors import EXIT_HELP, die, run
from .lazy import LazyGroup

#: The commands the other modules of rdea_lab.cli define: name -> (module, attribute, short help).
#: ``rdea-lab --help`` lists them from here without importing them; the short help is the first
#: sentence of the command's docstring (tests/cli/test_startup.py checks that it still is).
COMMANDS = {
    "calibrate": ("rdea_lab.cli.calibrate", "calibrate",
                  "Fit the Yeoh and viscoelastic parameters to measured runs (Nelder-Mead, or least squares)."),
    "campaign": ("rdea_lab.cli.runs", "campaign", "Run a whole campaign of experiments (campaigns/*.yaml)."),
    "catalog": ("rdea_lab.cli.catalog", "catalog",
                "The catalogue index of runs: rebuild it from the files, check it against them."),
    "curve": ("rdea_lab.cli.card", "curve", "Quasi-static stress and force against stretch at fixed voltages."),
    "design": ("rdea_lab.cli.design", "design", "Evaluate a design study: roll geometry, bias and operating point "
               "against objectives and constraints."),
    "geometry": ("rdea_lab.cli.card", "geometry",
                 "Ring radii, volume fractions and C0 of a specimen card (Appendix of the paper)."),
    "import": ("rdea_lab.cli.importer", "import_",
               "Import measurements (CSV, TDMS, MATLAB .mat) as datasets of the rdea-lab schema."),
    "ls": ("rdea_lab.cli.runs", "ls_",
           "A table of the runs below FOLDER, from their attributes (with the user's metadata)."),
    "abort": ("rdea_lab.cli.operate", "abort", "End a run in progress now: voltage off, status aborted, every "
              "sample kept."),
    "monitor": ("rdea_lab.cli.monitor", "monitor",
                "A live view of the runs in progress below DIR in the browser, and the catalogue of finished ones."),
    "pause": ("rdea_lab.cli.operate", "pause", "Pause a run in progress: the voltage to 0 at its protocol's ramp "
              "rate, the stretch held."),
    "resume": ("rdea_lab.cli.operate", "resume", "Resume a paused run: back to the plan's setpoints at the pause, "
               "then on with the plan."),
    "plan": ("rdea_lab.cli.plan", "plan", "Plan the voltage that drives the twin along a target force (blocking) "
             "or stretch (against a bias)."),
    "protocol": ("rdea_lab.cli.runs", "protocol", "Inspect protocols."),
    "recover": ("rdea_lab.cli.runs", "recover",
                "Rebuild the dataset of a run whose process died (SIGKILL, power loss) from its journal."),
    "report": ("rdea_lab.cli.report", "report",
               "Reports: the twin against measured runs (validation), and speed against error (speed)."),
    "rig": ("rdea_lab.cli.rig", "rig", "The test rig: serve the built-in emulator."),
    "run": ("rdea_lab.cli.runs", "run", "Run a protocol on a specimen and store the run as one netCDF file."),
    "selfsense": ("rdea_lab.cli.selfsense", "selfsense",
                  "Self-sensing: the stretch estimated from the amplifier current, beside the encoder's."),
    "suggest": ("rdea_lab.cli.suggest", "suggest", "Propose the next experiment: the candidate protocol that would "
                "shrink a target's prediction band most."),
    "show": ("rdea_lab.cli.runs", "show", "Summary of one run (with the user's metadata), and optionally a plot."),
}


@click.group(cls=LazyGroup, lazy_commands=COMMANDS,
             context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100}, epilog=EXIT_HELP)
@click.version_option(__version__, prog_name="rdea-lab")
def cli():
    """rdea-lab: rolled dielectric elastomer actuators, from protocol to validated model.

    \b
    Example:
      rdea-lab geometry specimens/specimen2.yaml
    """


@click.command(epilog=EXIT_HELP)
@click.option("--out", "out_dir", default="rdea-lab-reproduce", show_default=True,
              type=click.Path(file_okay=False), help="Folder for everything reproduce writes (refused if it "
              "holds files, unless --force).")
@click.option("--datasets", "datasets_dir", type=click.Path(file_okay=False),
              help="Folder for the campaign's datasets [default: OUT/datasets] (refused if it holds files, unless "
              "--force).")
@click.option("--campaign", "campaign_path", type=click.Path(dir_okay=False),
              help="Campaign file [default: the packaged paper2021]; must include specimen 2's tensile tests.")
@click.option("--force", "overwrite", is_flag=True,
              help="Write over an output folder (and a --datasets folder) that holds files.")
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
      rdea-lab reproduce --out reports/paper2021 --datasets datasets/paper2021 --force   # the reference report
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
    for line in result.lines():
        click.echo(line)


@click.command(epilog=EXIT_HELP)
@click.option("--samples", default=100_000, show_default=True, type=click.IntRange(1000, 10_000_000),
              help="Samples per model.")
@click.option("--baseline-samples", default=1000, show_default=True, type=click.IntRange(10, 100_000),
              help="Samples for the per-sample fsolve baseline of 3R.")
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(1, 100),
              help="Timing repeats (the median and the spread are reported).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@click.option("--no-vhb", is_flag=True,
              help="Leave out the calibrations on the shared VHB 4910 files (about a minute).")
@click.option("--steps", default=20_000, show_default=True, type=click.IntRange(100, 10_000_000),
              help="Timed calls of the per-sample step (step_latency_us).")
@click.option("--no-compile-probe", is_flag=True,
              help="Leave out numba's cold start (compile_s: two fresh processes, about 30 s).")
@click.option("--reproduce", "reproduce_", is_flag=True,
              help="Instead: rdea-lab reproduce's wall and stage times, warm (--repeat runs after a warm-up) and "
              "cold (one run, empty numba cache and byte code), each in a fresh process "
              "(benchmarks/bench_reproduce.py).")
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


for command in (reproduce, bench):  # this module's own; the others load from COMMANDS
    cli.add_command(command)


def main(argv=None):
    """The command, for a caller that has loaded the CLI already (``python -m rdea_lab.cli.main``); the console
    entry point is `rdea_lab.cli.entry`, which catches signals from before click loads."""
    sys.exit(run(cli, argv, process=True))


if __name__ == "__main__":
    main()
