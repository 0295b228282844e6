"""Plain HTML pages for the reports: inline CSS, no JavaScript, no network resources.

Every text that comes from a file or a dataset goes through ``html.escape``;
figures and files are linked relative to the page. Tables fit a 1400 px page:
a cell breaks after ``_`` and ``/`` (``<wbr>``) as well as at spaces, and a
hash is shown by its first `HASH_CHARS` characters with the full one in a
``title`` (hover) attribute (the CSV files keep it whole).
"""

from __future__ import annotations

import html
import os
from pathlib import Path

#: Characters of a sha256 or run id shown in a table (the full one on hover and in the CSV).
HASH_CHARS = 12

CSS = """
body { font-family: sans-serif; max-width: 1340px; margin: 1.5em auto; padding: 0 1em; color: #222; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.82em; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.4em; text-align: left; vertical-align: top; }
th { background: #eee; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.flag { color: #a40; }
code, .hash { font-family: monospace; font-size: 0.9em; }
.banner { border: 2px solid #c60; background: #fff4e5; padding: 0.6em 1em; font-weight: bold; }
.figures { display: grid; grid-template-columns: repeat(auto-fit, minmax(560px, 1fr)); gap: 1em; }
figure { margin: 0; }
figure img { width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; }
"""


class Markup(str):
    """Text that is HTML already (escaped where it had to be): put in a page as it is."""


def esc(value) -> str:
    return html.escape("—" if value is None else str(value), quote=True)


#: Words up to this many characters are kept whole (``0d01_1d5``, ``specimen-1``); longer ones may break.
WHOLE_WORD = 16


def _break_word(word: str) -> str:
    if len(word) <= WHOLE_WORD:
        return html.escape(word, quote=True)
    return html.escape(word, quote=True).replace("_", "_<wbr>").replace("/", "/<wbr>")


def breakable(value) -> str:
    """``value`` escaped; in a word longer than `WHOLE_WORD` characters a line-break opportunity
    (``<wbr>``) after every ``_`` and ``/`` (paths, protocol names)."""
    return " ".join(_break_word(w) for w in ("—" if value is None else str(value)).split(" "))


def short_hash(value) -> Markup:
    """A hash as its first `HASH_CHARS` characters, the whole of it in the hover text."""
    text = str(value or "")
    if len(text) <= HASH_CHARS:
        return Markup(f"<span class=\"hash\">{esc(text or '—')}</span>")
    return Markup(f"<span class=\"hash\" title=\"{esc(text)}\">{esc(text[:HASH_CHARS])}…</span>")


def link(href, text=None) -> Markup:
    """``<a href>`` to a relative path (shown with break opportunities)."""
    return Markup(f"<a href=\"{esc(href)}\">{breakable(text if text is not None else href)}</a>")


def _cell(value) -> str:
    return value if isinstance(value, Markup) else breakable(value)


def table(columns, rows, numeric=(), flagged=()) -> str:
    """An HTML table: ``columns`` as ``(key, header, format)``, cells escaped (a `Markup` value as it is).

    ``numeric`` keys are right-aligned; ``flagged`` keys are drawn in the warning colour where not ``—``.
    """
    head = "".join(f"<th>{esc(h)}</th>" for _, h, _ in columns)
    body = []
    for r in rows:
        cells = []
        for k, _, f in columns:
            shown = f(r.get(k))
            cls = " class='num'" if k in numeric else (" class='flag'" if k in flagged and shown != "—" else "")
            cells.append(f"<td{cls}>{_cell(shown)}</td>")
        body.append(f"<tr>{''.join(cells)}</tr>")
    return f"<table>\n<tr>{head}</tr>\n" + "\n".join(body) + "\n</table>\n"


def entries_table(entries) -> str:
    """A two-column table of ``(name, value)`` pairs (values escaped unless `Markup`)."""
    rows = "".join(f"<tr><th>{breakable(k)}</th><td>{_cell(_text(v))}</td></tr>\n" for k, v in entries)
    return "<table>\n" + rows + "</table>\n"


def page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{esc(title)}</title>\n"
            f"<style>{CSS}</style>\n</head>\n<body>\n<h1>{esc(title)}</h1>\n{body}</body>\n</html>\n")


def figures(paths, captions=None, base=None) -> str:
    """Each PNG with its caption and, when a PDF of it lies beside it, a link to the PDF.

    Links are relative to ``base`` (the page's folder; default: the figure's own folder).
    """
    captions = captions or {}
    out = []
    for p in map(Path, paths):
        href = os.path.relpath(p, base) if base is not None else p.name
        pdf = p.with_suffix(".pdf")
        vector = (f" (<a href=\"{esc(os.path.relpath(pdf, base) if base is not None else pdf.name)}\">PDF</a>)"
                  if pdf.is_file() else "")
        out.append(f"<figure><a href=\"{esc(href)}\"><img src=\"{esc(href)}\" alt=\"{esc(p.name)}\"></a>"
                   f"<figcaption>{esc(captions.get(p.name, p.name))}{vector}</figcaption></figure>")
    return "<div class=\"figures\">\n" + "\n".join(out) + "\n</div>\n"


