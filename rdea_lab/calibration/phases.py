"""Phases of a measured run (loading, unloading, hold) and the weight each sample has in a fit.

Definitions (stated once; the objective, the calibration record and the holds
benchmark quote them):

- a sample is *still* where ``|d stretch / dt| < HOLD_RATE`` (central differences,
  :func:`~rdea_lab.calibration.envelope.central_rate`, the envelope's own definition);
- a *hold* is a span of consecutive still samples lasting at least `MIN_HOLD`
  seconds (first to last sample); a shorter still span (the turning point of a
  loading-unloading run, a rest before the ramp) belongs to the ramps;
- every other sample is on a *ramp*: *loading* where the stretch rate is >= 0,
  *unloading* where it is < 0 (for reports; the weights do not tell them apart).

The weighting rule (`sample_weights`, ``PHASE_RULE``): within a run, its ramps
(all ramp samples together) and each of its holds weigh equally, ``1 / (1 +
holds)`` of the run each; within the ramps every sample weighs the same (at one
constant rate that is equal weight per unit of stretch, so loading and
unloading to one stretch weigh alike); within a hold the samples weigh equally
per decade of hold time (relaxation is about linear in log t): sample ``i``
weighs the width of its cell in ``ln(t - t_start + dt)`` (``dt`` the hold's
median sample interval, cell edges half-way between samples, the first cell
from ``dt / 2``). The weights of a run sum to 1. A run without a hold keeps
the weights it had before holds were weighted: every sample ``1 / n``.
"""

from __future__ import annotations

import numpy as np

from .envelope import HOLD_RATE, central_rate

#: Shortest still span [s] that is a hold (the envelope's hold tolerance floor, 1 s: the turning point
#: of a loading-unloading run at 0.01 /s is still for about 0.1 s).
MIN_HOLD = 1.0
#: Phase codes of `phases`.
LOADING, UNLOADING, HOLD = 0, 1, 2
PHASE_NAMES = ("loading", "unloading", "hold")
#: The weighting rule in words (the calibration record's ``weighting.rule``).
PHASE_RULE = ("within a run, its ramps (loading and unloading together) and each of its holds weigh equally "
              f"(a hold: still, |d stretch/dt| < {HOLD_RATE:g} /s, for at least {MIN_HOLD:g} s); ramp samples "
              "weigh equally; hold samples weigh equally per decade of hold time (the width of each sample's "
              "cell in ln(t - t_start + dt)); each run's weights sum to 1 and every run counts equally; a run "
              "without a hold: every sample 1/n")


def hold_spans(t, stretch) -> list[tuple[int, int]]:
    """``(first, last)`` sample indices of each hold (inclusive), in time order.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], increasing.
    stretch : array_like, shape (n,)
        Stretch [-].
    """
    t = np.asarray(t, float)
    still = np.abs(central_rate(t, stretch)) < HOLD_RATE
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(int(a), int(b)) for a, b in zip(starts, stops) if t[b] - t[a] >= MIN_HOLD]


def phases(t, stretch) -> np.ndarray:
    """The phase of every sample: `LOADING`, `UNLOADING` or `HOLD` (int8; see the module's definitions).

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], increasing.
    stretch : array_like, shape (n,)
        Stretch [-].

    Returns
    -------
    numpy.ndarray of int8, shape (n,)
    """
    t = np.asarray(t, float)
    out = np.where(central_rate(t, stretch) < 0.0, UNLOADING, LOADING).astype(np.int8)
    for a, b in hold_spans(t, stretch):
        out[a:b + 1] = HOLD
    return out


def _log_cells(t) -> np.ndarray:
    """Width of each sample's cell in ``ln(t - t[0] + dt)`` (see the module docstring)."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    tau = t - t[0] + dt
    edges = np.concatenate([[dt / 2], 0.5 * (tau[1:] + tau[:-1]), [tau[-1] + dt / 2]])
    return np.diff(np.log(edges))


def sample_weights(t, stretch) -> np.ndarray:
    """Weight of each sample of one run in the fit (the module's rule); they sum to 1.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], increasing.
    stretch : array_like, shape (n,)
        Stretch [-].

    Returns
    -------
    numpy.ndarray, shape (n,)
        Non-negative weights [-], summing to 1; ``1 / n`` each for a run without a hold.
    """
    t = np.asarray(t, float)
    n = t.size
    spans = hold_spans(t, stretch)
    if not spans:
        return np.full(n, 1.0 / n)
    w = np.zeros(n)
    ramp = np.ones(n, bool)
    for a, b in spans:
        ramp[a:b + 1] = False
    parts = len(spans) + (1 if ramp.any() else 0)
    for a, b in spans:
        cells = _log_cells(t[a:b + 1])
        w[a:b + 1] = cells / cells.sum() / parts
    if ramp.any():
        w[ramp] = 1.0 / ramp.sum() / parts
    return w


__all__ = ["HOLD", "LOADING", "MIN_HOLD", "PHASE_NAMES", "PHASE_RULE", "UNLOADING", "hold_spans", "phases",
           "sample_weights"]
