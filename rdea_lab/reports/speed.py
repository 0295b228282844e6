"""Speed against error: SU, 1R, 3R, CR and auto on the scenes that matter.

A scene is a roll, a material and the (stretch, voltage) samples it visits:
the three paper specimens under the paper's protocols (Table 3 material), and
the hollow, active and passive cores of Section 3.4 of [1] at 3.5 kV over
lambda1 from 1 to 1.75 (material of its ref. [36]). For each scene and model:
the time per sample (best of ``repeats`` after a warm-up, ``time.perf_counter``)
and the largest stress deviation from CR, with the deviation from 3R (the
paper's own reference) beside it. The stresses compared are the equations'
at the given stretch (``ModelResult.tension``: the slack clipping, which makes
every model's force 0 where the roll would push, is left out). ``auto`` is
:func:`~rdea_lab.physics.selection.select_model` followed by the model it
picks; the selection counts in its time.

The reference is the continuum roll model CR
(:mod:`~rdea_lab.physics.models.continuum`), the exact axisymmetric limit of
3R's ring lumping. Its one approximation is the quadrature over the
cross-section; it is checked against a rule of 48 points per panel on the
scenes with ``Ri > 0`` (with ``Ri = 0`` CR is the SU state exactly). 3R is
checked against the independent per-sample fsolve baseline
(``rdea_lab/reports/baseline_3r_fsolve.py``) on a subsample of the cores with
``Ri > 0``, where the baseline's stationary point is the physical one.

[1] Prechtl et al., Smart Mater. Struct. 30 (2021), doi:10.1088/1361-665X/ac34be.
"""

from __future__ import annotations

import math
import platform
import shutil
import time
from pathlib import Path

import matplotlib
import matplotlib.lines
import matplotlib.ticker
import numpy as np
from matplotlib.figure import Figure

from ..paths import data_dir
from ..physics.geometry import geometry_from_card
from ..physics.models import continuum, solve
from ..physics.selection import select_model
from ..protocols import load_plan
from ..specs import MODEL_CHOICES, load_params, load_specimen
from ..store.outputs import check_new
from . import tables
from .paper_models import IDENTICAL, figure8
from .plots import save_figure

MODELS = MODEL_CHOICES
SPECIMENS = ("specimen1", "specimen2", "specimen3")
#: The protocols of the paper's campaign (campaigns/paper2021.yaml).
PROTOCOLS = ("tensile_ramp_sine_0V", "tensile_ramp_sine_2.6kV", "blocking_force", "capacitance_sweep")
CORES = ("hollow_core", "active_core", "passive_core")
CORE_VOLTAGE = 3500.0
CORE_STRETCH = (1.0, 1.75)
#: The Pareto plot's marker of each model.
MARKERS = {"su": "o", "1r": "s", "3r": "^", "cr": "D", "auto": "x"}
REFERENCE = ("CR, the continuum roll model (the exact limit of 3R's ring lumping; its quadrature checked below), "
             "stresses at the given stretch (the tension, no slack clipping)")
#: Gauss points per panel of the rule the CR quadrature is checked against.
CHECK_POINTS = 48

COLUMNS = [
    ("scene", "scene", tables.text),
    ("model", "model", tables.text),
    ("model_used", "solves with", tables.text),
    ("samples", "samples", tables.text),
    ("time_per_sample_s", "time per sample [µs]", lambda v: tables.number(".3f")(v * 1e6)),
    ("max_error_Pa", "max |σ1 − σ1(CR)| [kPa]", lambda v: tables.number(".4g")(v / 1e3)),
    ("max_rel_error", "max error [% of peak]", lambda v: tables.number(".3g")(v * 100)),
    ("max_error_3r_Pa", "max |σ1 − σ1(3R)| [kPa]", lambda v: tables.number(".4g")(v / 1e3)),
    ("converged", "converged", tables.text),
    ("auto_reason", "auto: why", tables.text),
]
CSV_KEYS = ["scene", "roll", "protocol", "material", "voltage", "samples", "model", "model_used", "time_per_sample_s",
            "max_error_Pa", "max_rel_error", "max_error_3r_Pa", "peak_stress_Pa", "converged", "auto_reason",
            "reference"]