def _text(value) -> str:
    """``—`` for nothing; `Markup` kept as it is; anything else as text."""
    if value is None or value == "":
        return "—"
    return value if isinstance(value, Markup) else str(value)


RUN_COLUMNS = [
    ("name", "run", _text), ("file", "file", _text), ("sha256", "sha256", short_hash), ("run_id", "run_id", short_hash),
    ("created", "created", _text), ("origin", "data", _text), ("origin_detail", "source, credit", _text),
    ("protocol", "protocol", _text), ("specimen", "specimen", _text),
]


def write_validation_index(path: Path, report, columns, figure_captions: dict | None = None) -> Path:
    """``index.html`` of the validation report: origin of the data, the table, figures, provenance.

    Parameters
    ----------
    path : Path
        The page to write.
    report : ValidationReport
        What :func:`rdea_lab.reports.validation.validation_report` computed.
    columns : list of tuple
        The table's columns (key, heading, format).
    figure_captions : dict of Path to str, optional
        The PNG figures written beside the page, each with its caption (none: no figures section).

    Returns
    -------
    Path
        ``path``.
    """
    cal = report.params
    figure_captions = figure_captions or {}
    parts = [f"<p class=\"banner\">Data origin: {esc(report.origin)}</p>\n",
             f"<h2>Table 4 analogue</h2>\n<p>{esc(report.caption)}</p>\n",
             table(columns, list(report.rows), numeric=("rate_per_s", "max_stretch", "samples", "max_rel_error",
                                                        "paper_max_rel_error", "rms_rel_error", "p99_rel_error",
                                                        "rms_text"),
                   flagged=("beyond_calibration",)),
             f"<p class=\"legend\">{esc(report.legend)}</p>\n" if report.legend else "",
             _repeats(report),
             "<p>Files: <a href=\"table4.md\">table4.md</a>, <a href=\"table4.csv\">table4.csv</a> (full hashes "
             "and paths), <a href=\"table4.tex\">table4.tex</a>.</p>\n"]
    if figure_captions:
        parts += ["<h2>Figures (measured in colour, twin dashed black, residual twin − measured below)</h2>\n",
                  figures([str(f) for f in figure_captions], {Path(f).name: c for f, c in figure_captions.items()})]
    parts.append("<h2>Parameters</h2>\n")
    entries = [("file", cal["file"]), ("sha256", short_hash(cal["sha256"])), ("name", report.params_name),
               ("calibration", cal["summary"])]
    if cal["record"]:
        entries += [("calibration model", cal.get("model")),
                    ("objective", f"{cal.get('metric')}: {cal.get('objective')}"),
                    ("converged", f"{cal.get('converged')} ({cal.get('message')})"),
                    ("evaluations", cal.get("nfev")), ("software", cal.get("software")),
                    ("calibration envelope", f"{cal.get('envelope_text') or 'none'} ({cal.get('envelope_source')})")]
        entries += [(f"fitted on {r.get('specimen')}/{Path(str(r.get('file'))).stem}",
                     Markup(f"{breakable(r.get('file'))} (sha256 {short_hash(r.get('sha256'))})"))
                    for r in cal["runs"]]
    parts.append(entries_table(entries))
    parts.append("<h2>Runs</h2>\n")
    parts.append(table(RUN_COLUMNS, list(report.runs)))
    if report.skipped:
        parts.append("<h2>Skipped files</h2>\n<ul>\n" + "".join(
            f"<li><code>{breakable(s['file'])}</code>: {esc(s['reason'])}</li>\n" for s in report.skipped)
            + "</ul>\n")
    path = Path(path)
    path.write_text(page("Validation of the twin against measured runs", "".join(parts)))
    return path


def _repeats(report) -> str:
    """The repeat section of the validation page: one item per repeated test (none: nothing)."""
    lines = getattr(report, "repeat_lines", ())
    if not lines:
        return ""
    return ("<h3>Repeats: the measurement's own spread</h3>\n<ul>\n"
            + "".join(f"<li>{esc(line)}</li>\n" for line in lines) + "</ul>\n")


def _rel(path, base) -> str:
    return os.path.relpath(path, base)


def _files(base, paths) -> Markup:
    """Links to those of ``paths`` that exist, relative to ``base``, comma-separated."""
    return Markup(", ".join(link(_rel(p, base)) for p in map(Path, paths) if p.is_file()) or "—")


