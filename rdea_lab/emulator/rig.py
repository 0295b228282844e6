"""The emulated specimen on its rig: setpoints in, measured samples out, no sockets.

`EmulatedRig` turns the two setpoint arrays of one run into the eight
columns a rig returns (`COLUMNS`), on demand, carrying every state
(actuator, amplifier, viscoelastic branches, noise streams) from one block
of samples to the next; blocks are aligned on the start of the run, so
producing in chunks of any sizes gives bit-identical data:

- actuator: first-order lag (``actuator_lag``) on the stretch setpoint,
  starting at the first setpoint; the encoder reads its actual stretch, and
  ``position = (stretch - 1) L1`` with the configured ``L1``;
- amplifier: first-order low-pass (``amplifier_bandwidth``) on the voltage
  setpoint, starting at 0 V;
- true force and capacitance: `rdea_lab.emulator.roll.TrueRoll` on the true
  geometry (`true_geometry`) with the truth's material, model and effects
  (passive ends, clamp compliance, Mullins softening, fringe capacitance; with
  none, the twin `rdea_lab.twin.simulate.TwinStream`);
- load cell: + offset (drifting by ``force_drift`` from the run's start) +
  noise; LCR bridge: + parasitics + noise, and only where ``capacitance`` is
  measured and ``|voltage| < 1 V``;
- amplifier current monitor (only where ``current`` is measured: a ninth
  column, `CURRENT_COLUMN`): the true roll's charge ``C v`` (its true
  capacitance, fringe included, at the amplifier's output voltage) through
  an integrating ADC, plus leakage ``v / leakage_resistance`` and noise
  ``current_noise`` (`rdea_lab.emulator.instruments.CurrentMonitor`); the
  leads' parasitics are the LCR fixture's, not in this path;
- aborts: dielectric breakdown (field estimate ``|v| sqrt(lambda) / L3`` with
  the true ``L3`` and the electroded zone's stretch ``lambda`` above
  ``breakdown_field``, or no stable equilibrium
  left: pull-in), a load-cell reading above ``max_force``, or a block the
  truth's physics cannot solve (`rdea_lab.emulator.roll`: the reason says so). The samples up
  to and including the breaking one are kept (a pull-in sample has no force
  and is dropped); then voltage goes to 0 and the actuator back to its start;
- conditions (`rdea_lab.emulator.conditions`, from injected faults): the door
  interlock, the amplifier's temperature, a step of the load cell's zero (in
  the force column). A run that cannot pause aborts when it would drive a
  voltage with the door open.

A pausable run (`RunConfig.pause`, the rig's ``CONF:PAUS``) drives the setpoints
of `rdea_lab.protocols.pause.PausedSetpoints` and its rows gain a last column,
``paused`` (the phase of each sample). While no pause is asked for, its blocks
are the plan's own, computed ahead as above (so its data are those of the same
run without ``CONF:PAUS``); a pause asked for while part of such a block is not
yet produced rewinds the block to the last sample produced, so the pause acts
from the next sample. While it pauses, holds or resumes, blocks are at most
`PAUSE_BLOCK_TIME` long (aligned too; a held block is made once the wall
clock allows all of it). Sample ``k`` is at ``t = k / rate`` whatever it
drives: a paused run is longer than its plan by its paused samples.
"""

from __future__ import annotations

import copy
import math
import sys
import time as _time
from dataclasses import dataclass

import numpy as np

from ..physics.result import LIMIT_POINT, OUTSIDE_RANGE, STATUS_NAMES, is_valid
from ..protocols.pause import HELD, RAMPING_DOWN, RAMPING_UP, PausedSetpoints
from ..specs.rigwire import CHANNELS, COLUMNS, CURRENT_COLUMN, PAUSE_STATES, row_columns
from .conditions import Conditions
from .roll import TrueRoll
from .instruments import CurrentMonitor, FirstOrderLag, lcr_bridge, load_cell, tau_of_bandwidth
from .truth import true_geometry

