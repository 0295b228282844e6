"""`predict`: the twin on a run's own history (or on arrays), as a Dataset on its time axis."""

from __future__ import annotations

import json
from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..physics.selection import select_model
from ..specs import MODEL_CHOICES, SpecError, as_params, params_from_yaml, specimen_from_yaml
from .simulate import as_geometry, simulate

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
    params = as_params(params)
    geom = as_geometry(specimen)
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
