"""Prediction bands: how far to trust the twin's force, from the fit's covariance and the cross-validation.

A band at nominal level ``L`` (0.9: the 90 % band) around the predicted force F(t) [N] has two terms:

(a) **Parameter uncertainty.** The fit's covariance (the record's ``covar``: ``s^2 (J^T J)^-1`` with
    ``s^2 = redchi``, J the Jacobian of the peak-normalized, run-weighted residuals with respect to the
    parameters in SI, :func:`rdea_lab.calibration.fit.calibrate`) is carried over to the fit's change of
    variables (log for positive parameters, ``asinh(x / scale)`` for C20, C30, eta_v0: the ``u`` of
    :class:`~rdea_lab.calibration.parameters.FitParameter`) by the linear map ``du/dx``, and propagated
    through the twin by the **delta method** (the default): the Jacobian of the force in ``u`` by central
    differences (2 k twin evaluations), ``sd_F = sqrt(diag(J C_u J^T))`` per sample, half-width
    ``z_{(1+L)/2} sd_F``. An **ensemble** is there too (``method="ensemble"``: ``draws`` parameter sets from
    the multivariate normal in ``u``, antithetic pairs ``u* +- d`` so that its mean is the point prediction
    up to second order, mapped back (positive stays positive, bounds kept by clipping), each predicted, per
    sample the ``(1 - L) / 2`` and ``(1 + L) / 2`` quantiles). Why the delta method by default: the
    covariance is itself a linearization at the optimum, and where the data cannot identify a parameter
    (a branch's stiffness with a standard error of 2.6 times its value, eta_v1 and eta_v0 correlated at
    -0.998: a typical viscoelastic fit) the ensemble draws it e^{+-4} away, where that linearization says
    nothing and the force changes by far more than the data allow: on a twin-made truth with white noise
    its band was 14 noise standard deviations wide against the delta method's 0.07 (and a 90 % band with
    the misfit term covered 95-97 % of a new realization instead of 88-90 %). Both agree where the force is
    linear in ``u`` (tests/calibration/test_bands.py). The covariance assumes independent residuals; those
    of a time series are correlated (neighbouring samples share the model's error), so this term is
    optimistic, often by far (on the VHB files it covers 0.5-3 % of held-out samples): it is the misfit
    term that makes the band honest.
(b) **Model misfit**, learnt from cross-validation: the ``L`` quantile ``q_L`` of ``|held-out predicted -
    measured| / peak`` over the held-out samples of the folds (each held-out run weighted equally),
    stored in the record's ``calibration.validation.misfit`` (:func:`misfit_mapping`); its half-width is
    ``m = q_L * max |F|`` (the predicted peak: no measurement is needed to draw the band).

**Combination**: per side, in quadrature, ``lower = F - sqrt((F* - Q_lo)^2 + m^2)``, ``upper = F +
sqrt((Q_hi - F*)^2 + m^2)`` (``F*`` the ensemble's own point prediction, ``Q`` its quantiles): exact for
two independent Gaussian terms of the same level; since the held-out errors contain the fit's own scatter,
it counts that twice (conservative).

**Beyond the calibration envelope** (:func:`~rdea_lab.calibration.envelope.beyond` flags the run): the
misfit term comes from the held-out runs of the folds that were themselves beyond their fold's envelope
along every kind the run is (stretch, rate, voltage, hold, or a new stretch-rate or hold-stretch
combination: :func:`~rdea_lab.calibration.envelope.flag_axis`; the largest quantile of those), status
``widened``; where the cross-validation has no such fold (or there is no
cross-validation), the data cannot bound the error: the band is **unbounded** (``force_lower = -inf``,
``force_upper = +inf``), status ``unbounded``. Without cross-validation, inside the envelope, the band is
the parameter term alone, status ``parameter-only``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.stats import norm

from ..specs import ParameterSet, SpecError, as_params
from ..specs.record import CalibrationRecord, add_record_section
from ..specs.variables import variable_attrs
from .envelope import Envelope, beyond, envelope, flag_axis, run_envelope
from .objective import file_hash, load_run, predict_force
from .parameters import fit_parameters, keep_relaxation_times, values_of, with_values

#: Levels [-] at which the misfit's quantiles are stored; a band's level must lie within them.
LEVELS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.68, 0.7, 0.8, 0.9, 0.95, 0.975, 0.99)
#: Ensemble size (even: antithetic pairs) and the seed of its generator.
DRAWS, SEED = 64, 0
METHODS = ("ensemble", "delta")
#: ``band_status`` values.
BOUNDED, PARAMETER_ONLY, WIDENED, UNBOUNDED = "bounded", "parameter-only", "widened", "unbounded"
MISFIT_DEFINITION = ("|held-out predicted - measured force| / the held-out run's peak |measured force|, "
                     "pooled over the held-out samples of every fold, each held-out run weighted equally "
                     "(weighted quantiles, linear between samples); inside: held-out runs within their fold's "
                     "calibration envelope, beyond: those outside it")


def weighted_quantile(values, weights, q) -> np.ndarray:
    """Quantiles of ``values`` with ``weights`` (the weighted empirical distribution, linear between the
    midpoints of the sorted samples' cumulative weights).

    Parameters
    ----------
    values, weights : array_like
        Samples and their weights (>= 0, not all 0).
    q : array_like
        Levels in [0, 1].

    Returns
    -------
    numpy.ndarray
        One quantile per level (equal weights: numpy's ``"hazen"`` percentile).
    """
    v, w = np.asarray(values, float), np.asarray(weights, float)
    order = np.argsort(v)
    v, w = v[order], w[order]
    c = (np.cumsum(w) - 0.5 * w) / np.sum(w)
    return np.interp(np.asarray(q, float), c, v)


def _misfit_stats(items) -> dict | None:
    """``runs``, ``samples`` and ``quantiles`` at `LEVELS` of |error| / peak over (name, errors) items."""
    if not items:
        return None
    values = np.concatenate([np.abs(e) for _, e in items])
    weights = np.concatenate([np.full(e.size, 1.0 / e.size) for _, e in items])
    return {"runs": [name for name, _ in items], "samples": int(values.size),
            "quantiles": [float(f"{x:.6g}") for x in weighted_quantile(values, weights, LEVELS)]}


def misfit_mapping(cv, exclude=()) -> dict:
    """The record's ``validation.misfit``: quantiles of the held-out errors of a cross-validation.

    Parameters
    ----------
    cv : CrossValidation
        Of :func:`~rdea_lab.calibration.crossval.cross_validate` (its folds keep the held-out residuals).
    exclude : iterable of str
        File names of held-out runs to leave out (a band judged on a run must not learn from that run).

    Returns
    -------
    dict
        ``definition`` (`MISFIT_DEFINITION`), ``levels`` (`LEVELS`), ``inside`` and ``beyond``: each None or
        ``runs`` (names), ``samples`` and ``quantiles`` of ``|predicted - measured| / peak`` [-] at the levels;
        ``beyond_by_axes``: the same per set of extrapolation kinds of the held-out runs beyond their fold's
        envelope (``axes``, :func:`~rdea_lab.calibration.envelope.flag_axis` of their flags).
    """
    exclude = set(exclude)
    inside, outside, by_axes = [], [], {}
    for fold in cv.folds:
        for r in cv.rows(fold=fold.index, role="predicted"):
            if r["file"] in exclude or r["file"] not in fold.residuals:
                continue
            item = (r["file"], fold.residuals[r["file"]])
            (outside if r["flags"] else inside).append(item)
            if r["flags"]:
                by_axes.setdefault(tuple(sorted({flag_axis(f) for f in r["flags"]})), []).append(item)
    return {"definition": MISFIT_DEFINITION, "levels": list(LEVELS), "inside": _misfit_stats(inside),
            "beyond": _misfit_stats(outside),
            "beyond_by_axes": [{"axes": list(axes), **_misfit_stats(items)} for axes, items in sorted(by_axes.items())]}


def add_misfit(record, cv) -> None:
    """Write a cross-validation's misfit into a calibration record's ``validation.misfit`` (kept beside what
    the section holds), so that bands from the record (`Uncertainty.of_record`) have their misfit term.

    For a record of a fit to all the runs and a cross-validation of the same runs and settings
    (``cross_validate(..., cv="leave-one-out")``): the misfit of its held-out errors.

    Parameters
    ----------
    record : path
        The parameter file (written by ``rdea-lab calibrate``).
    cv : CrossValidation

    Raises
    ------
    ValueError
        The file has no calibration section.
    """
    old = CalibrationRecord.of_file(record)
    section = old.validation.mapping() if old is not None and old.validation is not None else {}
    add_record_section(record, {**section, "misfit": misfit_mapping(cv)}, "validation")


def check_level(level) -> float:
    """The band level as a float in [`LEVELS`[0], `LEVELS`[-1]]; else SpecError naming ``bands``."""
    ok = isinstance(level, (int, float)) and not isinstance(level, bool) and LEVELS[0] <= level <= LEVELS[-1]
    if not ok:
        raise SpecError("arguments", "bands", f"{level!r}; allowed: a nominal level from {LEVELS[0]} to "
                        f"{LEVELS[-1]} (0.9 for the 90 % band)")
    return float(level)


def _matrix(m, where) -> tuple[tuple, np.ndarray]:
    """Names and the covariance array [SI] of a record's ``covar`` (NaN for null)."""
    if m is None or isinstance(m, str):
        return (), np.zeros((0, 0))
    a = np.array([[np.nan if c is None else float(c) for c in row] for row in m.matrix], float)
    if a.shape != (len(m.names), len(m.names)):
        raise SpecError(where, "calibration.covar", f"a {a.shape} matrix for {len(m.names)} names; allowed: square, "
                        "one row and column per name")
    return tuple(m.names), a


@dataclass(frozen=True)
class Uncertainty:
    """What a prediction band is made of: the fit's covariance, its misfit from cross-validation, its envelope.

    Attributes
    ----------
    params : ParameterSet
        The calibrated (best) set.
    names : tuple of str
        Free parameters with a covariance (the identifiable ones).
    covar : numpy.ndarray
        Their covariance [SI^2], in `names` order.
    missing : tuple of str
        Free parameters without one (not identifiable: held at their value, their uncertainty not in the band).
    misfit : dict or None
        `misfit_mapping` (the record's ``validation.misfit``); None: no cross-validation.
    envelope : Envelope or None
        The calibration envelope (None: not known, extrapolation not checked).
    source : str
        Where it comes from, in words.
    hyperelastic : str
        The fit's hyperelastic choice (its parameters' bounds: `fit_parameters`).
    fixed_taus : bool
        A relaxation spectrum's: its moduli vary at fixed relaxation times (`keep_relaxation_times`).
    """

    params: ParameterSet
    names: tuple
    covar: np.ndarray
    missing: tuple = ()
    misfit: dict | None = None
    envelope: Envelope | None = None
    source: str = ""
    hyperelastic: str = "yeoh"
    fixed_taus: bool = False

    @classmethod
    def of_fit(cls, result, misfit: dict | None = None, calibrated: Envelope | None = None) -> "Uncertainty":
        """From a `CalibrationResult` (its covariance; envelope by default that of its fitted runs).

        Parameters
        ----------
        result : CalibrationResult
        misfit : dict, optional
            `misfit_mapping` of a cross-validation.
        calibrated : Envelope, optional
            Default: :func:`~rdea_lab.calibration.envelope.envelope` of ``result.run_data``.
        """
        names = tuple(result.free_names)
        cov = np.asarray(result.covar, float).reshape(len(names), len(names))
        env = calibrated if calibrated is not None else (envelope(result.run_data) if result.run_data else None)
        return cls._of(result.params, names, cov, misfit, env, "the fit's covariance",
                       getattr(result, "hyperelastic", "yeoh"), bool(getattr(result, "spectrum", None)))

    @classmethod
    def of_record(cls, path) -> "Uncertainty":
        """From a calibration record (a parameter file ``rdea-lab calibrate`` wrote).

        The envelope: the record's ``validation.envelope``, else that of its fitted runs where their files
        are still at the recorded path with the recorded sha256, else None.

        Parameters
        ----------
        path : path
            The parameter file.

        Raises
        ------
        SpecError
            The file has no calibration record, or no covariance (``metric max``), or a malformed one.
        """
        where = str(path)
        record = CalibrationRecord.of_file(path)
        if record is None:
            raise SpecError(where, "calibration", "no calibration record; allowed: a parameter file written by "
                            "'rdea-lab calibrate' (its covariance makes the band)")
        if record.covar is None or isinstance(record.covar, str):
            raise SpecError(where, "calibration.covar", f"{record.covar or 'missing'}; allowed: the covariance "
                            "matrix of a least-squares (metric rms) fit")
        names, cov = _matrix(record.covar, where)
        val = record.validation
        misfit = getattr(val, "misfit", None) if val is not None else None
        env = None
        if val is not None and val.envelope:
            env = Envelope.from_mapping(val.envelope)
        else:
            fitted = [r.file for r in record.runs if r.file and Path(r.file).is_file()
                      and file_hash(r.file) == r.sha256]
            if fitted and len(fitted) == len(record.runs):
                env = envelope([load_run(f) for f in fitted])
        return cls._of(as_params(path), names, cov, misfit, env, f"the calibration record {Path(path).name}",
                       record.hyperelastic or "yeoh", bool(record.spectrum))

    @classmethod
    def _of(cls, params, names, cov, misfit, env, source, hyperelastic="yeoh", fixed_taus=False):
        finite = np.isfinite(np.diag(cov)) if cov.size else np.zeros(0, bool)
        keep = [i for i, ok in enumerate(finite) if ok and np.all(np.isfinite(cov[i, finite]))]
        missing = tuple(n for i, n in enumerate(names) if i not in keep)
        return cls(params, tuple(names[i] for i in keep), cov[np.ix_(keep, keep)], missing, misfit, env, source,
                   hyperelastic, fixed_taus)

    # -------------------------------------------------------------- the parameter term
    def _internal(self):
        """The fit parameters of `names`, the best ``u``, and the covariance in ``u`` (``du/dx C du/dx``)."""
        fp = {p.name: p for p in fit_parameters(self.params, set(self.names), self.hyperelastic)}
        ps = [fp[n] for n in self.names]
        x = np.array([values_of(self.params)[n] for n in self.names])
        u = np.array([p._u(v) for p, v in zip(ps, x)])
        dudx = np.array([1.0 / v if p.kind == "log" else 1.0 / math.hypot(p.scale, v) for p, v in zip(ps, x)])
        return ps, u, self.covar * np.outer(dudx, dudx)

    def _force(self, run, model, ps, u):
        """Force [N] on ``run`` for internal values ``u`` (None where the physics refuses the set)."""
        base = values_of(self.params)
        values = dict(base)
        for p, ui in zip(ps, u):
            values[p.name] = float(np.clip(p._x(ui), p.lo, p.hi))
        if self.fixed_taus:
            values = keep_relaxation_times(values, base)
        try:
            params = with_values(self.params, values, self.params.M)
        except (SpecError, ValueError):
            return None
        return predict_force(run, params, model)

    def parameter_band(self, run, level: float, model: str = "su", *, method: str = "delta",
                       draws: int = DRAWS, seed: int = SEED) -> dict:
        """The parameter term on a run: the point force and the band's lower and upper quantiles [N].

        Parameters
        ----------
        run : RunData
            The history (``t`` [s], ``stretch`` [-], ``voltage`` [V], ``geom``).
        level : float
            Nominal level [-].
        model : str
            Quasi-static model.
        method : {"ensemble", "delta"}
        draws : int
            Ensemble size (even; antithetic pairs).
        seed : int
            Of the ensemble's generator (`numpy.random.default_rng`).

        Returns
        -------
        dict
            ``force`` (the best set's), ``lower``, ``upper`` [N] per sample, ``mean`` (the ensemble's mean, or
            the point force for delta), ``draws`` used and ``refused`` (draws the physics refused).
        """
        if method not in METHODS:
            raise SpecError("arguments", "band_method", f"{method!r}; allowed: {', '.join(METHODS)}")
        f0 = predict_force(run, self.params, model)
        if not self.names:
            return {"force": f0, "lower": f0, "upper": f0, "mean": f0, "draws": 0, "refused": 0}
        ps, u0, cu = self._internal()
        if method == "delta":
            h = 1e-4
            cols = []
            for i in range(len(ps)):
                du = np.zeros(len(ps))
                du[i] = h
                fp, fm = self._force(run, model, ps, u0 + du), self._force(run, model, ps, u0 - du)
                if fp is not None and fm is not None:
                    cols.append((fp - fm) / (2 * h))
                elif fp is not None or fm is not None:  # one side refused (a bound): one-sided
                    cols.append((fp - f0) / h if fp is not None else (f0 - fm) / h)
                else:
                    cols.append(np.full_like(f0, np.nan))
            J = np.column_stack(cols)
            sd = np.sqrt(np.clip(np.einsum("ni,ij,nj->n", J, cu, J), 0.0, None))
            half = norm.ppf(0.5 + level / 2) * sd
            return {"force": f0, "lower": f0 - half, "upper": f0 + half, "mean": f0, "draws": 0, "refused": 0}
        if draws < 2 or draws % 2:
            raise SpecError("arguments", "band_draws", f"{draws!r}; allowed: an even number >= 2 (antithetic pairs)")
        w, V = np.linalg.eigh(cu)
        rng = np.random.default_rng(seed)
        d = (rng.standard_normal((draws // 2, len(ps))) * np.sqrt(np.clip(w, 0.0, None))) @ V.T
        forces = [f for f in (self._force(run, model, ps, u0 + s * di) for di in d for s in (1, -1))
                  if f is not None]
        if not forces:
            raise SpecError("arguments", "bands", "the physics refused every parameter draw; allowed: a record "
                            "whose covariance describes physical parameter sets")
        F = np.vstack(forces)
        lo, hi = np.quantile(F, [0.5 - level / 2, 0.5 + level / 2], axis=0)
        return {"force": f0, "lower": lo, "upper": hi, "mean": F.mean(axis=0), "draws": len(forces),
                "refused": draws - len(forces)}

    # -------------------------------------------------------------- the misfit term and the rule
    def misfit_rel(self, level: float, extrapolating, axes=None) -> tuple[float | None, str, str]:
        """The misfit half-width [-] (of the predicted peak), the band status and why.

        ``axes`` (the run's kinds of extrapolation, :func:`~rdea_lab.calibration.envelope.flag_axis`): a run
        beyond the envelope learns only from the held-out runs that extrapolated along every one of them
        (the largest quantile of those groups of ``beyond_by_axes``); none: unbounded. Without ``axes`` (or
        a record written before ``beyond_by_axes``) every extrapolating held-out run counts.

        Returns
        -------
        tuple
            ``(q, status, detail)``: ``q`` None for a parameter-only band, ``inf`` for an unbounded one.
        """
        m = self.misfit
        if not extrapolating:
            stats = (m or {}).get("inside") or (m or {}).get("beyond")
            if stats is None:
                return None, PARAMETER_ONLY, ("parameter uncertainty only: the record has no cross-validation "
                                              "misfit (optimistic: residuals of a time series are correlated)")
            q = float(np.interp(level, m["levels"], stats["quantiles"]))
            which = "inside" if (m or {}).get("inside") else "beyond"
            return q, BOUNDED, (f"parameter uncertainty and the misfit of {len(stats['runs'])} held-out run(s) "
                                f"({which} their fold's envelope): {100 * q:.3g} % of the peak at level {level:g}")
        stats = (m or {}).get("beyond")
        groups = [stats] if stats is not None else []
        if axes and stats is not None and "beyond_by_axes" in m:
            groups = [g for g in m["beyond_by_axes"] if set(axes) <= set(g["axes"])]
        if not groups:
            why = ("no cross-validation" if m is None else "no cross-validation fold extrapolated" if stats is None
                   else f"no cross-validation fold extrapolated along {' and '.join(sorted(axes))}")
            return math.inf, UNBOUNDED, (f"unbounded: the run is beyond the calibration and {why}, so the data "
                                         "cannot bound its error")
        q = max(float(np.interp(level, m["levels"], g["quantiles"])) for g in groups)
        runs = sorted({r for g in groups for r in g["runs"]})
        return q, WIDENED, (f"widened: beyond the calibration; misfit of the {len(runs)} held-out run(s) "
                            f"that were themselves beyond their fold's envelope"
                            + (f" along {' and '.join(sorted(axes))}" if axes else "")
                            + f": {100 * q:.3g} % of the peak at level {level:g}")

    def flags(self, run) -> tuple[str, ...] | None:
        """`beyond` flags of ``run`` against the envelope (None when the envelope is not known)."""
        return None if self.envelope is None else beyond(self.envelope, run_envelope(run))

    def band(self, run, level: float = 0.9, model: str = "su", *, point=None, flags=None,
             method: str = "delta", draws: int = DRAWS, seed: int = SEED) -> dict:
        """The band on a run: lower and upper force [N] per sample, with its status (module docstring).

        Parameters
        ----------
        run : RunData
            The history.
        level : float
            Nominal level [-] (`check_level`).
        model : str
            Quasi-static model.
        point : array_like, optional
            The point prediction [N] to centre on (default: the best set's force on ``run``).
        flags : tuple of str, optional
            The run's extrapolation flags; default: `flags` (against `envelope`).
        method, draws, seed
            As `parameter_band`.

        Returns
        -------
        dict
            ``lower``, ``upper`` [N]; ``status`` (`BOUNDED`, `PARAMETER_ONLY`, `WIDENED`, `UNBOUNDED`),
            ``detail`` (in words), ``misfit_rel`` [-] (nan if none), ``flags``, ``method``, ``draws``,
            ``refused``, ``level``.
        """
        level = check_level(level)
        pb = self.parameter_band(run, level, model, method=method, draws=draws, seed=seed)
        f = pb["force"] if point is None else np.asarray(point, float)
        if flags is None:
            flags = self.flags(run)
        q, status, detail = self.misfit_rel(level, bool(flags), {flag_axis(f) for f in flags or ()})
        if flags is None:
            detail += "; extrapolation not checked (no calibration envelope known)"
        if self.missing:
            detail += f"; not identifiable, held at their values (not in the band): {', '.join(self.missing)}"
        m = 0.0 if q is None else q * float(np.nanmax(np.abs(f)))
        with np.errstate(invalid="ignore"):
            lower = f - np.hypot(np.clip(pb["force"] - pb["lower"], 0.0, None), m)
            upper = f + np.hypot(np.clip(pb["upper"] - pb["force"], 0.0, None), m)
        return {"lower": lower, "upper": upper, "status": status, "detail": detail,
                "misfit_rel": math.nan if q is None else q, "flags": tuple(flags or ()), "method": method,
                "draws": pb["draws"], "refused": pb["refused"], "level": level, "mean": pb["mean"],
                "force": pb["force"]}

    def add_to(self, prediction: xr.Dataset, level: float = 0.9, *, specimen=None, model: str | None = None,
               flags=None, method: str = "delta", draws: int = DRAWS, seed: int = SEED) -> xr.Dataset:
        """``prediction`` (of :func:`rdea_lab.twin.predict`) with ``force_lower`` and ``force_upper`` [N].

        Parameters
        ----------
        prediction : xarray.Dataset
            On its history's ``time`` [s], with ``stretch`` [-], ``voltage`` [V], ``force`` [N].
        level : float
            Nominal level [-].
        specimen : RollGeometry or StripGeometry
            The roll (default: the prediction's ``geometry`` is not enough: give it).
        model : str, optional
            Default: the prediction's ``model`` attribute.
        flags, method, draws, seed
            As `band`.

        Returns
        -------
        xarray.Dataset
            A copy with ``force_lower``, ``force_upper`` (CF attributes; NaN where the force is NaN,
            -inf/+inf for an unbounded band) and attributes ``band_level``, ``band_status``, ``band_detail``,
            ``band_method``, ``band_draws``, ``band_refused``, ``band_seed``, ``band_misfit_rel``,
            ``band_beyond_calibration`` and ``band_source``.
        """
        model = model or prediction.attrs.get("model", "su")
        t = np.asarray(prediction["time"].values, float)
        lam = np.asarray(prediction["stretch"].values, float)
        v = np.asarray(prediction["voltage"].values, float)
        f = np.asarray(prediction["force"].values, float)
        keep = np.isfinite(lam) & (lam >= 1.0) & np.isfinite(v) & np.isfinite(f)
        run = history_run(t[keep], lam[keep], v[keep], specimen, prediction.attrs.get("history_protocol_name", ""))
        b = self.band(run, level, model, point=f[keep], flags=flags, method=method, draws=draws, seed=seed)
        out = prediction.copy()
        for name, part in (("force_lower", b["lower"]), ("force_upper", b["upper"])):
            full = np.full(t.shape, np.nan)
            full[keep] = np.full(keep.sum(), -np.inf if name == "force_lower" else np.inf) \
                if b["status"] == UNBOUNDED else part
            attrs = variable_attrs(name)
            attrs["long_name"] = attrs["long_name"].replace("LEVEL", f"{100 * b['level']:g} %")
            out[name] = ("time", full, attrs)
        out.attrs.update(band_attrs(b, self.source, seed))
        return out


def band_attrs(b: dict, source: str, seed: int) -> dict:
    """The dataset attributes of a band (`Uncertainty.band`'s result); none is None."""
    return {"band_level": b["level"], "band_status": b["status"], "band_detail": b["detail"],
            "band_method": b["method"], "band_draws": int(b["draws"]), "band_refused": int(b["refused"]),
            "band_seed": int(seed), "band_misfit_rel": float(b["misfit_rel"]),
            "band_beyond_calibration": "; ".join(b["flags"]), "band_source": source}


def history_run(t, stretch, voltage, geom, protocol: str = ""):
    """A history as the `RunData` the objective predicts on (no measured force)."""
    from .objective import RunData

    if geom is None:
        raise SpecError("arguments", "specimen", "required for a band; allowed: the roll's card or geometry")
    t = np.asarray(t, float)
    return RunData(Path("<prediction>"), "", protocol or "prediction", "custom", getattr(geom, "id", ""), geom, t,
                   np.asarray(stretch, float), np.broadcast_to(np.asarray(voltage, float), t.shape).copy(),
                   np.full(t.shape, np.nan), math.nan)


def coverage(measured, lower, upper) -> float:
    """Fraction [-] of measured samples inside [lower, upper] (over the finite measured samples; NaN for an
    unbounded band or none)."""
    m, lo, hi = (np.asarray(a, float) for a in (measured, lower, upper))
    ok = np.isfinite(m) & ~np.isnan(lo) & ~np.isnan(hi)
    if not ok.any() or np.isinf(lo[ok]).all():
        return math.nan
    return float(np.mean((m[ok] >= lo[ok]) & (m[ok] <= hi[ok])))


__all__ = ["BOUNDED", "DRAWS", "LEVELS", "METHODS", "PARAMETER_ONLY", "SEED", "UNBOUNDED", "Uncertainty",
           "WIDENED", "add_misfit", "band_attrs", "check_level", "coverage", "history_run", "misfit_mapping",
           "weighted_quantile"]
