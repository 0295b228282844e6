"""`predict`: the twin on a run's own history (or on arrays), as a Dataset on its time axis."""

from __future__ import annotations

import json
from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..physics.selection import select_model
from ..specs import MODEL_CHOICES, SpecError, as_params, params_from_yaml, specimen_from_yaml
from ..physics.result import OK, is_valid
from ..specs import check_limits
from ..specs.status import STATUS_NAMES
from .simulate import TwinStream, as_geometry, history_limits, simulate, simulation_attrs

from ..specs.importing import MIN_STRETCH  # below it a compressed specimen; between it and 1, noise
MODELS = MODEL_CHOICES


def _history(history):
    """``(t, stretch, voltage, dataset or None)`` from a run Dataset, a mapping or a (t, stretch, voltage) tuple."""
    if isinstance(history, xr.Dataset):
        missing = [k for k in ("time", "stretch") if k not in history.variables]
        if missing:
            raise ValueError(f"history: the dataset has no {', '.join(missing)}; a run has time, stretch and voltage")
        t = np.asarray(history["time"].values, float)
        v = np.asarray(history["voltage"].values, float) if "voltage" in history else np.zeros_like(t)
        return t, np.asarray(history["stretch"].values, float), v, history
    if isinstance(history, Mapping):
        try:
            t, lam = history["time"], history["stretch"]
        except KeyError as exc:
            raise ValueError(f"history: no {exc.args[0]!r}; give time [s], stretch [-] and voltage [V]") from None
        return np.asarray(t, float), np.asarray(lam, float), history.get("voltage", 0.0), None
    if isinstance(history, (tuple, list)) and len(history) == 3:
        t, lam, v = history
        return np.asarray(t, float), np.asarray(lam, float), v, None
    raise TypeError(f"history: expected a run Dataset, a mapping with time, stretch and voltage, or a "
                    f"(t, stretch, voltage) tuple, got {type(history).__name__}")


def _material(ds, params, model, specimen):
    """``(geometry, ParameterSet)`` of a prediction: given, or the run's own; the model checked."""
    if model not in MODELS:
        raise ValueError(f"model: {model!r}; allowed: {', '.join(MODELS)}")
    if specimen is None:
        if ds is None or "specimen" not in ds.attrs:
            raise ValueError("specimen: required (the history is not a run that records its specimen card)")
        specimen = specimen_from_yaml(ds.attrs["specimen"], "history (attribute 'specimen')")
    if params is None:
        if ds is None or not ds.attrs.get("parameters"):
            raise ValueError("params: required (the history is not a twin run that records its parameter set)")
        params = params_from_yaml(ds.attrs["parameters"], "history (attribute 'parameters')")
    return as_geometry(specimen), as_params(params)


