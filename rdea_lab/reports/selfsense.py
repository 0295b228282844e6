"""Self-sensing report of one run: the stretch from the amplifier current beside the encoder's.

``selfsense_run(run, params)`` takes a run that recorded the amplifier
``current`` with a probe on the voltage (`rdea_lab.specs.protocol.Probe`),
estimates the capacitance online (`rdea_lab.twin.selfsense.capacitance_rls`),
turns it into a stretch with the inverse of the model's capacitance
``C(lambda1, v)`` (`rdea_lab.twin.selfsense.stretch_from_capacitance`) and
writes both beside the encoder's stretch, with the error in stretch and in
per cent of the run's stretch range.

What is fitted on what (``tare``):

- ``"rest"`` (default): one factor on the model's ``C0``, the median ratio of
  the estimated capacitance to the model's at the encoder's stretch over the
  run's first rest (from the estimator settling until the stretch setpoint
  leaves its start or the voltage setpoint exceeds twice the probe
  amplitude): the zeroing of a self-sensing rig at its known rest length. It
  takes up the radii's tolerance and the fringe field at rest.
- ``"reference"``: a gain on the model's ``C0`` and an offset, least squares
  of the estimated capacitance of another run of the same specimen
  (`reference`, at 0 V: ``protocols/selfsense_0V.yaml``, sensed with the same
  estimator) against the model's at that run's encoder stretch: the
  capacitance sweep of the paper done by self-sensing. It takes up the radii's
  tolerance and, to first order in the stretch, the fringe field.
- ``"none"``: the model's ``C0`` from the nominal geometry, nothing fitted.

Samples are scored where the estimate is valid (settled, excited, invertible)
and the roll is taut (the load cell reads more than `TAUT_FORCE`): a slack roll
is longer than its clamps' distance and its capacitance says how long it is,
not where the clamps are.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from .._version import __version__
from ..physics.geometry import geometry_from_card
from ..specs import SpecError, as_params, protocol_from_yaml, specimen_from_yaml
from ..specs.errors import DOCUMENT
from ..specs.truth import MODELS
from ..store import open_run
from ..store.journal import utc_now, write_dataset
from ..store.outputs import check_dataset_name, check_new
from ..specs.variables import SELFSENSE_VARIABLES, variable_attrs
from ..twin.selfsense import BLEND_VOLTAGE, capacitance_rls, capacitance_secant, stretch_from_capacitance

#: The roll counts as taut where the load cell reads more than this [N] (its offset and noise are mN).
TAUT_FORCE = 0.05
#: Forgetting time constant of the estimator, in probe periods.
TAU_PERIODS = 1.0
#: A reference run is fitted where |v| is below this [V]: the probe's amplitude and some (0 V runs).
LCR_LIKE_VOLTAGE = 250.0
TARES = ("rest", "reference", "none")
#: ``secant``: the charge's ``q / v`` (what the models' C is), ``small-signal``: the probe's ``dq/dv``.
ESTIMATORS = ("secant", "small-signal")


@dataclass(frozen=True)
class SelfSenseResult:
    """A self-sensing evaluation of one run.

    Attributes
    ----------
    dataset : xarray.Dataset
        The run's time, encoder stretch, voltage, current and force, and the
        `rdea_lab.specs.variables.SELFSENSE_VARIABLES`.
    max_error_percent, rms_error_percent : float
        Of the scored samples, |stretch error| as % of the run's stretch range.
    scored : int
        Samples scored (valid and taut).
    gain : float
        Factor on the model's C0 (1 without a tare).
    offset : float
        Capacitance added to the model's [F] (0 but with the ``reference`` tare).
    """

    dataset: xr.Dataset
    max_error_percent: float
    rms_error_percent: float
    scored: int
    gain: float
    offset: float = 0.0

    def summary(self) -> str:
        """One line: the errors, what was scored and fitted."""
        ds = self.dataset
        return (f"{ds.attrs['run']}: self-sensed stretch within {self.max_error_percent:.2f} % (max) and "
                f"{self.rms_error_percent:.2f} % (rms) of the stretch range {ds.attrs['stretch_range']:.4g}, "
                f"{self.scored} of {ds.sizes['time']} samples scored (estimate valid, roll taut); "
                f"model {ds.attrs['selfsense_model']}; {ds.attrs['selfsense_tare']}")


def _read(run, source: str) -> xr.Dataset:
    if isinstance(run, xr.Dataset):
        return run
    path = Path(run)
    if not path.is_file():
        raise SpecError(source, DOCUMENT, "no such file; give a run dataset (.nc) that recorded the current")
    try:
        return open_run(path)
    except SpecError:  # an attribute or variable not of rdea-lab's types
        raise
    except (OSError, ValueError) as exc:
        raise SpecError(source, DOCUMENT, f"not a readable netCDF run dataset ({type(exc).__name__})") from None


def _source(run) -> str:
    return str(run) if not isinstance(run, xr.Dataset) else f"<dataset {run.attrs.get('run_id', '?')}>"


def _sense(run, source: str, estimator: str, tau: float | None):
    """Read a run, check it can be sensed, and estimate its capacitance: (dataset, card, probe, estimate)."""
    ds = _read(run, source)
    for key in ("specimen", "protocol"):
        if key not in ds.attrs:
            raise SpecError(source, key, f"no '{key}' attribute: not an rdea-lab run dataset")
    if "current" not in ds.data_vars:
        raise SpecError(source, "current", "the run has no current variable; record it with a protocol that "
                                           "measures current and sets a probe (e.g. protocols/selfsense_2.6kV.yaml)")
    card = specimen_from_yaml(ds.attrs["specimen"], f"{source} (attribute 'specimen')")
    if getattr(card, "kind", "roll") != "roll":
        raise SpecError(source, "specimen", f"{card.id} is a {card.kind}; self-sensing inverts a roll's capacitance")
    protocol = protocol_from_yaml(ds.attrs["protocol"], f"{source} (attribute 'protocol')")
    probe = protocol.probe
    if probe is None:
        raise SpecError(source, "protocol.probe", "the run's protocol has no probe; the estimator needs a small "
                                                  "sine on the voltage (probe: {amplitude: 20 V, frequency: 200 Hz})")
    if tau is None:
        tau = TAU_PERIODS / probe.frequency
    t, v, i = (np.asarray(ds[k].values, float) for k in ("time", "voltage", "current"))
    if t.size < 2 or not np.all(np.isfinite(i)):
        raise SpecError(source, "current", "needs at least 2 samples, every one finite")
    est = capacitance_rls(t, v, i, tau)
    if estimator == "secant":
        charge = capacitance_secant(t, v, i, est)
        est = type(est)(charge.capacitance, est.conductance, est.excitation, charge.valid, est.tau)
    return ds, card, probe, est


def _fit_reference(reference, card, geom, params, model, estimator, tau):
    """Gain and offset of the model's capacitance from a 0 V reference run: (gain, offset, text)."""
    source = _source(reference)
    ref, ref_card, _, est = _sense(reference, source, estimator, tau)
    if ref_card.id != card.id:
        raise SpecError(source, "specimen", f"the reference run is of {ref_card.id}, the run of {card.id}: "
                                            "calibrate on the same specimen")
    lam, v = np.asarray(ref["stretch"].values, float), np.asarray(ref["voltage"].values, float)
    use = est.valid & (np.abs(v) < LCR_LIKE_VOLTAGE)
    if use.sum() < 100 or np.ptp(lam[use]) < 0.01:
        raise SpecError(source, "stretch", f"{int(use.sum())} valid samples below {LCR_LIKE_VOLTAGE:g} V over a "
                                           f"stretch range of {np.ptp(lam[use]) if use.any() else 0.0:.3g}: the "
                                           "reference needs 100 over at least 0.01 (a 0 V stretch sweep)")
    model_C = stretch_to_capacitance(lam[use], v[use], geom, params, model)
    A = np.column_stack([model_C, np.ones(model_C.size)])
    (gain, offset), *_ = np.linalg.lstsq(A, est.capacitance[use], rcond=None)
    text = (f"C = {gain:.6g} C_model + {offset * 1e12:.4g} pF: least squares over {int(use.sum())} samples of "
            f"{Path(source).name} (|v| < {LCR_LIKE_VOLTAGE:g} V, encoder stretch {lam[use].min():.4g} to "
            f"{lam[use].max():.4g})")
    return float(gain), float(offset), text


