"""Voltage plans from a target: the inverse twin turned into a voltage setpoint protocol.

`plan_target` (target, specimen, params, model) builds a protocol a rig (or
the emulator, or the twin) runs as it is:

- stretch: a ramp from 1 to the target's first stretch (``approach``, 0 V),
  a hold (``settle``) and then the target window: held at the fixed stretch
  (a force target, blocking) or the target's stretch history as a ``table``
  segment (a stretch target against a bias);
- voltage: 0 V during the approach, a ramp to the first planned voltage
  during the settle, then the planned voltage as a ``table`` segment.

The force the twin must give in the window is the target force (blocking) or
the bias force at the target stretch (the roll in equilibrium with its bias);
`rdea_lab.twin.inverse.voltage_for_force` inverts the twin along the plan's own
stretch history (viscoelastic history included). The plan is then checked
forward: the twin run on the planned voltage, whose force error is recorded
(`TargetPlan.twin_error`).

The rig is stretch-controlled, so a run of the plan measures the force the
roll gives along the target stretch history; against a real bias that force
error would move the roll: `tracking` turns it into the stretch error the
bias and the roll's own stiffness would give (linearized).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..physics.models import solve
from ..specs.errors import DOCUMENT, SpecError
from ..specs.protocol import ProtocolSpec
from ..specs.protocol_segments import (StretchHold, StretchRamp, StretchTable, VoltageHold, VoltageRamp,
                                       VoltageTable, sample_count)
from ..specs.target import Target, load_target
from ..specs.units import format_quantity
from ..twin.inverse import InverseResult, voltage_for_force
from ..twin.simulate import as_geometry, simulate
from ..specs import as_params
from .plan import Plan, expand, first_violation

#: Index of the target window's segment on both channels (approach, settle, window).
WINDOW = 2


@dataclass(frozen=True, eq=False)
class TargetPlan:
    """A voltage plan from a target, and what was checked.

    Attributes
    ----------
    target : Target
    plan : Plan
        The voltage setpoint protocol, expanded; ``plan.yaml`` is the file to run.
    model : str
    params_name : str
    window : slice
        The plan's samples of the target window.
    force : numpy.ndarray
        The force the twin must give in the window [N] (NaN outside).
    stretch : numpy.ndarray
        The plan's stretch [-] (the target's, resampled, in the window).
    bias_slope : float
        ``-dF_bias/dlambda1`` [N] (0 for none and a mass, ``stiffness L1`` for a spring).
    inverse : InverseResult
    roll_slope : numpy.ndarray
        ``dF/dlambda1`` of the quasi-static twin at the planned stretch and voltage [N] (NaN outside
        the window): with `bias_slope`, the stiffness that turns a force error into a stretch error.
    twin_force : numpy.ndarray
        The forward twin's force on the planned voltage [N].
    twin_error : float
        ``max |twin_force - force| / max force`` over the window [-].
    """

    target: Target
    plan: Plan
    model: str
    params_name: str
    window: slice
    force: np.ndarray
    stretch: np.ndarray
    bias_slope: float
    inverse: InverseResult
    roll_slope: np.ndarray
    twin_force: np.ndarray
    twin_error: float

    def summary(self) -> dict:
        w = self.window
        v = self.plan.voltage[w]
        return {"target": self.target.source, "kind": self.target.quantity, "model": self.model,
                "parameters": self.params_name, "samples": self.plan.samples, "window_samples": int(v.size),
                "window_start_s": float(self.plan.time[w.start]), "duration_s": float(self.plan.duration),
                "voltage_max_V": float(v.max()), "voltage_min_V": float(v.min()),
                "force_min_N": float(np.min(self.force[w])), "force_max_N": float(np.max(self.force[w])),
                "twin_error": self.twin_error, "bias": self.target.settings.bias.kind}

    def describe(self) -> str:
        s = self.summary()
        kv = lambda x: format_quantity(x, "kV", digits=4)  # noqa: E731
        return (f"{self.plan.name}: {s['samples']} samples ({s['window_samples']} planned from "
                f"{s['window_start_s']:g} s), voltage {kv(s['voltage_min_V'])} .. {kv(s['voltage_max_V'])}, "
                f"force {s['force_min_N']:.4g} .. {s['force_max_N']:.4g} N; twin ({self.model}) reaches it within "
                f"{self.twin_error:.1e} of the peak force")


def _resampled(target: Target, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """The target on the plan's grid ``k / rate`` over its duration (linear between its samples)."""
    m = sample_count(target.duration, rate)
    tau = np.arange(m) / rate  # the last may lie up to half a period past the target's end: it holds its end
    return tau, np.interp(tau, target.time, target.values)