def predict(history, params=None, model="su", *, specimen=None, protocol=None, tolerance=0.01, bands=None,
            uncertainty=None, band_flags=None) -> xr.Dataset:
    """The twin on a stretch and voltage history: force, capacitance, stress and status.

    Parameters
    ----------
    history : xarray.Dataset, mapping or tuple
        A run (its ``time`` [s], ``stretch`` [-] and ``voltage`` [V]; its
        ``specimen`` attribute gives the roll and, for a twin run, its
        ``parameters`` attribute the material), a mapping with those keys, or
        ``(t, stretch, voltage)``.
    params : ParameterSet or path, optional
        Material; default: the run's own parameters (twin runs only).
    model : {"su", "1r", "3r", "cr", "auto"}
        Quasi-static model; ``auto`` is the cheapest within `tolerance` of CR on
        this history (:func:`rdea_lab.physics.selection.select_model`).
    specimen : SpecimenCard, RollGeometry or path, optional
        The roll; default: the run's own card.
    protocol : ProtocolSpec, Plan, Limits or path, optional
        When given, the history is first checked against its limits (stretch,
        voltage and the field estimate with the specimen's L3), and a
        `~rdea_lab.specs.LimitError` names the first one it exceeds (samples
        within noise below 1 are not checked). Without it this is a bare model
        evaluation and no limit applies.
    tolerance : float
        For ``auto``: allowed deviation from CR relative to the peak stress [-].
    bands : float, optional
        Nominal level of a prediction band of the force [-] (0.9: the 90 % band), from ``uncertainty``
        (:class:`rdea_lab.calibration.bands.Uncertainty`: the fit's covariance propagated by the delta method,
        combined in quadrature with the cross-validated misfit; see that module for the rule beyond the
        calibration envelope). None (default): no band, the output as without it.
    uncertainty : Uncertainty, optional
        Required with ``bands`` (``Uncertainty.of_record("cal.yaml")``; ``ds.rdea.predict(..., bands=0.9)``
        builds it from the parameter file).
    band_flags : tuple of str, optional
        The history's extrapolation flags (:func:`rdea_lab.calibration.envelope.beyond`); default: checked
        against ``uncertainty.envelope``.

    Returns
    -------
    xarray.Dataset
        On the history's time coordinate: ``force`` [N], ``capacitance`` [F],
        ``sigma1``, ``sigma1_irr`` [Pa], ``lambda2b``, ``converged``,
        ``model_status`` and the ``stretch`` and ``voltage`` used; attributes
        ``model`` (and ``model_selection`` for auto), ``parameters``,
        ``geometry``; with ``bands``, ``force_lower`` and ``force_upper`` [N] and the ``band_*`` attributes
        (level, status, method, misfit, flags). Measured stretches within noise below 1
        (``MIN_STRETCH <= stretch < 1``) and NaN samples get NaN (status
        ``NaN input``, counted in ``excluded_samples``); the viscoelastic
        history runs on across them.

    Raises
    ------
    ValueError
        An unknown ``model``; no ``specimen`` (or ``params``) given for a history that does not record
        one; a history without ``time`` or ``stretch``.
    TypeError
        A ``history`` that is no Dataset, mapping or ``(t, stretch, voltage)`` tuple.
    SpecError
        A card or parameter file that cannot be read; ``bands`` outside the levels a band has (0.05-0.99),
        or without ``uncertainty``.
    LimitError
        With ``protocol``: the first limit the history exceeds.

    Notes
    -----
    Eqs. (43), (44) and (16) of [1] through :func:`rdea_lab.twin.compose`,
    the composition the calibration and the twin backend use too.

    References
    ----------
    [1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello, "Modeling and experimental
        validation of thin, tightly rolled dielectric elastomer actuators", Smart Mater. Struct. 31 (2022)
        015008 (2021 online), doi:10.1088/1361-665X/ac34be.
    """
    t, stretch, voltage, ds = _history(history)
    geom, params = _material(ds, params, model, specimen)
    voltage = np.broadcast_to(np.asarray(voltage, float), stretch.shape)
    noise = np.isfinite(stretch) & (stretch >= MIN_STRETCH) & (stretch < 1.0)
    used = np.where(noise, np.nan, stretch) if noise.any() else stretch
    choice = None
    if model == "auto":
        choice = select_model(geom, params, used, voltage, tolerance)
        model = choice.model
    out = simulate(geom, params, t, used, voltage, model=model, protocol=protocol)
    out["stretch"] = ("time", np.array(stretch, float), out["stretch"].attrs)  # the history as given
    if ds is not None:
        out["time"].attrs.update(ds["time"].attrs)
        for key in ("run_id", "specimen_id", "protocol_name"):
            if key in ds.attrs:
                out.attrs[f"history_{key}"] = ds.attrs[key]
    out.attrs["parameters_name"] = str(getattr(params, "name", ""))
    out.attrs["excluded_samples"] = int(noise.sum() + (~np.isfinite(stretch)).sum())
    if choice is not None:
        out.attrs["model_requested"] = "auto"
        out.attrs["model_selection"] = json.dumps(choice.as_dict())
    if bands is not None:
        if uncertainty is None:
            raise SpecError("arguments", "uncertainty", "required with bands; allowed: rdea_lab.calibration.bands."
                            "Uncertainty.of_record(PARAMS) (or ds.rdea.predict(PARAMS, bands=...), which builds it)")
        out = uncertainty.add_to(out, bands, specimen=geom, model=model, flags=band_flags)
    return out


