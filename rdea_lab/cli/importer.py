"""``rdea-lab import``: measurements from other tools as rdea-lab datasets."""

from __future__ import annotations

import shlex
import sys

import click

from ..api import _cli as api
from ..specs.importing import FORMATS, KINDS, MIN_STRETCH
from .errors import EXIT_HELP


@click.command(name="import", epilog=EXIT_HELP)
@click.argument("files", nargs=-1, required=True, type=click.Path())
@click.option("--format", "fmt", required=True, metavar="|".join(FORMATS),
              help="How the files are written: " + ", ".join(FORMATS) + ".")
@click.option("--map", "map_text", required=True, metavar="KEY=COL,...",
              help="Columns of time, position, force [, voltage, capacitance]: a name or a 0-based index "
                   "(CSV: a header name; TDMS: group/channel or a channel's name; .mat: a vector's name or "
                   "var[:, j] for column j of a 2-D array).")
@click.option("--units", "units_text", metavar="KEY=UNIT,...",
              help="Units of the mapped columns (e.g. position=mm,force=N); default: the file's units row, "
                   "header '(unit)' or TDMS unit_string.")
@click.option("--specimen", "card_path", required=True, type=click.Path(dir_okay=False),
              help="Specimen card (YAML); its unstretched length L1 gives stretch = 1 + position / L1.")
@click.option("--protocol-kind", "kind", required=True, type=click.Choice(KINDS, case_sensitive=False),
              help="What the test was.")
@click.option("--name", "protocol_name", help="Protocol name [default: the file's stem].")
@click.option("--encoding", help="CSV text encoding [default: the first of utf-8, utf-8-sig, gbk, cp1252, "
                                 "latin-1 that decodes the file].")
@click.option("--credit", help="Where the data come from (attribute source_credit).")
@click.option("--min-stretch", type=click.FloatRange(0.5, 1.0), default=MIN_STRETCH, show_default=True,
              help="Lowest stretch taken as noise at zero load; a lower one is an error.")
@click.option("--skip-start", type=click.FloatRange(0.0, None), default=0.0, show_default=True, metavar="SECONDS",
              help="Leave out the first SECONDS of every file (e.g. a machine's start-up spike); the rest keeps "
                   "its times, the dataset records what was left out.")
@click.option("--out", "out_path", type=click.Path(),
              help="A .nc file (one input) or a folder [default: datasets/imported/<specimen>/<stem>.nc].")
@click.option("--force", "overwrite", is_flag=True, help="Overwrite existing datasets.")
def import_(files, fmt, map_text, units_text, card_path, kind, protocol_name, encoding, credit, min_stretch,
            skip_start, out_path, overwrite):
    """Import measurements (CSV, TDMS, MATLAB .mat) as datasets of the rdea-lab schema.

    Positions are converted to SI and to the stretch 1 + position / L1;
    voltage is 0 and capacitance NaN where not mapped; setpoints are NaN.
    Every file is checked before any is written.

    \b
    Examples:
      # a VHB 4910 strip loaded to stretch 1.5 at three rates; the units row
      # (s),(mm),(N) gives the units. Data from the public repository
      # Chongran-Zhao/VHB4910_data (GitHub), credited in the datasets:
      rdea-lab import ../shared/data/vhb4910/*.csv --format csv \\
          --map time=0,position=1,force=2 --protocol-kind tensile \\
          --specimen specimens/vhb4910_strip.yaml \\
          --credit "github.com/Chongran-Zhao/VHB4910_data"
      rdea-lab import run.tdms --format tdms --map time=Rig/t,position=Rig/x,force=load \\
          --units position=um --specimen specimens/specimen2.yaml --protocol-kind tensile
      rdea-lab import run.mat --format mat --out datasets/run.nc \\
          --map "time=t,position=data[:, 0],force=data[:, 1]" --units time=s,position=mm,force=N \\
          --specimen specimens/specimen2.yaml --protocol-kind custom
    """
    from ..specs import load_specimen  # here: the module loads for --help too

    fmt = fmt.lower()  # choices in any case, as everywhere on the command line
    api.check_format(fmt, files[0])
    mapping = api.parse_map(map_text)
    units = api.parse_units(units_text, mapping)
    card = load_specimen(card_path)
    api.geometry(card_path)
    options = api.ImportOptions(fmt, mapping, units, kind, protocol_name, encoding, credit, min_stretch, skip_start)
    command = "rdea-lab " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    for source, target, ds in api.import_files(files, card, options, out_path, overwrite, command):
        t = ds["time"].values
        lam, f = ds["stretch"].values, ds["force"].values
        click.echo(f"{source} -> {target}: {t.size} samples over {t[-1] - t[0]:.6g} s at "
                   f"{ds.attrs['sample_rate']:.6g} Hz, stretch {lam.min():.5f}..{lam.max():.5f}, "
                   f"force {f.min():.5g}..{f.max():.5g} N")
