"""The physics twin: force and capacitance of a roll for given stretch and voltage histories."""

from __future__ import annotations

import dataclasses
import json
from datetime import datetime, timezone
from typing import NamedTuple

import numpy as np
import xarray as xr

from .._version import __version__
from ..physics import viscoelastic
from ..physics.geometry import RollGeometry, StripGeometry, geometry_from_card
from ..physics.models import solve
from ..physics.result import OK, SLACK, VALID, is_valid
from ..specs import ParameterSet, ViscoBranch, as_params, as_protocol, as_specimen, check_limits, dump_params
from ..specs.errors import SpecError
from ..specs.protocol import Limits
from ..specs.variables import global_attrs, time_attrs, variable_attrs

#: The variables `simulate` writes, in order (CF attributes: the one table, `rdea_lab.specs.variables`).
VARIABLES = ("stretch", "voltage", "force", "capacitance", "sigma1", "sigma1_irr", "lambda2b", "converged",
             "model_status")


def as_geometry(specimen):
    """The geometry of ``specimen``: a RollGeometry/StripGeometry as it is, a card, or a card's path."""
    if isinstance(specimen, (RollGeometry, StripGeometry)):
        return specimen
    return geometry_from_card(as_specimen(specimen))


class Viscous(NamedTuple):
    """A parameter set's Maxwell branches and parallel damper as arrays (:func:`viscous`; a tuple too, in
    this order).

    Attributes
    ----------
    modulus : numpy.ndarray, shape (M,)
        Each branch's spring [Pa]: ``k`` (law linear, eq. (44) of [1]) or ``mu`` (law finite_strain).
    eta : numpy.ndarray, shape (M,)
        Each branch's dashpot viscosity [Pa s].
    eta_v0 : float
        The parallel damper's viscosity [Pa s].
    law : str
        ``linear`` or ``finite_strain``.
    """

    modulus: np.ndarray
    eta: np.ndarray
    eta_v0: float
    law: str


class Composition(NamedTuple):
    """What :func:`compose` returns (a tuple too, in this order).

    Attributes
    ----------
    sigma1 : numpy.ndarray, shape (n,)
        Total axial stress ``sigma_rev + sigma_irr`` [Pa], eq. (43) of [1]; 0 where the specimen is slack.
    sigma1_irr : numpy.ndarray, shape (n,)
        Viscoelastic overstress [Pa], eq. (44) of [1] (or its finite-strain form).
    force : numpy.ndarray, shape (n,)
        Force [N], eq. (16) of [1]; 0 where it would be compressive (slack).
    state : ViscoState or None
        The branches' state after the last sample (for the next block).
    """

    sigma1: np.ndarray
    sigma1_irr: np.ndarray
    force: np.ndarray
    state: object


def viscous(params) -> Viscous:
    """The Maxwell branches and damper of a parameter set, as arrays.

    Parameters
    ----------
    params : ParameterSet
        Its ``branches`` (none: empty arrays), ``eta_v0`` [Pa s] (none: 0) and ``law`` (none: linear).

    Returns
    -------
    Viscous
        ``modulus`` [Pa] (each branch's ``k``, law linear, or ``mu``, law finite_strain), ``eta`` [Pa s],
        ``eta_v0`` [Pa s], ``law``.
    """
    branches = tuple(getattr(params, "branches", ()) or ())
    return Viscous(np.array([b.modulus for b in branches], float), np.array([b.eta for b in branches], float),
                   float(getattr(params, "eta_v0", 0.0) or 0.0), str(getattr(params, "law", "linear")))


