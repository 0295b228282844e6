"""``ds.rdea``: rdea-lab's helpers on a run's xarray Dataset (registered on ``import rdea_lab``).

In the manner of xarray extensions (cf_xarray, pint-xarray)::

    ds = rdea_lab.open_run("datasets/paper2021/specimen-2/blocking_force.nc")
    ds.rdea.specimen          # the SpecimenCard the run was made on
    ds.rdea.protocol          # its ProtocolSpec
    ds.rdea.parameters        # the twin's ParameterSet (twin runs), else None
    ds.rdea.metadata          # the user's metadata (operator, batch, notes)
    ds.rdea.plot(ax=None)     # the `rdea-lab show` figure; returns the Figure
    twin = ds.rdea.predict("params/paper2021_table3.yaml", "su")   # on the same time axis
"""

from __future__ import annotations

import json

import xarray as xr


@xr.register_dataset_accessor("rdea")
class RdeaAccessor:
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
        return str(self._ds.attrs.get("status", "?"))

    def _require(self, key):
        if key not in self._ds.attrs:
            raise ValueError(f"this dataset has no {key!r} attribute: not an rdea-lab run")
        return self._ds.attrs[key]

    def predict(self, params=None, model="su", **kwargs) -> xr.Dataset:
        """The twin on this run's own stretch and voltage history (:func:`rdea_lab.twin.predict`)."""
        from ..twin import predict

        return predict(self._ds, params, model, **kwargs)

    def plot(self, path=None, *, ax=None, fig=None, prediction=None):
        """The run's figure (:func:`rdea_lab.reports.plots.plot_run`): returns the Figure."""
        from ..reports.plots import plot_run

        return plot_run(self._ds, path, ax=ax, fig=fig, prediction=prediction)
