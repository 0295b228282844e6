"""Measured runs and the force error a parameter set makes on them."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..physics import viscoelastic, yeoh
from ..physics.geometry import geometry_from_card
from ..physics.models import solve, su
from ..physics.models._common import kappa
from ..specs import specimen_from_yaml
from ..store import open_run


#: Measured stretch below this is a compressed specimen (an error); between it and 1, noise.
MIN_STRETCH = 0.999


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

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def zero_voltage(self) -> bool:
        return bool(np.all(np.abs(self.voltage) < 1.0))

    def su_basis(self):
        """``(b, x, l v^2)``: SU stress = b W'(x) - kappa l v^2 (eq. 39), W' = C10 + 2 C20 x + 3 C30 x^2."""
        if self._basis is None:
            b, x = su.basis(self.stretch)
            self._basis = (b, x, self.stretch * self.voltage**2)
        return self._basis


def file_hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def load_run(path: Path) -> RunData:
    """Read a run dataset (the rdea-lab schema) for fitting."""
    ds = open_run(path)
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
    run = RunData(Path(path), file_hash(path), ds.attrs.get("protocol_name", Path(path).stem),
                  ds.attrs.get("protocol_kind", "custom"), card.id, geometry_from_card(card), t[keep], lam[keep],
                  v[keep], f[keep], float(np.max(np.abs(f[keep]))))
    run.excluded = int(noise.sum())
    run.index = np.flatnonzero(keep)
    return run


def find_runs(paths, kinds=("tensile",)) -> list[Path]:
    """Datasets named by ``paths``; a folder gives its runs (recursively) of the protocol ``kinds``."""
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            for f in sorted(p.rglob("*.nc")):
                try:
                    import xarray as xr
                    with xr.open_dataset(f) as ds:
                        if ds.attrs.get("protocol_kind") in kinds and ds.attrs.get("status") == "complete":
                            out.append(f)
                except (OSError, ValueError):
                    continue
        else:
            out.append(p)
    return out


def predict_force(run: RunData, params, model: str) -> np.ndarray:
    """Force [N] the twin predicts on the run's measured stretch and voltage history.

    For SU, and for every model at 0 V (uniaxial kinematics), the quasi-static
    stress is linear in the Yeoh coefficients: a cached basis makes it three
    vector operations. Otherwise the model is solved.
    """
    if model == "su" or run.zero_voltage:
        b, x, lv2 = run.su_basis()
        W1, _ = yeoh.slope(x, (params.C10, params.C20, params.C30))
        sigma = b * W1 - kappa(run.geom, params) * lv2
    else:
        sigma = solve(model, run.geom, params, run.stretch, run.voltage).sigma1
    if params.branches:
        k = np.array([br.k for br in params.branches])
        tau = np.array([br.eta / br.k for br in params.branches])
        sigma = sigma + k @ viscoelastic.branch_strains(run.t, run.stretch, tau)
    if params.eta_v0:
        sigma = sigma + params.eta_v0 * viscoelastic.stretch_rate(run.t, run.stretch)
    return run.geom.carried_force(sigma * run.geom.area / run.stretch)


def goodness(run: RunData, predicted: np.ndarray) -> dict:
    """Per-run fit statistics: rms error [N], R^2, max relative error (Table 4's metric)."""
    r = predicted - run.force
    ss_tot = float(np.sum((run.force - run.force.mean()) ** 2))
    return {"file": str(run.path), "protocol": run.protocol, "specimen": run.specimen, "samples": run.n,
            "excluded_samples": run.excluded,
            "rms_error_N": float(np.sqrt(np.mean(r**2))), "r2": 1.0 - float(np.sum(r**2)) / ss_tot if ss_tot else 0.0,
            "max_rel_error": float(np.max(np.abs(r)) / run.peak)}


def residuals(runs, params, model) -> np.ndarray:
    """Normalized residuals, each run weighted to count equally: e_rt sqrt(n_mean / n_r), e = (F_model - F) / peak."""
    n_mean = np.mean([r.n for r in runs])
    return np.concatenate([(predict_force(r, params, model) - r.force) / r.peak * np.sqrt(n_mean / r.n)
                           for r in runs])
