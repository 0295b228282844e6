"""The physics twin as a backend: the plan's setpoints through a model, block by block."""

from __future__ import annotations

import collections
import json
import math
import time as _time

import numpy as np

from .._version import __version__
from ..physics.models import three_ring
from ..protocols.pause import PausedSetpoints, pause_spec_of
from .base import PauseRefused
from ..physics.selection import select_model
from ..specs import as_params, as_specimen, dump_params
from ..twin.simulate import TwinStream, as_geometry


#: Most samples the twin computes in one vectorized step (several blocks, handed out one by one) [samples].
STEP_SAMPLES = 16384
#: Samples per block of a twin paced at wall-clock speed [s of run time]: a pause asked for while a block is
#: paced acts from the next one, so within this much of run time (and a smoother progress display).
REALTIME_BLOCK = 0.1
#: Longest a held (paused) twin waits for wall time before it hands out the held samples due [s]: the
#: engine reads a resume request between two blocks, so this bounds how late a resume acts.
HELD_WAIT = 0.05
#: ... and at most this many periods of the plan's fastest oscillation in one step: the path solver decides
#: the samples it cannot certify one after another (`rdea_lab.physics.scan_kernel`), in time order.
STEP_CYCLES = 16


def fastest_frequency(plan) -> float:
    """The highest frequency in a plan's segments and probe [Hz] (0 for ramps and holds only): a table of
    ``m`` values over ``T`` counts as ``(m - 1) / T``."""
    spec = getattr(plan, "spec", None)
    if spec is None:
        return math.inf  # a plan-like object: no segments to read
    top = spec.probe.frequency if spec.probe is not None else 0.0
    for segment in (*spec.stretch, *spec.voltage):
        if segment.kind == "table":
            top = max(top, (len(segment.values) - 1) / segment.duration)
        for key in ("frequency", "f_start", "f_end"):
            top = max(top, getattr(segment, key, None) or 0.0)
    return top