#: The LCR bridge measures only below this |voltage| [V].
LCR_MAX_VOLTAGE = 1.0
#: Samples computed at once, in blocks aligned on the start of the run [samples].
BLOCK = 2048
#: Relative slack of the limit checks, as in `rdea_lab.protocols.check_plan`.
SLACK = 1e-12
#: Longest block of a pausable run while it pauses, holds or resumes [s]: how late a pause may act on
#: samples computed already.
PAUSE_BLOCK_TIME = 0.05
#: `EmulatedRig.n` of a pausable run still running: its length is not known until it ends.
UNBOUNDED = sys.maxsize


def pause_block(rate: float) -> int:
    """Samples of a block of a pausable run while it pauses, holds or resumes: at most `PAUSE_BLOCK_TIME`
    of them, at least 1, at most `BLOCK`.

    Parameters
    ----------
    rate : float
        Sample rate [Hz].
    """
    return max(1, min(BLOCK, int(math.floor(PAUSE_BLOCK_TIME * rate + 1e-9))))


def samples_before(t: float, rate: float) -> int:
    """Number of sample times ``k / rate`` (k >= 0) below `t` [s]."""
    k = max(0, math.ceil(t * rate))
    while k > 0 and (k - 1) / rate >= t:
        k -= 1
    while k / rate < t:
        k += 1
    return k


@dataclass(frozen=True)
class RunConfig:
    """What the host configured for one run (SI).

    Attributes
    ----------
    rate : float
        Sample rate [Hz].
    stretch_setpoint, voltage_setpoint : numpy.ndarray
        One setpoint per sample [-], [V].
    L1 : float
        Unstretched specimen length for ``position`` [m].
    L3 : float
        Single-membrane thickness for the field limit [m].
    max_voltage, max_stretch, max_force, max_field : float
        Limits [V], [-], [N], [V/m].
    measure : tuple of str
        Measured channels, from `CHANNELS`.
    pause : PauseSpec, optional
        How the run pauses (``CONF:PAUS``); None: it cannot pause and its rows have no ``paused`` column.
    """

    rate: float
    stretch_setpoint: np.ndarray
    voltage_setpoint: np.ndarray
    L1: float
    L3: float
    max_voltage: float = math.inf
    max_stretch: float = math.inf
    max_force: float = math.inf
    max_field: float = math.inf
    measure: tuple = ("force",)
    pause: object = None

    def __post_init__(self):
        for name in ("stretch_setpoint", "voltage_setpoint"):
            arr = np.array(getattr(self, name), dtype=float).ravel()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        unknown = set(self.measure) - set(CHANNELS)
        if unknown:
            raise ValueError(f"unknown channels {sorted(unknown)}; allowed: {', '.join(CHANNELS)}")

    @property
    def n(self) -> int:
        """Number of samples of the run."""
        return self.stretch_setpoint.size

    @property
    def columns(self) -> tuple:
        """The columns of this run's rows: `COLUMNS`, ``current`` when it is measured, ``paused`` when the run
        can pause."""
        return row_columns(self.measure, paused=self.pause is not None)

    @property
    def time(self) -> np.ndarray:
        """Sample times ``k / rate`` [s]."""
        return np.arange(self.n) / self.rate


def _g(value: float, other: float | None = None) -> str:
    """`value` with enough digits to differ from `other` (a limit) in print."""
    for digits in (6, 9, 12, 17):
        text = f"{value:.{digits}g}"
        if other is None or text != f"{other:.{digits}g}":
            return text
    return text


def seconds(t: float) -> str:
    """A sample time for messages: ``12.5`` [s], up to 10 significant digits."""
    return f"{t:.10g}"


