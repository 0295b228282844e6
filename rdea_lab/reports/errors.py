"""The validation report's error measures of a long run, accumulated block by block.

:func:`rdea_lab.reports.validation.compare` takes a run's whole measured and predicted series;
`ErrorAccumulator` gives the same numbers from blocks of them, holding only running sums, the peak and
the largest 1 % of the errors (what the 99th percentile needs), and `long_run_errors` feeds it from the
twin predicted block by block (:func:`rdea_lab.twin.predict.predict_blocks`) on a lazily opened run.
"""

from __future__ import annotations

import math

import numpy as np

from ..calibration.objective import ERROR_PERCENTILE


class ErrorAccumulator:
    """`compare`'s numbers (max, rms and 99th-percentile error over the peak) from blocks of a run.

    Parameters
    ----------
    samples : int
        Upper bound of the samples that will be added (the run's length): the 99th percentile needs
        the largest ``ceil(0.01 samples) + 2`` errors, which are kept.

    Notes
    -----
    With ``m`` finite predictions, ``numpy.percentile``'s linear rule interpolates between the sorted
    absolute errors at ``floor(p)`` and ``floor(p) + 1``, ``p = 0.99 (m - 1)``; both lie among the
    largest ``0.01 m + 2``, which `add` keeps (``numpy.partition`` of the kept ones and the new block).
    """

    def __init__(self, samples: int):
        self.keep = math.ceil((1.0 - ERROR_PERCENTILE / 100.0) * int(samples)) + 2
        self.capacity = int(samples)
        self.count = 0  # finite predictions
        self.added = 0  # samples
        self.sum_sq = 0.0
        self.max_abs = 0.0
        self.peak = 0.0
        self.top = np.empty(0)

    def add(self, measured, predicted) -> ErrorAccumulator:
        """Add a block: measured and predicted samples [N] or [F] (a prediction NaN where no equilibrium)."""
        measured, predicted = np.asarray(measured, float), np.asarray(predicted, float)
        self.added += measured.size
        if self.added > self.capacity:
            raise ValueError(f"ErrorAccumulator: {self.added} samples added, made for {self.capacity}")
        if measured.size:
            self.peak = float(np.maximum(self.peak, np.max(np.abs(measured))))  # NaN stays NaN, as in compare
        ok = np.isfinite(predicted)
        r = np.abs(predicted[ok] - measured[ok])
        if r.size:
            self.count += r.size
            self.sum_sq += float(np.dot(r, r))
            self.max_abs = max(self.max_abs, float(r.max()))
            top = np.concatenate([self.top, r])
            self.top = np.partition(top, top.size - self.keep)[top.size - self.keep:] if top.size > self.keep else top
        return self

    def percentile(self) -> float:
        """The ``ERROR_PERCENTILE`` th percentile of the absolute errors (numpy's linear rule)."""
        m, top = self.count, np.sort(self.top)
        pos = ERROR_PERCENTILE / 100.0 * (m - 1)
        lo = int(math.floor(pos))
        g = pos - lo
        first = m - top.size  # the rank (from the bottom) of top[0]
        a = top[lo - first]
        b = top[min(lo + 1, m - 1) - first]
        return float(b - (b - a) * (1.0 - g)) if g >= 0.5 else float(a + (b - a) * g)

    def result(self) -> dict:
        """``max_rel_error``, ``rms_rel_error``, ``p99_rel_error`` [-], ``rms_error`` (the unit of the data),
        ``peak`` and ``excluded`` (samples without a finite prediction): `compare`'s dict."""
        excluded = self.added - self.count
        if not self.count or self.peak == 0.0:
            return {"max_rel_error": math.nan, "rms_rel_error": math.nan, "p99_rel_error": math.nan,
                    "rms_error": math.nan, "peak": self.peak, "excluded": excluded}
        rms = math.sqrt(self.sum_sq / self.count)
        return {"max_rel_error": self.max_abs / self.peak, "rms_rel_error": rms / self.peak,
                "p99_rel_error": self.percentile() / self.peak, "rms_error": rms, "peak": self.peak,
                "excluded": excluded}


def long_run_errors(ds, params=None, model: str = "su", *, quantity: str = "force", block=None,
                    **kwargs) -> dict:
    """The error measures of the twin against a run, predicted and compared block by block.

    Parameters
    ----------
    ds : xarray.Dataset
        A run, opened lazily (:func:`rdea_lab.store.open_run`) or loaded.
    params : ParameterSet or path, optional
        Material; default the run's own (twin runs).
    model : {"su", "1r", "3r", "cr"}
        Quasi-static model.
    quantity : {"force", "capacitance"}
        Compared over every sample (force) or where the capacitance was measured (finite).
    block : int, optional
        Samples per block (default `rdea_lab.twin.predict.BLOCK`).
    **kwargs
        Passed to :func:`rdea_lab.twin.predict.predict_blocks` (``specimen``, ``protocol``).

    Returns
    -------
    dict
        `ErrorAccumulator.result`: the keys of `compare`, the same numbers as
        ``compare(measured, predict(ds, ...)[quantity])`` (to rounding).

    Raises
    ------
    ValueError
        A ``quantity`` other than force or capacitance, or one the run does not have.
    """
    from ..twin.predict import BLOCK, predict_blocks

    if quantity not in ("force", "capacitance") or quantity not in ds:
        raise ValueError(f"quantity: {quantity!r}; allowed: force or capacitance, a variable of the run")
    blocks = predict_blocks(ds, params, model, block=block or BLOCK, **kwargs)
    acc = ErrorAccumulator(blocks.samples)
    for a, b, data in blocks:
        measured = np.asarray(ds[quantity][a:b].values, float)
        predicted = data[quantity]
        if quantity == "capacitance":
            where = np.isfinite(measured)
            measured, predicted = measured[where], predicted[where]
        acc.add(measured, predicted)
    return acc.result()
