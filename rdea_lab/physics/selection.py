"""Model only what a scene needs: the cheapest model that is accurate enough.

A scene is a roll, a material and the (stretch, voltage) pairs a run will
visit. The models form a ladder by cost, SU < 1R < 3R < CR; the continuum
roll model CR (:mod:`~rdea_lab.physics.models.continuum`, the exact
axisymmetric limit of 3R's ring lumping) is the reference, and SU, 1R and 3R
are its approximations. :func:`select_model` returns the cheapest of SU, 1R,
3R whose largest stress deviation from CR over the scene's own envelope stays
within a tolerance (relative to the largest CR stress there), CR itself if
none does, and the deviations it measured, so the choice can be recorded and
checked. The stresses compared are the equations' (``slack=False``, the
``tension``): where a roll would go slack every model's force is 0, and the
comparison would say nothing about the physics.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..specs import MODELS
from .models import solve

#: Cheapest first; the last is the reference the others are measured against.
ORDER = MODELS
REFERENCE = ORDER[-1]


@dataclass(frozen=True)
class ModelChoice:
    """The model picked for a scene and why.

    Attributes
    ----------
    model : str
        ``"su"``, ``"1r"``, ``"3r"`` or ``"cr"``.
    tolerance : float
        Allowed deviation from the reference, relative to ``peak_stress`` [-].
    deviation : dict
        Largest ``|sigma1 - sigma1_ref|`` relative to ``peak_stress``, per model
        measured [-] (the equations' stresses, ``slack=False``).
    peak_stress : float
        Largest ``|sigma1_ref|`` over the envelope [Pa].
    samples : int
        Envelope points evaluated.
    reason : str
        One sentence for the record.
    reference : str
        The model the deviations are measured against (``"cr"``; empty where
        none was needed, e.g. a strip).
    """

    model: str
    tolerance: float
    deviation: dict = field(default_factory=dict)
    peak_stress: float = 0.0
    samples: int = 0
    reason: str = ""
    reference: str = REFERENCE

    def as_dict(self) -> dict:
        return {"model": self.model, "tolerance": self.tolerance, "reference": self.reference,
                "deviation_from_reference": self.deviation, "peak_stress_Pa": self.peak_stress,
                "samples": self.samples, "reason": self.reason}


def envelope_indices(n: int, largest_stretch: int, largest_voltage: int, max_points=2000) -> np.ndarray:
    """The samples `envelope` keeps of ``n`` (finite) ones: ``max_points - 2`` evenly spaced and the two
    given (the first sample of largest stretch, of largest |voltage|), increasing, without repeats; all
    of them when ``n <= max_points``."""
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.concatenate([np.linspace(0, n - 1, max_points - 2).astype(int),
                                     [largest_stretch, largest_voltage]]))


def envelope(stretch, voltage, max_points=2000):
    """At most ``max_points`` (stretch, voltage) pairs covering a run: evenly spaced
    samples plus the samples of largest stretch and largest |voltage| (`envelope_indices`)."""
    lam = np.asarray(stretch, float).ravel()
    v = np.abs(np.asarray(voltage, float).ravel())
    ok = np.isfinite(lam) & np.isfinite(v)
    lam, v = lam[ok], v[ok]
    if lam.size > max_points:
        pick = envelope_indices(lam.size, int(np.argmax(lam)), int(np.argmax(v)), max_points)
        lam, v = lam[pick], v[pick]
    return lam, v


def select_model(geom, material, stretch, voltage, tolerance=0.01, max_points=2000) -> ModelChoice:
    """Cheapest model within ``tolerance`` of CR over the scene's envelope.

    Parameters
    ----------
    geom : RollGeometry
    material : parameter set (``C10, C20, C30`` [Pa], ``eps_r``)
    stretch, voltage : array_like
        The run's stretch [-] and voltage [V] histories.
    tolerance : float
        Allowed deviation, relative to the peak CR stress [-]; > 0.
    """
    if not tolerance > 0:
        raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
    lam, v = envelope(stretch, voltage, max_points)
    if getattr(geom, "kind", "roll") == "strip":
        return ModelChoice("1r", tolerance, {}, 0.0, int(lam.size),
                           "a strip: the 1R model is its exact lumped model (uniaxial, sides free of traction)",
                           reference="")
    ref_name = REFERENCE.upper()
    ref = solve(REFERENCE, geom, material, lam, v, slack=False)
    peak = float(np.nanmax(np.abs(ref.sigma1))) if np.any(ref.converged) else 0.0
    if not ref.all_converged or peak == 0.0:
        reason = (f"{ref_name} has samples without a stable equilibrium on this envelope (" + ref.summary()
                  + "): no approximation can be vouched for") if not ref.all_converged else "zero stress everywhere"
        return ModelChoice(REFERENCE, tolerance, {}, peak, int(lam.size), reason)
    dev = {}
    for model in ORDER[:-1]:
        res = solve(model, geom, material, lam, v, slack=False)
        dev[model] = float(np.max(np.abs(res.sigma1 - ref.sigma1)) / peak) if res.all_converged else float("inf")
        if dev[model] <= tolerance:
            return ModelChoice(model, tolerance, dev, peak, int(lam.size),
                               f"{model.upper()} stays within {dev[model]:.2%} of {ref_name} "
                               f"(tolerance {tolerance:.2%})")
    listed = ", ".join(f"{m.upper()} {d:.2%}" for m, d in dev.items())
    return ModelChoice(REFERENCE, tolerance, dev, peak, int(lam.size),
                       f"every approximation deviates from {ref_name} by more than {tolerance:.2%} ({listed})")
