"""Repeats: runs of one test, how much two measurements of it differ, and a prediction judged against that.

Two measurements of the same test never agree exactly (noise, the specimen's
history, the rig); no model can be asked to be closer to a measurement than a
second measurement is. The validation report gives, where runs repeat a test,
their spread, and judges each prediction against it.

Definitions (stated here once; the report quotes them):

- the same test (`repeat_key`): runs of one specimen and one protocol kind and quantity
  measured (never twin simulations: a model, not a measurement), and
  - imported runs (backend ``import``): the same nominal stretch rate and maximum stretch
    (:func:`~rdea_lab.calibration.crossval.nominal_rate`, :func:`~rdea_lab.calibration.crossval.nominal_stretch`)
    and voltage (as the table writes it): their protocol attribute names the source file;
  - every other run (emulator, rig): the same protocol as run, the sha256 of the dataset's
    ``protocol`` attribute;
- pair difference (`pair_difference`) of runs a and b: on a's samples of the row (the ones its
  errors are measured on), with the time counted from each run's first sample and within the
  shorter run's duration, the rms of ``y_a(t) - y_b(t)``, y the force (or capacitance) and
  y_b linearly interpolated [N or F];
- a run's repeat spread: ``sqrt(mean over its repeats of the pair difference squared)`` over
  the run's peak (the largest |measured| force or capacitance: the scale of the report's other
  errors) [-]. Two runs that differ only by white noise of std s each: ``s * sqrt(2) / peak``;
- judged: ``rms / repeat spread``, the prediction's rms/peak over the run's repeat spread;
  within the measurement's repeatability when at most 1: the twin is no farther from the
  measurement than a second measurement of the same test is (a twin equal to the truth,
  against white noise, scores ``1 / sqrt(2)``).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from ..calibration.crossval import nominal_rate, nominal_stretch
from ..calibration.envelope import stretch_text
from . import tables

#: Within the measurement's repeatability when rms / repeat spread is at most this [-].
WITHIN = 1.0
#: The repeat columns of the table (shown when some run has a repeat): (key, header, format).
REPEAT_COLUMNS = [("repeat_spread", "repeat spread [%]", tables.percent),
                  ("rms_over_spread", "rms / repeat spread", tables.number(".2f"))]
#: The CSV's repeat keys: the test's label, the other runs of it, the spread [-] and the ratio [-].
REPEAT_KEYS = ["test", "repeats", "repeat_spread", "rms_over_spread"]
#: The legend's sentence on the repeat columns.
REPEAT_LEGEND = ("Repeat spread: where runs repeat a test (same specimen and protocol; imported files: same "
                 "nominal rate, maximum stretch and voltage), the rms difference between the run and its "
                 "repeats (time from each run's start, the other interpolated), over the run's peak; "
                 "rms / repeat spread at most 1: the twin is within the measurement's own repeatability.")


def repeat_key(attrs, run, voltage_label: str, quantity: str) -> str:
    """Which test a run is, as a label; runs with one label repeat each other (``""``: a simulation,
    no repeats).

    Parameters
    ----------
    attrs : mapping
        The dataset's attributes (``backend``, ``protocol``).
    run : RunData
        The run (its specimen, kind, stretch and times).
    voltage_label : str
        The run's voltage as the table writes it (``0 V``, ``2.60 kV``).
    quantity : str
        ``force`` or ``capacitance``: what the row compares.

    Returns
    -------
    str
        E.g. ``vhb4910 tensile force: 0.03 /s to 1.5, 0 V (imported)`` or ``specimen-1 custom force:
        protocol cf_short (sha256 3f2a9c01b7de)``.
    """
    backend = str(attrs.get("backend", ""))
    if backend == "twin":
        return ""
    head = f"{run.specimen} {run.kind} {quantity}"
    if backend == "import":
        return (f"{head}: {nominal_rate(run):g} /s to {stretch_text(nominal_stretch(run))}, {voltage_label} "
                "(imported)")
    sha = hashlib.sha256(str(attrs.get("protocol", "")).encode()).hexdigest()
    return f"{head}: protocol {run.protocol} (sha256 {sha[:12]})"


def pair_difference(t_a, y_a, t_b, y_b) -> float:
    """The rms difference [unit of y] between two measurements of one test, on a's samples.

    Parameters
    ----------
    t_a, t_b : array_like
        Sample times [s] of each run, increasing; counted here from each one's first sample.
    y_a, y_b : array_like
        The measured quantity (force [N], capacitance [F]) at those times.

    Returns
    -------
    float
        ``rms(y_a - interp(y_b))`` over a's samples within the shorter duration (nan if none).
    """
    t_a, t_b = np.asarray(t_a, float), np.asarray(t_b, float)
    if not (t_a.size and t_b.size):
        return math.nan
    ta, tb = t_a - t_a[0], t_b - t_b[0]
    keep = ta <= tb[-1]
    if not keep.any():
        return math.nan
    d = np.asarray(y_a, float)[keep] - np.interp(ta[keep], tb, np.asarray(y_b, float))
    return float(np.sqrt(np.mean(d**2)))


def measured(series: dict, quantity: str) -> tuple[np.ndarray, np.ndarray]:
    """(times from the run's first sample [s], measured values) of the samples a row's errors use."""
    t = np.asarray(series["t"], float)
    t = t - t[0]
    if quantity == "capacitance":
        return t[series["cap_mask"]], np.asarray(series["capacitance"], float)
    window = series.get("window")
    window = np.ones(t.size, bool) if window is None else window
    return t[window], np.asarray(series["force"], float)[window]


def add_repeats(evaluated) -> tuple[dict, ...]:
    """Give every evaluated row its repeats, repeat spread and ``rms / repeat spread`` (the module's
    definitions); rows without a repeat get ``repeats`` ``""`` and None.

    Parameters
    ----------
    evaluated : sequence of dict
        ``{"row", "series"}`` of the validation report's runs (their rows have ``test``, ``quantity``,
        ``peak``, ``rms_rel_error`` and ``name``); changed in place.

    Returns
    -------
    tuple of dict
        One per repeated test: ``test``, ``runs`` (names), ``spread`` and ``ratio`` (per run, [-]),
        ``within`` (every ratio at most `WITHIN`).
    """
    groups = {}
    for e in evaluated:
        r = e["row"]
        r.update({"repeats": "", "repeat_spread": None, "rms_over_spread": None})
        if r.get("test"):
            groups.setdefault(r["test"], []).append(e)
    out = []
    for test, members in groups.items():
        if len(members) < 2:
            continue
        data = [measured(e["series"], e["row"]["quantity"]) for e in members]
        for i, e in enumerate(members):
            r = e["row"]
            d2 = [pair_difference(*data[i], *data[j]) ** 2 for j in range(len(members)) if j != i]
            spread = math.sqrt(float(np.mean(d2))) / r["peak"] if r["peak"] else math.nan
            r["repeats"] = ", ".join(m["row"]["name"] for j, m in enumerate(members) if j != i)
            r["repeat_spread"] = spread
            r["rms_over_spread"] = (r["rms_rel_error"] / spread if spread and math.isfinite(spread)
                                    and math.isfinite(r["rms_rel_error"]) else math.nan)
        ratios = [m["row"]["rms_over_spread"] for m in members]
        out.append({"test": test, "runs": [m["row"]["name"] for m in members],
                    "spread": [m["row"]["repeat_spread"] for m in members], "ratio": ratios,
                    "within": all(math.isfinite(x) and x <= WITHIN for x in ratios)})
    return tuple(out)


def repeat_lines(repeats) -> list[str]:
    """One sentence per repeated test: its runs, their spread, the twin's ratio and the verdict."""
    lines = []
    for g in repeats:
        each = ", ".join(f"{n} {tables.percent(s)} % (ratio {tables.number('.2f')(x)})"
                         for n, s, x in zip(g["runs"], g["spread"], g["ratio"]))
        verdict = ("within the measurement's own repeatability" if g["within"] else
                   "not within the measurement's own repeatability (a ratio above 1)")
        lines.append(f"{g['test']}: {len(g['runs'])} runs, repeat spread (rms of peak) {each}: the twin is "
                     f"{verdict}.")
    return lines


def columns_for(columns, rows) -> list:
    """``columns`` with the repeat columns before ``notes`` when some row has a repeat."""
    if not any(r.get("repeats") for r in rows):
        return list(columns)
    keys = [k for k, _, _ in columns]
    at = keys.index("notes") if "notes" in keys else len(columns)
    return list(columns[:at]) + REPEAT_COLUMNS + list(columns[at:])


__all__ = ["REPEAT_COLUMNS", "REPEAT_KEYS", "REPEAT_LEGEND", "WITHIN", "add_repeats", "columns_for", "measured",
           "pair_difference", "repeat_key", "repeat_lines"]