def scenes(root: Path, core_samples: int = 2001) -> list[dict]:
    """The scenes: paper specimens x protocols, then the Section 3.4 cores at 3.5 kV."""
    out = []
    table3 = load_params(root / "params" / "paper2021_table3.yaml")
    for spec in SPECIMENS:
        card = load_specimen(root / "specimens" / f"{spec}.yaml")
        for proto in PROTOCOLS:
            plan = load_plan(root / "protocols" / f"{proto}.yaml")
            out.append({"scene": f"{card.id} / {proto}", "roll": card.id, "protocol": proto,
                        "geom": geometry_from_card(card), "material": table3,
                        "stretch": np.asarray(plan.stretch, float), "voltage": np.asarray(plan.voltage, float),
                        "voltage_text": f"{np.max(np.abs(plan.voltage)) / 1e3:g} kV max"})
    rizzello = load_params(root / "params" / "rizzello2020.yaml")
    lam = np.linspace(*CORE_STRETCH, core_samples)
    for core in CORES:
        card = load_specimen(root / "specimens" / f"{core}.yaml")
        out.append({"scene": f"{card.id} @ 3.5 kV", "roll": card.id, "protocol": "lambda1 1 to 1.75",
                    "geom": geometry_from_card(card), "material": rizzello, "stretch": lam,
                    "voltage": np.full_like(lam, CORE_VOLTAGE), "voltage_text": "3.5 kV"})
    return out


def timed(fn, repeats: int):
    """Best wall time of ``repeats`` calls of ``fn`` after one warm-up [s], and the warm-up's result."""
    result = fn()
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def best_time(fn, repeats: int) -> float:
    """Best wall time of ``repeats`` calls of ``fn`` after one warm-up [s]."""
    return timed(fn, repeats)[0]


def deviation(sigma, ref_sigma) -> tuple[float, int]:
    """Largest ``|sigma - sigma_ref|`` [Pa] where both converged, and the samples where only the reference did."""
    both = np.isfinite(sigma) & np.isfinite(ref_sigma)
    lost = int(np.sum(np.isfinite(ref_sigma) & ~np.isfinite(sigma)))
    return (float(np.max(np.abs(sigma[both] - ref_sigma[both]))) if both.any() else math.nan), lost


def study_scene(sc: dict, repeats: int, tolerance: float) -> list[dict]:
    """One row per model for one scene; errors are of the tension, against CR (and 3R)."""
    geom, mat, lam, v = sc["geom"], sc["material"], sc["stretch"], sc["voltage"]
    timings = {}
    for model in MODELS:  # each model's warm-up gives its result (CR's and 3R's are the references)
        if model == "auto":
            def run():
                choice = select_model(geom, mat, lam, v, tolerance)
                return choice, solve(choice.model, geom, mat, lam, v)
        else:
            def run(model=model):
                return None, solve(model, geom, mat, lam, v)
        timings[model] = timed(run, repeats)
    ref, three = timings["cr"][1][1], timings["3r"][1][1]
    peak = float(np.nanmax(np.abs(ref.tension))) if np.any(ref.converged) else math.nan
    rows = []
    for model, (seconds, (choice, res)) in timings.items():
        err, lost = deviation(res.tension, ref.tension)
        err3, _ = deviation(res.tension, three.tension)
        rows.append({"scene": sc["scene"], "roll": sc["roll"], "protocol": sc["protocol"], "material": mat.name,
                     "voltage": sc["voltage_text"], "samples": int(lam.size), "model": model,
                     "model_used": choice.model if choice else model, "time_per_sample_s": seconds / lam.size,
                     "max_error_Pa": err, "max_rel_error": err / peak if peak else math.nan, "max_error_3r_Pa": err3,
                     "peak_stress_Pa": peak,
                     "converged": f"{int(res.converged.sum())}/{lam.size}" + (f" ({lost} lost)" if lost else ""),
                     "auto_reason": choice.reason if choice else "", "reference": REFERENCE})
    return rows


