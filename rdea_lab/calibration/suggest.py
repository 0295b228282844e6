"""The next experiment: the candidate protocol that would tell the calibrated twin most.

`suggest` ranks candidate protocols the rig's limits allow (loading-unloading ramps at several rates to
several stretches, step-and-holds of several durations) by how much each, added to the fit set, would
shrink the prediction variance of a target scene, or, without one, the parameter covariance's
determinant (D-optimal design). The ranking is linearized (Fisher information), from the calibration
record's covariance; nothing is refitted.

A **scene** is a protocol (a protocol YAML: the run the lab wants to predict, e.g. a 30 min hold at
stretch 2.5) on the specimen of the card: its predicted force over its samples is what the suggestion
should make certain.

Linearization (every symbol in the fit's internal variables ``u``: ``log x`` for a positive parameter,
``asinh(x / scale)`` for a signed or non-negative one, `~rdea_lab.calibration.parameters.FitParameter`):

- current information ``F0 = C_u^-1``, with ``C_u = D C D`` the record's covariance ``C = s^2 (J^T J)^-1``
  (SI, `~rdea_lab.specs.record.CalibrationRecord` ``covar``) carried to ``u`` by ``D = diag(du/dx)``:
  that is ``F0 = J_fit^T J_fit / s^2`` of the fit's own weighted, peak-normalized residuals, ``s^2``
  their variance (``redchi``). A parameter the record leaves without a variance (not identifiable) gets
  no information, and every direction a weak prior ``F_prior = I / 10^2`` (a standard deviation of 10 in
  ``u``, a factor e^10 for a log parameter), so that the variance there is large and finite;
- a candidate ``c`` adds ``F_c = J_c^T W_c J_c / s^2``: ``J_c`` the Jacobian (central differences through
  the twin, :func:`~rdea_lab.calibration.objective.predict_force`) of its predicted force over its
  predicted peak, as the objective normalizes each run, each sample weighted as the objective weighs it,
  ``n_fit w_t`` (``n_fit`` the fitted runs' mean sample count, ``w_t`` the sample's weight in its run,
  :func:`~rdea_lab.calibration.phases.sample_weights`: ``1 / n_c`` each without a hold longer than the
  ramps): the objective counts each run equally, so a candidate counts as one more run, whatever its
  sample rate;
- the scene's variance ``V(F) = mean_t g_t^T F^-1 g_t`` over its samples ``t``, ``g_t`` the derivative of
  its predicted force [N] in ``u``; the band shrink of candidate ``c`` is ``1 - sqrt(V(F0 + F_c) / V(F0))``;
- without a scene (D-optimal): the shrink is ``1 - (det F0 / det(F0 + F_c))^(1 / 2k)``, the geometric mean
  over the ``k`` free parameters of how much the standard deviations shrink.

This is the variance of a model taken as right; a model that is wrong (a missing branch) has a bias the
linearization does not see: ``benchmarks/suggest_check.py`` checks the ranking against refitting on
every candidate, on an emulated truth beyond the model.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..paths import resolve
from ..physics.geometry import geometry_from_card
from ..protocols import expand
from ..runs.checked import checked_plan
from ..specs import SpecError, as_specimen, load_params
from ..specs.limits import Limits
from ..specs.protocol import ProtocolSpec, dump_protocol, load_protocol
from ..specs.record import CalibrationRecord, Matrix
from .objective import RunData, predict_force
from .parameters import fit_parameters, keep_relaxation_times, values_of, with_values

ARGS = "arguments"
#: Default candidate levels: peak stretches [-], ramp rates [1/s], hold durations [s].
STRETCHES = (1.5, 2.0, 2.5, 3.0)
RATES = (0.01, 0.05, 0.25)
HOLDS = (60.0, 300.0, 1200.0)
#: Rate of a step-and-hold's ramps [1/s] (as the real VHB relaxation tests: 0.25 /s).
HOLD_RATE = 0.25
#: Standard deviation of the prior in each internal variable (see the module docstring).
PRIOR_SD = 10.0
#: Relative step of the central differences in the internal variables.
STEP = 1e-4


@dataclass(frozen=True)
class Candidate:
    """One candidate protocol.

    Attributes
    ----------
    name : str
        Its protocol name (``ramp_2.5_at_0.05_per_s``, ``hold_2.5_for_300s``).
    kind : {"ramp", "hold"}
        Loading-unloading at ``rate``, or a ramp at `HOLD_RATE` to ``stretch``, a hold of ``hold``, a ramp back.
    stretch : float
        Peak stretch [-].
    rate : float
        Stretch rate of the ramps [1/s].
    hold : float
        Hold duration [s] (0 for a ramp).
    spec : ProtocolSpec
    """

    name: str
    kind: str
    stretch: float
    rate: float
    hold: float
    spec: ProtocolSpec


def _name(x: float) -> str:
    """A number as a protocol name may hold it: ``0.25``, ``1200``, ``1e9`` (no ``+``)."""
    return f"{x:g}".replace("+", "")


def candidate_spec(kind: str, stretch: float, rate: float, hold: float, limits: Limits,
                   sample_rate: float = 10.0) -> ProtocolSpec:
    """The protocol of one candidate (a tensile test at 0 V, explicit segments).

    Parameters
    ----------
    kind : {"ramp", "hold"}
    stretch : float
        Peak stretch [-], > 1.
    rate : float
        Stretch rate of the ramps [1/s], > 0.
    hold : float
        Hold at the peak [s] (``kind="hold"``).
    limits : Limits
        The rig's limits, written into the protocol.
    sample_rate : float
        [Hz].

    Returns
    -------
    ProtocolSpec

    Raises
    ------
    SpecError
        A value the protocol spec refuses.
    """
    ramp = (stretch - 1.0) / rate
    segments = [{"kind": "ramp", "duration": ramp, "to": stretch}]
    if kind == "hold":
        name = f"hold_{_name(stretch)}_for_{_name(hold)}s"
        segments.append({"kind": "hold", "duration": hold})
        what = f"ramp at {_name(rate)} /s to stretch {_name(stretch)}, hold {_name(hold)} s, ramp back"
    else:
        name = f"ramp_{_name(stretch)}_at_{_name(rate)}_per_s"
        what = f"loading-unloading at {_name(rate)} /s to stretch {_name(stretch)}"
    segments.append({"kind": "ramp", "duration": ramp, "to": 1.0})
    duration = sum(s["duration"] for s in segments)
    return ProtocolSpec(name=name, kind="tensile", description=what, source="rdea-lab suggest",
                        sample_rate=sample_rate, measure=("force",), limits=limits, stretch=tuple(segments),
                        voltage=({"kind": "hold", "duration": duration, "value": 0.0},)).with_origin("<suggest>")


def candidates(card, limits: Limits, *, stretches=STRETCHES, rates=RATES, holds=HOLDS, hold_rate=HOLD_RATE,
               sample_rate: float = 10.0) -> tuple[list[Candidate], list[str]]:
    """The candidate protocols inside the rig's limits, and why the others are not.

    Every ramp rate and every hold at every stretch; each is checked as ``rdea-lab run`` checks a plan
    before anything moves (:func:`~rdea_lab.runs.checked.checked_plan`: stretch, voltage and field for
    the card's L3).

    Parameters
    ----------
    card : SpecimenCard or path
    limits : Limits
        The rig's limits.
    stretches, rates, holds : sequence of float
        Peak stretches [-], ramp rates [1/s], hold durations [s].
    hold_rate : float
        Ramp rate of the holds [1/s].
    sample_rate : float
        Of the candidates [Hz].

    Returns
    -------
    kept : list of Candidate
    refused : list of str
        One line per candidate outside the limits (its name and the limit).

    Raises
    ------
    SpecError
        A non-positive rate or hold, a stretch <= 1.
    """
    card = as_specimen(card)
    geom = geometry_from_card(card)
    for name, values, ok in (("stretches", stretches, lambda x: x > 1.0), ("rates", rates, lambda x: x > 0.0),
                             ("holds", holds, lambda x: x > 0.0)):
        bad = [v for v in values if not (math.isfinite(v) and ok(v))]
        if bad:
            allowed = "numbers > 1" if name == "stretches" else "numbers > 0"
            raise SpecError(ARGS, name, f"{', '.join(map(_name, bad))}; allowed: {allowed}")
    wanted = [("ramp", s, r, 0.0) for s in stretches for r in rates]
    wanted += [("hold", s, hold_rate, d) for s in stretches for d in holds]
    kept, refused = [], []
    for kind, s, r, d in wanted:
        spec = candidate_spec(kind, s, r, d, limits, sample_rate)
        try:
            checked_plan(expand(spec), card, geom)
        except SpecError as err:
            refused.append(f"{spec.name}: {err.message}")
            continue
        kept.append(Candidate(spec.name, kind, s, r, d, spec))
    return kept, refused


def plan_run(spec: ProtocolSpec, card) -> RunData:
    """A `RunData` on a protocol's setpoints (force zero: only its history is used)."""
    card = as_specimen(card)
    plan = expand(spec)
    t, lam, v = (np.array(a, float) for a in (plan.time, plan.stretch, plan.voltage))
    return RunData(Path(f"<{spec.name}>"), "", spec.name, spec.kind, card.id, geometry_from_card(card), t, lam, v,
                   np.zeros_like(t), 1.0)


def sensitivity(run: RunData, params, model: str, parameters, step: float = STEP,
                fixed_taus: bool = False) -> np.ndarray:
    """Derivative of the predicted force [N] in each free parameter's internal variable (central differences).

    Parameters
    ----------
    run : RunData
    params : ParameterSet
    model : str
    parameters : sequence of FitParameter
        The free ones, in order; their ``_u``/``_x`` maps define the internal variables.
    step : float
        Step in the internal variable (one-sided where the physics refuses the other side; a column
        both sides refuse is 0).
    fixed_taus : bool
        Vary a branch modulus at its fixed relaxation time (a spectrum's:
        :func:`~rdea_lab.calibration.parameters.keep_relaxation_times`), not at its fixed viscosity.

    Returns
    -------
    numpy.ndarray, shape (n, k)
        [N per unit of internal variable].
    """
    values = values_of(params)
    f0 = predict_force(run, params, model)
    J = np.zeros((run.n, len(parameters)))
    for i, p in enumerate(parameters):
        u = p._u(values[p.name])
        sides = {}
        for sign in (1.0, -1.0):
            v = dict(values)
            v[p.name] = float(p._x(u + sign * step))
            if fixed_taus:  # a spectrum's moduli vary on its fixed grid of time scales
                v = keep_relaxation_times(v, values)
            try:
                ps = with_values(params, v, params.M)
            except SpecError:
                continue
            f = predict_force(run, ps, model)
            if np.all(np.isfinite(f)):
                sides[sign] = f
        if len(sides) == 2:
            J[:, i] = (sides[1.0] - sides[-1.0]) / (2 * step)
        elif sides:
            (sign, f), = sides.items()
            J[:, i] = (f - f0) / (sign * step)
    return J


@dataclass(frozen=True)
class Calibrated:
    """What a ranking needs of a calibration: the set, the model, the free parameters and the information.

    Attributes
    ----------
    params : ParameterSet
    model : str
    parameters : tuple of FitParameter
        The free parameters (internal-variable maps).
    information : numpy.ndarray, shape (k, k)
        ``F0`` in the internal variables, with the prior (module docstring).
    s2 : float
        Residual variance of the fit (``redchi``) [-].
    samples_per_run : float
        The fitted runs' mean sample count ``n_fit``.
    fixed_taus : bool
        A relaxation spectrum's record: its moduli vary at fixed relaxation times.
    """

    params: object
    model: str
    parameters: tuple
    information: np.ndarray
    s2: float
    samples_per_run: float
    fixed_taus: bool = False


def information_from_covariance(parameters, values: dict, covar: np.ndarray) -> np.ndarray:
    """``F0`` in the internal variables from a covariance [SI^2] of the same free parameters (with the prior).

    Rows and columns that are not finite (a parameter without a variance) give no information.
    """
    k = len(parameters)
    d = np.empty(k)
    for i, p in enumerate(parameters):
        x = values[p.name]
        d[i] = 1.0 / x if p.kind == "log" else 1.0 / math.hypot(p.scale, x)
    C = np.asarray(covar, float) * np.outer(d, d)
    ok = np.all(np.isfinite(C), axis=0) & np.all(np.isfinite(C), axis=1)
    F = np.zeros((k, k))
    if np.any(ok):
        F[np.ix_(ok, ok)] = np.linalg.pinv(C[np.ix_(ok, ok)])
    return F + np.eye(k) / PRIOR_SD**2


def from_record(path) -> Calibrated:
    """`Calibrated` of a calibration record (a parameter file written by ``rdea-lab calibrate``).

    Parameters
    ----------
    path : path
        The record.

    Returns
    -------
    Calibrated

    Raises
    ------
    SpecError
        No such file; a parameter file without a calibration section, or one without a covariance
        (``metric max``), or whose covariance names parameters the set does not have.
    """
    path = os.fspath(path)
    if not Path(path).is_file():
        raise SpecError(path, "<document>", "no such file; allowed: a calibration record (rdea-lab calibrate --out)")
    params = load_params(path)
    record = CalibrationRecord.of_file(path)
    if record is None:
        raise SpecError(path, "calibration", "no calibration record: suggest needs the fit's covariance; allowed: "
                        "a parameter file written by rdea-lab calibrate --out")
    if not isinstance(record.covar, Matrix):
        raise SpecError(path, "calibration.covar", f"{record.covar or 'missing'}: suggest needs the covariance of "
                        "a least-squares (metric rms) fit")
    free = set(record.covar.names)
    parameters = [p for p in fit_parameters(params, free, record.hyperelastic or "yeoh") if p.free]
    missing = free - {p.name for p in parameters}
    if missing:
        raise SpecError(path, "calibration.covar.names", f"{', '.join(sorted(missing))} not parameters of the set")
    order = [record.covar.names.index(p.name) for p in parameters]
    covar = np.array([[np.nan if c is None else c for c in row] for row in record.covar.matrix], float)
    covar = covar[np.ix_(order, order)]
    stats = record.statistics
    redchi = getattr(stats, "redchi", None)
    ndata = getattr(stats, "ndata", None)
    if redchi is None or not ndata or not record.runs:
        raise SpecError(path, "calibration.statistics", "no redchi, ndata or runs: not a complete calibration record")
    return Calibrated(params, record.model or "su", tuple(parameters),
                      information_from_covariance(parameters, values_of(params), covar), float(redchi),
                      float(ndata) / len(record.runs), bool(record.spectrum))


def candidate_information(cal: Calibrated, run: RunData) -> tuple[np.ndarray, float]:
    """``F_c`` of a candidate's run (module docstring) and its predicted peak force [N]."""
    f = predict_force(run, cal.params, cal.model)
    peak = float(np.max(np.abs(f)))
    if not (np.isfinite(peak) and peak > 0):
        return np.zeros_like(cal.information), peak
    J = sensitivity(run, cal.params, cal.model, cal.parameters, fixed_taus=cal.fixed_taus) / peak
    w = cal.samples_per_run * run.weights()  # the objective's sample weights (1 / n each without a long hold)
    return (J.T * w) @ J / cal.s2, peak


def scene_variance(G: np.ndarray, F: np.ndarray) -> float:
    """``mean_t g_t^T F^-1 g_t`` [N^2]: the scene's prediction variance averaged over its samples."""
    X = np.linalg.solve(F, G.T)
    return float(np.mean(np.sum(G.T * X, axis=0)))


@dataclass(frozen=True)
class Suggestion:
    """The ranking of `suggest`.

    Attributes
    ----------
    best : Candidate
    rows : tuple of dict
        One per candidate, best first: ``rank``, ``name``, ``kind``, ``stretch``, ``rate_per_s``,
        ``hold_s``, ``duration_s``, ``shrink`` (band shrink with a scene, else D-optimal; [-]) and, with a
        scene, ``band_before_N``, ``band_after_N`` (its standard deviation, sqrt V [N]).
    criterion : {"scene", "D-optimal"}
    scene : str
        The scene's protocol name ("" without one).
    scene_peak : float
        Its predicted peak force [N] (NaN without one).
    refused : tuple of str
        Candidates outside the limits, and why.
    """

    best: Candidate
    rows: tuple
    criterion: str
    scene: str
    scene_peak: float
    refused: tuple

    def table(self, top: int | None = None) -> str:
        """The ranking as text (``top`` rows, default all), with the criterion in the heading."""
        if self.criterion == "scene":
            head = (f"candidates ranked by how much they shrink the prediction band of scene {self.scene} "
                    f"(linearized; sd over its samples, peak {self.scene_peak:.4g} N):")
        else:
            head = "candidates ranked by D-optimality (shrink of the parameter standard deviations, geometric mean):"
        lines = [head, f"{'rank':>4}  {'candidate':<28} {'duration':>9}  {'shrink':>7}"
                 + ("  band sd before -> after [N]" if self.criterion == "scene" else "")]
        for r in self.rows[:top]:
            line = f"{r['rank']:>4}  {r['name']:<28} {r['duration_s']:>7.0f} s  {100 * r['shrink']:6.2f} %"
            if self.criterion == "scene":
                line += f"  {r['band_before_N']:.4g} -> {r['band_after_N']:.4g}"
            lines.append(line)
        return "\n".join(lines)


def suggest(params, card, *, scene=None, limits: Limits | None = None, stretches=STRETCHES, rates=RATES,
            holds=HOLDS, hold_rate=HOLD_RATE, sample_rate: float = 10.0, calibrated: Calibrated | None = None
            ) -> Suggestion:
    """The candidate protocol that would shrink the scene's prediction band most (or D-optimal without one).

    Parameters
    ----------
    params : path
        A calibration record (``rdea-lab calibrate --out``): the set, its model, its covariance.
    card : SpecimenCard or path
        The specimen.
    scene : ProtocolSpec or path, optional
        The protocol to predict (module docstring); checked against its own limits and the rig's.
    limits : Limits, optional
        The rig's limits; default the scene's (with a scene) or rdea-lab's defaults.
    stretches, rates, holds, hold_rate, sample_rate
        The candidates (:func:`candidates`).
    calibrated : Calibrated, optional
        Instead of reading ``params`` (a fit in memory).

    Returns
    -------
    Suggestion

    Raises
    ------
    SpecError
        A missing or non-record ``params`` (:func:`from_record`), a scene outside its limits or the
        rig's, no candidate inside the limits.
    """
    cal = calibrated if calibrated is not None else from_record(params)
    card = as_specimen(card)
    geom = geometry_from_card(card)
    G = None
    scene_name, scene_peak = "", float("nan")
    if scene is not None:
        spec = scene if isinstance(scene, ProtocolSpec) else load_scene(scene)
        rig = limits if limits is not None else spec.limits
        for lim, whose in ((spec.limits, "its own"), (rig, "the rig's")):
            try:
                checked_plan(expand(spec.model_copy(update={"limits": lim})), card, geom)
            except SpecError as err:
                raise SpecError(err.source, err.field, f"the scene is outside {whose} limits: {err.message}") from None
        limits = rig
        run = plan_run(spec, card)
        G = sensitivity(run, cal.params, cal.model, cal.parameters, fixed_taus=cal.fixed_taus)
        scene_name, scene_peak = spec.name, float(np.max(np.abs(predict_force(run, cal.params, cal.model))))
    limits = limits if limits is not None else Limits()
    kept, refused = candidates(card, limits, stretches=stretches, rates=rates, holds=holds, hold_rate=hold_rate,
                               sample_rate=sample_rate)
    if not kept:
        raise SpecError(ARGS, "candidates", f"no candidate inside the limits (max_stretch {limits.max_stretch:g}; "
                        f"stretches {', '.join(map(_name, stretches))}): " + (refused[0] if refused else "none given")
                        + "; allowed: stretch levels and rates the rig's limits allow")
    F0 = cal.information
    k = F0.shape[0]
    before = scene_variance(G, F0) if G is not None else None
    logdet0 = np.linalg.slogdet(F0)[1]
    rows = []
    for c in kept:
        Fc, _ = candidate_information(cal, plan_run(c.spec, card))
        F = F0 + Fc
        row = {"name": c.name, "kind": c.kind, "stretch": c.stretch, "rate_per_s": c.rate, "hold_s": c.hold,
               "duration_s": float(expand(c.spec).duration)}
        if G is not None:
            after = scene_variance(G, F)
            row.update(band_before_N=math.sqrt(before), band_after_N=math.sqrt(after),
                       shrink=1.0 - math.sqrt(after / before) if before > 0 else 0.0)
        else:
            row["shrink"] = 1.0 - math.exp(-(np.linalg.slogdet(F)[1] - logdet0) / (2 * k))
        rows.append((row, c))
    rows.sort(key=lambda rc: -rc[0]["shrink"])
    table = tuple({"rank": i, **r} for i, (r, _) in enumerate(rows, start=1))
    return Suggestion(rows[0][1], table, "scene" if G is not None else "D-optimal", scene_name, scene_peak,
                      tuple(refused))


def load_scene(path) -> ProtocolSpec:
    """The scene of `suggest`: the protocol YAML at ``path`` (or the packaged protocol it names).

    Raises
    ------
    SpecError
        No such file, or not a protocol.
    """
    path = resolve(path, "protocols")
    if not Path(path).is_file():
        raise SpecError(os.fspath(path), "<document>", "no such file; allowed: a protocol YAML (the scene)")
    return load_protocol(path)


def write_suggestion(suggestion: Suggestion, out, overwrite: bool = False) -> Path:
    """Write the winning candidate as a protocol YAML (`~rdea_lab.specs.protocol.load_protocol` reads it back).

    Raises
    ------
    OutputError
        ``out`` exists (and not ``overwrite``) or cannot be written.
    """
    from ..store.outputs import check_new

    out = Path(out)
    check_new(out, overwrite, "--out")
    out.parent.mkdir(parents=True, exist_ok=True)
    best = suggestion.rows[0]
    why = (f"# suggested by rdea-lab suggest: {best['name']}, {suggestion.criterion} shrink "
           f"{100 * best['shrink']:.2f} %" + (f" of the band of {suggestion.scene}" if suggestion.scene else "") + "\n")
    out.write_text(why + dump_protocol(suggestion.best.spec))
    return out


__all__ = ["Calibrated", "Candidate", "Suggestion", "candidate_spec", "candidates", "from_record",
           "information_from_covariance", "load_scene", "plan_run", "sensitivity", "suggest", "write_suggestion"]