#: Samples per block of `predict_blocks` (about 2 MB per variable).
BLOCK = 1 << 18


class PredictionBlocks:
    """`predict` block by block, for a history too long to hold: iterate it for ``(start, stop, data)``.

    Made by :func:`predict_blocks`, which checks its arguments at once. Each block reads only samples
    ``start`` to ``stop - 1`` of the history (``history[name][start:stop]``, so a lazily opened run is
    never loaded whole) and gives the variables of `predict` there; a `TwinStream` carries the
    viscoelastic state and the equilibrium path from block to block, so the blocks join into the one-shot
    prediction. Iterate once.

    Attributes
    ----------
    geometry : RollGeometry or StripGeometry
    params : ParameterSet
    model : str
    samples : int
        Length of the history.
    block : int or tuple of int
        Samples per block (the last one shorter), or each block's size.
    status_counts : dict of int to int
        Samples per ``model_status`` code so far.
    excluded : int
        Samples so far with a NaN stretch, or one within noise below 1 (NaN in the output).
    """

    def __init__(self, history, geometry, params, model, protocol, block, samples):
        self._history, self.geometry, self.params, self.model = history, geometry, params, model
        self._limits = history_limits(protocol) if protocol is not None else None
        self.block, self.samples = block, samples
        self.status_counts, self.excluded = {}, 0

    def _read(self, name, a, b):
        if name not in self._history:
            return np.zeros(b - a) if name == "voltage" else None
        part = self._history[name][a:b]
        return np.asarray(getattr(part, "values", part), float)

    def __iter__(self):
        stream = TwinStream(self.geometry, self.params, self.model)
        last = None  # the previous block's last sample, for the limit checks across the boundary
        for a, b in self.bounds():
            t, stretch = self._read("time", a, b), self._read("stretch", a, b)
            voltage = np.broadcast_to(self._read("voltage", a, b), stretch.shape)
            if self._limits is not None:
                limits, source = self._limits
                joined = [np.concatenate([[p], q]) for p, q in zip(last, (t, stretch, voltage))] if last else None
                check_limits(limits, source, *(joined or (t, stretch, voltage)), L3=self.geometry.L3)
                last = (t[-1], stretch[-1], voltage[-1])
            noise = np.isfinite(stretch) & (stretch >= MIN_STRETCH) & (stretch < 1.0)
            out = stream.step(t, np.where(noise, np.nan, stretch) if noise.any() else stretch, voltage)
            self.excluded += int(noise.sum() + (~np.isfinite(stretch)).sum())
            codes, counts = np.unique(out["model_status"], return_counts=True)
            for code, count in zip(codes.tolist(), counts.tolist()):
                self.status_counts[code] = self.status_counts.get(code, 0) + count
            data = {"time": t, "stretch": stretch, "voltage": np.array(voltage), "force": out["force"],
                    "capacitance": out["capacitance"], "sigma1": out["sigma1"], "sigma1_irr": out["sigma1_irr"],
                    "lambda2b": out["lambda2b"],
                    "converged": is_valid(out["model_status"]).astype(np.int8),
                    "model_status": out["model_status"]}
            yield a, b, data

    def bounds(self) -> list[tuple[int, int]]:
        """``(start, stop)`` of each block."""
        if isinstance(self.block, int):
            edges = list(range(0, self.samples, self.block)) + [self.samples]
        else:
            edges = [0, *np.cumsum(self.block).tolist()]
        return [(a, b) for a, b in zip(edges[:-1], edges[1:])]

    def summary(self) -> str:
        """The samples without a valid equilibrium so far, counted per status (or ``all N samples converged``)."""
        parts = [f"{count} of {self.samples} samples {STATUS_NAMES[code]}"
                 for code, count in sorted(self.status_counts.items()) if code != OK]
        return "; ".join(parts) or f"all {self.samples} samples converged"

    def attrs(self, created: str) -> dict:
        """The global attributes of the prediction (`predict`'s, with the `summary` of the blocks so far)."""
        out = simulation_attrs(self.geometry, self.params, self.model, self.summary(), created)
        if isinstance(self._history, xr.Dataset):
            for key in ("run_id", "specimen_id", "protocol_name"):
                if key in self._history.attrs:
                    out[f"history_{key}"] = self._history.attrs[key]
        out["parameters_name"] = str(getattr(self.params, "name", ""))
        out["excluded_samples"] = self.excluded
        out["prediction_blocks"] = self.block
        return out