def quadrature_check(scene_list: list[dict]) -> list[dict]:
    """CR's default quadrature against :data:`CHECK_POINTS` points per panel on each scene with ``Ri > 0``."""
    out = []
    for sc in scene_list:
        g, mat, lam, v = sc["geom"], sc["material"], sc["stretch"], sc["voltage"]
        if g.Ri <= 0.0:
            continue
        fine = continuum.evaluate(g, mat, lam, v, points=CHECK_POINTS).fields["sigma1"]
        ours = continuum.evaluate(g, mat, lam, v).fields["sigma1"]
        peak = float(np.nanmax(np.abs(fine)))
        dev = float(np.nanmax(np.abs(ours - fine)))
        out.append({"scene": sc["scene"], "nodes": int(continuum.quadrature(g)[0].size),
                    "check_nodes": int(continuum.quadrature(g, CHECK_POINTS)[0].size), "max_error_Pa": dev,
                    "max_rel_error": dev / peak, "note": f"CR against {CHECK_POINTS} Gauss points per panel"})
    return out


def fsolve_check(scene_list: list[dict], n: int = 16) -> list[dict]:
    """3R against the fsolve baseline on ``n`` samples of each scene with ``Ri > 0``."""
    from . import baseline_3r_fsolve as module

    out = []
    for sc in scene_list:
        g, mat = sc["geom"], sc["material"]
        if g.Ri <= 0.0:
            continue
        pick = np.linspace(0, sc["stretch"].size - 1, n).astype(int)
        lam, v = sc["stretch"][pick], sc["voltage"][pick]
        ref = solve("3r", g, mat, lam, v, slack=False).sigma1  # the equations (27), as fsolve solves them
        t0 = time.perf_counter()
        base = module.solve_3r_fsolve(lam, v, Ri=g.Ri, Rie=g.Rie, Roe=g.Roe, Ro=g.Ro, L3=g.L3, alpha_e1=g.alpha_e1,
                                      C10=mat.C10, C20=mat.C20, C30=mat.C30, eps_r=mat.eps_r)
        seconds = time.perf_counter() - t0
        ok = base["converged"] & np.isfinite(ref)
        peak = float(np.nanmax(np.abs(ref)))
        dev = float(np.max(np.abs(base["sigma1"][ok] - ref[ok]))) if ok.any() else math.nan
        out.append({"scene": sc["scene"], "samples": int(n), "converged": int(ok.sum()), "max_error_Pa": dev,
                    "max_rel_error": dev / peak, "fsolve_time_per_sample_s": seconds / n,
                    "note": "3R (library) against fsolve on the corrected eq. (27)"})
    return out


def _bands(errors: np.ndarray) -> tuple[float, float, float, float]:
    """Where the Pareto plot's log error axis [%] starts and ends, and where its two bands sit below it:
    (bottom decade, top, y of the "identical" band, y of the "exact 0" band)."""
    shown = errors[np.isfinite(errors) & (errors > IDENTICAL)] * 100
    lo, hi = (float(shown.min()), float(shown.max())) if shown.size else (1e-2, 1.0)
    bottom = 10.0 ** math.floor(math.log10(lo))
    return bottom, max(hi * 1.8, bottom * 10), bottom / 3.0, bottom / 9.0


def pareto_plot(rows: list[dict], path: Path, pdf: bool = True) -> Path:
    """`pareto_figure` as PNG at 200 dpi and, with ``pdf``, a PDF beside."""
    save_figure(pareto_figure(rows), path, vector=pdf)
    return Path(path)


