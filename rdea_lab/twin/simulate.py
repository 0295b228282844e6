"""The physics twin: force and capacitance of a roll for given stretch and voltage histories."""

from __future__ import annotations

import json

import numpy as np
import xarray as xr

from .. import __version__
from ..physics import viscoelastic
from ..physics.geometry import RollGeometry, StripGeometry, geometry_from_card
from ..physics.models import solve
from ..physics.result import VALID

#: CF attributes of the variables the twin writes.
VARIABLES = {
    "stretch": ("1", "axial stretch lambda1 = l1 / L1"),
    "voltage": ("V", "voltage across the electrodes"),
    "force": ("N", "axial force"),
    "capacitance": ("F", "capacitance"),
    "sigma1": ("Pa", "axial true stress (reversible + viscoelastic)"),
    "sigma1_irr": ("Pa", "viscoelastic overstress, eq. (44)"),
    "lambda2b": ("1", "circumferential stretch of the active ring b"),
    "converged": ("1", "1 where the model has a stable equilibrium"),
    "model_status": ("1", "0 ok, 1 past limit point, 2 NaN input, 3 not converged, 4 snap-through"),
}


def _geometry(specimen):
    return specimen if isinstance(specimen, (RollGeometry, StripGeometry)) else geometry_from_card(specimen)


def simulate(specimen, params, t, stretch, voltage, model="su") -> xr.Dataset:
    """Run the twin over a time series.

    Parameters
    ----------
    specimen : SpecimenCard or RollGeometry
        The roll.
    params : ParameterSet
        Yeoh coefficients ``C10, C20, C30`` [Pa], ``eps_r`` [-], viscoelastic
        ``branches`` (each with ``k`` [Pa] and ``eta`` [Pa s]) and ``eta_v0`` [Pa s].
    t : array_like, shape (n,)
        Sample times [s], strictly increasing.
    stretch : array_like, shape (n,)
        Axial stretch [-], >= 1.
    voltage : array_like, shape (n,)
        Voltage [V].
    model : {"su", "1r", "3r"}
        Quasi-static model, Sections 3.1-3.3 of [1].

    Returns
    -------
    xarray.Dataset
        Variables over ``time`` [s] with ``units`` and ``long_name``
        (see :data:`VARIABLES`); ``force = (sigma1_rev + sigma1_irr) pi
        (Ro**2 - Ri**2) / lambda1``, eq. (43) and (16) of [1]. The branch
        strains start relaxed at ``t[0]``.
    """
    geom = _geometry(specimen)
    stretch = np.asarray(stretch, float)
    voltage = np.broadcast_to(np.asarray(voltage, float), stretch.shape)
    out = TwinStream(geom, params, model).step(t, stretch, voltage)  # the whole series as one block
    branches = tuple(getattr(params, "branches", ()) or ())
    eta_v0 = float(getattr(params, "eta_v0", 0.0) or 0.0)
    data = {
        "stretch": stretch,
        "voltage": voltage,
        "force": out["force"],
        "capacitance": out["capacitance"],
        "sigma1": out["sigma1"],
        "sigma1_irr": out["sigma1_irr"],
        "lambda2b": out["lambda2b"],
        "converged": np.isin(out["model_status"], VALID).astype(np.int8),
        "model_status": out["model_status"],
    }
    ds = xr.Dataset(
        {name: ("time", np.asarray(values), {"units": VARIABLES[name][0], "long_name": VARIABLES[name][1]})
         for name, values in data.items()},
        coords={"time": ("time", t, {"units": "s", "long_name": "time since start of run"})},
    )
    ds.attrs.update({
        "model": model,
        "model_summary": out["summary"],
        "geometry": json.dumps(geom.as_dict(params.eps_r)),
        "parameters": json.dumps({
            "C10": params.C10, "C20": params.C20, "C30": params.C30, "eps_r": params.eps_r,
            "branches": [{"k": b.k, "eta": b.eta} for b in branches], "eta_v0": eta_v0,
        }),
        "rdea_lab_version": __version__,
    })
    return ds


class TwinStream:
    """The twin one block at a time, carrying the viscoelastic state across blocks.

    Block by block it gives the same numbers as :func:`simulate` over the whole
    series (the branch update is exact over each interval, including the one
    between two blocks).

    Parameters
    ----------
    specimen : SpecimenCard or RollGeometry
    params : ParameterSet
    model : {"su", "1r", "3r"}
    """

    def __init__(self, specimen, params, model="su"):
        self.geom = _geometry(specimen)
        self.params = params
        self.model = model
        branches = tuple(getattr(params, "branches", ()) or ())
        self._k = np.array([b.k for b in branches], float)
        self._tau = np.array([b.eta / b.k for b in branches], float)
        self._eta_v0 = float(getattr(params, "eta_v0", 0.0) or 0.0)
        self._last = None  # (t, stretch, q) at the end of the previous block

    def step(self, t, stretch, voltage) -> dict:
        """Force [N], capacitance [F], stress [Pa] and model status for one block."""
        stretch = np.asarray(stretch, float)
        t = viscoelastic.check_time(t, stretch.shape)
        res = solve(self.model, self.geom, self.params, stretch, np.broadcast_to(voltage, stretch.shape))
        sigma_irr = np.zeros_like(stretch)
        if self._last is not None and not t[0] > self._last[0]:
            raise ValueError(f"block starts at t = {float(t[0])!r}, not after the previous block's end")
        ok = np.isfinite(stretch)
        if self._k.size or self._eta_v0:
            prev_t, prev_lam, prev_q = self._last if self._last is not None else (None, None, None)
            tt, ll = t[ok], stretch[ok]
            if prev_t is not None:
                tt, ll = np.concatenate([[prev_t], tt]), np.concatenate([[prev_lam], ll])
            q = None
            if self._k.size and tt.size:
                q = viscoelastic.branch_strains(tt, ll, self._tau, prev_q)
                part = self._k @ q
                sigma_irr[ok] = part[1:] if prev_t is not None else part
            if self._eta_v0 and tt.size > 1:
                rate = viscoelastic.stretch_rate(tt, ll)
                sigma_irr[ok] += self._eta_v0 * (rate[1:] if prev_t is not None else rate)
            if tt.size:
                self._last = (tt[-1], ll[-1], q[:, -1] if q is not None else None)
        elif np.any(ok):
            self._last = (t[ok][-1], stretch[ok][-1], None)
        sigma_irr[~ok] = np.nan
        sigma = res.sigma1 + sigma_irr
        return {"force": self.geom.carried_force(sigma * self.geom.area / stretch), "capacitance": res.capacitance,
                "sigma1": sigma, "sigma1_irr": sigma_irr, "lambda2b": res.lambda2b, "model_status": res.status,
                "summary": res.summary()}
