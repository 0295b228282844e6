"""Where the project's shipped inputs live (specimen cards, parameter sets, benchmarks)."""

from __future__ import annotations

from pathlib import Path


def project_root() -> Path | None:
    """The folder holding ``specimens/`` and ``params/``: the working directory if it
    has them, else the source checkout this package was installed from (``pip install -e``)."""
    for base in (Path.cwd(), Path(__file__).resolve().parents[1]):
        if (base / "specimens").is_dir() and (base / "params").is_dir():
            return base
    return None


def benchmarks_dir() -> Path | None:
    """The checkout's ``benchmarks/`` (holding ``bench_models.py``), or None outside a source checkout."""
    for base in (Path.cwd(), Path(__file__).resolve().parents[1]):
        if (base / "benchmarks" / "bench_models.py").is_file():
            return base / "benchmarks"
    return None
