"""The emulated rig's state behind the command set: settings, limits, the armed run, faults, the e-stop.

`RigState` is what `rdea_lab.emulator.controller.RigController` (the
interpreter of ``docs/rig-protocol.md``) acts on: the configuration a client
sent, the rig's own hard limits, the state (``IDLE``, ``ARMED``,
``RUNNING``, ``DONE``, ``ABORTED``) and who controls it, the run
(`EmulatedRig`) and its unfetched rows, the injected faults, the heartbeat
watchdog and the realtime producer. Its arguments arrive parsed and checked
against the protocol (`rdea_lab.specs.rigwire`); what it checks itself is
what depends on the state: a setting while armed, a limit above the rig's
own, a run that is not ready.

One lock (`lock`) guards it; the interpreter takes it around a command, the
producer and the e-stop's bookkeeping take it too. `emergency_stop` never
waits for it: the amplifier's interlock opens first, the bookkeeping
follows under the lock.

Time is virtual by default: samples are produced when ``FETC?`` asks for them.
With ``realtime=True`` only samples with ``t <=`` the wall time since ``INIT``
exist, and a thread produces them (so limits abort a run even when nobody
fetches).

A run armed after ``CONF:PAUS`` can pause (``PAUS``, ``CONT``; the setpoints of
`rdea_lab.protocols.pause.PausedSetpoints`), stays ``RUNNING`` while paused (the
heartbeat and every limit still apply) and pauses by itself when the door
interlock opens; one armed without it aborts when it would drive a voltage with
the door open. ``CONT`` is refused while the door is open.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import threading
import time

import numpy as np

from ..physics import viscoelastic
from ..protocols.pause import PauseSpec
from ..specs.rigwire import (DATA_OUT_OF_RANGE, LIMITS, MAX_POINTS, SETTINGS_CONFLICT, COMMANDS, RigError,
                             armed_checksum)
from .conditions import FAULTS, Conditions, Fault, check_faults
from .rig import BLOCK, EmulatedRig, RunConfig, _g, limit_violation
#: Longest the rig computes samples while holding its lock [s]: a ``FETC?`` returns the rows made by then
#: (fewer than asked; the client asks again), the realtime producer goes on at its next turn. So no
#: command, heartbeat or status waits longer than this (and a block) for the lock; ``ABOR`` waits for none.
PRODUCE_SLICE = 0.1


class CloseConnection(Exception):
    """The session's connection is to be closed without a reply (injected disconnect)."""


