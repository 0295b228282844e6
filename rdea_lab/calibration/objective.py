"""Measured runs and the force error a parameter set makes on them."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from ..physics import viscoelastic
from ..physics.geometry import geometry_from_card
from ..physics.models import solve, su
from ..twin import MIN_STRETCH, compose, viscous
from ..specs import specimen_from_yaml
from .phases import sample_weights
from ..store import open_run
from ..store.journal import walk_runs


@dataclass
class RunData:
    """One measured run, with what every evaluation reuses precomputed.

    Attributes
    ----------
    path : Path
    sha256 : str
        Content hash of the file.
    protocol, kind, specimen : str
    geom : RollGeometry
    t, stretch, voltage, force : numpy.ndarray
        Measured histories [s], [-], [V], [N] (finite samples only).
    peak : float
        Largest |measured force| [N]: the run's error scale (Table 4).
    excluded : int
        Samples left out: stretch within noise below 1 (``MIN_STRETCH`` <= stretch < 1).
    index : numpy.ndarray
        Positions in the dataset of the samples kept (to align its other variables).
    """

    path: Path
    sha256: str
    protocol: str
    kind: str
    specimen: str
    geom: object
    t: np.ndarray
    stretch: np.ndarray
    voltage: np.ndarray
    force: np.ndarray
    peak: float
    excluded: int = 0
    index: np.ndarray = field(default=None, repr=False)
    _basis: tuple = field(default=None, repr=False)
    _visco_history: object = field(default=None, repr=False)
    _weights: np.ndarray = field(default=None, repr=False)

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def zero_voltage(self) -> bool:
        return bool(np.all(np.abs(self.voltage) < 1.0))

    def su_basis(self):
        """The SU stress basis of the run's history (:func:`rdea_lab.physics.models.su.stress_basis`), cached."""
        if self._basis is None:
            self._basis = su.stress_basis(self.stretch, self.voltage)
        return self._basis

    def weights(self) -> np.ndarray:
        """Each sample's weight in the fit (:func:`rdea_lab.calibration.phases.sample_weights`: a hold longer
        than the ramps weighs as much as they do, its samples per decade of hold time; ``1 / n`` each
        otherwise), summing to 1; cached."""
        if self._weights is None:
            self._weights = sample_weights(self.t, self.stretch)
        return self._weights

    def visco_history(self):
        """The run's time and stretch for the overstress (:class:`rdea_lab.physics.viscoelastic.History`), cached."""
        if self._visco_history is None:
            self._visco_history = viscoelastic.History.of(self.t, self.stretch)
        return self._visco_history


def file_hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def load_run(path) -> RunData:
    """Read a run dataset (the rdea-lab schema) for fitting; a Dataset in memory is taken as it is."""
    if isinstance(path, xr.Dataset):
        return run_data(path)
    return run_data(open_run(path), Path(path), file_hash(path))


def run_data(ds: xr.Dataset, path: Path | None = None, sha256: str | None = None) -> RunData:
    """A run dataset as `RunData`; ``path`` and ``sha256`` default to its source file's (or a hash of its data)."""
    if path is None:
        source = ds.encoding.get("source")
        path = Path(source) if source else Path(f"<dataset {ds.attrs.get('run_id', '?')}>")
        if sha256 is None:
            if source and Path(source).is_file():
                sha256 = file_hash(source)
            else:
                h = hashlib.sha256()
                for k in ("time", "stretch", "voltage", "force"):
                    h.update(np.ascontiguousarray(ds[k].values, "<f8").tobytes())
                sha256 = h.hexdigest()
    if "specimen" not in ds.attrs:
        raise ValueError(f"{path}: no 'specimen' attribute; not an rdea-lab run")
    card = specimen_from_yaml(ds.attrs["specimen"], f"{path} (attribute 'specimen')")
    t, lam, v, f = (np.asarray(ds[k].values, float) for k in ("time", "stretch", "voltage", "force"))
    ok = np.isfinite(t) & np.isfinite(lam) & np.isfinite(v) & np.isfinite(f)
    if np.any(lam[ok] < MIN_STRETCH):
        raise ValueError(f"{path}: stretch {np.min(lam[ok]):.6g} below {MIN_STRETCH} (the specimen must stay in "
                         "tension; more than measurement noise around the unloaded length)")
    # measured stretches a hair below 1 (encoder noise at zero load) are left out of the
    # fit, and counted; the viscoelastic history runs on across them
    noise = ok & (lam < 1.0)
    keep = ok & ~noise
    if keep.sum() < 10:
        raise ValueError(f"{path}: fewer than 10 usable samples of time, stretch, voltage and force")
    run = RunData(Path(path), sha256, ds.attrs.get("protocol_name", Path(path).stem),
                  ds.attrs.get("protocol_kind", "custom"), card.id, geometry_from_card(card), t[keep], lam[keep],
                  v[keep], f[keep], float(np.max(np.abs(f[keep]))))
    run.excluded = int(noise.sum())
    run.index = np.flatnonzero(keep)
    return run