def write_reproduce_index(out: Path, result: dict, validation_columns) -> Path:
    """``index.html`` at the top of a ``reproduce`` folder: the data origin, links to the calibration
    record, the validation report, the speed study and the model-side results, with their key tables
    and figures.

    Parameters
    ----------
    out : Path
        The ``reproduce`` folder.
    result : ReproduceResult
        What :func:`rdea_lab.reports.reproduce.reproduce` made (its ``seconds``: the time so far).
    validation_columns : list of tuple
        The validation table's columns (key, heading, format).

    Returns
    -------
    Path
        ``out/index.html``.
    """
    out = Path(out)
    rep, fit, cal = result.validation, result.calibration_result, result.calibration
    parts = [f"<p class=\"banner\">Data origin: {esc(rep.origin)}</p>\n",
             "<p>Contents: <a href=\"#calibration\">calibration</a>, <a href=\"#validation\">validation</a>, "
             + ("<a href=\"#speed\">speed against error</a>, " if result.speed is not None else "")
             + "<a href=\"#models\">model-side results</a>, <a href=\"#datasets\">datasets</a>."
             + f" Written in {result.seconds:.1f} s." + "</p>\n"]
    record = rep.params
    parts.append("<h2 id=\"calibration\">Calibration</h2>\n")
    parts.append(entries_table([
        ("record", _files(out, [cal["params"]])), ("history", _files(out, [cal["history"], cal["plot"]])),
        ("sha256", short_hash(record["sha256"])),
        ("model, method", f"{fit.model}, {fit.method}, metric {fit.metric}"),
        ("result", f"{fit.message}; {fit.nfev} evaluations in {fit.wall_time:.1f} s; objective {fit.objective:.6g}"),
        ("fitted runs", ", ".join(f"{r.get('specimen')}/{Path(str(r.get('file'))).stem}" for r in record["runs"])),
        ("calibration envelope", f"{record.get('envelope_text') or 'none'} ({record.get('envelope_source')})")]))
    parts.append("<h2 id=\"validation\">Validation: the Table 4 analogue</h2>\n"
                 f"<p>{link('validation/index.html', 'validation/index.html')} (figures, provenance of every run), "
                 f"{_files(out, [result.validation_files[k] for k in ('markdown', 'csv', 'latex')])}.</p>\n")
    keep = ("experiment", "voltage", "specimen", "name", "role", "max_rel_error", "paper_max_rel_error",
            "rms_rel_error", "beyond_calibration")
    parts.append(table([c for c in validation_columns if c[0] in keep], list(rep.rows),
                       numeric=("max_rel_error", "paper_max_rel_error", "rms_rel_error"),
                       flagged=("beyond_calibration",)))
    if result.speed is not None:
        sp = result.speed["files"]
        listed = [sp["markdown"], sp["csv"], sp["pareto"], Path(sp["pareto"]).with_suffix(".pdf")]
        parts.append("<h2 id=\"speed\">Speed against error: SU, 1R, 3R, CR and auto</h2>\n"
                     f"<p>{_files(out, listed)}</p>\n")
        parts.append(table([("scene", "scene", _text), ("model_used", "auto picks", _text),
                            ("auto_reason", "why", _text)], result.speed["auto"]))
        parts.append(figures([sp["pareto"]], {"pareto.png": "Time per sample against the largest stress error "
                                              "from CR, one panel per roll."}, base=out))
    models = out / "models"
    pngs = sorted(models.glob("figure*.png"))
    parts.append("<h2 id=\"models\">Model-side results: Table 2, Section 3.4, Figures 5-8</h2>\n"
                 f"<p>{_files(out, [models / 'models.md', models / 'models.json'])}</p>\n")
    captions = {p.name: (f"As Figure {p.name[6]}: SU, 1R, 3R and CR on the {p.stem.split('_', 1)[1]} roll at 0 and "
                         "3.5 kV: circumferential stretch, axial stress, deviation from 3R."
                         if p.name[6] in "567" else "As Figure 8: Ri swept from 0.1 to 0.9 Rie at 3.5 kV, the "
                         "deviations of 1R, SU and CR from 3R.") for p in pngs}
    parts.append(figures(pngs, captions, base=out))
    runs = result.campaign
    parts.append("<h2 id=\"datasets\">Datasets</h2>\n"
                 f"<p>{len(runs)} runs in {link('datasets/', 'datasets/')} (one netCDF file per specimen and "
                 "protocol; their origin and hashes in the validation report's Runs table).</p>\n")
    path = out / "index.html"
    path.write_text(page(f"rdea-lab reproduce: {result.campaign_name}", "".join(parts)))
    return path
