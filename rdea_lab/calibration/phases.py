"""Phases of a measured run (loading, unloading, hold) and the weight each sample has in a fit.

Definitions (stated once; the objective, the calibration record and the holds
benchmark quote them):

- a *hold* is a span the calibration envelope calls a hold
  (:func:`~rdea_lab.calibration.envelope.phases`, its one definition of phase: still,
  ``|d stretch / dt| < HOLD_RATE``, or drifting by less than its ``HOLD_STRETCH``, for at
  least `MIN_HOLD` seconds); a shorter still span (the turning point of a
  loading-unloading run, a rest before the ramp) belongs to the ramps;
- every other sample is on a *ramp*: *loading* where the stretch rate is >= 0,
  *unloading* where it is < 0 (for reports; the weights do not tell them apart).

The weighting rule (`sample_weights`, ``PHASE_RULE``): a hold of more samples
than the ramps of its run (all ramp samples together) weighs as much as those
ramps, its samples equally per decade of hold time (relaxation is about linear in
log t): sample ``i`` weighs the width of its cell in ``ln(t - t_start + dt)``
(``dt`` the hold's median sample interval, cell edges half-way between samples,
the first cell from ``dt / 2``); every other sample, ramp or a sample of a
shorter hold, weighs the same; a run of holds alone weighs each hold alike. The
weights of a run sum to 1, and every run counts equally. So a long hold does not
drown the ramps, and a run whose holds are shorter than its ramps (the paper's
ramp-sine tensile tests, which settle for a few seconds) keeps the weights it
had before holds were weighted: every sample ``1 / n``.
"""

from __future__ import annotations

import numpy as np

from . import envelope
from .envelope import HOLD_RATE, MIN_HOLD, central_rate
#: Phase codes of `phases`.
LOADING, UNLOADING, HOLD = 0, 1, 2
PHASE_NAMES = ("loading", "unloading", "hold")
#: The weighting rule in words (the calibration record's ``weighting.rule``).
PHASE_RULE = ("a hold of more samples than the ramps of its run weighs as much as those ramps, its samples "
              "equally per decade of hold time (the width of each sample's cell in ln(t - t_start + dt)); every "
              "other sample weighs the same (a run whose holds are shorter than its ramps: every sample 1/n); "
              f"a hold: the calibration envelope's (still, |d stretch/dt| < {HOLD_RATE:g} /s, or drifting by less "
              f"than {100 * envelope.HOLD_STRETCH[0]:g} % of the run's stretch range, for at least {MIN_HOLD:g} s); "
              "each run's weights sum to 1 and every run counts equally")


def hold_spans(t, stretch) -> list[tuple[int, int]]:
    """``(first, last)`` sample indices of each hold (inclusive), in time order.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], increasing.
    stretch : array_like, shape (n,)
        Stretch [-].
    """
    hold = envelope.phases(t, stretch)[0] == envelope.HOLD
    edges = np.diff(np.concatenate([[0], hold.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(int(a), int(b)) for a, b in zip(starts, stops)]


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
    w = np.ones(n)
    ramp = np.ones(n, bool)
    for a, b in spans:
        ramp[a:b + 1] = False
    n_ramp = int(ramp.sum())
    for a, b in spans:
        if n_ramp and b + 1 - a <= n_ramp:
            continue  # a hold no longer than the ramps: its samples weigh as ramp samples (1/n in all)
        cells = _log_cells(t[a:b + 1])
        w[a:b + 1] = cells / cells.sum() * (n_ramp or 1)
    return w / w.sum()


__all__ = ["HOLD", "LOADING", "MIN_HOLD", "PHASE_NAMES", "PHASE_RULE", "UNLOADING", "hold_spans", "phases",
           "sample_weights"]