def _channels(target: Target, stretch_window: np.ndarray, duration: float, voltage: np.ndarray):
    s = target.settings
    first = float(stretch_window[0])
    approach = StretchRamp(duration=s.approach, to=first) if first > 1.0 else StretchHold(duration=s.approach)
    if target.quantity == "force":
        window = StretchHold(duration=duration, value=first)
    else:
        window = StretchTable(duration=duration, values=tuple(stretch_window.tolist()))
    stretch = (approach, StretchHold(duration=s.settle, value=first), window)
    volt = (VoltageHold(duration=s.approach, value=0.0), VoltageRamp(duration=s.settle, **{"from": 0.0},
                                                                     to=float(voltage[0])),
            VoltageTable(duration=duration, values=tuple(voltage.tolist())))
    return stretch, volt


def _protocol(target: Target, stretch, voltage, description: str) -> ProtocolSpec:
    s = target.settings
    return ProtocolSpec(name=f"{s.name}-plan", kind="blocking" if target.quantity == "force" else "custom",
                        description=description, source=f"rdea-lab plan from target {target.source}",
                        sample_rate=s.sample_rate, measure=("force",), limits=s.limits,
                        stretch=stretch, voltage=voltage)


def _unreachable(target: Target, inv: InverseResult, need, stretch, t_window, window, bias_force, model):
    i = int(np.flatnonzero(~inv.reachable)[0])
    k = i - window.start
    kv = format_quantity(inv.voltage_max[i], "kV", digits=4)
    why = "the fold (pull-in)" if inv.fold[i] else "the voltage/field limit"
    reach = (f"the twin ({model}) gives {inv.force_min[i]:.6g} N at {kv} ({why}) to {inv.force_max[i]:.6g} N "
             "at 0 V")
    t = format_quantity(float(t_window[k]), "s", digits=6)
    if target.quantity == "force":
        msg = (f"at t = {t}: {need[i]:.6g} N is out of reach at stretch {stretch[i]:.6g}: {reach}")
    else:
        msg = (f"at t = {t}: stretch {stretch[i]:.6g} is out of reach against the {target.settings.bias.kind} "
               f"bias, which pulls {bias_force[i]:.6g} N there: {reach}")
    return SpecError(target.source, target.field, msg)


