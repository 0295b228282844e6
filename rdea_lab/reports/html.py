"""Plain HTML pages for the reports: inline CSS, no JavaScript, no network resources.

Every text that comes from a file or a dataset goes through ``html.escape``;
figures are linked by their file name, relative to the page.
"""

from __future__ import annotations

import html
from pathlib import Path

CSS = """
body { font-family: sans-serif; max-width: 72em; margin: 1.5em auto; padding: 0 1em; color: #222; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
th { background: #eee; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
code, .hash { font-family: monospace; font-size: 0.85em; word-break: break-all; }
.banner { border: 2px solid #c60; background: #fff4e5; padding: 0.6em 1em; font-weight: bold; }
figure { margin: 1em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; }
"""


def esc(value) -> str:
    return html.escape("—" if value is None else str(value), quote=True)


def table(columns, rows, numeric=()) -> str:
    """An HTML table: ``columns`` as ``(key, header, format)``, cells escaped."""
    head = "".join(f"<th>{esc(h)}</th>" for _, h, _ in columns)
    body = []
    for r in rows:
        cells = "".join(("<td class='num'>" if k in numeric else "<td>") + esc(f(r.get(k))) + "</td>"
                        for k, _, f in columns)
        body.append(f"<tr>{cells}</tr>")
    return f"<table>\n<tr>{head}</tr>\n" + "\n".join(body) + "\n</table>\n"


def page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{esc(title)}</title>\n"
            f"<style>{CSS}</style>\n</head>\n<body>\n<h1>{esc(title)}</h1>\n{body}</body>\n</html>\n")


def figures(paths, captions=None) -> str:
    captions = captions or {}
    out = []
    for p in paths:
        name = Path(p).name
        out.append(f"<figure><img src=\"{esc(name)}\" alt=\"{esc(name)}\">"
                   f"<figcaption>{esc(captions.get(name, name))}</figcaption></figure>")
    return "\n".join(out) + "\n"


def _kv(text) -> str:
    return str(text)


RUN_COLUMNS = [
    ("file", "file", _kv), ("sha256", "sha256", _kv), ("run_id", "run_id", _kv), ("backend", "backend", _kv),
    ("created", "created", _kv), ("source", "emulated / simulated", _kv), ("protocol", "protocol", _kv),
    ("specimen", "specimen", _kv),
]


def _source(p) -> str:
    if p["emulated"]:
        return f"emulated (truth: {p['truth'] or 'unnamed'})"
    if p["backend"] == "twin":
        return f"twin simulation ({p['model'] or '?'}, {p['parameters_name'] or '?'})"
    return "not marked as emulated"


def write_validation_index(path: Path, result: dict, columns) -> Path:
    """``index.html`` of the validation report: origin of the data, the table, figures, provenance."""
    cal = result["params"]
    parts = [f"<p class=\"banner\">Data origin: {esc(result['origin'])}</p>\n",
             f"<h2>Table 4 analogue</h2>\n<p>{esc(result['caption'])}</p>\n",
             table(columns, result["rows"], numeric=("samples", "max_rel_error", "paper_max_rel_error",
                                                     "rms_rel_error", "p99_rel_error")),
             f"<p class=\"legend\">{esc(result.get('legend', ''))}</p>\n" if result.get("legend") else "",
             "<p>Files: <code>table4.md</code>, <code>table4.csv</code>, <code>table4.tex</code>.</p>\n"]
    if result["figures"]:
        parts += ["<h2>Figures (measured in colour, twin dashed black)</h2>\n",
                  figures(result["figures"], result.get("figure_captions"))]
    parts.append("<h2>Parameters</h2>\n<table>\n")
    entries = [("file", cal["file"]), ("sha256", cal["sha256"]), ("name", result["params_name"]),
               ("calibration", cal["summary"])]
    if cal["record"]:
        entries += [("calibration model", cal.get("model")),
                    ("objective", f"{cal.get('metric')}: {cal.get('objective')}"),
                    ("converged", f"{cal.get('converged')} ({cal.get('message')})"),
                    ("evaluations", cal.get("nfev")), ("software", cal.get("software"))]
        entries += [(f"fitted on {r.get('specimen')}/{r.get('protocol')}",
                     f"{r.get('file')} (sha256 {r.get('sha256')})") for r in cal["runs"]]
    parts += [f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>\n" for k, v in entries]
    parts.append("</table>\n<h2>Runs</h2>\n")
    parts.append(table(RUN_COLUMNS, [{**p, "source": _source(p)} for p in result["runs"]]))
    if result["skipped"]:
        parts.append("<h2>Skipped files</h2>\n<ul>\n" + "".join(
            f"<li><code>{esc(s['file'])}</code>: {esc(s['reason'])}</li>\n" for s in result["skipped"]) + "</ul>\n")
    path = Path(path)
    path.write_text(page("Validation of the twin against measured runs", "".join(parts)))
    return path
