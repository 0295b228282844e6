"""What a study writes (`StudyResult.write`): the dataset, the Pareto front and Sobol tables, the figures,
the best design's card; the checks of its output folder and of a run of the card, and that run.

``OUT/`` holds ``study.nc`` (the one Dataset), ``pareto.csv`` (the front, best
first by the first objective), ``sobol.csv`` (with a sensitivity), ``card.yaml``
(with ``optimize``: the best design's specimen card, which ``rdea-lab run``
takes), ``summary.json`` and the figures ``pareto.png``, ``parallel.png``,
``stroke_map.png``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..specs.errors import SpecError
from ..specs.study import METRICS
from ..specs.units import format_quantity
from ..store.outputs import check_writable

FILES = ("study.nc", "pareto.csv", "sobol.csv", "card.yaml", "summary.json", "pareto.png", "parallel.png",
         "stroke_map.png")


def check_study_out(out, overwrite: bool = False) -> Path:
    """The output folder, refused (a `SpecError`, exit 2) if it holds a study's files and not ``overwrite``,
    or cannot be written."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise SpecError(str(out), "--out", "is a file; give a folder for the study's outputs")
    taken = [f for f in FILES if (out / f).exists()]
    if taken and not overwrite:
        raise SpecError(str(out), "--out", f"already holds {taken[0]}; give another folder or --force to replace")
    check_writable(out / "study.nc", "--out")
    return out


def _shown(metric: str, value: float) -> str:
    si, unit, _ = METRICS[metric]
    if not np.isfinite(value):
        return "nan"
    return format_quantity(float(value), unit, 4) if unit else f"{value:.4g}"


def _var(study, name, value) -> str:
    v = next(x for x in study.variables if x.name == name)
    return f"{name} {format_quantity(float(value), v.unit, 4) if v.unit else f'{value:.4g}'}"


def check_card_run(study) -> None:
    """Refuse (`StudyError`, exit 2) a run of the best design's card that the study cannot give: it needs
    ``optimize`` and ``protocol``, and the card holds the membrane only, so no material or voltage variable."""
    from .study import StudyError

    if study.optimize is None or study.protocol is None:
        raise StudyError(f"{study.source}: a run of the card needs a study with optimize and protocol; it has "
                         f"{'no optimize' if study.optimize is None else 'no protocol'}")
    varied = sorted(set(study.names) & {"C10", "C20", "C30", "eps_r", "voltage"})
    if varied:
        raise StudyError(f"{study.source}: variables: a run of the card would not see {', '.join(varied)} (the card "
                         "holds the membrane only); run it yourself with the optimum's values from summary.json")


def run_card(result, card_path, backend: str, out, overwrite: bool = False) -> dict:
    """Run the study's protocol on the best design's card (``emulator`` or ``twin``); the run's peak force and
    the study's prediction of it for the card."""
    from ..runs.app import run_protocol
    from ..runs.backend import Emulator, Twin

    study = result.study
    check_card_run(study)
    executor = Twin(study.params, study.model) if backend == "twin" else Emulator()
    ds = run_protocol(study.protocol_path, card_path, executor, out=out, overwrite=overwrite,
                      metadata={"study": study.name}, command="rdea-lab design")
    return {"backend": backend, "dataset": str(out), "peak_force": float(ds["force"].max()),
            "predicted_peak_force": result.optimum["card_metrics"].get("peak_force", float("nan"))}

