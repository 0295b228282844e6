"""``ds.rdea``: rdea-lab's helpers on a run's xarray Dataset (registered when this module is imported).

Looking up a public name that returns a run dataset (`rdea_lab.open_run`, `rdea_lab.run_protocol`,
`rdea_lab.predict`, ...) imports this module, so ``ds.rdea`` comes with what returns ``ds``.

In the manner of xarray extensions (cf_xarray, pint-xarray)::

    ds = rdea_lab.open_run("datasets/paper2021/specimen-2/blocking_force.nc")
    ds.rdea.specimen          # the SpecimenCard the run was made on
    ds.rdea.protocol          # its ProtocolSpec
    ds.rdea.parameters        # the twin's ParameterSet (twin runs), else None
    ds.rdea.metadata          # the user's metadata (operator, batch, notes)
    ds.rdea.pauses            # the run's pauses (start, end, reason, by), a DataFrame
    ds.rdea.plot(ax=None)     # the `rdea-lab show` figure; returns the Figure
    twin = ds.rdea.predict("params/paper2021_table3.yaml", "su")   # on the same time axis
"""

from __future__ import annotations

import json
import os

import xarray as xr


@xr.register_dataset_accessor("rdea")
class RdeaAccessor:
    """rdea-lab's helpers on a run dataset, as ``ds.rdea``: its inputs, its figure, the twin on its history.

    xarray makes one per dataset on first use of ``ds.rdea`` (`xarray.register_dataset_accessor`).
    """

    def __init__(self, ds: xr.Dataset):
        self._ds = ds

    @property
    def path(self):
        """The file the run was read from, or None."""
        return self._ds.encoding.get("source")

    @property
    def specimen(self):
        """The `SpecimenCard` of the run (its ``specimen`` attribute)."""
        from ..specs import specimen_from_yaml

        return specimen_from_yaml(self._require("specimen"), "dataset attribute 'specimen'")

    @property
    def protocol(self):
        """The `ProtocolSpec` of the run (its ``protocol`` attribute)."""
        from ..specs import protocol_from_yaml

        return protocol_from_yaml(self._require("protocol"), "dataset attribute 'protocol'")

    @property
    def parameters(self):
        """The twin's `ParameterSet` for a twin run; None for a measured run."""
        from ..specs import params_from_yaml

        text = self._ds.attrs.get("parameters")
        return params_from_yaml(text, "dataset attribute 'parameters'") if text else None

    @property
    def metadata(self) -> dict:
        """The user's metadata (``metadata`` attribute, JSON): {} if none."""
        try:
            value = json.loads(self._ds.attrs.get("metadata") or "{}")
        except ValueError:
            return {}
        return value if isinstance(value, dict) else {}

    @property
    def status(self) -> str:
        """The run's ``status`` attribute (``complete``, ``aborted``, ``interrupted``), or ``"?"``."""
        return str(self._ds.attrs.get("status", "?"))

    @property
    def pauses(self):
        """The run's pauses (issue 29) as a pandas DataFrame, one row per pause: ``start``, ``end`` [s since
        the run's start], ``first``, ``samples`` (its samples along ``time``), ``reason``, ``by``; no rows for
        a run that never paused (`rdea_lab.store.pauses`)."""
        from ..store.pauses import pauses

        return pauses(self._ds)

    def _require(self, key):
        if key not in self._ds.attrs:
            raise ValueError(f"this dataset has no {key!r} attribute: not an rdea-lab run")
        return self._ds.attrs[key]

    def predict(self, params=None, model="su", *, bands=None, out=None, block=None, overwrite=False,
                **kwargs) -> xr.Dataset:
        """The twin on this run's own stretch and voltage history (:func:`rdea_lab.twin.predict`).

        Parameters
        ----------
        params : ParameterSet or path, optional
            The material; default: the run's own parameters (twin runs only).
        model : {"su", "1r", "3r", "cr", "auto"}
            Quasi-static model (Sections 3.1-3.3 of [1]).
        bands : float, optional
            Nominal level of a prediction band of the force [-] (0.9: the 90 % band). Its ``uncertainty``
            (`rdea_lab.calibration.bands.Uncertainty`) is read from ``params``, a calibration record,
            unless given; the run is checked against the record's calibration envelope.
        out : str or path-like, optional
            Predict block by block (:func:`rdea_lab.twin.predict.predict_blocks`: the run is read a block
            at a time, the model's state carried across) and write the prediction there as netCDF, one
            block at a time: for a run too long to hold. The same numbers as the one-shot prediction (to
            rounding); not with ``bands`` or model ``auto``.
        block : int, optional
            Samples per block with ``out`` (default `rdea_lab.twin.predict.BLOCK`).
        overwrite : bool
            With ``out``: replace an existing file.
        **kwargs
            Passed to `rdea_lab.predict`: ``specimen`` (default: the run's card), ``protocol`` (check the
            history against its limits first), ``tolerance`` [-] (for ``auto``), ``uncertainty``.

        Returns
        -------
        xarray.Dataset
            On the run's ``time`` [s]: ``force`` [N], ``capacitance`` [F], ``sigma1``, ``sigma1_irr``
            [Pa], ``model_status``, ... (see `rdea_lab.predict`); with ``bands``, ``force_lower`` and
            ``force_upper`` [N] and the ``band_*`` attributes. With ``out``: that file, opened lazily
            (close it when done).

        Raises
        ------
        ValueError
            No ``params`` for a measured run (it records none), or an unknown ``model``.
        SpecError
            A card or parameter file that cannot be read; ``bands`` with a ``params`` that is no calibration
            record (and no ``uncertainty``), or a level outside 0.05-0.99; with ``out``: ``bands``, model
            ``auto`` or ``tolerance``, or an ``out`` that exists (and not ``overwrite``) or is no ``.nc`` name.

        References
        ----------
        [1] J. Prechtl et al., "Modeling and experimental validation of thin, tightly rolled dielectric
            elastomer actuators", Smart Mater. Struct. 31 (2022) 015008, doi:10.1088/1361-665X/ac34be.
        """
        from ..twin import predict

        if out is not None or block is not None:
            return self._predict_to(out, params, model, bands, block, overwrite, kwargs)
        if bands is not None and kwargs.get("uncertainty") is None:
            from ..calibration.bands import Uncertainty
            from ..specs import SpecError

            if params is None or not isinstance(params, (str, os.PathLike)):
                raise SpecError("arguments", "params", "a band needs the calibration record; allowed: the path of "
                                "a parameter file 'rdea-lab calibrate' wrote (or uncertainty=...)")
            kwargs["uncertainty"] = Uncertainty.of_record(params)
        return predict(self._ds, params, model, bands=bands, **kwargs)

    def _predict_to(self, out, params, model, bands, block, overwrite, kwargs) -> xr.Dataset:
        """`predict` block by block into the file ``out``, opened lazily."""
        from datetime import datetime, timezone

        from ..specs import SpecError
        from ..store.blocks import write_blocks
        from ..twin.predict import BLOCK, predict_blocks

        if out is None:
            raise SpecError("arguments", "block", "needs out=PATH (the file the prediction is written to block "
                            "by block)")
        for name, value in (("bands", bands), ("tolerance", kwargs.pop("tolerance", None)),
                            ("uncertainty", kwargs.pop("uncertainty", None))):
            if value is not None:
                raise SpecError("arguments", name, "not with out= (a band needs the whole prediction); "
                                "allowed: predict without out=")
        blocks = predict_blocks(self._ds, params, model, block=block or BLOCK, **kwargs)
        created = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
        write_blocks(out, blocks.samples, blocks, lambda: blocks.attrs(created),
                     time_attrs=dict(self._ds["time"].attrs), overwrite=overwrite)
        return xr.open_dataset(out, engine="netcdf4", decode_times=False)

    def plot(self, path=None, *, ax=None, fig=None, prediction=None, envelope=None):
        """The run's figure (:func:`rdea_lab.reports.plots.plot_run`), as ``rdea-lab show`` draws it.

        Parameters
        ----------
        path : str or path-like, optional
            Save the figure there as PNG (a figure made here is then closed; it is still returned).
        ax : matplotlib.axes.Axes, optional
            Draw only force [N] against time [s] on this axis.
        fig : matplotlib.figure.Figure, optional
            Draw the full layout into this (empty) figure: time histories, and force [N] against
            displacement [mm]. Not with ``ax``.
        prediction : xarray.Dataset, optional
            The twin on the same ``time`` (`predict`): its ``force`` [N] (and ``capacitance`` [F]) drawn
            dashed over the measurement, with residual panels in the full layout.
        envelope : bool, optional
            Draw the time histories as min/max envelopes per pixel column, read chunk by chunk (a long
            run is never loaded whole; the title says so). Default: for a run of more than
            `rdea_lab.reports.plots.ENVELOPE_ABOVE` samples.

        Returns
        -------
        matplotlib.figure.Figure
            The figure drawn on (``ax.figure`` when ``ax`` is given).

        Raises
        ------
        ValueError
            Both ``ax`` and ``fig``, or a ``prediction`` not on the run's time coordinate.
        """
        from ..reports.plots import plot_run

        return plot_run(self._ds, path, ax=ax, fig=fig, prediction=prediction, envelope=envelope)
