"""``rdea-lab calibrate``."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..specs import load_params
from .errors import die

KINDS = ("tensile", "blocking", "capacitance", "custom")


def register(cli: click.Group) -> None:
    @cli.command()
    @click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=False))
    @click.option("--model", type=click.Choice(["su", "1r", "3r", "auto"], case_sensitive=False), default="su",
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
                  help=f"For folders: which runs, comma-separated from {', '.join(KINDS)}.")
    @click.option("--metric", type=click.Choice(["rms", "max"]), default="rms", show_default=True,
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
        from ..calibration import calibrate as fit, find_runs, initial_guess, load_run
        from ..calibration.record import write_record
        from ..physics.selection import select_model
        from ..specs import ViscoBranch

        kinds = tuple(k.strip() for k in kinds_text.split(",") if k.strip())
        bad = [k for k in kinds if k not in KINDS]
        if bad or not kinds:
            die(f"--protocol-kind: {kinds_text!r}; allowed: comma-separated from {', '.join(KINDS)}")
        for p in inputs:
            if not Path(p).exists():
                die(f"{p}: no such dataset or folder")
        paths = find_runs(inputs, kinds)
        if not paths:
            die(f"{', '.join(inputs)}: no complete runs of kind {', '.join(kinds)} found")
        try:
            runs = [load_run(p) for p in paths]
        except (KeyError, OSError, ValueError) as exc:
            die(f"cannot fit: {exc}")
        init = load_params(init_path) if init_path else None
        eps = eps_r if eps_r is not None else (init.eps_r if init else 2.8)
        if not eps >= 1.0:
            die(f"--eps-r: {eps} is not a relative permittivity; allowed: >= 1")
        M = M if M is not None else (init.M if init else 1)
        if init is None:
            start = initial_guess(runs, M, eps)
        else:
            branches = list(init.branches[:M])
            while len(branches) < M:  # more branches than the start has: slower ones, same stiffness
                last = branches[-1] if branches else ViscoBranch(k=init.C10, eta=init.C10)
                branches.append(ViscoBranch(k=last.k, eta=last.eta * 30))
            start = init.replace(eps_r=eps, branches=tuple(branches))
        names = ["C10", "C20", "C30", *[f"{p}_v{j}" for j in range(1, M + 1) for p in ("k", "eta")], "eta_v0"]
        if free_text:
            free = [f.strip() for f in free_text.split(",") if f.strip()]
            unknown = [f for f in free if f not in names]
            if unknown:
                die(f"--free: {', '.join(unknown)} unknown; allowed: {', '.join(names)}")
        else:
            free = names
        model = model.lower()
        if model == "auto":
            import numpy as np
            geoms = {r.specimen: r.geom for r in runs}
            choices = [select_model(g, start, np.concatenate([r.stretch for r in runs if r.specimen == s]),
                                    np.concatenate([r.voltage for r in runs if r.specimen == s]))
                       for s, g in geoms.items()]
            order = ("su", "1r", "3r")
            model = max((c.model for c in choices), key=order.index)
            click.echo(f"model auto: {model} ({'; '.join(c.reason for c in choices)})")
        click.echo(f"calibrating {', '.join(free)} ({model}, {metric}) on {len(runs)} runs: "
                   + ", ".join(f"{r.specimen}/{r.protocol}" for r in runs))
        show = not quiet and sys.stderr.isatty()

        def progress(n, best, elapsed):
            if show:
                click.echo(f"\r  evaluations {n:6d}  best {best:.6e}  elapsed {elapsed:6.1f} s", nl=False, err=True)

        try:
            if init is None and M > 1:  # from the data: grow the branches one by one (they merge otherwise)
                from ..calibration.fit import calibrate_growing
                result = calibrate_growing(runs, initial_guess(runs, 1, eps), M, model=model, free=free, metric=metric,
                                           max_evals=max_evals, max_time=max_time, progress=progress)
            else:
                result = fit(runs, start, model=model, free=free, metric=metric, max_evals=max_evals,
                             max_time=max_time, progress=progress)
        except ValueError as exc:
            die(f"cannot fit: {exc}")
        if show:
            click.echo("", err=True)
        out = Path(out_path)
        files = write_record(result, runs, out, name=name or out.stem.replace(" ", "_"))
        click.echo(f"{result.message}; objective {result.objective:.4e} after {result.nfev} evaluations, "
                   f"{result.restarts} restarts, {result.wall_time:.2f} s")
        for p in result.parameters:
            v = result.values[p.name]
            se = result.stderr.get(p.name)
            flags = [f for f, names_ in (("at bound", result.at_bound), ("unmoved", result.unmoved),
                                         ("not identifiable", result.unidentifiable)) if p.name in names_]
            scale = 1e3
            unit = "kPa" if p.unit == "Pa" else "kPa s"
            click.echo(f"  {p.name:<7} {v / scale:12.5g} {unit:<6}" + (f" +- {se / scale:.3g}" if p.free and se == se else "")
                       + ("" if p.free else "  (fixed)") + (f"  [{', '.join(flags)}]" if flags else ""))
        for g in result.runs:
            click.echo(f"  {g['specimen']}/{g['protocol']}: rms {g['rms_error_N']:.4g} N, R2 {g['r2']:.5f}, "
                       f"max rel. error {100 * g['max_rel_error']:.2f} %")
        click.echo(f"  AIC {result.aic:.1f}, BIC {result.bic:.1f}")
        click.echo(f"wrote {files['params']}, {files['history']}, {files['plot']}")
