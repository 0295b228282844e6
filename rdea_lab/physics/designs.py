"""The quasi-static models over many rolls at once: arrays of geometry and material broadcast against samples.

A design study evaluates thousands of rolls on one history. For the SU and 1R
models of [1] a roll's geometry enters the equilibrium only through the
electrical load factor ``kappa = eps0 eps_r alpha_e1 eta_b / (2 L3**2)``
(`rdea_lab.physics.models._common.kappa`): the stationary conditions (33) and
(39) contain ``kappa v**2`` and nothing else of the roll. So roll ``d`` at
voltage ``v`` is the reference roll at the *effective voltage*
``v sqrt(kappa_d / kappa_ref)``, with the force scaled by the cross-sections
``A_d / A_ref`` (eq. (16)) and the capacitance by ``C0_d / C0_ref`` (eqs. (34),
(41)). :func:`solve_designs` flattens designs x samples into one call of the
models' own `~rdea_lab.physics.models.solve` (its compiled kernels, its
branch certification, its slack free states), so no equation is written a
second time.

The 3R and CR models see the ring fractions and radii themselves and are not
mapped: each design is solved with its own radii. Where numba is installed the
states of every design and sample come from one compiled loop
(`rdea_lab.physics.design_kernels.rolls`: the twin's certified per-sample
state and free state, each design with its own ring constants); a sample it
does not take as an ordinary state (a fold, a snap, the end of the model's
range, NaN input), and every CR roll with a hollow core, is solved by the
model's own `solve` for that design alone, which gives its status and
voltage (on a path, that sample and every one after it, continued from the
state before it, as `solve` itself does). So the
result is a loop over `solve` per design, to the kernels' 1e-12, but for one
case: the reference grades its 1R/3R scan to the largest span of the call's
samples, the compiled state to each sample's own, so a fold lying between
the nodes of one and not the other may be seen by one only. SU calls
large enough for the compiled kernels (`solve`'s ``auto`` rule on designs x
samples: a study's protocol) take the same loop, its closed form with each
design's own ``kappa`` and its free states compiled with it.

Material arrays: ``eps_r`` enters only ``kappa`` and ``C0`` (so any model);
per-design Yeoh coefficients enter the SU closed form sample by sample
(:class:`SampleMaterial`, the numpy form of `su.evaluate`); the 1R branch
solver takes one material, so a 1R study varies geometry and ``eps_r`` only; 3R and CR, solved per
design, take any material per design.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._backend import AUTO_MIN_SAMPLES, compiled
from .geometry import RollGeometry
from .models import solve
from .models._common import kappa
from .result import LIMIT_POINT, OUTSIDE_RANGE, SNAPPED, PathEnd, prepare_inputs

#: The models :func:`solve_designs` solves over designs.
DESIGN_MODELS = ("su", "1r", "3r", "cr")
#: The models it maps onto one reference roll (geometry only through kappa).
MAPPED = ("su", "1r")
_GEOMETRY = ("Ri", "Rie", "Roe", "Ro", "L1", "L1e", "L3")
_MATERIAL = ("C10", "C20", "C30", "eps_r")


@dataclass(frozen=True)
class SampleMaterial:
    """A material whose Yeoh coefficients vary per sample (SU only): the models' machinery takes the
    entries of the samples it works on (`take`)."""

    C10: np.ndarray
    C20: np.ndarray
    C30: np.ndarray
    eps_r: float

    def take(self, idx) -> "SampleMaterial":
        return SampleMaterial(self.C10[idx], self.C20[idx], self.C30[idx], self.eps_r)


@dataclass(frozen=True)
class Material:
    """Yeoh coefficients [Pa] and ``eps_r`` [-], each a float or an array over designs."""

    C10: object
    C20: object
    C30: object
    eps_r: object

    @classmethod
    def of(cls, material, **overrides) -> "Material":
        """A parameter set's material with some fields replaced (arrays over designs)."""
        return cls(**{k: np.asarray(overrides.get(k, getattr(material, k)), float) for k in _MATERIAL})