def compose(geom, visco, t, stretch, sigma_rev, state=None, history=None):
    """Total stress and force from the quasi-static stress and the history: eqs. (43), (44) and (16) of [1].

    (Eq. (44) or its finite-strain form, by the parameter set's ``law``.)

    The one composition of the twin: `TwinStream` (and so `simulate`,
    `predict`, the twin backend and the emulator) and the calibration objective
    all come here.

    Parameters
    ----------
    geom : RollGeometry or StripGeometry
    visco : Viscous
        ``(modulus, eta, eta_v0, law)`` of :func:`viscous`.
    t : numpy.ndarray, shape (n,)
        Sample times [s].
    stretch : numpy.ndarray, shape (n,)
        Axial stretch [-].
    sigma_rev : numpy.ndarray, shape (n,)
        Quasi-static (reversible) axial stress of a model [Pa].
    state : ViscoState, optional
        End of the previous block.
    history : History, optional
        ``viscoelastic.History.of(t, stretch)``, precomputed for a history
        evaluated many times (the calibration objective); the overstress then
        comes from it (`~rdea_lab.physics.viscoelastic.overstress_step`).

    Returns
    -------
    Composition
        ``sigma1 = sigma_rev + sigma_irr`` [Pa] (43), the overstress ``sigma1_irr`` (44) [Pa],
        the ``force`` ``sigma1 pi (Ro**2 - Ri**2) / lambda1`` [N] (16), and the branches' ``state``
        after the last sample. Where the force would be compressive the specimen is slack (a roll
        buckles, a membrane wrinkles): force and ``sigma1`` are 0. The overstress follows the clamps'
        stretch throughout (a slack specimen's own, larger stretch is not tracked: an approximation
        while it is slack).
    """
    k, eta, eta_v0, law = visco
    if history is not None and history.t.shape != np.shape(stretch):
        raise ValueError(f"history of {history.t.size} samples for a stretch of shape {np.shape(stretch)}")
    source = (t, stretch) if history is None else (history, None)
    sigma_irr, state = viscoelastic.overstress_step(*source, k, eta, eta_v0, state=state, law=law)
    sigma = sigma_rev + sigma_irr
    force = geom.carried_force(sigma * geom.area / stretch)
    with np.errstate(invalid="ignore"):
        sigma = np.where(force == 0.0, 0.0, sigma)
    return Composition(sigma, sigma_irr, force, state)


def slack_status(status, pushes, force):
    """Model status with slack where the total (quasi-static + viscous) stress would be compressive
    (`pushes`): a quasi-static slack state the overstress pulls taut (``force > 0``) carries force
    (its stretches stay the free state's) and is OK."""
    valid = is_valid(status)
    out = np.where(valid & pushes & (status == OK), SLACK, status)
    return np.where(valid & (force > 0.0) & (status == SLACK), OK, out).astype(np.int8)


def history_limits(protocol):
    """``(Limits, source)`` of a protocol given as a spec, a path, a plan or bare Limits."""
    if isinstance(protocol, Limits):
        return protocol, "<limits>"
    if hasattr(protocol, "limits") and hasattr(protocol, "source"):  # a Plan (protocols layer, duck-typed)
        return protocol.limits, str(protocol.source)
    spec = as_protocol(protocol)
    return spec.limits, spec.origin


def simulate(specimen, params, t, stretch, voltage, model="su", *, protocol=None) -> xr.Dataset:
    """Run the twin over a time series.

    Parameters
    ----------
    specimen : SpecimenCard, RollGeometry or path
        The roll (a card's path is read).
    params : ParameterSet or path
        Yeoh coefficients ``C10, C20, C30`` [Pa], ``eps_r`` [-], viscoelastic
        ``branches`` (each with ``k`` [Pa] and ``eta`` [Pa s]) and ``eta_v0`` [Pa s].
    t : array_like, shape (n,)
        Sample times [s], strictly increasing.
    stretch : array_like, shape (n,)
        Axial stretch [-], >= 1.
    voltage : array_like, shape (n,)
        Voltage [V].
    model : {"su", "1r", "3r", "cr"}
        Quasi-static model, Sections 3.1-3.3 of [1].
    protocol : ProtocolSpec, Plan, Limits or path, optional
        When given, the history is first checked against its limits (stretch,
        voltage, the field estimate with the specimen's L3) and a
        `~rdea_lab.specs.LimitError` names the first one exceeded; without it,
        a bare model evaluation (no limit applies).

    Returns
    -------
    xarray.Dataset
        Variables over ``time`` [s] with ``units`` and ``long_name``
        (see :data:`VARIABLES`); ``force = (sigma1_rev + sigma1_irr) pi
        (Ro**2 - Ri**2) / lambda1``, eq. (43) and (16) of [1]. The branch
        strains start relaxed at ``t[0]``.

    Raises
    ------
    SpecError
        A card or parameter file that cannot be read.
    LimitError
        With ``protocol``: the first limit the history exceeds.
    ValueError
        An unknown ``model``; a card whose radii describe no possible roll.

    Notes
    -----
    Eqs. (43), (44) and (16) of [1] (the viscoelastic branches by eq. (44), or its finite-strain form by
    the parameter set's ``law``), through :func:`rdea_lab.twin.compose`.

    References
    ----------
    [1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello, "Modeling and experimental
        validation of thin, tightly rolled dielectric elastomer actuators", Smart Mater. Struct. 31 (2022)
        015008 (2021 online), doi:10.1088/1361-665X/ac34be.
    """
    geom = as_geometry(specimen)
    params = as_params(params)
    stretch = np.asarray(stretch, float)
    voltage = np.broadcast_to(np.asarray(voltage, float), stretch.shape)
    if protocol is not None:
        limits, source = history_limits(protocol)
        check_limits(limits, source, t, stretch, voltage, L3=geom.L3)
    out = TwinStream(geom, params, model).step(t, stretch, voltage)  # the whole series as one block
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
    created = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    ds = xr.Dataset(
        {name: ("time", np.asarray(data[name]), variable_attrs(name)) for name in VARIABLES},
        coords={"time": ("time", np.asarray(t, float), time_attrs(created))},
    )
    ds["time"].encoding.update({"_FillValue": None})  # a coordinate has no missing values (CF 2.5.1)
    ds.attrs.update(simulation_attrs(geom, params, model, out["summary"], created))
    return ds