def pareto_figure(rows: list[dict]) -> Figure:
    """Time per sample against the largest error from CR: one panel per roll, a marker per model, a colour
    per scene (the roll's protocol).

    The log error axis spans the errors above `IDENTICAL` of the peak (the data); below it two marked
    bands: errors within `IDENTICAL` of the peak (rounding: the model is identical to CR there) and
    exact zeros (CR against itself).
    """
    markers = MARKERS
    rolls = list(dict.fromkeys(r["roll"] for r in rows))
    protocols = list(dict.fromkeys(r["protocol"] for r in rows))
    colors = {p: matplotlib.colormaps["tab10"](i % 10) for i, p in enumerate(protocols)}
    err = np.array([r["max_rel_error"] for r in rows], float)
    bottom, top, y_same, y_zero = _bands(err)
    ncol = min(3, len(rolls))
    nrow = math.ceil(len(rolls) / ncol)
    fig = Figure(figsize=(4.2 * ncol, 3.4 * nrow + 1.2))
    axes = fig.subplots(nrow, ncol, sharex=True, sharey=True, squeeze=False).ravel()
    for ax, roll in zip(axes, rolls):
        for r, e in zip(rows, err):
            if r["roll"] != roll or not math.isfinite(e):
                continue
            y = y_zero if e == 0.0 else (y_same if e <= IDENTICAL else e * 100)
            ax.plot(r["time_per_sample_s"] * 1e6, y, markers[r["model"]], color=colors[r["protocol"]], ms=7,
                    mfc="none", mew=1.4)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())  # decades only: the grid is on them
        ax.axhline(bottom / 1.7, color="gray", lw=0.8, ls=":")
        ax.set_title(roll, fontsize=9)
        ax.grid(alpha=0.3, which="major")
    for ax in axes[len(rolls):]:
        ax.set_visible(False)
    decades = [10.0 ** k for k in range(int(round(math.log10(bottom))), math.floor(math.log10(top)) + 1)]
    axes[0].set_yticks([y_zero, y_same] + decades,
                       ["exact 0", f"≤ {IDENTICAL:g} of peak"] + [f"{d:g}" for d in decades])
    axes[0].set_ylim(y_zero / 1.8, top)
    axes[0].yaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    for ax in axes.reshape(nrow, ncol)[:, 0]:
        ax.set_ylabel("max |σ1 − σ1(CR)| [% of peak]")
    for ax in axes.reshape(nrow, ncol)[-1, :]:
        ax.set_xlabel("time per sample [µs]")
    handles = [matplotlib.lines.Line2D([], [], ls="none", marker=mk, color="gray", mfc="none", mew=1.4,
                                       label=m.upper() if m != "auto" else "auto") for m, mk in markers.items()]
    handles += [matplotlib.lines.Line2D([], [], ls="none", marker="s", color=c, ms=8, label=p)
                for p, c in colors.items()]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=8, frameon=False,
               bbox_to_anchor=(0.5, 0.01))
    fig.suptitle("speed against error from CR (the reference; below the dotted line: errors within "
                 f"{IDENTICAL:g} of the peak stress, and CR's own exact 0)", fontsize=10)
    w, h = fig.get_size_inches()  # fixed margins [in]: a layout engine would cost more than the drawing
    fig.subplots_adjust(left=1.55 / w, right=1 - 0.25 / w, top=1 - 0.65 / h, bottom=1.25 / h, wspace=0.06,
                        hspace=0.35)
    return fig


def _markdown(rows, auto, check, quad, sweep, repeats, tolerance) -> str:
    lines = ["# Speed against error: SU, 1R, 3R, CR and auto", "",
             f"Time per sample: best of {repeats} after a warm-up, on {platform.machine()} "
             f"({platform.python_implementation()} {platform.python_version()}). Error: the largest "
             f"|σ1 − σ1(CR)| over the scene's samples, quasi-static stress at the given stretch "
             f"(|σ1 − σ1(3R)| beside it). Reference: {REFERENCE}. "
             f"auto = select_model (tolerance {tolerance:.0%} of the peak CR stress) then the model it picks, "
             "selection included in its time.", "", tables.markdown(COLUMNS, rows), "## What auto picks", "",
             tables.markdown([("scene", "scene", tables.text), ("model_used", "auto picks", tables.text),
                              ("auto_reason", "why", tables.text)], auto),
             "## The reference's quadrature", ""]
    if quad:
        lines.append(tables.markdown([
            ("scene", "scene", tables.text), ("nodes", "nodes", tables.text),
            ("check_nodes", "check nodes", tables.text),
            ("max_error_Pa", "max |Δσ1| [Pa]", tables.number(".3g")),
            ("max_rel_error", "relative to peak", tables.number(".3g")), ("note", "note", tables.text)], quad))
    else:
        lines.append("No scene with Ri > 0: with Ri = 0 CR is the SU state, no quadrature.\n")
    lines += ["## 3R against the fsolve baseline", ""]
    if check:
        lines.append(tables.markdown([
            ("scene", "scene", tables.text), ("samples", "samples", tables.text),
            ("converged", "fsolve converged", tables.text),
            ("max_error_Pa", "max |Δσ1| [Pa]", tables.number(".3g")),
            ("max_rel_error", "relative to peak", tables.number(".3g")),
            ("fsolve_time_per_sample_s", "fsolve time per sample [s]", tables.number(".3g")),
            ("note", "note", tables.text)], check))
    else:
        lines.append("No scene with Ri > 0: not checked.\n")
    lines += ["## Figure 8 sweep: Ri from 0.1 to 0.9 Rie at 3.5 kV (`figure8_sweep.png`)", "",
              tables.markdown([("Ri_over_Rie", "Ri / Rie", tables.number(".1f"))]
                              + [(f"max_dev_{m}_MPa", f"{m.upper()} from 3R [MPa]", tables.number(".4f"))
                                 for m in ("su", "1r", "cr")]
                              + [(f"max_dev_{m}_from_cr_MPa", f"{m.upper()} from CR [MPa]", tables.number(".4f"))
                                 for m in ("su", "1r", "3r")], sweep)]
    return "\n".join(lines)