class RigState:
    """State of one emulated rig (see the module docstring); the parameters are `RigController`'s."""

    def __init__(self, card, truth, *, realtime=False, faults=(), truth_source=None, close_session=None,
                 clock=time.monotonic, limits=None, heartbeat=10.0):
        from ..physics.geometry import geometry_from_card
        from ..specs import Limits

        self.card, self.truth, self.truth_source = card, truth, truth_source
        viscoelastic.prepare(truth.material.law)  # before any client waits on a reply
        hard = limits if limits is not None else Limits()
        self.hard_limits = dict(zip(LIMITS, (float(hard.max_voltage), float(hard.max_stretch),
                                             float(hard.max_force), float(hard.max_field))))
        self.thickness = float(geometry_from_card(card).L3)  # the rig's own, for the field limit
        if not (isinstance(heartbeat, (int, float)) and 0.1 <= heartbeat <= 3600):
            raise ValueError(f"heartbeat {heartbeat!r} s; allowed: 0.1 to 3600 s")
        self.heartbeat = float(heartbeat)
        self._last_heard = clock()
        self._answering = 0  # commands of the controlling connection being answered now
        self._watchdog: threading.Thread | None = None
        self.realtime = bool(realtime)
        self.faults = check_faults(faults)
        self._close_session = close_session or (lambda session: None)
        self._doomed = None  # the session an injected realtime disconnect closes at its next command
        self._clock = clock
        self.lock = threading.RLock()
        self._tripped: str | None = None  # an emergency stop not yet booked under the lock (see emergency_stop)
        self._trip_lock = threading.Lock()  # held for a few statements only, never while computing
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.clear()

    # ------------------------------------------------------------- state
    def clear(self) -> None:
        self.rate: float | None = None
        self.measure: tuple = ("force",)
        self.L1: float | None = None
        self.L3: float | None = None
        self.seed = 0
        self.pause: tuple | None = None  # CONF:PAUS (ramp rate, hold stretch or 0, stretch rate)
        self.limits: dict[str, float | None] = {header: None for header in LIMITS}
        self.trajectories: dict[str, np.ndarray | None] = {"TRAJ:STR": None, "TRAJ:VOLT": None}
        self.state = "IDLE"
        self.reason = ""
        self.owner = None
        self._armed: RunConfig | None = None
        self.run: EmulatedRig | None = None
        self._rows: collections.deque = collections.deque()
        self._buffered = 0
        self.fetched = 0
        self._t0 = 0.0
        self._disconnect_fired = False

    @property
    def acquired(self) -> int:
        return self.run.acquired if self.run is not None else 0

    @property
    def voltage_on(self) -> bool:
        """True while a run drives the specimen (the amplifier may be on); False from the instant of an
        emergency stop, before its bookkeeping."""
        run = self.run
        return run is not None and run.running and not run.interlocked and self._tripped is None

    def status(self) -> tuple[str, int, int, str]:
        """``(state, acquired, fetched, reason)``; also without the lock (an emergency stop not yet booked
        reads ABORTED)."""
        state, reason, tripped = self.state, self.reason, self._tripped
        if tripped is not None and state in ("ARMED", "RUNNING"):
            state, reason = "ABORTED", tripped
        return state, self.acquired, self.fetched, reason

    def limits_in_force(self) -> list[float]:
        """The client's limits where it set one, else the rig's own (in the order of `LIMITS`)."""
        return [self.limits[h] if self.limits[h] is not None else self.hard_limits[h] for h in LIMITS]

    # --------------------------------------------------------- control
    def heard(self, session) -> None:
        """A command from `session`: a heartbeat if it controls the rig."""
        if session == self.owner:
            self._last_heard = self._clock()

    @contextlib.contextmanager
    def answering(self, session):
        """The controlling connection's command being answered: its silence is not counted meanwhile (a
        ``FETC?`` that computes a block: seconds without numba on a busy machine), and counts from the reply.
        The heartbeat guards against a client that falls silent, not against the rig's own computing."""
        mine = session == self.owner
        if mine:
            self._answering += 1
        try:
            yield
        finally:
            if mine:
                self._answering -= 1
                self._last_heard = self._clock()

    def take_control(self, session) -> None:
        self.owner, self._last_heard = session, self._clock()

    def doomed(self, session) -> bool:
        """Whether `session` is the one an injected realtime disconnect closes (once)."""
        if session is not None and session == self._doomed:
            self._doomed = None
            return True
        return False

    def release(self, session) -> None:
        if self.state in ("ARMED", "RUNNING"):
            raise RigError(SETTINGS_CONFLICT, f"settings conflict: SYST:REL while {self.state}; send ABOR first")
        self.owner = None

    def reset(self, session) -> None:
        """``*RST``: abort (voltage off), clear; `session` controls the rig unless another did."""
        self._abort("*RST")
        self._stop.set()  # the producer thread ends by itself (joining here, under the lock, would deadlock)
        owner = self.owner
        self.clear()
        if owner is not None and owner != session:  # an emergency stop from elsewhere: control is released
            self.owner = None
        else:
            self.owner = session

    def session_closed(self, session) -> None:
        """A connection ended: a run it armed or drives aborts (voltage off), and it controls the rig no more."""
        with self.lock:
            if self.owner == session:
                if self.state in ("ARMED", "RUNNING"):
                    self._abort("client disconnected")
                self.owner = None
        if self._stop.is_set():
            self._stop_producer()

    def shutdown(self) -> None:
        """End of the server: abort anything running (voltage off) and stop the producer."""
        with self.lock:
            self._abort("server shut down")
        self._stop_producer()

    # -------------------------------------------------------- settings
    def check_configurable(self, header: str) -> None:
        if self.state in ("ARMED", "RUNNING"):
            raise RigError(SETTINGS_CONFLICT,
                           f"settings conflict: {header} while {self.state}; send ABOR or *RST first")

    def configure(self, name: str, value) -> None:
        """One of ``rate``, ``measure``, ``L1``, ``L3``, ``seed``, ``pause``, checked by the protocol already."""
        setattr(self, name, value)

    def set_limit(self, header: str, value: float) -> None:
        """A client's ``LIM:*``: it can only lower the rig's own."""
        hard, unit = self.hard_limits[header], COMMANDS[header].arg.unit
        if value > hard * (1.0 + 1e-12):
            raise RigError(DATA_OUT_OF_RANGE, f"{header} {value:g} {unit} is above the rig's own limit {hard:g} "
                                              f"{unit}; a client can only lower it".replace("  ", " "))
        self.limits[header] = value

    def set_trajectory(self, header: str, values: np.ndarray) -> None:
        self.trajectories[header] = values

    # -------------------------------------------------------------- run
    def arm(self, session) -> str:
        """Check the configuration and both trajectories against every limit; state ARMED; the checksum."""
        if self.state == "RUNNING":
            raise RigError(SETTINGS_CONFLICT, "settings conflict: a run is RUNNING; send ABOR first")
        missing = [COMMANDS[h].usage for h in LIMITS if self.limits[h] is None]
        if missing:
            raise RigError(SETTINGS_CONFLICT, f"no limit in force for {', '.join(c.split()[0] for c in missing)}: "
                                              f"set {' and '.join(missing)} before ARM")
        lim = {h: min(self.limits[h], self.hard_limits[h]) for h in LIMITS}  # never above the rig's own
        for value, header in ((self.rate, "CONF:RATE"), (self.L1, "CONF:LENG"), (self.L3, "CONF:THIC")):
            if value is None:
                raise RigError(SETTINGS_CONFLICT, f"set {COMMANDS[header].usage} before ARM")
        x, v = self.trajectories["TRAJ:STR"], self.trajectories["TRAJ:VOLT"]
        if x is None or v is None or x.size == 0:
            raise RigError(SETTINGS_CONFLICT, "no trajectories: upload TRAJ:STR and TRAJ:VOLT before ARM")
        if x.size != v.size:
            raise RigError(SETTINGS_CONFLICT, f"TRAJ:STR has {x.size} setpoints but TRAJ:VOLT {v.size}; need as many")
        # the field is checked with the thinner of the rig's own thickness and the client's: CONF:THIC
        # cannot talk the rig out of its field limit
        config = RunConfig(self.rate, x, v, L1=self.L1, L3=min(self.L3, self.thickness),
                           max_voltage=lim["LIM:VOLT"], max_stretch=lim["LIM:STR"], max_force=lim["LIM:FORC"],
                           max_field=lim["LIM:FIEL"], measure=self.measure)
        problem = limit_violation(config)
        if problem:
            raise RigError(DATA_OUT_OF_RANGE, problem)
        if self.pause is not None:  # no client talks the rig past its limits by pausing
            ramp_rate, hold, stretch_rate = self.pause
            if hold and hold > lim["LIM:STR"] * (1.0 + 1e-12):
                raise RigError(DATA_OUT_OF_RANGE, f"CONF:PAUS hold_stretch {_g(hold, lim['LIM:STR'])} is above "
                                                  f"LIM:STR {_g(lim['LIM:STR'])}")
            ramps = [(np.max(np.abs(v)) / ramp_rate, f"ramp_rate {ramp_rate:g} V/s takes {{n:.3g}} samples from "
                                                     f"{np.max(np.abs(v)):g} V to 0")]
            if hold:
                ramps.append((np.max(np.abs(x - hold)) / stretch_rate,
                              f"stretch_rate {stretch_rate:g} /s takes {{n:.3g}} samples to hold_stretch {hold:g}"))
            for seconds, what in ramps:  # the rig holds a ramp in memory: no longer than a trajectory
                if seconds * self.rate > MAX_POINTS:
                    raise RigError(DATA_OUT_OF_RANGE, f"CONF:PAUS {what.format(n=seconds * self.rate)}; at most "
                                                      f"{MAX_POINTS:g}")
            config = dataclasses.replace(config, pause=PauseSpec(ramp_rate, hold or None, stretch_rate))
        self._stop.set()
        self._armed, self.run, self.state, self.reason, self.owner = config, None, "ARMED", "", session
        self._rows.clear()
        self._buffered = self.fetched = 0
        self._disconnect_fired = False
        return armed_checksum(self.rate, [self.limits[h] for h in LIMITS], self.L3, x, v, self.pause)

    def init(self) -> None:
        """Start the armed run: state RUNNING, the watchdog (and, realtime, the producer) running."""
        if self.state != "ARMED":
            raise RigError(SETTINGS_CONFLICT, f"settings conflict: INIT needs an armed run, the rig is {self.state}; "
                                              "send ARM first")
        rng = np.random.default_rng([self.truth.seed, self.seed])
        breakdown = self.faults.get("breakdown")
        self.run = EmulatedRig(self.card, self.truth, rng, self._armed,
                               breakdown_at=breakdown.at if breakdown is not None else None,
                               truth_source=self.truth_source, clock=self._clock,
                               conditions=Conditions(self.faults, self.truth.instrument.force_drift))
        self.state = "RUNNING"
        self._t0 = self._last_heard = self._clock()
        self._start_watchdog()
        if self.realtime:
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._producer, args=(self._stop,), daemon=True,
                                            name="rig-emulator-daq")
            self._thread.start()

    # ------------------------------------------------------------ pause
    def _pausable_run(self, header: str) -> EmulatedRig:
        if self.state != "RUNNING" or self.run is None:
            raise RigError(SETTINGS_CONFLICT, f"settings conflict: {header} needs a RUNNING run, the rig is "
                                              f"{self.state}")
        if not self.run.pausable:
            raise RigError(SETTINGS_CONFLICT, f"settings conflict: {header}: this run was armed without CONF:PAUS, "
                                              "so it cannot pause (send CONF:PAUS before ARM; ABOR stops it)")
        return self.run

    def pause_run(self) -> None:
        """``PAUS``: the run ramps its voltage to 0 and holds, from the next sample produced (already pausing
        or held: nothing changes)."""
        run = self._pausable_run("PAUS")
        if not run.pause() and not run.paused:
            raise RigError(SETTINGS_CONFLICT, "settings conflict: PAUS: the run has driven every sample of its "
                                              "trajectories, nothing is left to pause")

    def resume_run(self) -> None:
        """``CONT``: the paused run goes back to its trajectories; refused while the door interlock is open."""
        run = self._pausable_run("CONT")
        if self.realtime:
            self.advance_realtime()
        if run.condition_reading()["interlock"] == "open":
            raise RigError(SETTINGS_CONFLICT, "settings conflict: CONT: the door interlock is open; the rig puts "
                                              "no voltage on with its door open (close it, then CONT)")
        if not run.resume():
            raise RigError(SETTINGS_CONFLICT, f"settings conflict: CONT: the run is not paused (PAUS? "
                                              f"{run.pause_state()[0]})")

    def pause_status(self) -> tuple[str, int]:
        """``PAUS?``: ``(state, pauses so far)`` of the run (the last one when none goes)."""
        if self.run is None:
            raise RigError(SETTINGS_CONFLICT, f"settings conflict: PAUS? describes a run started by INIT; the rig "
                                              f"is {self.state}")
        if self.realtime:
            self.advance_realtime()
        return self.run.pause_state()

    def conditions(self) -> dict:
        """``COND?``: the condition channels at the latest sample of the run (run time 0 without one)."""
        if self.realtime:
            self.advance_realtime()
        if self.run is None:
            return Conditions(self.faults, self.truth.instrument.force_drift).reading(0.0)
        return self.run.condition_reading()

    def fetch(self, session, wanted: int) -> np.ndarray | list:
        """Up to `wanted` unfetched rows (producing them first in virtual time).

        Raises
        ------
        CloseConnection
            The injected disconnect fired: no rows are taken.
        """
        if self.run is None:
            return []
        if self.realtime:
            self.advance_realtime()
            if self.doomed(session):  # the disconnect fired: no rows taken
                raise CloseConnection()
        elif self.state == "RUNNING" and self._buffered < wanted:
            target = self.run.acquired + wanted - self._buffered
            self._produce_to(target)
            if self._disconnect_due(target):
                self._fire_disconnect()
                raise CloseConnection()
        rows = self._pop(wanted)
        self.fetched += rows.shape[0]
        return rows

    def _pop(self, n: int) -> np.ndarray:
        out, got = [], 0
        while self._rows and got < n:
            head = self._rows[0]
            take = min(n - got, head.shape[0])
            out.append(head[:take])
            if take == head.shape[0]:
                self._rows.popleft()
            else:
                self._rows[0] = head[take:]
            got += take
        self._buffered -= got
        return np.concatenate(out) if out else np.empty((0, len(self.run.config.columns)))

    # -------------------------------------------------- emergency stop
    def emergency_stop(self, reason: str = "aborted by ABOR") -> None:
        """Voltage off now, whatever else the rig is doing: never waits for the lock.

        The amplifier's interlock opens first (`EmulatedRig.interlock`: no sample is made with the voltage
        on after it; a computation under way stops at its next block); the bookkeeping (state ``ABORTED``,
        the reason, the actuator back to its start) follows under the lock, by a thread of its own, and
        every command that takes the lock books it first.
        """
        with self._trip_lock:
            first = self._tripped is None
            if first:
                self._tripped = reason
            run = self.run
        if run is not None:
            run.interlock()
        self._stop.set()
        if first:  # one booking thread per stop, however many ABOR arrive before it is booked
            threading.Thread(target=self._book_trip, daemon=True, name="rig-emulator-estop").start()

    def _book_trip(self) -> None:
        with self.lock:
            self.take_trip()

    def take_trip(self) -> None:
        """Book an emergency stop (under the lock): the run aborts, state ABORTED."""
        with self._trip_lock:
            reason, self._tripped = self._tripped, None
        if reason is not None:
            self._abort(reason)

    def _abort(self, reason: str) -> None:
        """Voltage to 0, actuator back to start; state ABORTED with `reason`."""
        if self.state == "RUNNING" and self.run is not None:
            self.run.abort(reason)
        if self.state in ("ARMED", "RUNNING"):
            self.state, self.reason = "ABORTED", reason
        self._stop.set()

    def _sync_state(self) -> None:
        if self.state == "RUNNING" and self.run is not None and not self.run.running:
            self.state = "DONE" if self.run.state == "done" else "ABORTED"
            self.reason = self.run.reason
            self._stop.set()  # the controlling connection keeps control for its next run

    def _start_watchdog(self) -> None:
        """A thread that aborts the run (voltage off) when its controlling connection falls silent."""
        if self._watchdog is not None and self._watchdog.is_alive():
            return

        def watch():  # without the lock: it trips the emergency stop, which waits for nothing
            while True:
                time.sleep(min(0.2, self.heartbeat / 4))
                if self.state != "RUNNING" or self._tripped is not None:
                    return
                if self._answering:  # the rig is computing its controller's reply
                    continue
                silent = self._clock() - self._last_heard
                if silent > self.heartbeat:
                    self.emergency_stop(f"no command from the controlling connection for {silent:.3g} s "
                                        f"(heartbeat {self.heartbeat:g} s)")
                    return

        self._watchdog = threading.Thread(target=watch, daemon=True, name="rig-emulator-heartbeat")
        self._watchdog.start()

    # ------------------------------------------------------- production
    def _caps(self) -> int:
        """Samples that may exist at all: before a stall or an injected disconnect."""
        cap = self.run.n
        for kind in ("stall", "disconnect"):
            if kind in self.faults:
                cap = min(cap, self.run.samples_before(self.faults[kind].at))
        return cap

    def _produce_to(self, target: int) -> None:
        """Samples up to `target` (within the faults' caps), for at most `PRODUCE_SLICE` s of computing."""
        target = min(target, self._caps())
        end = time.monotonic() + PRODUCE_SLICE
        while self.run.running and self.run.acquired < target and self._tripped is None:
            rows = self.run.produce(min(target - self.run.acquired, BLOCK))
            if rows.shape[0]:
                self._rows.append(rows)
                self._buffered += rows.shape[0]
            elif self.run.running:  # a held run: no sample due yet (the wall clock paces it)
                break
            if time.monotonic() >= end:
                break
        self.take_trip()
        self._sync_state()

    def _disconnect_due(self, wanted: int) -> bool:
        """Whether the run has reached the injected disconnect (asked for a sample at t >= T)."""
        if "disconnect" not in self.faults or self._disconnect_fired or self.state != "RUNNING":
            return False
        cap = self.run.samples_before(self.faults["disconnect"].at)
        return cap < self.run.n and wanted > cap and self.run.acquired >= cap  # every sample before it made

    def _fire_disconnect(self) -> object:
        self._disconnect_fired = True
        session = self.owner
        self._abort("client disconnected")
        return session

    def advance_realtime(self) -> None:
        if self.state != "RUNNING":
            return
        elapsed = self._clock() - self._t0
        wanted = self.run.samples_until(elapsed)
        self._produce_to(wanted)
        if self._disconnect_due(wanted):
            # the line drops between two commands of the controlling connection, never under a reply
            # already taken from the buffer (closing the socket from here raced with the handler sending
            # a FETC? reply: its rows were counted fetched and lost): an idle connection is closed now
            # (close_session leaves a busy one alone), a busy one at its next command
            self._doomed = self._fire_disconnect()
            self._close_session(self._doomed)

    def _producer(self, stop: threading.Event) -> None:
        while not stop.is_set():
            with self.lock:
                if stop.is_set():
                    break
                self.advance_realtime()
                if self.state != "RUNNING":
                    break
            stop.wait(0.02)

    def _stop_producer(self) -> None:
        """Stop and join the producer thread; never call it holding the lock."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join()


__all__ = ["FAULTS", "CloseConnection", "Fault", "RigState", "check_faults"]