def simulation_attrs(geom, params, model: str, summary: str, created: str) -> dict:
    """The global attributes of a dataset `simulate` makes (also of a prediction written chunk by chunk)."""
    return {
        "Conventions": "CF-1.8",
        "title": f"twin ({model}) of a roll over a given stretch and voltage history",
        "model": model,
        "viscoelastic_law": viscous(params)[3],
        "model_summary": summary,
        "geometry": json.dumps(geom.as_dict(params.eps_r)),
        "parameters": parameters_yaml(params),  # YAML, as every run writes it
        "rdea_lab_version": __version__,
        "created": created,
        "history": f"{created}: rdea_lab.twin.simulate",
        **global_attrs(f"rdea-lab {__version__} twin.simulate, model {model}, parameters "
                       f"{getattr(params, 'name', 'unnamed')}"),
    }


def parameters_yaml(params) -> str:
    """The ``parameters`` attribute: `dump_params`'s YAML, as a run writes it, also for a parameter set
    in disguise (any object with ``C10, C20, C30, eps_r`` and the viscous fields `viscous` reads)."""
    if isinstance(params, ParameterSet):
        return dump_params(params)
    k, eta, eta_v0, law = viscous(params)
    fields = {key: float(getattr(params, key)) for key in ("C10", "C20", "C30", "eps_r")}
    try:
        return dump_params(ParameterSet(name=str(getattr(params, "name", "") or "unnamed"), law=law, eta_v0=eta_v0,
                                        branches=tuple(ViscoBranch.of(law, a, b) for a, b in zip(k, eta)),
                                        **fields))
    except (SpecError, ValueError) as exc:
        raise ValueError(f"params: not a parameter set ({exc})") from None


class TwinStream:
    """The twin one block at a time, carrying the viscoelastic state across blocks.

    Block by block it gives the same numbers as :func:`simulate` over the whole
    series (the branch update is exact over each interval, including the one
    between two blocks, and each block's equilibria continue the previous
    block's path: ``solve(..., path=True)``, so loops show hysteresis).

    Parameters
    ----------
    specimen : SpecimenCard, RollGeometry or path
    params : ParameterSet or path
    model : {"su", "1r", "3r", "cr"}
    """

    def __init__(self, specimen, params, model="su"):
        self.geom = as_geometry(specimen)
        self.params = as_params(params)
        self.model = model
        self._visco = viscous(self.params)
        self._state = None  # ViscoState at the end of the previous block
        self._path = None  # the equilibrium's state at the end of the previous block (PathEnd)

    def step(self, t, stretch, voltage, *, summary: bool = True) -> dict:
        """Force [N], capacitance [F], stress [Pa] and model status for one block (and, with `summary`,
        the model result's one-line ``summary``; a backend that does not record it skips it)."""
        stretch = np.asarray(stretch, float)
        t = viscoelastic.check_time(t, stretch.shape)
        if self._state is not None and not t[0] > self._state.t:
            raise ValueError(f"block starts at t = {float(t[0])!r}, not after the previous block's end")
        res = solve(self.model, self.geom, self.params, stretch, np.broadcast_to(voltage, stretch.shape),
                    path=True, start=self._path)
        self._path = res.end
        sigma, sigma_irr, force, self._state = compose(self.geom, self._visco, t, stretch, res.tension, self._state)
        with np.errstate(invalid="ignore"):
            status = slack_status(res.status, res.tension + sigma_irr < 0.0, force)
        out = {"force": force, "capacitance": res.capacitance, "sigma1": sigma, "sigma1_irr": sigma_irr,
               "lambda2b": res.lambda2b, "model_status": status}
        if summary:
            out["summary"] = dataclasses.replace(res, status=status).summary()
        return out