def limit_violation(config: RunConfig) -> str | None:
    """The first sample of a run's setpoints that breaks a limit, as a message.

    Checks, per sample: finite setpoints; ``1 <= stretch <= max_stretch``;
    ``|voltage| <= max_voltage``; field estimate ``|v| sqrt(stretch) / L3 <=
    max_field`` (each with a relative slack of `SLACK` for rounding).

    Returns
    -------
    str or None
        E.g. ``voltage 3200 V at t = 12.5 s is above LIM:VOLT 3000 V`` for
        the earliest violating sample (stretch before voltage before field
        within a sample); None if every sample is within the limits.
    """
    x, v, t = config.stretch_setpoint, config.voltage_setpoint, config.time
    if x.size != v.size:
        raise ValueError(f"{x.size} stretch setpoints but {v.size} voltage setpoints")
    av = np.abs(v)
    with np.errstate(invalid="ignore"):
        field = av * np.sqrt(np.maximum(x, 0.0)) / config.L3
    checks = [
        (~np.isfinite(x), lambda k: f"stretch setpoint {float(x[k])!r} at t = {seconds(t[k])} s "
                                    "is not a finite number"),
        (~np.isfinite(v), lambda k: f"voltage setpoint {float(v[k])!r} at t = {seconds(t[k])} s "
                                    "is not a finite number"),
        (x < 1.0 - SLACK, lambda k: f"stretch {_g(x[k], 1.0)} at t = {seconds(t[k])} s is below 1 "
                                    "(the roll must stay in tension)"),
        (x > config.max_stretch * (1.0 + SLACK),
         lambda k: f"stretch {_g(x[k], config.max_stretch)} at t = {seconds(t[k])} s is above "
                   f"LIM:STR {_g(config.max_stretch)}"),
        (av > config.max_voltage * (1.0 + SLACK),
         lambda k: f"voltage {_g(v[k], math.copysign(config.max_voltage, v[k]))} V at t = {seconds(t[k])} s is "
                   f"{'above' if v[k] > 0 else 'beyond (in magnitude)'} LIM:VOLT {_g(config.max_voltage)} V"),
        (field > config.max_field * (1.0 + SLACK),
         lambda k: f"field estimate {_g(field[k], config.max_field)} V/m (voltage {_g(v[k])} V, stretch "
                   f"{_g(x[k])}, CONF:THIC {_g(config.L3)} m) at t = {seconds(t[k])} s is above "
                   f"LIM:FIEL {_g(config.max_field)} V/m"),
    ]
    first = [(int(np.argmax(mask)), order) for order, (mask, _) in enumerate(checks) if mask.any()]
    if not first:
        return None
    k, order = min(first)
    return checks[order][1](k)


@dataclass
class _Event:
    index: int
    keep: int  # samples kept (up to, excluding, this index)
    reason: str


