"""Tracking error of a voltage plan from a target: a run of the plan against its target.

The rig is stretch-controlled: a run of a plan (`rdea_lab.protocols.target`)
moves the roll along the planned stretch and applies the planned voltage, and
the load cell measures the force the roll gives.

- Force target (blocking): the error is ``measured force - target force``.
- Stretch target against a bias: the roll is in equilibrium with its bias
  where its force equals the bias force at its stretch, so the error is
  ``measured force - bias force at the measured stretch``. Against a real
  bias a force error ``e`` would move the roll by about
  ``-e / (dF/dlambda1 + k_b)`` in stretch, with ``dF/dlambda1`` the twin's
  quasi-static roll stiffness at the planned state and ``k_b = -dF_bias/dlambda1``
  (``stiffness L1`` for a spring, 0 for a mass): the equivalent stretch error
  reported (a linearization; the overstress's own stiffness is left out).
"""

from __future__ import annotations

import os

import numpy as np

from ..protocols.target import TargetPlan, plan_target
from ..runs.app import as_backend, run_protocol
from ..runs.backend import Twin
from ..specs.errors import DOCUMENT, SpecError
from ..store import open_run
from ..twin.simulate import as_geometry


def tracking_error(run, target_plan: TargetPlan, specimen=None) -> dict:
    """How well a run of a plan follows its target, over the target window.

    Parameters
    ----------
    run : xarray.Dataset or path
        A run of ``target_plan.plan`` (any backend).
    target_plan : TargetPlan
    specimen : SpecimenCard, RollGeometry or path, optional
        For a bias target, the roll (its ``L1`` turns stretch into the bias's displacement); default
        the run's own card.

    Returns
    -------
    dict
        ``samples``, ``force_error_max_N``, ``force_error_rms_N``, ``force_error_mean_N`` (measured minus
        target), ``relative_max``, ``relative_rms`` (to the largest target force), ``target_force_range_N``;
        for a stretch target also ``stretch_error_max``, ``stretch_error_rms`` [-] (equivalent, see the
        module docstring), ``stroke`` (the target's stretch range) and ``stretch_error_max_of_stroke``.

    Raises
    ------
    SpecError
        The run is not a run of this plan (other samples or voltage setpoints).
    """
    ds = open_run(run) if isinstance(run, (str, os.PathLike)) else run
    source = str(ds.encoding.get("source", run if isinstance(run, (str, os.PathLike)) else "<dataset>"))
    plan, w = target_plan.plan, target_plan.window
    if ds.sizes.get("time") != plan.samples:
        raise SpecError(source, DOCUMENT, f"{ds.sizes.get('time')} samples; a run of the plan "
                        f"{plan.name} has {plan.samples} (a complete run of that plan)")
    setpoint = np.asarray(ds["voltage_setpoint"].values, float)
    scale = max(1.0, float(np.max(np.abs(plan.voltage))))
    if not np.allclose(setpoint, plan.voltage, rtol=0.0, atol=1e-6 * scale):
        raise SpecError(source, "voltage_setpoint", f"differs from the plan {plan.name} by up to "
                        f"{np.max(np.abs(setpoint - plan.voltage)):.3g} V: not a run of this plan")
    force = np.asarray(ds["force"].values, float)[w]
    if target_plan.target.quantity == "force":
        want = target_plan.force[w]
    else:
        if specimen is None:
            from ..specs import specimen_from_yaml

            specimen = specimen_from_yaml(ds.attrs["specimen"], f"{source} (attribute 'specimen')")
        L1 = as_geometry(specimen).L1
        want = target_plan.target.settings.bias.force(np.asarray(ds["stretch"].values, float)[w], L1)
    e = force - want
    peak = float(np.max(target_plan.force[w]))
    out = {"samples": int(e.size), "force_error_max_N": float(np.max(np.abs(e))),
           "force_error_rms_N": float(np.sqrt(np.mean(e**2))), "force_error_mean_N": float(np.mean(e)),
           "relative_max": float(np.max(np.abs(e)) / peak), "relative_rms": float(np.sqrt(np.mean(e**2)) / peak),
           "target_force_range_N": [float(np.min(want)), float(np.max(want))]}
    if target_plan.target.quantity == "stretch":
        de = -e / (target_plan.roll_slope[w] + target_plan.bias_slope)
        stroke = float(np.ptp(target_plan.stretch[w]))
        out.update({"stretch_error_max": float(np.max(np.abs(de))), "stretch_error_rms": float(np.sqrt(np.mean(de**2))),
                    "stroke": stroke,
                    "stretch_error_max_of_stroke": float(np.max(np.abs(de)) / stroke) if stroke > 0 else float("nan")})
    return out


def track_target(target, specimen, params, model="su", *, backend="emulator", out=None, overwrite=False, seed=0,
                 command="") -> dict:
    """Plan a target on the twin, run the plan (emulator or twin) and measure its tracking error.

    Returns
    -------
    dict
        ``plan`` (the `TargetPlan`), ``run`` (the dataset), ``tracking`` (`tracking_error`).
    """
    tp = target if isinstance(target, TargetPlan) else plan_target(target, specimen, params, model)
    executor = Twin(params, model) if backend == "twin" else as_backend(backend)
    ds = run_protocol(tp.plan, specimen, executor, out=out, overwrite=overwrite, seed=seed, command=command)
    return {"plan": tp, "run": ds, "tracking": tracking_error(ds, tp, specimen)}


__all__ = ["track_target", "tracking_error"]