def selfsense_run(run, params, model: str = "su", *, tare: str = "rest", estimator: str = "secant", out=None,
                  overwrite: bool = False, tau: float | None = None, reference=None) -> SelfSenseResult:
    """The self-sensed stretch of a run beside its encoder's, with the error.

    Parameters
    ----------
    run : path or xarray.Dataset
        A run with a ``current`` variable and a probe in its protocol.
    params : ParameterSet or path
        The calibrated parameters (``eps_r`` gives ``C0``; the other models'
        ``C(lambda1, v)`` use the whole material).
    model : {"su", "1r", "3r", "cr"}
        The capacitance model inverted.
    tare : {"rest", "reference", "none"}
        What is fitted (see the module docstring); ``reference`` is implied by `reference`.
    estimator : {"secant", "small-signal"}
        ``secant`` (default): `capacitance_secant`, the charge over the voltage
        (blended with the small-signal estimate below `BLEND_VOLTAGE`);
        ``small-signal``: `capacitance_rls` alone, ``dq/dv`` at the probe,
        biased by ``v dC/dv`` where the capacitance depends on the voltage.
    out : path, optional
        Where to write the dataset (netCDF).
    overwrite : bool
        Replace an existing `out`.
    tau : float, optional
        Forgetting time constant [s]; default `TAU_PERIODS` probe periods.
    reference : path or xarray.Dataset, optional
        A run of the same specimen at 0 V with current and probe, for the ``reference`` tare.

    Raises
    ------
    SpecError
        Naming the run's file and the field: no ``current``, no probe, no
        specimen or protocol attribute, no usable samples; a bad `model`,
        `tare` or `tau`; `out` exists.
    """
    source = _source(run)
    if model not in MODELS:
        raise SpecError("arguments", "model", f"{model!r} is not one of {', '.join(MODELS)}")
    if reference is not None and tare == "rest":
        tare = "reference"
    if tare not in TARES:
        raise SpecError("arguments", "tare", f"{tare!r} is not one of {', '.join(TARES)}")
    if (tare == "reference") != (reference is not None):
        raise SpecError("arguments", "reference", "the reference tare needs a reference run (--reference RUN.nc), "
                                                  "and a reference run is for the reference tare")
    if estimator not in ESTIMATORS:
        raise SpecError("arguments", "estimator", f"{estimator!r} is not one of {', '.join(ESTIMATORS)}")
    if tau is not None and not (tau > 0.0 and np.isfinite(tau)):
        raise SpecError("arguments", "tau", f"{tau!r} is not a finite time > 0 s")
    if out is not None:
        check_dataset_name(out)
        check_new(out, overwrite)
    params = as_params(params)
    ds, card, probe, est = _sense(run, source, estimator, tau)
    protocol_name = str(ds.attrs.get("protocol_name", "unknown"))
    t, lam, v, force = (np.asarray(ds[k].values, float) for k in ("time", "stretch", "voltage", "force"))
    tau = est.tau
    geom = geometry_from_card(card)
    gain, offset, tare_text = 1.0, 0.0, "nothing fitted: C0 from the nominal geometry"
    if tare == "rest":
        vs, ss = np.asarray(ds["voltage_setpoint"].values, float), np.asarray(ds["stretch_setpoint"].values, float)
        moved = (np.abs(ss - ss[0]) > 1e-9) | (np.abs(vs) > 2.0 * probe.amplitude)
        end = int(np.argmax(moved)) if moved.any() else t.size
        rest = est.valid[:end]
        if rest.sum() < 10:
            raise SpecError(source, "stretch_setpoint", f"the run's first rest holds {int(rest.sum())} settled "
                                                        "samples; the tare needs 10 (or use tare none)")
        model_C = stretch_to_capacitance(lam[:end][rest], v[:end][rest], geom, params, model)
        gain = float(np.median(est.capacitance[:end][rest] / model_C))
        tare_text = (f"C0 x {gain:.6g}: the median ratio of estimated to model capacitance over the first rest "
                     f"(t < {t[end - 1]:.4g} s, {int(rest.sum())} samples, encoder stretch {np.median(lam[:end]):.6g})")
    elif tare == "reference":
        gain, offset, tare_text = _fit_reference(reference, card, geom, params, model, estimator, tau)
    lam_est = stretch_from_capacitance((est.capacitance - offset) / gain, v, geom, params, model)
    error = lam_est - lam
    span = float(np.nanmax(lam) - np.nanmin(lam))
    if not span > 0.0:
        raise SpecError(source, "stretch", "the encoder's stretch does not move: no range to score against")
    used = est.valid & np.isfinite(lam_est) & (force > TAUT_FORCE)
    pct = 100.0 * error / span
    scored = int(used.sum())
    max_pct = float(np.max(np.abs(pct[used]))) if scored else float("nan")
    rms_pct = float(np.sqrt(np.mean(pct[used] ** 2))) if scored else float("nan")
    out_vars = {"capacitance_estimate": est.capacitance, "stretch_estimate": lam_est, "stretch_error": error,
                "stretch_error_percent": pct, "estimate_valid": used.astype(np.int8)}
    data = {k: ("time", np.asarray(ds[k].values), variable_attrs(k))
            for k in ("stretch", "voltage", "current", "force")}
    data.update({k: ("time", np.asarray(val, SELFSENSE_VARIABLES[k][2]), variable_attrs(k))
                 for k, val in out_vars.items()})
    result_ds = xr.Dataset(data, coords={"time": ("time", t, dict(ds["time"].attrs))})
    result_ds.attrs = {
        "Conventions": "CF-1.8", "title": f"self-sensing of {ds.attrs.get('run_id', source)}",
        "rdea_lab_version": __version__, "created": utc_now(), "status": str(ds.attrs.get("status", "unknown")),
        "backend": str(ds.attrs.get("backend", "unknown")), "protocol_name": protocol_name,
        "sample_rate": float(ds.attrs.get("sample_rate", 1.0 / float(np.median(np.diff(t))))),
        "run": Path(source).name, "run_id": uuid.uuid4().hex,  # a dataset of its own (the catalogue's key)
        "source_run_id": str(ds.attrs.get("run_id", "")), "specimen_id": card.id,
        "source": f"rdea-lab selfsense of {Path(source).name} ({ds.attrs.get('source', 'unknown source')})",
        "institution": str(ds.attrs.get("institution", "not stated")),
        "references": str(ds.attrs.get("references", "")),
        "history": f"{utc_now()} rdea-lab selfsense of {Path(source).name} (model {model}, tare {tare}, "
                   f"estimator {estimator})",
        "selfsense_model": model, "selfsense_parameters": params.name, "selfsense_tare": tare_text,
        "selfsense_gain": gain, "selfsense_offset": offset, "selfsense_tau": float(tau), "selfsense_estimator": (
            f"secant q / v from the integrated current less the fitted leakage, blended below {BLEND_VOLTAGE:g} V "
            "with the small-signal estimate (rdea_lab.twin.selfsense.capacitance_secant)" if estimator == "secant"
            else "small-signal dq/dv: recursive least squares with exponential forgetting on i = C dv/dt + "
                 "v (dC/dt + 1/R_leak) (rdea_lab.twin.selfsense.capacitance_rls)"),
        "probe_amplitude": float(probe.amplitude), "probe_frequency": float(probe.frequency),
        "stretch_range": span, "taut_force": TAUT_FORCE, "scored_samples": scored,
        "max_error_percent": max_pct, "rms_error_percent": rms_pct,
    }
    if out is not None:
        write_dataset(result_ds, Path(out))
    return SelfSenseResult(result_ds, max_pct, rms_pct, scored, gain, offset)


