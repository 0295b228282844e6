"""The calibration envelope: the stretches, stretch rates, voltages and holds a fit has seen.

A prediction beyond them is an extrapolation: the parameters were never asked
to describe it. `envelope` measures a set of fitted runs, `beyond` lists, in
words, where another run leaves it, e.g. ``stretch 3.0 beyond the calibrated 1.5``.

Definitions (stated here once; the reports quote them):

- stretch: the smallest and largest measured stretch of the runs [-];
- rate: the stretch rate ``|d stretch / dt|`` [1/s] by central differences
  (``numpy.gradient`` on the samples' times), over the samples where it moves
  (``|rate| >= HOLD_RATE``); per run its 1st to 99th percentile (`RATE_PERCENTILES`,
  robust to the spikes of a differentiated, quantized signal and to the turning
  points), over the runs the lowest and the highest of those;
- voltage: the smallest and largest measured voltage [V];
- hold: the longest time span [s] of consecutive samples with ``|rate| < HOLD_RATE``
  (first to last sample of the span; one still sample alone is 0 s).

A run is beyond the envelope only by more than a small tolerance, so that a
repeat at the same nominal setting is not flagged (3.0001 against 3.0): see
`STRETCH_RTOL`, `RATE_RTOL`, `VOLTAGE_TOL`, `HOLD_TOL`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Below this |stretch rate| [1/s] a sample is still (0.1 %/s: far above the rate noise of a 1e-4 mm
#: encoder on an 80 mm strip sampled at 50 Hz, about 6e-5 /s, far below the slowest tensile test, 0.01 /s).
HOLD_RATE = 1e-3
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
    """

    stretch: tuple
    rate: tuple
    voltage: tuple
    hold: float
    runs: tuple = ()

    def mapping(self) -> dict:
        """YAML- and JSON-ready, with the definitions' constants."""
        return {"stretch": [float(x) for x in self.stretch], "rate_per_s": [_finite(x) for x in self.rate],
                "voltage_V": [float(x) for x in self.voltage], "hold_s": float(self.hold), "runs": list(self.runs),
                "definitions": {"hold_rate_per_s": HOLD_RATE, "rate_percentiles": list(RATE_PERCENTILES),
                                "stretch_rtol": STRETCH_RTOL, "rate_rtol": RATE_RTOL,
                                "voltage_tol": list(VOLTAGE_TOL), "hold_tol": list(HOLD_TOL)}}

    @classmethod
    def from_mapping(cls, m: dict) -> "Envelope":
        """The inverse of `mapping` (e.g. a record's ``calibration.validation.envelope``); a null rate is nan."""
        return cls(stretch=tuple(float(x) for x in m["stretch"]),
                   rate=tuple(np.nan if x is None else float(x) for x in m["rate_per_s"]),
                   voltage=tuple(float(x) for x in m["voltage_V"]), hold=float(m["hold_s"]),
                   runs=tuple(str(r) for r in m.get("runs") or ()))

    def describe(self) -> str:
        """One line: ``stretch 1-1.5, rate 0.01-0.05 /s, voltage 0 V, longest hold 0 s``."""
        return (f"stretch {stretch_text(self.stretch[0])}-{stretch_text(self.stretch[1])}, "
                f"rate {_rate_range(self.rate)}, voltage {_volts_range(self.voltage)}, longest hold {_g(self.hold)} s")


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


def moving_rates(run) -> np.ndarray:
    """|d stretch / dt| [1/s] of a run's samples that move (``>= HOLD_RATE``)."""
    a = np.abs(central_rate(run.t, run.stretch))
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


def run_envelope(run) -> Envelope:
    """The envelope of one `RunData` (its times, stretch and voltage)."""
    moving = moving_rates(run)
    rate = (tuple(float(x) for x in np.percentile(moving, RATE_PERCENTILES)) if moving.size
            else (np.nan, np.nan))
    return Envelope(stretch=(float(np.min(run.stretch)), float(np.max(run.stretch))), rate=rate,
                    voltage=(float(np.min(run.voltage)), float(np.max(run.voltage))),
                    hold=longest_hold(run.t, run.stretch), runs=(_name(run),))


def envelope(runs) -> Envelope:
    """The envelope of fitted runs: the union of each run's `run_envelope`.

    Parameters
    ----------
    runs : sequence of RunData
    """
    each = [r if isinstance(r, Envelope) else run_envelope(r) for r in runs]
    if not each:
        raise ValueError("no runs: an envelope needs at least one")
    lo = [e.rate[0] for e in each if np.isfinite(e.rate[0])]
    hi = [e.rate[1] for e in each if np.isfinite(e.rate[1])]
    return Envelope(stretch=(min(e.stretch[0] for e in each), max(e.stretch[1] for e in each)),
                    rate=(min(lo), max(hi)) if lo else (np.nan, np.nan),
                    voltage=(min(e.voltage[0] for e in each), max(e.voltage[1] for e in each)),
                    hold=max(e.hold for e in each), runs=tuple(n for e in each for n in e.runs))


def beyond(calibrated: Envelope, run) -> tuple[str, ...]:
    """Where ``run`` (a `RunData` or its `Envelope`) leaves the ``calibrated`` envelope, in words.

    Returns
    -------
    tuple of str
        Empty when it stays inside (within the module's tolerances); else e.g.
        ``"stretch 3.0 beyond the calibrated 1.5"``, ``"rate 0.05 /s beyond the
        calibrated 0.01-0.03 /s"``, ``"hold 600 s beyond the calibrated 0 s"``,
        ``"voltage 2.6 kV beyond the calibrated 0 V"``, and ``below`` for the lower bounds.
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
    return tuple(flags)


def _name(run) -> str:
    return f"{run.specimen}/{run.protocol}"


__all__ = ["Envelope", "HOLD_RATE", "HOLD_TOL", "RATE_PERCENTILES", "RATE_RTOL", "STRETCH_RTOL", "VOLTAGE_TOL",
           "beyond", "envelope", "longest_hold", "moving_rates", "run_envelope", "central_rate", "stretch_text"]
