"""Model only what a scene needs: the cheapest model that is accurate enough.

A scene is a roll, a material and the (stretch, voltage) pairs a run will
visit. The 3R model is the reference (Section 3.4 of [1]); SU and 1R are
its approximations. :func:`select_model` returns the cheapest of SU, 1R, 3R
whose largest stress deviation from 3R over the scene's own envelope stays
within a tolerance (relative to the largest 3R stress there), and the
deviations it measured, so the choice can be recorded and checked.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .models import solve

#: Cheapest first.
ORDER = ("su", "1r", "3r")


@dataclass(frozen=True)
class ModelChoice:
    """The model picked for a scene and why.

    Attributes
    ----------
    model : str
        ``"su"``, ``"1r"`` or ``"3r"``.
    tolerance : float
        Allowed deviation from 3R, relative to ``peak_stress`` [-].
    deviation : dict
        Largest ``|sigma1 - sigma1_3R|`` relative to ``peak_stress``, per model [-].
    peak_stress : float
        Largest ``|sigma1_3R|`` over the envelope [Pa].
    samples : int
        Envelope points evaluated.
    reason : str
        One sentence for the record.
    """

    model: str
    tolerance: float
    deviation: dict = field(default_factory=dict)
    peak_stress: float = 0.0
    samples: int = 0
    reason: str = ""

    def as_dict(self) -> dict:
        return {"model": self.model, "tolerance": self.tolerance, "deviation_from_3r": self.deviation,
                "peak_stress_Pa": self.peak_stress, "samples": self.samples, "reason": self.reason}


def envelope(stretch, voltage, max_points=2000):
    """At most ``max_points`` (stretch, voltage) pairs covering a run: evenly spaced
    samples plus the samples of largest stretch and largest |voltage|."""
    lam = np.asarray(stretch, float).ravel()
    v = np.abs(np.asarray(voltage, float).ravel())
    ok = np.isfinite(lam) & np.isfinite(v)
    lam, v = lam[ok], v[ok]
    if lam.size > max_points:
        pick = np.unique(np.concatenate([np.linspace(0, lam.size - 1, max_points - 2).astype(int),
                                         [np.argmax(lam), np.argmax(v)]]))
        lam, v = lam[pick], v[pick]
    return lam, v


def select_model(geom, material, stretch, voltage, tolerance=0.01, max_points=2000) -> ModelChoice:
    """Cheapest model within ``tolerance`` of 3R over the scene's envelope.

    Parameters
    ----------
    geom : RollGeometry
    material : parameter set (``C10, C20, C30`` [Pa], ``eps_r``)
    stretch, voltage : array_like
        The run's stretch [-] and voltage [V] histories.
    tolerance : float
        Allowed deviation, relative to the peak 3R stress [-]; > 0.
    """
    if not tolerance > 0:
        raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
    lam, v = envelope(stretch, voltage, max_points)
    if getattr(geom, "kind", "roll") == "strip":
        return ModelChoice("1r", tolerance, {}, 0.0, int(lam.size),
                           "a strip: the 1R model is its exact lumped model (uniaxial, sides free of traction)")
    ref = solve("3r", geom, material, lam, v)
    peak = float(np.nanmax(np.abs(ref.sigma1))) if np.any(ref.converged) else 0.0
    if not ref.all_converged or peak == 0.0:
        reason = ("3R has samples without a stable equilibrium on this envelope (" + ref.summary()
                  + "): no approximation can be vouched for") if not ref.all_converged else "zero stress everywhere"
        return ModelChoice("3r", tolerance, {}, peak, int(lam.size), reason)
    dev = {}
    for model in ORDER[:-1]:
        res = solve(model, geom, material, lam, v)
        dev[model] = float(np.max(np.abs(res.sigma1 - ref.sigma1)) / peak) if res.all_converged else float("inf")
        if dev[model] <= tolerance:
            return ModelChoice(model, tolerance, dev, peak, int(lam.size),
                               f"{model.upper()} stays within {dev[model]:.2%} of 3R (tolerance {tolerance:.2%})")
    return ModelChoice("3r", tolerance, dev, peak, int(lam.size),
                       f"SU and 1R deviate from 3R by {dev['su']:.2%} and {dev['1r']:.2%}, above {tolerance:.2%}")