def predict_blocks(history, params=None, model="su", *, specimen=None, protocol=None,
                   block: int = BLOCK) -> PredictionBlocks:
    """`predict` block by block, with the model's history carried across the blocks.

    Parameters
    ----------
    history : xarray.Dataset or mapping
        A run (opened lazily or loaded: ``time`` [s], ``stretch`` [-], ``voltage`` [V], its ``specimen``
        and, for a twin run, ``parameters`` attributes), or a mapping of arrays with those keys.
    params : ParameterSet or path, optional
        Material; default: the run's own parameters (twin runs only).
    model : {"su", "1r", "3r", "cr"}
        Quasi-static model. Not ``auto``: its choice compares the models over the whole history.
    specimen : SpecimenCard, RollGeometry or path, optional
        The roll; default: the run's own card.
    protocol : ProtocolSpec, Plan, Limits or path, optional
        Check each block against its limits first (as `predict`).
    block : int or sequence of int
        Samples per block, >= 2 (the last block shorter); or the size of each block (>= 1, adding up to
        the history's length).

    Returns
    -------
    PredictionBlocks
        Iterate for ``(start, stop, data)``: ``data`` maps ``time`` [s] and the variables of `predict` (``stretch``,
        ``voltage``, ``force`` [N], ``capacitance`` [F], ``sigma1``, ``sigma1_irr`` [Pa], ``lambda2b``,
        ``converged``, ``model_status``) to samples ``start`` to ``stop - 1``, the same numbers as
        ``predict(history, ...)`` there (to rounding).

    Raises
    ------
    SpecError
        ``model`` auto, or ``block`` not as above.
    ValueError
        An unknown ``model``; no ``specimen`` (or ``params``) for a history that records none; no ``time``
        or ``stretch``.
    """
    if model == "auto":
        raise SpecError("arguments", "model", "auto chooses over the whole history; allowed for a prediction "
                        f"block by block: {', '.join(m for m in MODELS if m != 'auto')} (the model auto picks "
                        "on a shorter part of the run)")
    for name in ("time", "stretch"):
        if name not in history:
            raise ValueError(f"history: no {name!r}; a run has time, stretch and voltage")
    n = int(np.shape(history["time"])[0])
    sizes = np.atleast_1d(np.asarray(block))
    if sizes.dtype.kind not in "iu" or np.any(sizes < 1) or (sizes.size == 1 and sizes[0] < 2) or (
            sizes.size > 1 and sizes.sum() != n):
        raise SpecError("arguments", "block", f"{block!r}; allowed: an integer >= 2 samples, or the sizes of "
                        f"the blocks (integers >= 1 that add up to the history's {n} samples)")
    ds = history if isinstance(history, xr.Dataset) else None
    geom, params = _material(ds, params, model, specimen)
    block = int(sizes[0]) if np.ndim(block) == 0 else tuple(int(k) for k in sizes)
    return PredictionBlocks(history, geom, params, model, protocol, block, n)