def plan_target(target, specimen, params, model="su") -> TargetPlan:
    """Plan the voltage that drives the twin along a target; see the module docstring.

    Parameters
    ----------
    target : Target or path
        A target (`rdea_lab.specs.target.load_target`).
    specimen : SpecimenCard, RollGeometry or path
        The roll.
    params : ParameterSet or path
        The twin's material (a calibrated set, for a real specimen).
    model : {"su", "1r", "3r", "cr"}
        The twin's quasi-static model (Sections 3.1-3.3 of [1]).

    Returns
    -------
    TargetPlan
        The planned protocol (``plan``, expanded: its ``voltage`` [V] in the target's ``window``), the
        force the twin must give there (``force`` [N]), the forward twin's on the planned voltage
        (``twin_force`` [N]) and their largest difference relative to the peak force (``twin_error`` [-]).

    Raises
    ------
    SpecError
        A bad target; a target sample out of the twin's reach between 0 V and
        the fold or the voltage and field limits (naming its time and the
        reachable range); a bias that would push; a plan beyond its limits.

    Notes
    -----
    The voltage is the inverse of the twin's force, eqs. (43), (44) and (16) of [1], solved sample by
    sample (`rdea_lab.twin.inverse`).

    References
    ----------
    [1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello, "Modeling and experimental
        validation of thin, tightly rolled dielectric elastomer actuators", Smart Mater. Struct. 31 (2022)
        015008 (2021 online), doi:10.1088/1361-665X/ac34be.
    """
    target = target if isinstance(target, Target) else load_target(target)
    geom = as_geometry(specimen)
    params = as_params(params)
    s = target.settings
    rate = s.sample_rate
    t_window, values = _resampled(target, rate)
    stretch_window = np.full(t_window.shape, s.stretch) if target.quantity == "force" else values
    duration = (t_window.size - 1) / rate
    shape = _protocol(target, *_channels(target, stretch_window, duration, np.zeros(t_window.size)), "draft")
    draft = expand(shape, source=target.source)
    window = slice(int(np.searchsorted(draft.voltage_segment, WINDOW)), draft.samples)
    if window.stop - window.start != t_window.size:  # the grid of the window is the target's grid
        raise RuntimeError(f"plan window of {window.stop - window.start} samples for {t_window.size} target samples")
    stretch = np.asarray(draft.stretch, float)
    bias_force = s.bias.force(stretch, geom.L1)
    need = np.full(stretch.shape, np.nan)
    need[window] = values if target.quantity == "force" else bias_force[window]
    if target.quantity == "stretch":
        bad = np.flatnonzero(~(bias_force[window] > 0.0))
        if bad.size:
            t = format_quantity(float(t_window[bad[0]]), "s", digits=6)
            raise SpecError(target.source, "bias", f"at t = {t} (stretch {stretch_window[bad[0]]:.6g}) the "
                            f"{s.bias.kind} would pull {bias_force[window][bad[0]]:.4g} N; a roll only takes "
                            "tension: the bias must pull (> 0 N) over the whole target")
    limit = np.minimum(s.limits.max_voltage, s.limits.max_field * geom.L3 / np.sqrt(stretch))
    inv = voltage_for_force(geom, params, draft.time, stretch, need, model, max_voltage=limit)
    if not inv.reachable.all():
        raise _unreachable(target, inv, need, stretch, t_window, window, bias_force, model)
    description = (f"voltage planned by rdea-lab from target {s.name} ({target.quantity}"
                   f"{', bias ' + s.bias.kind if s.bias.kind != 'none' else ''}) with the twin {model}, "
                   f"parameters {getattr(params, 'name', 'unnamed')}")
    spec = _protocol(target, *_channels(target, stretch_window, duration, inv.voltage[window]), description)
    plan = expand(spec, source=target.source)
    first_violation(plan, L3=geom.L3)
    twin = simulate(geom, params, plan.time, plan.stretch, plan.voltage, model)
    twin_force = np.asarray(twin["force"].values, float)
    err = float(np.max(np.abs(twin_force[window] - need[window])) / np.max(need[window]))
    slope = np.full(stretch.shape, np.nan)
    slope[window] = roll_slope(geom, params, plan.stretch[window], plan.voltage[window], model)
    return TargetPlan(target, plan, model, str(getattr(params, "name", "")), window, need,
                      np.asarray(plan.stretch, float), float(s.bias.slope(geom.L1)), inv, slope, twin_force, err)


def write_protocol(target_plan: TargetPlan, path, overwrite: bool = False) -> str:
    """Write the planned protocol (YAML, as `rdea-lab run` reads it) to `path`; returns the path.

    Raises
    ------
    SpecError
        `path` exists (and not `overwrite`), or cannot be written.
    """
    path = os.fspath(path)
    if os.path.exists(path) and not overwrite:
        raise SpecError(path, DOCUMENT, "exists; give another --out or --force to replace it")
    s = target_plan.summary()
    header = (f"# Voltage setpoint protocol planned by rdea-lab from {s['target']} (twin {s['model']}, parameters "
              f"{s['parameters']});\n# the twin reaches the target within {s['twin_error']:.1e} of its peak "
              "force. Run it with: rdea-lab run THIS_FILE --specimen CARD --backend emulator\n")
    try:
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(header + target_plan.plan.yaml)
    except OSError as exc:
        raise SpecError(path, DOCUMENT, f"cannot write: {exc.strerror}") from None
    return path


def roll_slope(specimen, params, stretch, voltage, model="su", h=1e-6):
    """``dF/dlambda1`` [N] of the quasi-static twin at (stretch, voltage): central difference (step `h`)."""
    geom = as_geometry(specimen)
    params = as_params(params)
    up = solve(model, geom, params, stretch + h, voltage).force
    down = solve(model, geom, params, np.maximum(stretch - h, 1.0), voltage).force
    return (up - down) / (stretch + h - np.maximum(stretch - h, 1.0))


__all__ = ["TargetPlan", "WINDOW", "plan_target", "roll_slope", "write_protocol"]
