"""``rdea-lab calibrate``."""

from __future__ import annotations

import functools
import sys
import time
import types

import click

from ..api import _cli as api
from ..specs import MODEL_CHOICES
from .errors import EXIT_HELP, headless


class FitProgress:
    """A fit's progress on stderr, fed as the library's monitor (``progress``, ``stage``; the folds'
    ``fold_done``): on a terminal one line redrawn in place
    (as often as the library reports, twice a second), otherwise a line every `every` seconds (a log
    stays short); a line per growth stage and per fold, and a final line per fit."""

    def __init__(self, enabled: bool = True, every: float = 10.0, clock=time.monotonic):
        self.enabled, self.every, self.clock = enabled, every, clock
        self.tty = sys.stderr.isatty()
        self.width = 0  # of the line drawn in place, 0 when none is showing
        self.last = -float("inf")

    @staticmethod
    def status(evaluations, best, elapsed) -> str:
        return f"  evaluations {evaluations:6d}  best {best:.6e}  elapsed {elapsed:6.1f} s"

    def __call__(self, evaluations, best, elapsed):
        """The monitor's ``progress(evaluations, best, elapsed)``."""
        if not self.enabled:
            return
        text = self.status(evaluations, best, elapsed)
        if self.tty:
            click.echo("\r" + text.ljust(self.width), nl=False, err=True)
            self.width = len(text)
        elif self.clock() - self.last >= self.every:
            self.last = self.clock()
            click.echo(text, err=True)

    def end_line(self):
        """End a line drawn in place (before something is printed on stdout, the same terminal)."""
        if self.width:
            click.echo("", err=True)
            self.width = 0

    def line(self, text: str):
        """A line of its own (a stage, a fold), below a line drawn in place."""
        if not self.enabled:
            return
        if self.width:
            click.echo("\r" + text.ljust(self.width), err=True)
            self.width = 0
        else:
            click.echo(text, err=True)

    def stage(self, index, count, label):
        """The monitor's ``stage(index, count, label)`` (branches grown one at a time)."""
        self.line(f"stage {index}/{count}: {label}")

    def done(self, result, prefix: str = "done"):
        """The final line of a fit, from its result."""
        state = "converged" if result.converged else f"not converged ({result.message})"
        self.line(f"{prefix}: {result.nfev} evaluations, best {result.objective:.6e}, {result.wall_time:.1f} s, "
                  f"{state}")

    def fold_done(self, index, count, fold, rows):
        """The library's ``fold_done(index, count, fold, rows)``: the fit's final line and the held-out errors."""
        held = "; ".join(f"{r['file']} rms/peak {100 * r['rms_rel_error']:.2f} %" for r in rows
                         if r["role"] == "predicted")
        self.done(fold.result, prefix=f"fold {index}/{count} done")
        if held:
            self.line(f"  held out: {held}")


class Branches(click.ParamType):
    """``--viscous-branches``: an integer from 0 to 6, ``auto`` (the library chooses M) or ``spectrum``."""

    name = "0-6|auto|spectrum"

    def convert(self, value, param, ctx):
        word = str(value).strip().lower()
        if word in ("auto", "spectrum"):
            return word
        try:
            M = int(value)
        except (TypeError, ValueError):
            M = None
        if M is None or not 0 <= M <= 6 or str(value).strip() not in (str(M), f"+{M}"):
            self.fail(f"{value!r}; allowed: an integer from 0 to 6, auto or spectrum", param, ctx)
        return M


@click.command(epilog=EXIT_HELP)
@click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=False))
@click.option("--model", type=click.Choice(MODEL_CHOICES, case_sensitive=False), default="su",
              show_default=True, help="Quasi-static model of the twin.")
@click.option("--init", "init_path", type=click.Path(dir_okay=False),
              help="Start values (a parameter file); default: estimated from the data.")
@click.option("--free", "free_text", help="Parameters to fit, e.g. C10,C20,C30,k_v1,eta_v1 "
                                          "[default: every Yeoh and viscoelastic parameter].")
@click.option("--viscous-branches", "M", type=Branches(),
              help="Maxwell branches M [default: those of --init, or 1]; without --init they are fitted "
                   "one at a time, each from the previous optimum. auto: M from 0 to 4, grown while an "
                   "information criterion improves (BIC with an effective sample count from the residuals' "
                   "autocorrelation; --metric rms). spectrum: time scales log-spaced over the data's span, "
                   "moduli by smoothed non-negative least squares (docs/guide/calibrate.md).")
@click.option("--eps-r", type=float, default=None, help="Relative permittivity, fixed [default: --init's, or 2.8].")
@click.option("--protocol-kind", "kinds_text", default="tensile", show_default=True,
              help="For folders: which runs, comma-separated from tensile, blocking, capacitance, custom.")
@click.option("--metric", type=click.Choice(["rms", "max"], case_sensitive=False), default="rms", show_default=True,
              help="Error metric on the peak-normalized force.")
@click.option("--method", type=click.Choice(["nelder-mead", "least-squares"], case_sensitive=False),
              default="nelder-mead", show_default=True,
              help="Minimizer: Nelder-Mead with restarts, or bounded least squares (--metric rms only).")