@dataclass(frozen=True)
class DesignResult:
    """Quasi-static response of ``n`` rolls to a history: every array has shape ``(n, samples)``.

    ``force`` [N], ``sigma1`` and ``tension`` [Pa], ``capacitance`` [F], ``lambda2b`` [-],
    ``free_stretch`` [-], ``status`` (int8, the codes of `rdea_lab.physics.result`),
    ``critical_voltage`` and ``range_voltage`` [V]: as `~rdea_lab.physics.result.ModelResult`'s.
    """

    model: str
    force: np.ndarray
    sigma1: np.ndarray
    tension: np.ndarray
    capacitance: np.ndarray
    lambda2b: np.ndarray
    free_stretch: np.ndarray
    status: np.ndarray
    critical_voltage: np.ndarray
    range_voltage: np.ndarray


def design_geometry(**fields) -> RollGeometry:
    """A `RollGeometry` whose fields are 1-D arrays over designs (checked as one roll each)."""
    arrays = np.broadcast_arrays(*(np.atleast_1d(np.asarray(fields[k], float)) for k in _GEOMETRY))
    if arrays[0].ndim != 1:
        raise ValueError(f"design geometry: expected 1-D arrays over designs, got shape {arrays[0].shape}")
    return RollGeometry(**dict(zip(_GEOMETRY, arrays)))


def _entry(geom: RollGeometry, i: int) -> RollGeometry:
    return RollGeometry(**{k: float(np.broadcast_to(getattr(geom, k), np.shape(geom.Ro))[i]) for k in _GEOMETRY})


