"""The physics twin as a backend: the plan's setpoints through a model, block by block."""

from __future__ import annotations

import json
import time as _time

import numpy as np

from .._version import __version__
from ..physics.models import three_ring
from ..physics.selection import select_model
from ..specs import as_params, as_specimen, dump_params
from ..twin.simulate import TwinStream, as_geometry


class TwinBackend:
    """Run a plan on the twin.

    Parameters
    ----------
    card : SpecimenCard or path
    params : ParameterSet or path
    model : {"su", "1r", "3r", "cr", "auto"}
        ``auto`` picks the cheapest model within ``tolerance`` of 3R over the
        plan's own (stretch, voltage) envelope (:func:`select_model`).
    tolerance : float
        For ``auto``: allowed deviation from 3R relative to the peak stress.
    realtime : bool
        Pace blocks at wall-clock speed, as a rig would run.
    block_seconds : float, optional
        Samples per block, in seconds of run time; at most 1 s, which keeps
        the journal's at-most-a-second-lost promise. Default 1 s, or 0.25 s
        with ``realtime`` (a smoother progress display).
    seed : int
        Recorded; the twin itself is deterministic.
    geometry : RollGeometry or StripGeometry, optional
        The card's geometry, as the run's preparation made it (`rdea_lab.runs.app.RunSetup.geometry`);
        made from ``card`` here when not given (a twin backend built by hand).
    """

    name = "twin"
    extra_variables = ("model_status",)

    def __init__(self, card, params, model="su", tolerance=0.01, realtime=False, block_seconds=None, seed=0,
                 clock=_time.monotonic, sleep=_time.sleep, geometry=None):
        self.card = as_specimen(card)
        self.params = as_params(params)
        self.geom = as_geometry(self.card if geometry is None else geometry)  # the twin's one way in
        self.requested = model
        self.tolerance = tolerance
        self.realtime = realtime
        if block_seconds is None:
            block_seconds = 0.25 if realtime else 1.0
        if not 0.0 < block_seconds <= 1.0:
            raise ValueError(f"block_seconds must be in (0, 1], got {block_seconds!r}")
        self.block_seconds = block_seconds
        self.seed = seed
        self.choice = None
        self.model = None if model == "auto" else model
        self._clock, self._sleep = clock, sleep
        self._plan = None
        self._blocks = None
        self._stream = None
        self._t0 = None
        self.aborted = None

    def start(self, plan):
        if self.model == "3r":
            three_ring.check_applicable(self.geom)  # refuse before anything is written
        self._plan = plan
        if self.requested == "auto":
            self.choice = select_model(self.geom, self.params, plan.stretch, plan.voltage, self.tolerance)
            self.model = self.choice.model
        self._stream = TwinStream(self.geom, self.params, self.model)
        self._charge = (0.0, 0.0)  # (C v, v) before the first sample: no charge at 0 V
        self._blocks = iter(plan.block_slices(self.block_seconds))
        self._t0 = self._clock()

    def attrs(self) -> dict:
        out = {"source": f"rdea-lab {__version__} twin, model {self.model or self.requested}, parameters "
                         f"{self.params.name}",
               "model": self.model or self.requested, "model_requested": self.requested,
               "parameters": dump_params(self.params), "parameters_name": self.params.name,
               "realtime": int(self.realtime)}
        if self.choice is not None:
            out["model_selection"] = json.dumps(self.choice.as_dict())
        return out

    def read_block(self):
        if self.aborted is not None:
            return None
        sl = next(self._blocks, None)
        if sl is None:
            return None
        plan = self._plan
        t = plan.time[sl]
        stretch = plan.stretch[sl]
        voltage = plan.voltage[sl]
        if self.realtime:
            wait = (t[-1] - plan.time[0]) - (self._clock() - self._t0)
            if wait > 0:
                self._sleep(wait)
        out = self._stream.step(t, stretch, voltage)
        capacitance = out["capacitance"] if "capacitance" in plan.measure else np.full(t.size, np.nan)
        extra = {}
        if "current" in plan.measure:  # an ideal current monitor: the charge change per interval, no leakage
            q = out["capacitance"] * voltage
            extra["current"] = np.diff(q, prepend=self._charge[0]) * plan.sample_rate
            self._charge = (float(q[-1]), float(voltage[-1]))
        return {**extra,
            "time": t, "stretch": stretch, "position": (stretch - 1.0) * self.geom.L1, "voltage": voltage,
            "force": out["force"], "capacitance": capacitance,
            "stretch_setpoint": stretch, "voltage_setpoint": voltage,
            "model_status": out["model_status"],
        }

    def abort(self, reason):
        self.aborted = reason  # the twin drives no hardware: nothing to switch off

    def close(self):
        self._blocks = None