def find_runs(paths, kinds=("tensile",), skipped=None) -> list[Path]:
    """Datasets named by ``paths``; a folder gives its complete runs (recursively) of the protocol ``kinds``.

    ``skipped``, a list, receives ``{"file", "reason"}`` for every ``*.nc`` in a folder left out
    because it cannot be read or is not a complete run (other kinds are not listed).
    """
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            for f in map(Path, walk_runs(p)[0]):  # a journal's inside (a shadow file) is not entered
                try:
                    with xr.open_dataset(f) as ds:
                        kind, status = ds.attrs.get("protocol_kind"), ds.attrs.get("status")
                except (OSError, ValueError) as exc:
                    if skipped is not None:
                        skipped.append({"file": str(f), "reason": f"unreadable ({type(exc).__name__})"})
                    continue
                if kind in kinds and status == "complete":
                    out.append(f)
                elif kind in kinds and skipped is not None:
                    skipped.append({"file": str(f), "reason": f"status {status}"})
        else:
            out.append(p)
    return out


def predict_force(run: RunData, params, model: str) -> np.ndarray:
    """Force [N] the twin predicts on the run's measured stretch and voltage history.

    For SU, and for every model at 0 V (uniaxial kinematics), the quasi-static
    stress is linear in the Yeoh coefficients: a cached basis makes it three
    vector operations. Otherwise the model is solved along the run's path. The
    rest is the twin's own composition of eqs. (43), (44) and (16), on the
    run's cached `RunData.visco_history`
    (:func:`rdea_lab.twin.compose`), which clips a roll that would push to 0 N
    (slack): a measured slack sample then says only that the model force is <= 0.
    """
    if model == "su" or run.zero_voltage:
        sigma_rev = su.stress_from_basis(run.su_basis(), run.geom, params)
    else:
        # the equilibrium's tension is all compose needs (it clips); no free states to search
        sigma_rev = solve(model, run.geom, params, run.stretch, run.voltage, path=True, slack=False).sigma1
    return compose(run.geom, viscous(params), run.t, run.stretch, sigma_rev, history=run.visco_history())[2]


#: The percentile of |error| that `error_measures` reports beside the maximum and the rms.
ERROR_PERCENTILE = 99.0
#: One line per error measure, for the legends under the tables that show them.
ERROR_LEGEND = ("max/peak: the largest |predicted - measured| over the run's largest |measured| (Table 4's metric); "
                "rms/peak: the root mean square of the error over the same peak; "
                "p99/peak: the 99th percentile of |error| (numpy's linear interpolation) over the same peak")


def error_measures(residual, peak: float) -> dict:
    """The error measures of one run, each relative to its peak measured value.

    Parameters
    ----------
    residual : array_like
        Predicted minus measured [N] (or [F]: any unit, the ratios are dimensionless).
    peak : float
        Largest |measured| of the run, in the unit of ``residual``.

    Returns
    -------
    dict
        ``max_rel_error`` = max |r| / peak (Table 4 of [1]), ``rms_rel_error`` =
        sqrt(mean r^2) / peak and ``p99_rel_error`` = the 99th percentile of |r|
        (:data:`ERROR_PERCENTILE`, ``numpy.percentile``'s linear interpolation) / peak.
        The last two are robust to a single bad sample, which the first is not.
    """
    a = np.abs(np.asarray(residual, float))
    return {"max_rel_error": float(np.max(a) / peak), "rms_rel_error": float(np.sqrt(np.mean(a * a)) / peak),
            "p99_rel_error": float(np.percentile(a, ERROR_PERCENTILE) / peak)}


def goodness(run: RunData, predicted: np.ndarray) -> dict:
    """Per-run fit statistics: rms error [N], R^2 and the relative errors of `error_measures`
    (``max_rel_error``, Table 4's metric; ``rms_rel_error``; ``p99_rel_error``)."""
    r = predicted - run.force
    ss_tot = float(np.sum((run.force - run.force.mean()) ** 2))
    return {"file": str(run.path), "protocol": run.protocol, "specimen": run.specimen, "samples": run.n,
            "excluded_samples": run.excluded,
            "rms_error_N": float(np.sqrt(np.mean(r**2))), "r2": 1.0 - float(np.sum(r**2)) / ss_tot if ss_tot else 0.0,
            **error_measures(r, run.peak)}