def solve_designs(model: str, geom: RollGeometry, material, stretch, voltage, *, slack=True, path=False,
                  kernel="auto") -> DesignResult:
    """Solve the quasi-static model for every roll of ``geom`` on the same (or its own) history.

    Parameters
    ----------
    model : {"su", "1r", "3r", "cr"}
    geom : RollGeometry
        Fields 1-D arrays over ``n`` designs (:func:`design_geometry`), or scalars (one roll).
    material : parameter set or Material
        ``C10, C20, C30`` [Pa] and ``eps_r`` [-]: floats, or arrays of length ``n`` (Yeoh
        coefficients per design with SU, 3R and CR, not 1R).
    stretch, voltage : array_like
        Shape ``(samples,)`` (one history for every roll) or ``(n, samples)``.
    slack, kernel
        As `~rdea_lab.physics.models.solve`; with 3R and CR, ``auto`` takes the compiled states
        whenever numba is installed (a study solves the same designs many times).
    path : bool
        Each row a time series continuing from the previous sample's state (`solve`'s ``path=True``):
        one call per design (a path cannot run across designs); SU, which has no path, stays one call.

    Returns
    -------
    DesignResult
        Equal to solving each roll on its own (3R and CR to the kernels' 1e-12; SU and 1R up to the
        rounding of the load, see the module docstring): the call sees roll ``d``'s load ``K = kappa_d
        l1**2 v**2`` as ``kappa_ref l1**2 (v gain)**2``, a few ulps apart, and a state ``y`` moves by
        ``dK / h'(y)`` (``h = psi_y / c_y``, the load at which ``y`` is an equilibrium). Away from folds
        that is rounding (4e-16 relative seen); at a fold ``h'`` vanishes as ``sqrt(K_fold - K)``, so
        within 1e-12 of a fold's load a 1R state differs by up to about 1e-9 relative (7.9e-10 seen).
        Bound (tested): ``|d lambda2| <= 16 eps K / |h'(lambda2)| + 4 eps lambda2``; statuses agree from
        1e-14 of a fold's load on (nearer, within the load's rounding, a sample may fall on either side).
    """
    model = model.lower()
    if model not in DESIGN_MODELS:
        raise ValueError(f"solve_designs: unknown model {model!r}; allowed: {', '.join(DESIGN_MODELS)}")
    n = int(np.size(geom.Ro))
    if np.ndim(geom.Ro) == 0:
        geom = design_geometry(**{k: getattr(geom, k) for k in _GEOMETRY})
    stretch = np.asarray(stretch, float)
    voltage = np.asarray(voltage, float)
    try:
        shape = np.broadcast_shapes((n, 1), stretch.shape if stretch.ndim else (1,),
                                    voltage.shape if voltage.ndim else (1,))
    except ValueError:
        shape = None
    if shape is None or len(shape) != 2 or shape[0] != n:
        raise ValueError(f"solve_designs: stretch {stretch.shape} and voltage {voltage.shape} do not broadcast "
                         f"against {n} designs as (samples,) or ({n}, samples)")
    mat = Material.of(material)
    if model not in MAPPED or (model == "su" and compiled(kernel, n * shape[1]) is not None):
        return _solve_rolls(model, geom, mat, stretch, voltage, shape, slack=slack, path=path, kernel=kernel)
    ref = _entry(geom, 0)
    eps_ref = float(np.ravel(mat.eps_r)[0])
    ref_mat = Material(*(np.ravel(getattr(mat, k))[0] for k in ("C10", "C20", "C30")), eps_ref)
    kap = np.broadcast_to(kappa(geom, mat), (n,))
    kap_ref = float(kappa(ref, ref_mat))
    gain = np.sqrt(kap / kap_ref)[:, None]              # effective voltage per design
    per_design = [np.ndim(getattr(mat, k)) > 0 and np.ptp(getattr(mat, k)) > 0 for k in ("C10", "C20", "C30")]
    l1 = np.broadcast_to(stretch, shape).ravel()
    v_eff = (np.broadcast_to(voltage, shape) * gain).ravel()
    if any(per_design):
        if model != "su":
            raise ValueError("solve_designs: the 1R branch solver takes one material; vary C10, C20, C30 with the "
                             "SU model (eps_r may vary with either)")
        cols = [np.repeat(np.broadcast_to(getattr(mat, k), (n,)), shape[1]) for k in ("C10", "C20", "C30")]
        sample_mat = SampleMaterial(*cols, eps_ref)
    else:
        sample_mat = Material(*(float(np.ravel(getattr(mat, k))[0]) for k in ("C10", "C20", "C30")), eps_ref)
    if path and model != "su":
        rows = [solve(model, ref, sample_mat, l1r, vr, slack=slack, kernel=kernel, path=True)
                for l1r, vr in zip(l1.reshape(shape), v_eff.reshape(shape))]
        res = type(rows[0])(**{f: (np.concatenate([getattr(r, f) for r in rows])
                                   if isinstance(getattr(rows[0], f), np.ndarray) else getattr(rows[0], f))
                               for f in rows[0].__dataclass_fields__})
    else:
        res = solve(model, ref, sample_mat, l1, v_eff, slack=slack, kernel=kernel)

    def grid(a):
        return np.asarray(a, float).reshape(shape)

    area = (geom.area / ref.area)[:, None]
    c0 = (np.broadcast_to(geom.C0(mat.eps_r), (n,)) / ref.C0(eps_ref))[:, None]
    status = res.status.reshape(shape)
    crit = np.where(np.isin(status, (LIMIT_POINT, SNAPPED)), grid(res.critical_voltage) / gain, np.nan)
    rng = np.where(status == OUTSIDE_RANGE, grid(res.range_voltage) / gain, np.nan)
    return DesignResult(model, grid(res.force) * area, grid(res.sigma1), grid(res.tension),
                        grid(res.capacitance) * c0, grid(res.lambda2b), grid(res.free_stretch), status, crit, rng)


_FIELDS = ("force", "sigma1", "tension", "capacitance", "lambda2b", "free_stretch", "critical_voltage",
           "range_voltage")


