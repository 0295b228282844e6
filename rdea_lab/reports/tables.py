"""Tables as Markdown, CSV and LaTeX from one list of columns and rows.

A column is ``(key, header, format)``: ``key`` indexes the row dicts,
``header`` is shown, ``format`` turns a value into display text (the CSV
keeps the raw value, floats written with ``repr`` so they read back equal).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

_LATEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
          "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}
#: Characters a LaTeX document cannot take as they are, outside math mode.
_UNICODE = {"λ": r"$\lambda$", "σ": r"$\sigma$", "–": "--", "—": "---", "±": r"$\pm$", "≤": r"$\le$",
            "−": "-", "·": r"$\cdot$"}


def latex_escape(text: str) -> str:
    """``text`` with LaTeX's special characters escaped (``%`` -> ``\\%``, ``_`` -> ``\\_``, ...)."""
    out = "".join(_LATEX.get(ch, ch) for ch in str(text))
    return "".join(_UNICODE.get(ch, ch) for ch in out)


def percent(value, digits=2) -> str:
    """A ratio as a percentage for display, ``—`` for a missing or non-finite value."""
    if value is None or not math.isfinite(value):
        return "—"
    return f"{100.0 * value:.{digits}f}"


def number(fmt: str):
    """A formatter that writes finite floats with ``fmt`` and ``—`` otherwise."""
    def show(value):
        if value is None or (isinstance(value, float) and not math.isfinite(value)):
            return "—"
        return format(value, fmt)
    return show


def text(value) -> str:
    return "—" if value is None else str(value)


def markdown(columns, rows) -> str:
    """A GitHub-flavoured Markdown table (``|`` in cells escaped)."""
    def cell(s):
        return str(s).replace("|", r"\|")
    lines = ["| " + " | ".join(cell(h) for _, h, _ in columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(f(r.get(k))) for k, _, f in columns) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def _raw(value):
    if isinstance(value, float):
        return repr(value)
    return "" if value is None else value


def write_csv(path: Path, keys, rows) -> Path:
    """One line per row with the raw values of ``keys`` (floats as ``repr``; None as empty)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(keys)
        w.writerows([[_raw(r.get(k)) for k in keys] for r in rows])
    return Path(path)


def latex_tabular(columns, rows, align=None) -> str:
    """A ``tabular`` environment (no packages needed): ``\\hline`` rules, every cell escaped."""
    align = align or "l" * len(columns)
    lines = [rf"\begin{{tabular}}{{{align}}}", r"\hline",
             " & ".join(latex_escape(h) for _, h, _ in columns) + r" \\", r"\hline"]
    lines += [" & ".join(latex_escape(f(r.get(k))) for k, _, f in columns) + r" \\" for r in rows]
    lines += [r"\hline", r"\end{tabular}"]
    return "\n".join(lines) + "\n"
