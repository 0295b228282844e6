"""The calibration envelope: the stretches, stretch rates, voltages and holds a fit has seen, and in
which combinations.

A prediction beyond them is an extrapolation: the parameters were never asked
to describe it. `envelope` measures a set of fitted runs, `beyond` lists, in
words, where another run leaves it, e.g. ``stretch 3.0 beyond the calibrated 1.5``
(one axis) or ``stretch 1.81-3.0 at 0.01 /s (loading, unloading): fitted only at
0.05 /s`` (each axis inside, the combination new).

Definitions (stated here once; the reports quote them):

- phase: each sample is loading, unloading, hold or turn. From the central-difference
  rate ``d stretch / dt`` [1/s] (``numpy.gradient`` on the samples' times) a sample moves
  up (``>= HOLD_RATE``), down (``<= -HOLD_RATE``) or is still; maximal spans of
  consecutive samples of one kind are cut; a moving span whose net stretch change
  (last sample minus first) is below `HOLD_STRETCH` (5 % of the run's stretch range,
  at least 0.002) is still: drift, overshoot and settling in a hold are a hold, not a
  slow rate; a still span shorter than `MIN_HOLD` between two spans of one direction
  is part of them (a pause). Then the moving spans are loading and unloading, the
  still spans of at least `MIN_HOLD` are holds, the shorter ones turns (turning
  points, not tested for their combination);
- stretch: the smallest and largest measured stretch of the runs [-];
- rate: over the loading and unloading samples that move (``|rate| >= HOLD_RATE``), per run
  the 1st to 99th percentile of ``|rate|`` (`RATE_PERCENTILES`, robust to the spikes of a
  differentiated, quantized signal and to the turning points), over the runs the lowest
  and the highest of those;
- voltage: the smallest and largest measured voltage [V];
- hold: the longest hold or turn [s] (first to last sample of the span; one still sample
  alone is 0 s);
- span rate: of a loading or unloading span, ``|net stretch change| / its duration`` [1/s]
  (first to last sample): the rate a protocol would name;
- joint coverage: each sample is a point ``(stretch / STRETCH_SCALE, log10(x) / LOG_SCALE,
  voltage / VOLTAGE_SCALE)`` of its phase, x its span rate [1/s] (loading, unloading) or
  its time since the start of its hold [s], at least `MIN_HOLD` (hold). A sample is covered
  when a fitted point of the same phase lies within `JOINT_DISTANCE` (Euclidean, in those
  units: a stretch 0.25 apart, or a factor 3 in rate or hold time, or 250 V, is 1). The
  envelope keeps the fitted points decimated (`Envelope.points`): one point per cell of
  side `CELL` in those units (the sample of the largest stretch in the cell, for holds
  the latest), so a fitted sample is within ``CELL * sqrt(3) / 2`` = 0.22 of a kept
  point; a run is tested by its own decimated points in the same way;
- a run leaves the envelope along an axis when its range passes the calibrated one, and
  in combination where its points that are inside every axis (stretch, rate, voltage,
  hold time within the ranges and their tolerances) are not covered; the holds of a run
  that leaves the hold axis (or of any run when no fitted run holds) are that axis's
  flag alone. Flags name the new combination and what the fitted runs did at that stretch.

A run is beyond the envelope only by more than a small tolerance, so that a
repeat at the same nominal setting is not flagged (3.0001 against 3.0): see
`STRETCH_RTOL`, `RATE_RTOL`, `VOLTAGE_TOL`, `HOLD_TOL`. An envelope read from a record
written before the joint test (no ``points``) is checked axis by axis only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

#: Below this |stretch rate| [1/s] a sample is still (0.1 %/s: far above the rate noise of a 1e-4 mm
#: encoder on an 80 mm strip sampled at 50 Hz, about 6e-5 /s, far below the slowest tensile test, 0.01 /s).
HOLD_RATE = 1e-3
#: A moving span whose net stretch change is below this is still: (fraction of the run's stretch range,
#: floor [-]). 5 % of a tensile ramp; the overshoot and settling of a 0.25 /s step to 2.0 is 0.9 % of it.
HOLD_STRETCH = (0.05, 0.002)
#: A still span shorter than this [s] is a turn or a pause, not a hold (the floor of `HOLD_TOL`).
MIN_HOLD = 1.0
#: Percentiles [%] of a run's |stretch rate| over its moving samples that make its rate range.
RATE_PERCENTILES = (1.0, 99.0)
#: Relative tolerance on the stretch range (0.1 %: 3.003 is still 3.0).
STRETCH_RTOL = 1e-3
#: Relative tolerance on the rate range (5 %: the 99th percentile of repeats at one nominal rate
#: scatters by about 1 %).
RATE_RTOL = 0.05
#: Tolerance on the voltage range: 1 % of the calibrated bound, and at least 5 V (a run at "0 V").
VOLTAGE_TOL = (0.01, 5.0)
#: Tolerance on the longest hold: 5 % of the calibrated one, and at least 1 s.
HOLD_TOL = (0.05, 1.0)
#: The joint test's units: stretch [-], decades of rate or hold time (a factor 3), voltage [V].
STRETCH_SCALE, LOG_SCALE, VOLTAGE_SCALE = 0.25, float(np.log10(3.0)), 250.0
#: A sample is covered by a fitted point of its phase within this distance (in the units above).
JOINT_DISTANCE = 1.0
#: Side of the cells [units above] that decimate the points an envelope keeps.
CELL = 0.25
#: Phase codes of `phases`.
LOADING, UNLOADING, HOLD, TURN = 1, -1, 0, 2
PHASE_NAMES = {LOADING: "loading", UNLOADING: "unloading", HOLD: "hold"}


@dataclass(frozen=True)
class Envelope:
    """What a set of runs covers (see the module's definitions).

    Attributes
    ----------
    stretch : tuple of float
        (min, max) stretch [-].
    rate : tuple of float
        (low, high) |stretch rate| [1/s] of the moving samples; (nan, nan) if nothing moves.
    voltage : tuple of float
        (min, max) voltage [V].
    hold : float
        Longest hold [s].
    runs : tuple of str
        Names of the runs measured.
    points : tuple of tuple
        The decimated points of the joint test, each ``(phase, stretch [-], x, voltage [V])``: phase
        ``loading``, ``unloading`` or ``hold``, x the span rate [1/s] or the time into the hold [s].
        Empty for an envelope read from an older record: then checked axis by axis only.
    """

    stretch: tuple
    rate: tuple
    voltage: tuple
    hold: float
    runs: tuple = ()
    points: tuple = field(default=(), repr=False)

    def mapping(self) -> dict:
        """YAML- and JSON-ready, with the definitions' constants; the points grouped by phase as
        ``[stretch, x, voltage]`` rows, 4 significant figures."""
        groups = {}
        for ph, lam, x, v in self.points:
            groups.setdefault(ph, []).append([_sig4(lam), _sig4(x), _sig4(v)])
        return {"stretch": [float(x) for x in self.stretch], "rate_per_s": [_finite(x) for x in self.rate],
                "voltage_V": [float(x) for x in self.voltage], "hold_s": float(self.hold), "runs": list(self.runs),
                "points": {ph: groups[ph] for ph in PHASE_NAMES.values() if ph in groups},
                "definitions": {"hold_rate_per_s": HOLD_RATE, "rate_percentiles": list(RATE_PERCENTILES),
                                "stretch_rtol": STRETCH_RTOL, "rate_rtol": RATE_RTOL,
                                "voltage_tol": list(VOLTAGE_TOL), "hold_tol": list(HOLD_TOL),
                                "hold_stretch": list(HOLD_STRETCH), "min_hold_s": MIN_HOLD,
                                "points": "[stretch, span rate 1/s (hold: time into the hold s), voltage V]",
                                "joint_scales": [STRETCH_SCALE, LOG_SCALE, VOLTAGE_SCALE],
                                "joint_distance": JOINT_DISTANCE, "cell": CELL}}

    @classmethod
    def from_mapping(cls, m: dict) -> "Envelope":
        """The inverse of `mapping` (e.g. a record's ``calibration.validation.envelope``); a null rate is nan;
        no ``points`` (an older record) gives an envelope checked axis by axis only."""
        pts = m.get("points") or {}
        return cls(stretch=tuple(float(x) for x in m["stretch"]),
                   rate=tuple(np.nan if x is None else float(x) for x in m["rate_per_s"]),
                   voltage=tuple(float(x) for x in m["voltage_V"]), hold=float(m["hold_s"]),
                   runs=tuple(str(r) for r in m.get("runs") or ()),
                   points=tuple((str(ph), float(a), float(b), float(c)) for ph in PHASE_NAMES.values()
                                for a, b, c in pts.get(ph, ())))

    def describe(self) -> str:
        """One line: ``stretch 1-1.5, rate 0.01-0.05 /s, voltage 0 V, longest hold 0 s``."""
        return (f"stretch {stretch_text(self.stretch[0])}-{stretch_text(self.stretch[1])}, "
                f"rate {_rate_range(self.rate)}, voltage {_volts_range(self.voltage)}, longest hold {_g(self.hold)} s"
                + ("" if self.points else " (no points recorded: checked axis by axis only)"))


def _sig4(x) -> float:
    return float(f"{x:.4g}")


def _finite(x):
    return float(x) if np.isfinite(x) else None


def _g(x: float) -> str:
    return f"{x:.3g}"


def stretch_text(x: float) -> str:
    """A stretch as a nominal one reads: ``3.0``, ``1.5``, ``1.25``."""
    s = _g(x)
    return s if "." in s or "e" in s else s + ".0"


def _volts(v: float) -> str:
    return "0 V" if abs(v) < VOLTAGE_TOL[1] else (f"{v / 1e3:.3g} kV" if abs(v) >= 1e3 else f"{v:.3g} V")


def _volts_range(v) -> str:
    return _volts(v[0]) if _volts(v[0]) == _volts(v[1]) else f"{_volts(v[0])} to {_volts(v[1])}"


def _rate_range(r) -> str:
    if not np.isfinite(r[0]):
        return "none (no moving samples)"
    return f"{_g(r[0])} /s" if _g(r[0]) == _g(r[1]) else f"{_g(r[0])}-{_g(r[1])} /s"


def central_rate(t, stretch) -> np.ndarray:
    """d stretch / dt [1/s] by central differences (one-sided at the ends).

    Parameters
    ----------
    t : array_like
        Sample times [s], increasing.
    stretch : array_like
        Stretch [-].
    """
    t, stretch = np.asarray(t, float), np.asarray(stretch, float)
    if t.size < 2:
        return np.zeros_like(stretch)
    return np.gradient(stretch, t)


def _starts(kind: np.ndarray) -> np.ndarray:
    """First index of each maximal span of equal values."""
    return np.flatnonzero(np.concatenate([[True], kind[1:] != kind[:-1]]))


def _spans(kind: np.ndarray):
    """(starts, stops (inclusive), span of each sample) of the maximal spans of equal ``kind``."""
    starts = _starts(kind)
    stops = np.concatenate([starts[1:], [kind.size]]) - 1
    mark = np.zeros(kind.size, np.int64)
    mark[starts] = 1
    return starts, stops, np.cumsum(mark) - 1


def phases(t, stretch) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's phase and its x: the span rate (loading, unloading) or the time into the hold.

    Parameters
    ----------
    t : array_like
        Sample times [s], increasing.
    stretch : array_like
        Stretch [-].

    Returns
    -------
    phase : numpy.ndarray of int8
        `LOADING`, `UNLOADING`, `HOLD` or `TURN` (the module's definition of phase).
    x : numpy.ndarray
        Span rate [1/s] (> 0) for loading and unloading, time since the hold's first sample [s] for
        holds and turns.
    """
    t, lam = np.asarray(t, float), np.asarray(stretch, float)
    if lam.size == 0:
        return np.zeros(0, np.int8), np.zeros(0)
    rate = central_rate(t, lam)
    kind = np.where(rate >= HOLD_RATE, 1, np.where(rate <= -HOLD_RATE, -1, 0)).astype(np.int8)
    rel, floor = HOLD_STRETCH
    tol = max(rel * float(np.ptp(lam)), floor)
    starts, stops, span = _spans(kind)
    drift = (kind[starts] != 0) & (np.abs(lam[stops] - lam[starts]) < tol)
    kind[drift[span]] = 0  # drift, overshoot, noise: still
    starts, stops, span = _spans(kind)
    k = kind[starts]
    before, after = np.concatenate([[0], k[:-1]]), np.concatenate([k[1:], [0]])
    pause = (k == 0) & (t[stops] - t[starts] < MIN_HOLD) & (before == after) & (before != 0)
    k = np.where(pause, before, k)
    kind = k[span]
    starts, stops, span = _spans(kind)
    k, dur = kind[starts], t[stops] - t[starts]
    phase = np.where(k != 0, k, np.where(dur >= MIN_HOLD, HOLD, TURN)).astype(np.int8)[span]
    with np.errstate(divide="ignore", invalid="ignore"):
        span_rate = np.abs(lam[stops] - lam[starts]) / dur
    x = np.where(kind != 0, span_rate[span], t - t[starts][span])
    return phase, x


def _ramp(run) -> np.ndarray:
    """The run's loading and unloading samples (a boolean mask)."""
    phase, _ = phases(run.t, run.stretch)
    return (phase == LOADING) | (phase == UNLOADING)


def moving_rates(run) -> np.ndarray:
    """|d stretch / dt| [1/s] of a run's loading and unloading samples that move (``>= HOLD_RATE``):
    drift in a hold is not among them."""
    a = np.abs(central_rate(run.t, run.stretch))[_ramp(run)]
    return a[a >= HOLD_RATE]


def longest_hold(t, stretch) -> float:
    """Longest span [s] of consecutive samples with |d stretch/dt| below `HOLD_RATE`."""
    t = np.asarray(t, float)
    still = np.abs(central_rate(t, stretch)) < HOLD_RATE
    if not still.any():
        return 0.0
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return float(np.max(t[stops] - t[starts]))


def _units(phase, stretch, x, voltage) -> np.ndarray:
    """The joint test's coordinates (module definitions), one row per point."""
    x = np.where(phase == HOLD, np.maximum(x, MIN_HOLD), x)
    return np.column_stack([np.asarray(stretch, float) / STRETCH_SCALE, np.log10(x) / LOG_SCALE,
                            np.asarray(voltage, float) / VOLTAGE_SCALE])


def decimate(phase, stretch, x, voltage) -> tuple:
    """One point per cell of side `CELL` and phase (the largest stretch, for holds the latest), as the
    `Envelope.points` tuples; turns are left out.

    Parameters
    ----------
    phase : array_like of int
        `LOADING`, `UNLOADING`, `HOLD` or `TURN` per sample.
    stretch, x, voltage : array_like
        Stretch [-], span rate [1/s] or time into the hold [s], voltage [V] per sample.

    Returns
    -------
    tuple of tuple
        ``(phase name, stretch, x, voltage)``, ordered by phase and cell.
    """
    phase, stretch, x, voltage = (np.asarray(a) for a in (phase, stretch, x, voltage))
    keep = phase != TURN
    phase, stretch, x, voltage = phase[keep], stretch[keep], x[keep], voltage[keep]
    if not phase.size:
        return ()
    order = np.argsort(-np.where(phase == HOLD, x, stretch), kind="stable")
    phase, stretch, x, voltage = phase[order], stretch[order], x[order], voltage[order]
    cells = np.floor(_units(phase, stretch, x, voltage) / CELL).astype(np.int64)
    _, first = np.unique(np.column_stack([phase, cells]), axis=0, return_index=True)
    return tuple((PHASE_NAMES[int(phase[i])], float(stretch[i]), float(x[i]), float(voltage[i])) for i in first)


def run_envelope(run) -> Envelope:
    """The envelope of one `RunData` (its times, stretch and voltage)."""
    phase, x = phases(run.t, run.stretch)
    a = np.abs(central_rate(run.t, run.stretch))
    moving = a[((phase == LOADING) | (phase == UNLOADING)) & (a >= HOLD_RATE)]
    rate = (tuple(float(r) for r in np.percentile(moving, RATE_PERCENTILES)) if moving.size
            else (np.nan, np.nan))
    still = (phase == HOLD) | (phase == TURN)
    return Envelope(stretch=(float(np.min(run.stretch)), float(np.max(run.stretch))), rate=rate,
                    voltage=(float(np.min(run.voltage)), float(np.max(run.voltage))),
                    hold=float(np.max(x[still])) if still.any() else 0.0, runs=(_name(run),),
                    points=decimate(phase, run.stretch, x, run.voltage))


def _arrays(points) -> tuple[np.ndarray, np.ndarray]:
    """Points as (phase codes, [stretch, x, voltage] rows)."""
    codes = {v: k for k, v in PHASE_NAMES.items()}
    if not points:
        return np.zeros(0, np.int8), np.zeros((0, 3))
    return (np.array([codes[p[0]] for p in points], np.int8), np.array([p[1:] for p in points], float))


def envelope(runs) -> Envelope:
    """The envelope of fitted runs: the union of each run's `run_envelope` (its points decimated again).

    Parameters
    ----------
    runs : sequence of RunData or Envelope

    Returns
    -------
    Envelope

    Raises
    ------
    ValueError
        No runs.
    """
    each = [r if isinstance(r, Envelope) else run_envelope(r) for r in runs]
    if not each:
        raise ValueError("no runs: an envelope needs at least one")
    lo = [e.rate[0] for e in each if np.isfinite(e.rate[0])]
    hi = [e.rate[1] for e in each if np.isfinite(e.rate[1])]
    code, p = _arrays([q for e in each for q in e.points])
    return Envelope(stretch=(min(e.stretch[0] for e in each), max(e.stretch[1] for e in each)),
                    rate=(min(lo), max(hi)) if lo else (np.nan, np.nan),
                    voltage=(min(e.voltage[0] for e in each), max(e.voltage[1] for e in each)),
                    hold=max(e.hold for e in each), runs=tuple(n for e in each for n in e.runs),
                    points=decimate(code, p[:, 0], p[:, 1], p[:, 2]) if code.size else ())


def beyond(calibrated: Envelope, run) -> tuple[str, ...]:
    """Where ``run`` (a `RunData` or its `Envelope`) leaves the ``calibrated`` envelope, in words.

    Parameters
    ----------
    calibrated : Envelope
        Of the fitted runs.
    run : RunData or Envelope
        The run to judge.

    Returns
    -------
    tuple of str
        Empty when it stays inside (within the module's tolerances); else, per axis, e.g.
        ``"stretch 3.0 beyond the calibrated 1.5"``, ``"rate 0.05 /s beyond the
        calibrated 0.01-0.03 /s"``, ``"hold 600 s beyond the calibrated 0 s"``,
        ``"voltage 2.6 kV beyond the calibrated 0 V"``, and ``below`` for the lower bounds;
        then the new combinations (`joint_flags`), e.g. ``"stretch 1.81-3.0 at 0.01 /s
        (loading, unloading): fitted only at 0.05 /s"``.
    """
    e = run if isinstance(run, Envelope) else run_envelope(run)
    c = calibrated
    flags = []
    if e.stretch[1] > c.stretch[1] * (1 + STRETCH_RTOL):
        flags.append(f"stretch {stretch_text(e.stretch[1])} beyond the calibrated {stretch_text(c.stretch[1])}")
    if e.stretch[0] < c.stretch[0] * (1 - STRETCH_RTOL):
        flags.append(f"stretch {stretch_text(e.stretch[0])} below the calibrated {stretch_text(c.stretch[0])}")
    if np.isfinite(e.rate[1]):
        if not np.isfinite(c.rate[1]):
            flags.append(f"rate {_g(e.rate[1])} /s beyond the calibrated {_rate_range(c.rate)}")
        else:
            if e.rate[1] > c.rate[1] * (1 + RATE_RTOL):
                flags.append(f"rate {_g(e.rate[1])} /s beyond the calibrated {_rate_range(c.rate)}")
            if e.rate[0] < c.rate[0] * (1 - RATE_RTOL):
                flags.append(f"rate {_g(e.rate[0])} /s below the calibrated {_rate_range(c.rate)}")
    rel, floor = VOLTAGE_TOL
    if e.voltage[1] > c.voltage[1] + max(rel * abs(c.voltage[1]), floor):
        flags.append(f"voltage {_volts(e.voltage[1])} beyond the calibrated {_volts_range(c.voltage)}")
    if e.voltage[0] < c.voltage[0] - max(rel * abs(c.voltage[0]), floor):
        flags.append(f"voltage {_volts(e.voltage[0])} below the calibrated {_volts_range(c.voltage)}")
    rel, floor = HOLD_TOL
    if e.hold > c.hold + max(rel * c.hold, floor):
        flags.append(f"hold {_g(e.hold)} s beyond the calibrated {_g(c.hold)} s")
    return tuple(flags) + joint_flags(c, e)


def flag_axis(flag: str) -> str:
    """The kind of extrapolation a `beyond` flag names: ``stretch``, ``rate``, ``voltage`` or ``hold`` for a
    flag of one axis (``"... beyond the calibrated ..."``, ``"... below the calibrated ..."``), and
    ``stretch-rate`` or ``hold-stretch`` for a new combination (`joint_flags`, ``"...: fitted ..."``)."""
    first = flag.split(" ", 1)[0]
    if " the calibrated " in flag:
        return first
    return "hold-stretch" if first == "hold" else "stretch-rate"


def _inside_axes(c: Envelope, code: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Which points lie inside every axis of ``c`` (its ranges and their tolerances)."""
    lam, x, v = p.T
    ok = (lam <= c.stretch[1] * (1 + STRETCH_RTOL)) & (lam >= c.stretch[0] * (1 - STRETCH_RTOL))
    rel, floor = VOLTAGE_TOL
    ok &= (v <= c.voltage[1] + max(rel * abs(c.voltage[1]), floor))
    ok &= (v >= c.voltage[0] - max(rel * abs(c.voltage[0]), floor))
    ramp = code != HOLD
    if np.isfinite(c.rate[1]):
        ok &= ~ramp | ((x <= c.rate[1] * (1 + RATE_RTOL)) & (x >= c.rate[0] * (1 - RATE_RTOL)))
    else:
        ok &= ~ramp
    rel, floor = HOLD_TOL
    return ok & (ramp | (x <= c.hold + max(rel * c.hold, floor)))


def uncovered(calibrated: Envelope, points) -> np.ndarray:
    """Which of ``points`` (`Envelope.points` tuples) are inside every axis of ``calibrated`` but farther
    than `JOINT_DISTANCE` from its points of the same phase (the module's joint coverage).

    Parameters
    ----------
    calibrated : Envelope
        With points (an envelope without them covers nothing jointly: all False).
    points : sequence of tuple
        ``(phase, stretch [-], x, voltage [V])``.

    Returns
    -------
    numpy.ndarray of bool
        One per point.
    """
    code, p = _arrays(points)
    out = np.zeros(code.size, bool)
    if not calibrated.points or not code.size:
        return out
    ccode, cp = _arrays(calibrated.points)
    test = _inside_axes(calibrated, code, p)
    rel, floor = HOLD_TOL
    held_long = code == HOLD
    if not (ccode == HOLD).any() or p[held_long, 1].max(initial=0.0) > calibrated.hold + max(rel * calibrated.hold,
                                                                                                floor):
        test &= ~held_long  # no fitted hold, or a run beyond the hold axis: its holds are that axis's flag
    for ph in PHASE_NAMES:
        mine, theirs = test & (code == ph), ccode == ph
        if not mine.any():
            continue
        if not theirs.any():
            out[mine] = True
            continue
        d, _ = cKDTree(_units(ccode[theirs], *cp[theirs].T)).query(_units(code[mine], *p[mine].T))
        out[mine] = d > JOINT_DISTANCE
    return out


def _rates_text(rates) -> str:
    """Span rates [1/s] at 2 significant figures: up to three listed (``0.01, 0.05 /s``), more as a range."""
    r = sorted({float(f"{x:.2g}") for x in rates})
    return (", ".join(f"{x:g}" for x in r) if len(r) <= 3 else f"{r[0]:g}-{r[-1]:g}") + " /s"


def _stretch_span(lam) -> str:
    lo, hi = stretch_text(float(np.min(lam))), stretch_text(float(np.max(lam)))
    return lo if lo == hi else f"{lo}-{hi}"


def _volt_text(v) -> str:
    """Voltages [V] as labels: up to three listed (``0 V, 2.6 kV``), more as a range."""
    labels = sorted({_volts(x) for x in v}, key=lambda u: float(np.min([x for x in v if _volts(x) == u])))
    return ", ".join(labels) if len(labels) <= 3 else f"{_volts(np.min(v))} to {_volts(np.max(v))}"


def _fitted_text(q: np.ndarray, volts: bool, what) -> str:
    """``what(rows)`` of fitted rows ``q`` ([stretch, x, voltage]), per voltage where voltages matter
    (up to three; more: over all, with their range)."""
    if not volts:
        return what(q)
    labels = np.array([_volts(x) for x in q[:, 2]])
    if len(set(labels)) > 3:
        return f"{what(q)} ({_volt_text(q[:, 2])})"
    order = sorted(set(labels), key=lambda u: float(np.min(q[labels == u, 2])))
    return ", ".join(f"{what(q[labels == u])} ({u})" for u in order)


def joint_flags(calibrated: Envelope, run: Envelope) -> tuple[str, ...]:
    """The combinations of ``run`` that ``calibrated`` never covered (its `uncovered` points), in words.

    Parameters
    ----------
    calibrated, run : Envelope
        Of the fitted runs and of the run to judge.

    Returns
    -------
    tuple of str
        For uncovered loading and unloading points one flag, e.g. ``"stretch 1.81-3.0 at 0.01 /s
        (loading, unloading): fitted only at 0.05 /s"``: their stretches and span rates, then the rates
        of the fitted points of those phases at those stretches (``no fitted loading at that stretch`` if
        none); voltages are named where any is not 0 V. One per stretch of uncovered hold points, e.g.
        ``"hold at stretch 3.0 to 300 s: fitted holds only at stretch 2.0 (to 300 s)"``.
    """
    new = uncovered(calibrated, run.points)
    if not new.any():
        return ()
    code, p = _arrays(run.points)
    ccode, cp = _arrays(calibrated.points)
    code, p = code[new], p[new]
    volts = bool(np.any(np.abs(cp[:, 2]) >= VOLTAGE_TOL[1]) or np.any(np.abs(p[:, 2]) >= VOLTAGE_TOL[1]))
    flags = []
    ramp = code != HOLD
    if ramp.any():
        phs = [ph for ph in (LOADING, UNLOADING) if (code[ramp] == ph).any()]
        lo, hi = p[ramp, 0].min(), p[ramp, 0].max()
        near = np.isin(ccode, phs) & (cp[:, 0] >= lo - CELL * STRETCH_SCALE) & (cp[:, 0] <= hi + CELL * STRETCH_SCALE)
        names = ", ".join(PHASE_NAMES[ph] for ph in phs)
        what = ("fitted only at " + _fitted_text(cp[near], volts, lambda q: _rates_text(q[:, 1])) if near.any()
                else f"no fitted {names} at that stretch")
        flags.append(f"stretch {_stretch_span(p[ramp, 0])} at {_rates_text(p[ramp, 1])}"
                     f"{', ' + _volt_text(p[ramp, 2]) if volts else ''} ({names}): {what}")
    held, fitted_holds = ~ramp, ccode == HOLD
    levels = np.array([stretch_text(x) for x in p[:, 0]])
    for s in sorted(set(levels[held]), key=float):
        sel = held & (levels == s)
        near = fitted_holds & (np.abs(cp[:, 0] - float(s)) <= STRETCH_SCALE)
        if near.any():
            what = "fitted holds near that stretch only " + _fitted_text(cp[near], volts,
                                                                          lambda q: f"to {_g(q[:, 1].max())} s")
        else:
            fitted = sorted({stretch_text(x) for x in cp[fitted_holds, 0]}, key=float)
            what = f"fitted holds only at stretch {', '.join(fitted)} (to {_g(cp[fitted_holds, 1].max())} s)"
        flags.append(f"hold at stretch {s}{', ' + _volt_text(p[sel, 2]) + ',' if volts else ''} to "
                     f"{_g(p[sel, 1].max())} s: {what}")
    return tuple(flags)


def _name(run) -> str:
    return f"{run.specimen}/{run.protocol}"


__all__ = ["CELL", "Envelope", "HOLD_RATE", "HOLD_STRETCH", "HOLD_TOL", "JOINT_DISTANCE", "LOG_SCALE", "MIN_HOLD",
           "RATE_PERCENTILES", "RATE_RTOL", "STRETCH_RTOL", "STRETCH_SCALE", "VOLTAGE_SCALE", "VOLTAGE_TOL", "beyond",
           "central_rate", "decimate", "envelope", "joint_flags", "longest_hold", "moving_rates", "phases",
           "run_envelope", "stretch_text", "uncovered"]