def _solve_rolls(model, geom, mat, stretch, voltage, shape, *, slack, path, kernel) -> DesignResult:
    """Each design with its own radii and material (module docstring): 3R, CR, and SU on calls large enough
    for the compiled kernels (one pass over designs x samples, the free states of slack samples with it)."""
    n, m = shape
    l1 = np.broadcast_to(stretch, shape)
    v = np.broadcast_to(voltage, shape)
    with np.errstate(invalid="ignore"):
        if np.any(l1 < 1.0):
            prepare_inputs(l1, v)  # the error `solve` raises for a stretch below 1
    cols = [np.broadcast_to(np.asarray(getattr(geom, k), float), (n,)) for k in _GEOMETRY]
    cols += [np.broadcast_to(np.asarray(getattr(mat, k), float), (n,)) for k in _MATERIAL]
    rows = list(zip(*(c.tolist() for c in cols)))
    # "auto": the compiled states whatever the call's size (a study solves its designs many times)
    fast = compiled(kernel, max(n * m, AUTO_MIN_SAMPLES))
    # the compiled states: every SU and 3R design, and the solid CR rolls (r_i = 0 pinned: the SU state exactly)
    mine = cols[0] == 0.0 if model == "cr" else np.ones(n, bool)
    y = None
    if fast is not None and mine.all():  # the compiled loop's arrays are the result's (no copies)
        from .design_kernels import rolls

        out = rolls(model, rows, l1, v, path=path, slack=slack)
        todo = ~out.pop("ok")
        y = out.pop("y")
        out["force"] = out["sigma1"] * np.broadcast_to(geom.area, (n,))[:, None] / l1
        if todo.any():
            for k in _FIELDS[:6]:
                out[k][todo] = np.nan
        out["critical_voltage"] = np.full(shape, np.nan)
        out["range_voltage"] = np.full(shape, np.nan)
        status = out.pop("status")
    else:
        out = {k: np.full(shape, np.nan) for k in _FIELDS}
        status = np.zeros(shape, np.int8)
        todo = np.ones(shape, bool)
        if fast is not None and mine.any():
            from .design_kernels import rolls

            idx = np.flatnonzero(mine)
            got = rolls(model, [rows[i] for i in idx], l1[idx], v[idx], path=path, slack=slack)
            ok = got["ok"]
            got["force"] = got["sigma1"] * np.broadcast_to(geom.area, (n,))[idx, None] / l1[idx]
            for k in _FIELDS[:6]:
                out[k][idx] = np.where(ok, got[k], np.nan)
            status[idx] = got["status"]
            todo[idx] = ~ok
            y = np.full(shape, np.nan)
            y[idx] = got["y"]
    kd = "numba" if fast is not None else kernel
    for d in np.flatnonzero(todo.any(axis=1)).tolist():
        g = RollGeometry(**dict(zip(_GEOMETRY, rows[d][:7])))
        md = Material(*rows[d][7:])
        if not path:
            parts = [(np.flatnonzero(todo[d]), None)]
        else:
            edges = np.flatnonzero(np.diff(np.r_[0, todo[d].astype(np.int8), 0])).reshape(-1, 2)
            if fast is None:
                parts = [(np.arange(m), None)]
            else:
                parts = [(np.arange(a, b), PathEnd(model, float(y[d, a - 1])) if a else None)
                         for a, b in edges.tolist()]
        for sel, start in parts:
            r = solve(model, g, md, l1[d, sel], v[d, sel], path=path, start=start, slack=slack, kernel=kd)
            for k in _FIELDS:
                out[k][d, sel] = getattr(r, k)
            status[d, sel] = r.status
    return DesignResult(model, out["force"], out["sigma1"], out["tension"], out["capacitance"], out["lambda2b"],
                        out["free_stretch"], status, out["critical_voltage"], out["range_voltage"])