class EmulatedRig:
    """One run of the emulated specimen, produced on demand.

    Parameters
    ----------
    card : SpecimenCard
        The nominal specimen on the rig.
    truth : TruthSpec
        True physics and instrument effects.
    rng : numpy.random.Generator
        Source of all noise (independent streams are spawned from it: load
        cell and LCR bridge, and the current monitor when ``current`` is
        measured).
    config : RunConfig
        Rate, setpoints, L1, limits, measured channels.
    breakdown_at : float, optional
        Injected fault: the membrane breaks down at the first sample with
        ``t >= breakdown_at`` [s].
    truth_source : str, optional
        Where `truth` came from, for error messages.
    conditions : Conditions, optional
        The rig's condition channels over the run (injected interlock, overheat, drift); default: nominal.
    clock : callable
        Wall time [s]: paces the held samples of a pausable run.

    Attributes
    ----------
    acquired : int
        Samples produced so far.
    state : str
        ``"running"``, ``"done"`` or ``"aborted"``.
    reason : str
        Why the run aborted (``""`` otherwise).
    """

    def __init__(self, card, truth, rng: np.random.Generator, config: RunConfig, *,
                 breakdown_at: float | None = None, truth_source: str | None = None, conditions=None,
                 clock=_time.monotonic):
        if config.n < 1:
            raise ValueError("a run needs at least one sample")
        self.config = config
        self.truth = truth
        self.geom = true_geometry(card, truth, source=truth_source)
        self._roll = TrueRoll(self.geom, truth)
        inst = truth.instrument
        dt = 1.0 / config.rate
        self._start = float(config.stretch_setpoint[0])
        self._actuator = FirstOrderLag(inst.actuator_lag, dt, self._start)
        self._amplifier = FirstOrderLag(tau_of_bandwidth(inst.amplifier_bandwidth), dt, 0.0)
        self._force_rng, self._cap_rng = rng.spawn(2)
        self._current = None
        if "current" in config.measure:  # a third stream: the other two stay what they were
            self._current = CurrentMonitor(dt, inst.leakage_resistance, inst.current_noise, rng.spawn(1)[0])
        self.breakdown_at = breakdown_at
        self.acquired = 0
        self._computed = 0
        self._pending = None  # (rows computed but not yet produced, first abort event of their block)
        self.state = "running"
        self.reason = ""
        self.interlocked = False  # the amplifier's interlock: open, no sample is made with the voltage on
        self.conditions = conditions if conditions is not None else Conditions(force_drift=inst.force_drift)
        self._sp = None  # a pausable run's setpoints
        self._ahead = None  # (k0, j0, state) of a pausable run's block computed ahead from the plan
        self._woken = False  # a resume asked for while held, not yet acted on
        if config.pause is not None:
            x, v = config.stretch_setpoint, config.voltage_setpoint
            self._sp = PausedSetpoints(lambda a, b: (x[a:b], v[a:b]), config.n, config.rate, config.pause,
                                       clock=clock)
            self._short = pause_block(config.rate)

    # ------------------------------------------------------------ state
    @property
    def n(self) -> int:
        """Samples in the whole run: the plan's; a pausable run's, the plan's and its paused ones, known once it
        has ended (`UNBOUNDED` until then)."""
        if self._sp is None:
            return self.config.n
        return UNBOUNDED if self.state == "running" else self.acquired

    @property
    def pausable(self) -> bool:
        return self._sp is not None

    def pause(self) -> bool:
        """Pause a pausable run from the next sample produced; False when it pauses already, or when every
        plan sample is taken (`paused` tells them apart)."""
        self._woken = False
        return self._sp.pause()

    def resume(self) -> bool:
        """Resume a pausable run from the next sample produced; False when it is not paused."""
        self._woken = self._sp.resume()
        return self._woken

    @property
    def paused(self) -> bool:
        """A pausable run pausing, held or resuming."""
        return self._sp is not None and self._sp.paused

    def pause_state(self) -> tuple[str, int]:
        """``(state, pauses so far)``, state one of `PAUSE_STATES` (``RUNNING`` for a run that cannot pause)."""
        sp = self._sp
        if sp is None:
            return PAUSE_STATES[0], 0
        names = {RAMPING_DOWN: "PAUSING", HELD: "PAUSED", RAMPING_UP: "RESUMING"}
        state = names.get(sp.phase, "PAUSING" if sp.paused else "RUNNING")
        return state, sp.pauses

    def condition_reading(self) -> dict:
        """The condition channels at the latest sample's time (`Conditions.reading`; t = 0 before any)."""
        t = (self.acquired - 1) / self.config.rate if self.acquired else 0.0
        return self.conditions.reading(t)

    @property
    def running(self) -> bool:
        return self.state == "running"

    def interlock(self) -> None:
        """Open the amplifier's interlock (an emergency stop, from any thread, without a lock): `produce`
        makes no further sample; `abort` follows with the bookkeeping."""
        self.interlocked = True

    def abort(self, reason: str) -> None:
        """Stop the run: voltage to 0, actuator back to its start; no further samples."""
        if self.state != "running":
            return
        self.state, self.reason = "aborted", reason
        self._pending = None
        self._amplifier.reset(0.0)
        self._actuator.reset(self._start)
        if self._current is not None:
            self._current.reset()

    def samples_before(self, t: float) -> int:
        """Number of samples of the run with time ``k / rate < t``."""
        return min(samples_before(t, self.config.rate), self.n)

    def samples_until(self, t: float) -> int:
        """Number of samples of the run with time ``k / rate <= t``."""
        k = self.samples_before(t)
        while k < self.n and k / self.config.rate <= t:
            k += 1
        return k

    # ------------------------------------------------------------ output
    def produce(self, n: int) -> np.ndarray:
        """The next up to `n` samples, shape ``(m, 8)`` (`COLUMNS`; 9 with ``current``), ``m <= n``.

        Fewer than `n` (maybe none) when the run ends or aborts.
        """
        out = []
        n = int(n)
        while n > 0 and self.state == "running" and not self.interlocked:
            if self._ahead is not None and self._sp.paused:  # a pause asked for after the block was computed
                self._rewind()
                if self.state != "running":  # the physics failed computing the rewound samples again
                    break
            if self._pending is None or self._pending[0].shape[0] == 0:
                self._pending = self._compute_block()
                if self._pending[0].shape[0] == 0:  # aborted, or held and no sample due yet
                    break
            rows, event = self._pending
            take = min(n, rows.shape[0])
            if event is not None:
                take = min(take, event.keep - self.acquired)
            if self._ahead is not None:
                self._sp.take(take)  # in step: the plan's own setpoints, no pause asked for
            out.append(rows[:take])
            self._pending = (rows[take:], event)
            self.acquired += take
            n -= take
            if event is not None and self.acquired == event.keep:
                self.abort(event.reason)
            elif self._ended():
                self.state = "done"
                self._amplifier.reset(0.0)
                self._actuator.reset(self._start)
        return np.concatenate(out) if out else np.empty((0, len(self.config.columns)))

    def _ended(self) -> bool:
        if self._sp is None:
            return self.acquired >= self.n
        return self._sp.done and (self._pending is None or self._pending[0].shape[0] == 0)

    def produce_until(self, t: float) -> np.ndarray:
        """Every not yet produced sample with time ``<= t`` [s]."""
        return self.produce(self.samples_until(t) - self.acquired)

    def _compute_block(self):
        """The next `BLOCK` samples (fewer at the end of the run) and the first abort among them.

        Always the same blocks from the start of the run, whatever `produce`
        is asked for: the physics (whose viscoelastic prefix scan rounds
        differently for different block lengths) and the noise streams see
        the same blocks, so any chunking gives bit-identical data. A pausable
        run: see the module docstring.
        """
        cfg = self.config
        k0 = self._computed
        if self._sp is None:
            m = min(BLOCK, self.n - k0)
            return self._physics(k0, cfg.stretch_setpoint[k0:k0 + m], cfg.voltage_setpoint[k0:k0 + m])
        sp = self._sp
        self._ahead = None
        if self.conditions.active("interlock", k0 / cfg.rate):
            sp.pause()  # the rig does not drive its plan with its door open
        size = self._short if sp.paused else BLOCK
        m = size - k0 % size
        opening = self.conditions.opening()
        if opening is not None and samples_before(opening, cfg.rate) > k0:  # a pause acts as the door opens
            m = min(m, samples_before(opening, cfg.rate) - k0)
        if not sp.paused:  # the plan's own setpoints, computed ahead (a pause asked for meanwhile rewinds)
            j0 = sp.next
            m = min(m, sp.samples - j0)
            if m <= 0:
                return np.empty((0, len(cfg.columns))), None
            self._ahead = (k0, j0, self._state())
            return self._physics(k0, cfg.stretch_setpoint[j0:j0 + m], cfg.voltage_setpoint[j0:j0 + m], np.zeros(m))
        if sp.phase == HELD and not self._woken and sp.held_due() < m:
            # held: whole blocks only, as the wall clock allows them (a block's physics costs the same however
            # few its samples)
            return np.empty((0, len(cfg.columns))), None
        self._woken = False
        got = sp.take(m)
        if not got.stretch.size:
            return np.empty((0, len(cfg.columns))), None
        return self._physics(k0, got.stretch, got.voltage, got.paused.astype(float))

    def _state(self):
        """A copy of everything a block changes: instruments, roll, noise streams."""
        return copy.deepcopy((self._actuator, self._amplifier, self._roll, self._force_rng, self._cap_rng,
                              self._current))

    def _rewind(self):
        """A pause asked for while a block computed ahead from the plan is not all produced: back to the
        block's start, its samples produced so far computed again from there (their rows were sent; the
        state goes on from them), the rest dropped."""
        k0, j0, state = self._ahead
        self._ahead = None
        if self._pending is None or self._pending[0].shape[0] == 0:
            return
        (self._actuator, self._amplifier, self._roll, self._force_rng, self._cap_rng, self._current) = state
        self._pending, self._computed = None, k0
        m = self.acquired - k0
        if m:
            cfg = self.config
            self._physics(k0, cfg.stretch_setpoint[j0:j0 + m], cfg.voltage_setpoint[j0:j0 + m], np.zeros(m))

    def _physics(self, k0, s_sp, v_sp, paused=None):
        """Rows of samples ``k0, k0 + 1, ...`` driven by setpoints `s_sp`, `v_sp` (and their ``paused`` phase,
        the last column of a pausable run), and their first abort event."""
        cfg, inst = self.config, self.truth.instrument
        m = len(s_sp)
        self._computed = k0 + m
        k = np.arange(k0, k0 + m)
        t = k / cfg.rate
        stretch = self._actuator(s_sp)
        voltage = self._amplifier(v_sp)
        # the roll cannot be compressed: a setpoint of 1 - 1e-16 is 1
        try:
            true = self._roll.step(t, np.maximum(stretch, 1.0), voltage)
        except RuntimeError as exc:  # the truth's physics has no solution here: stop, voltage off
            self.abort(f"the emulated roll has no solution from t = {seconds(t[0])} s: {exc}")
            return np.empty((0, len(cfg.columns))), None
        offset = inst.force_offset + inst.force_drift * t
        if self.conditions.drifts:  # the injected step of the zero
            offset = offset + self.conditions.offset_step(t)
        force = load_cell(true["force"], offset, inst.force_noise, self._force_rng)
        capacitance = lcr_bridge(true["capacitance"], voltage, inst.parasitic_capacitance, inst.capacitance_noise,
                                 self._cap_rng, enabled="capacitance" in cfg.measure, max_voltage=LCR_MAX_VOLTAGE)
        rows = np.column_stack([
            t, stretch, (stretch - 1.0) * cfg.L1, voltage,
            force if "force" in cfg.measure else np.full(m, np.nan),
            capacitance, s_sp, v_sp,
            *([self._current(true["capacitance"], voltage)] if self._current is not None else []),
            *([paused] if paused is not None else []),
        ])
        event = self._first_event(t, np.where(np.isnan(true["lambda_a"]), stretch, true["lambda_a"]), voltage, force,
                                  true["model_status"], v_sp)
        if event is not None:
            event.index += k0
            event.keep += k0
        return rows, event

    def _first_event(self, t, stretch, voltage, force, status, v_sp) -> _Event | None:
        """The earliest abort in a block: breakdown, pull-in, force limit, or (a run that cannot pause) a
        voltage setpoint with the door open (indices in the block).

        `stretch` is the electroded zone's (the field's) stretch."""
        E = np.abs(voltage) * np.sqrt(np.maximum(stretch, 1.0)) / self.geom.L3
        fmt = lambda i: f"dielectric breakdown at t = {seconds(t[i])} s (field {E[i] / 1e6:.4g} V/um"  # noqa: E731
        events = []
        over = E > self.truth.instrument.breakdown_field
        if over.any():
            i = int(np.argmax(over))
            events.append(_Event(i, i + 1, fmt(i) + ")"))
        if self.breakdown_at is not None:
            hit = t >= self.breakdown_at
            if hit.any():
                i = int(np.argmax(hit))
                events.append(_Event(i, i + 1, fmt(i) + "; injected fault)"))
        lost = ~is_valid(status)
        if lost.any():
            i = int(np.argmax(lost))
            if status[i] == LIMIT_POINT:
                what = "pull-in: no stable equilibrium"
            elif status[i] == OUTSIDE_RANGE:
                what = "the state lies beyond the model's solved range"
            else:
                what = f"no state ({STATUS_NAMES.get(int(status[i]), 'unknown')})"
            events.append(_Event(i, i, fmt(i) + f"; {what} at {voltage[i]:.4g} V, stretch {stretch[i]:.4g})"))
        high = np.abs(force) > self.config.max_force
        if high.any():
            i = int(np.argmax(high))
            events.append(_Event(i, i + 1, f"force {force[i]:.4g} N at t = {seconds(t[i])} s above "
                                           f"LIM:FORC {_g(self.config.max_force)} N"))
        if self._sp is None and self.conditions.opening() is not None:
            hot = self.conditions.active("interlock", t) & (np.asarray(v_sp) != 0.0)
            if hot.any():
                i = int(np.argmax(hot))
                events.append(_Event(i, i, f"the door interlock is open at t = {seconds(t[i])} s with the voltage "
                                           f"setpoint at {v_sp[i]:.4g} V: armed without CONF:PAUS, the run cannot "
                                           "pause, so it aborts (voltage off)"))
        if not events:
            return None
        first = min(events, key=lambda e: e.index)  # ties: in the order above
        if lost[first.index]:  # a sample without equilibrium has no force to keep
            first.keep = first.index
        return first


__all__ = ["CHANNELS", "COLUMNS", "CURRENT_COLUMN", "EmulatedRig", "PAUSE_BLOCK_TIME", "RunConfig", "limit_violation",
           "pause_block"]