def residual_scale(runs) -> list[np.ndarray]:
    """Per run, what `residuals` multiplies its force error [N] by: ``sqrt(n_mean w_rt) / peak_r``.

    ``w_rt`` are the run's sample weights (`RunData.weights`, summing to 1: each run counts equally;
    within it the phases weigh by :data:`rdea_lab.calibration.phases.PHASE_RULE`), ``n_mean`` the mean
    number of samples per run, so that a run without a hold has ``sqrt(n_mean / n_r)`` as before.
    """
    n_mean = np.mean([r.n for r in runs])
    return [np.sqrt(n_mean * r.weights()) / r.peak for r in runs]


def residuals(runs, params, model, scale=None) -> np.ndarray:
    """Normalized, weighted residuals: ``e_rt sqrt(n_mean w_rt)`` with ``e = (F_model - F) / peak`` (`residual_scale`).

    Every run counts equally; within a run a hold longer than its ramps weighs as much as they do, its samples
    per decade of hold time (:mod:`rdea_lab.calibration.phases`); otherwise its samples weigh alike.
    ``scale``: `residual_scale` of ``runs``, for a caller that evaluates them many times (the objective).
    """
    scale = residual_scale(runs) if scale is None else scale
    fused = _fused_kernel() if runs else None
    if fused is None:
        return np.concatenate([(predict_force(r, params, model) - r.force) * s for r, s in zip(runs, scale)])
    out = np.empty(sum(r.n for r in runs))
    visco = viscous(params)
    linear = _fused_law(visco)
    start = 0
    for r, s in zip(runs, scale):
        end = start + r.n
        history = r.visco_history()
        if linear and _fused_run(r, s, model, history):
            fused(r.su_basis(), r.geom, params, visco, history, r.stretch, r.force, s, out[start:end])
        else:
            out[start:end] = (predict_force(r, params, model) - r.force) * s
        start = end
    return out


class FusedRuns:
    """`residuals` of many parameter sets on the same runs, by the compiled pass alone, with what does not
    depend on the parameters prepared once: each run's stress basis, history, arrays, its place in the
    residual vector and the pass's scratch (for ``M`` branches). The same pass with the same inputs as
    `residuals` takes, so the same numbers to the last bit; `of` gives None where `residuals` would not
    take the pass for every run whatever the parameters (no compiled kernels, another model at voltage,
    a run with a non-finite sample or a single one, a scale of another shape).
    """

    def __init__(self, fused, items, ndata):
        self._fused, self._items, self.ndata = fused, items, ndata

    @classmethod
    def of(cls, runs, scale, model, M):
        fused = _fused_kernel() if runs else None
        if fused is None:
            return None
        items, start = [], 0
        for r, s in zip(runs, scale):
            history = r.visco_history()
            if not _fused_run(r, s, model, history):
                return None
            items.append((r.su_basis(), r.geom, history, r.stretch, r.force, s, start, start + r.n,
                          np.empty((M, r.n))))
            start += r.n
        return cls(fused, items, start)

    def __call__(self, params, visco):
        """The residuals of ``params`` (what the pass reads of a parameter set: ``C10``, ``C20``, ``C30``,
        ``eps_r``) with ``visco`` (:func:`~rdea_lab.twin.viscous` of it, ``M`` branches), or None where the
        pass does not apply to them (the law not linear, or an ``eta / k`` not positive): `residuals` then."""
        if not _fused_law(visco):
            return None
        out = np.empty(self.ndata)
        fused = self._fused
        for basis, geom, history, stretch, force, s, start, end, work in self._items:
            fused(basis, geom, params, visco, history, stretch, force, s, out[start:end], work)
        return out


def _fused_law(visco) -> bool:
    """Whether the compiled residual pass takes a parameter set's viscoelastic branches (`twin.viscous`'s
    ``(k, eta, eta_v0, law)``): the linear law, every ``eta / k`` positive (what `branch_strains` refuses, the
    physics' check refuses first)."""
    k, eta, _, law = visco
    return law == "linear" and bool(np.all(eta / k > 0))


def _fused_run(run, scale, model, history) -> bool:
    """Whether the compiled residual pass takes ``run`` (its `History` ``history``, its `residual_scale`
    ``scale``) whatever the parameters: SU's stress basis applies (``model`` SU or the run at 0 V), every
    sample finite, two samples or more."""
    return ((model == "su" or run.zero_voltage) and history.all_finite and history.t.size > 1
            and np.shape(scale) == (run.n,))


def _fused_kernel():
    """The compiled residual pass (`rdea_lab.physics.models.su.residual_pass`: SU's stress basis, linear law,
    every sample finite), or None where the compiled kernels are off or numba is missing (the branch update's
    own choice for a `History`: the two then agree to the last bit, the fused pass running the same compiled
    update)."""
    return su.residual_pass()