def plot_selfsense(ds, path=None, *, ax=None, fig=None):
    """The self-sensed stretch beside the encoder's, and the error, against time.

    Parameters
    ----------
    ds : xarray.Dataset
        A `selfsense_run` dataset (``SelfSenseResult.dataset``, or the file it wrote, opened).
    path : str or path-like, optional
        Save the figure there (PNG at 200 dpi); a figure made here is then closed.
    ax : matplotlib.axes.Axes, optional
        Draw only the two stretches [-] against time [s] on this axis.
    fig : matplotlib.figure.Figure, optional
        Draw both panels into this (empty) figure. Not with ``ax``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from .plots import _finish, _new_figure, minmax_index

    if ax is not None and fig is not None:
        raise ValueError("give ax or fig, not both")
    t = np.asarray(ds["time"].values, float)
    lam, est = np.asarray(ds["stretch"].values, float), np.asarray(ds["stretch_estimate"].values, float)
    pct = np.asarray(ds["stretch_error_percent"].values, float)
    used = np.asarray(ds["estimate_valid"].values) == 1
    keep = minmax_index(t.size, [lam, np.nan_to_num(est), np.nan_to_num(pct)])
    created = ax is None and fig is None
    if ax is None:
        fig = fig if fig is not None else _new_figure((8.0, 5.0))
        top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    else:
        fig, top, bottom = ax.figure, ax, None
    top.plot(t[keep], lam[keep], color="tab:blue", lw=1.0, label="encoder")
    top.plot(t[keep], np.where(used, est, np.nan)[keep], color="black", ls="--", lw=0.8, label="self-sensed")
    top.set_ylabel("stretch λ1 [-]")
    top.grid(alpha=0.3)
    top.legend(fontsize=8, loc="upper left")
    top.set_title(f"{ds.attrs.get('run', '')}: max {ds.attrs.get('max_error_percent', float('nan')):.2f} %, "
                  f"rms {ds.attrs.get('rms_error_percent', float('nan')):.2f} % of the stretch range", fontsize=9)
    if bottom is not None:
        bottom.plot(t[keep], np.where(used, pct, np.nan)[keep], color="tab:red", lw=0.6, label="scored")
        bottom.plot(t[keep], np.where(used, np.nan, pct)[keep], color="0.7", lw=0.6,
                    label="not scored (slack, unsettled)")
        bottom.axhline(0.0, color="black", lw=0.5)
        bottom.set_xlabel("time [s]")
        bottom.set_ylabel("error [% of range]")
        bottom.grid(alpha=0.3)
        bottom.legend(fontsize=7, loc="upper right")
    else:
        top.set_xlabel("time [s]")
    return _finish(fig, path, created)


def stretch_to_capacitance(stretch, voltage, geom, params, model: str) -> np.ndarray:
    """The model's clamped-state capacitance ``C(lambda1, v)`` [F] (the forward map the inverse undoes)."""
    from ..physics.models import solve

    if model == "su":
        return geom.C0(params.eps_r) * np.asarray(stretch, float)
    return solve(model, geom, params, np.asarray(stretch, float), np.asarray(voltage, float), slack=False).capacitance


__all__ = ["ESTIMATORS", "SelfSenseResult", "TAUT_FORCE", "TARES", "plot_selfsense", "selfsense_run",
           "stretch_to_capacitance"]