def speed_study(out, root=None, repeats: int = 3, tolerance: float = 0.01, core_samples: int = 2001,
                pdf: bool = True, sweep=None, overwrite: bool = False) -> dict:
    """Write ``speed.md``, ``speed.csv``, ``pareto.png``, ``figure8_sweep.png`` and ``figure8.csv`` into ``out``.

    Parameters
    ----------
    out : path
        Output folder (created); one that holds files is refused before the work unless ``overwrite``.
    root : path, optional
        Folder holding ``specimens/``, ``params/``, ``protocols/`` (default: the packaged ones,
        `rdea_lab.paths.data_dir`).
    repeats : int
        Timing repeats; the best is kept.
    tolerance : float
        For auto: allowed deviation from CR relative to the peak CR stress [-].
    core_samples : int
        Stretch samples of the core scenes.
    pdf : bool
        A PDF beside each PNG.
    sweep : tuple, optional
        The Figure 8 sweep made already (``(rows, png)``: what :func:`~rdea_lab.reports.paper_models.figure8`
        returned and the PNG it wrote, a PDF beside it if ``pdf``), copied here instead of computed again
        (`reproduce` makes it for the models section).
    overwrite : bool
        Write into an ``out`` that holds files (the CLI's ``--force``).

    Returns
    -------
    dict
        ``rows`` (one per scene and model), ``auto`` (per scene: model and reason),
        ``reference_check`` (3R against fsolve), ``quadrature_check`` (CR against a finer
        quadrature), ``figure8``, ``files``.
    """
    check_new(out, overwrite, "--out", folder=True)  # before the timing, not after it
    root = Path(root) if root is not None else data_dir()
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scene_list = scenes(root, core_samples)
    rows = [r for sc in scene_list for r in study_scene(sc, repeats, tolerance)]
    auto = [{"scene": r["scene"], "model_used": r["model_used"], "auto_reason": r["auto_reason"]}
            for r in rows if r["model"] == "auto"]
    check = fsolve_check(scene_list)
    quad = quadrature_check(scene_list)
    if sweep is None:
        sweep = figure8(load_params(root / "params" / "rizzello2020.yaml"), out / "figure8_sweep.png", pdf=pdf)
    else:
        sweep, png = sweep
        for suffix in (".png", ".pdf") if pdf else (".png",):
            shutil.copyfile(Path(png).with_suffix(suffix), out / f"figure8_sweep{suffix}")
    files = {"markdown": out / "speed.md", "csv": out / "speed.csv", "pareto": out / "pareto.png",
             "figure8": out / "figure8_sweep.png", "figure8_csv": out / "figure8.csv"}
    files["markdown"].write_text(_markdown(rows, auto, check, quad, sweep, repeats, tolerance))
    tables.write_csv(files["csv"], CSV_KEYS, rows)
    tables.write_csv(files["figure8_csv"], list(sweep[0]), sweep)
    pareto_plot(rows, files["pareto"], pdf)
    return {"rows": rows, "auto": auto, "reference_check": check, "quadrature_check": quad, "figure8": sweep,
            "files": {k: str(v) for k, v in files.items()}}