def blocks_per_step(plan, block: int) -> int:
    """How many blocks of `block` samples the twin computes at once: as many as fit `STEP_SAMPLES` samples
    and `STEP_CYCLES` periods of the plan's `fastest_frequency`, at least one. The same plan is always
    stepped the same way, so a run is reproducible bit for bit."""
    f = fastest_frequency(plan)
    most = STEP_SAMPLES if f == 0.0 else min(STEP_SAMPLES, STEP_CYCLES * plan.sample_rate / f)
    return max(1, int(most // block))


def _window(plan, a, b):
    """``(time, stretch, voltage)`` of samples ``a`` to ``b`` of a plan (`rdea_lab.protocols.Plan.window`),
    or of a plan-like object that has whole arrays but no ``window``."""
    if hasattr(plan, "window"):
        w = plan.window(a, b)
        return w.time, w.stretch, w.voltage
    return plan.time[a:b], plan.stretch[a:b], plan.voltage[a:b]


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
        the journal's at-most-a-second-lost promise. Default 1 s, or `REALTIME_BLOCK`
        with ``realtime`` (a smoother progress display). Without ``realtime``
        several blocks are computed in one step (`blocks_per_step`) and handed
        out one by one; the plan is read in windows (`rdea_lab.protocols.Plan.window`),
        never whole.
    seed : int
        Recorded; the twin itself is deterministic.
    geometry : RollGeometry or StripGeometry, optional
        The card's geometry, as the run's preparation made it (`rdea_lab.runs.app.RunSetup.geometry`);
        made from ``card`` here when not given (a twin backend built by hand).
    """

    name = "twin"
    extra_variables = ("model_status", "paused")

    def __init__(self, card, params, model="su", tolerance=0.01, realtime=False, block_seconds=None, seed=0,
                 clock=_time.monotonic, sleep=_time.sleep, geometry=None):
        self.card = as_specimen(card)
        self.params = as_params(params)
        self.geom = as_geometry(self.card if geometry is None else geometry)  # the twin's one way in
        self.requested = model
        self.tolerance = tolerance
        self.realtime = realtime
        if block_seconds is None:
            block_seconds = REALTIME_BLOCK if realtime else 1.0
        if not 0.0 < block_seconds <= 1.0:
            raise ValueError(f"block_seconds must be in (0, 1], got {block_seconds!r}")
        self.block_seconds = block_seconds
        self.seed = seed
        self.choice = None
        self.model = None if model == "auto" else model
        self._clock, self._sleep = clock, sleep
        self._plan = None
        self._live = False  # started, not closed
        self._pending = collections.deque()  # blocks computed, not yet handed out
        self._step = None  # (model state, path state, charge, setpoints) before the last step
        self._stream = None
        self._t0 = None
        self.aborted = None

    def start(self, plan):
        if self.model == "3r":
            three_ring.check_applicable(self.geom)  # refuse before anything is written
        self._plan = plan
        if self.requested == "auto":  # over the plan's envelope: a long plan is not held for it
            lam, v = plan.envelope() if hasattr(plan, "envelope") else (plan.stretch, plan.voltage)
            self.choice = select_model(self.geom, self.params, lam, v, self.tolerance)
            self.model = self.choice.model
        self._stream = TwinStream(self.geom, self.params, self.model)
        self._charge = (0.0, 0.0)  # (C v, v) before the first sample: no charge at 0 V
        slices = plan.block_slices(self.block_seconds)
        self._block = slices[0].stop - slices[0].start
        self._per = 1 if self.realtime else blocks_per_step(plan, self._block)
        self._setpoints = PausedSetpoints(lambda a, b: _window(plan, a, b)[1:], plan.samples, plan.sample_rate,
                                          pause_spec_of(plan), clock=self._clock)
        self._live = True
        self._t0 = self._clock()

    # ------------------------------------------------------------ pause
    def pause(self, reason: str = "") -> None:
        """Voltage to 0 at the plan's pause ramp rate from the next sample handed out, the stretch held
        (`rdea_lab.protocols.pause.PausedSetpoints`). Blocks computed ahead of it (several per step, without
        ``realtime``) are given back and the model's state taken back to the last sample handed out (that
        part of the step computed again), so the pause acts where the run is, not where it computed to."""
        ahead = sum(len(b["time"]) for b in self._pending)
        if ahead and self._step is not None and self._setpoints.untake(ahead):
            state, path, charge, taken = self._step
            self._stream._state, self._stream._path, self._charge = state, path, charge
            kept = taken.paused.size - ahead
            if kept:
                self._advance(taken.stretch[:kept], taken.voltage[:kept], self._setpoints.taken - kept)
            self._pending.clear()
        if not self._setpoints.pause():
            raise PauseRefused("the twin has driven every sample of its plan: nothing is left to pause")

    def resume(self) -> None:
        """Back to the plan's setpoints at the pause, then on with the plan."""
        if not self._setpoints.resume():
            raise PauseRefused("the twin is not paused")

    def conditions(self) -> dict:
        """The twin has no rig channels (no interlock, amplifier or load cell): none."""
        return {}

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
        if self.aborted is not None or not self._live:
            return None
        while not self._pending:
            sp = self._setpoints
            if sp.done:
                return None
            taken = sp.take(self._per * self._block)
            if taken.paused.size == 0:  # held (nothing else takes none): the wall clock paces the held samples
                self._sleep(max(HELD_WAIT, 1.0 / self._plan.sample_rate))
                continue
            self._compute(taken)
        block = self._pending.popleft()
        if self.realtime:
            wait = float(block["time"][-1]) - (self._clock() - self._t0)  # the plan starts at t = 0
            if wait > 0:
                self._sleep(wait)
        return block

    def _compute(self, taken):
        """The blocks of the setpoints `taken` (`PausedSetpoints.take`), computed in one vectorized step and
        queued as views of at most a block each."""
        self._step = (self._stream._state, self._stream._path, self._charge, taken)
        data = self._advance(taken.stretch, taken.voltage, self._setpoints.taken - taken.paused.size)
        data["paused"] = taken.paused
        for i in range(0, taken.paused.size, self._block):
            self._pending.append({name: values[i:i + self._block] for name, values in data.items()})

    def _advance(self, stretch, voltage, a: int) -> dict:
        """The model over samples ``a, a + 1, ...`` driven at ``stretch`` and ``voltage``: the block's
        variables, the model's state carried on. Sample ``k`` of the run is at ``t = k / rate``, paused
        samples counted: the time axis runs on uniformly through a pause."""
        plan = self._plan
        t = np.arange(a, a + stretch.size) / plan.sample_rate
        out = self._stream.step(t, stretch, voltage, summary=False)
        capacitance = out["capacitance"] if "capacitance" in plan.measure else np.full(t.size, np.nan)
        data = {"time": t, "stretch": stretch, "position": (stretch - 1.0) * self.geom.L1, "voltage": voltage,
                "force": out["force"], "capacitance": capacitance,
                "stretch_setpoint": stretch, "voltage_setpoint": voltage, "model_status": out["model_status"]}
        if "current" in plan.measure:  # an ideal current monitor: the charge change per interval, no leakage
            q = out["capacitance"] * voltage
            data = {"current": np.diff(q, prepend=self._charge[0]) * plan.sample_rate, **data}
            self._charge = (float(q[-1]), float(voltage[-1]))
        return data

    def abort(self, reason):
        self.aborted = reason  # the twin drives no hardware: nothing to switch off

    def close(self):
        self._live = False
        self._pending.clear()