@click.option("--law", type=click.Choice(["linear", "finite_strain"], case_sensitive=False), default=None,
              help="Viscoelastic law of the branches: eq. (44) of the paper, or neo-Hookean springs with "
                   "Newtonian dashpots (fit names mu_v<j>, eta_v<j>) [default: --init's, or linear].")
@click.option("--hyperelastic", type=click.Choice(["yeoh", "yeoh-monotone", "neo-hookean"], case_sensitive=False),
              default="yeoh", show_default=True,
              help="Yeoh coefficients the fit may reach: the paper's Yeoh; a Yeoh restricted to monotone stiffening "
                   "(C20, C30 >= 0), which extrapolates in stretch without softening; neo-Hookean (C20 = C30 = 0).")
@click.option("--max-evals", type=click.IntRange(10, 10**7), default=20000, show_default=True)
@click.option("--max-time", type=click.FloatRange(0.1, 86400), default=300.0, show_default=True,
              help="Wall-time budget [s].")
@click.option("--name", help="Name of the calibrated parameter set [default: from --out].")
@click.option("--out", "out_path", required=True, type=click.Path(),
              help="Record to write (a parameter file with a calibration section); with --cv a folder.")
@click.option("--force", "overwrite", is_flag=True,
              help="Replace an existing record (--out and the files beside it; with --cv a folder that holds files).")
@click.option("--quiet", is_flag=True, help="No progress on stderr (evaluations, best objective, stages, folds).")
@click.option("--holdout", multiple=True, type=click.Path(), metavar="FILE",
              help="A run among INPUTS to predict instead of fit (repeatable); its errors and envelope flags "
                   "are printed, written to <out stem>.holdout.csv and under calibration.validation in --out.")
@click.option("--cv", metavar="leave-one-out|by-rate|by-stretch",
              help="Cross-validate: one run per fold, or the runs grouped by nominal stretch rate or by maximum "
                   "stretch; each fold fits the others and predicts its own. --out is then a folder: cv.csv, "
                   "cv.md, fold-<k>.yaml.")
def calibrate(inputs, model, init_path, free_text, M, eps_r, kinds_text, metric, method, law, hyperelastic, max_evals,
              max_time, name, out_path, overwrite, quiet, holdout, cv):
    """Fit the Yeoh and viscoelastic parameters to measured runs (Nelder-Mead, or least squares).

    INPUTS are datasets or folders of datasets (a folder gives its complete
    runs of --protocol-kind, by default the tensile tests, as in the paper).

    \b
    Example:
      rdea-lab calibrate datasets/paper2021/specimen-2 --model su --out params/calibrated.yaml
      rdea-lab calibrate datasets/vhb4910 --model 1r --holdout datasets/vhb4910/0d05_3d0.nc --out vhb.yaml
      rdea-lab calibrate datasets/vhb4910 --model 1r --cv by-rate --out reports/vhb4910-cv
    """
    headless()
    progress = FitProgress(enabled=not quiet)

    def announce(runs, chosen, reason, free, skipped):
        if not cross:  # the inputs are checked, the fit not begun: refuse an existing record now
            for path in api.record_files(out_path).values():
                api.check_new(path, overwrite)
        progress.end_line()
        for s in skipped:
            click.echo(f"skipped {s['file']}: {s['reason']}")
        if reason:
            click.echo(f"model auto: {chosen} ({reason})")
        shape = "" if hyperelastic.lower() == "yeoh" else f", {hyperelastic.lower()}"
        click.echo(f"calibrating {', '.join(free)} ({chosen}, {metric}{shape}) on {len(runs)} runs: "
                   + ", ".join(f"{r.specimen}/{r.protocol}" for r in runs))

    def announce_fold(k, count, label, fitted, predicted):
        progress.end_line()
        click.echo(f"fold {k}/{count} (held out: {label}): fitting {', '.join(fitted)}")

    cross = cv is not None or bool(holdout)
    if not cross:  # a record file, as the option's type said before --cv made it a folder too
        ctx = click.get_current_context()
        param = next(p for p in ctx.command.params if p.name == "out_path")
        click.Path(dir_okay=False).convert(out_path, param, ctx)
    fit = (functools.partial(api.cross_validate, cv=cv, holdout=list(holdout) or None, out=out_path, name=name,
                             overwrite=overwrite) if cross else api.calibrate_runs)
    kinds = [k.strip() for k in kinds_text.split(",") if k.strip()]
    monitor = types.SimpleNamespace(progress=progress, stage=progress.stage, announce=announce,
                                    announce_fold=announce_fold, fold_done=progress.fold_done)
    result = fit(list(inputs), model=model.lower(), init=init_path, free=free_text, branches=M,
                 eps_r=eps_r, kinds=kinds, metric=metric, budget=api.Budget(evaluations=max_evals, seconds=max_time),
                 monitor=monitor, method=method.lower(), law=law.lower() if law else None,
                 hyperelastic=hyperelastic.lower())
    if not cross:
        files = result.write(out_path, name=name, overwrite=overwrite)
        progress.done(result)
    if cross:
        for s in result.skipped:
            click.echo(f"skipped {s['file']}: {s['reason']}")
        if holdout:
            click.echo(result.folds[0].result.fit_report())
        click.echo(api.format_cv(result), nl=False)
        click.echo("wrote " + ", ".join(str(f) for f in result.files.values()))
        return
    click.echo(result.fit_report())
    click.echo(f"wrote {files['params']}, {files['history']}, {files['plot']}")
