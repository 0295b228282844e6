"""What every quasi-static model returns, and the checks on its inputs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..specs.errors import UserError
# The per-sample status codes of `ModelResult` and their names: declared once in `rdea_lab.specs.status`, the
# data's vocabulary too (the ``model_status`` variable's flags), and used (and re-exported) here.
from ..specs.status import (BAD_INPUT, LIMIT_POINT, NOT_CONVERGED, OK, OUTSIDE_RANGE, OVERFLOW,  # noqa: F401
                            SLACK, SNAPPED, STATUS_NAMES)

#: Statuses with a valid state.
VALID = (OK, SNAPPED, SLACK)


def is_valid(status) -> np.ndarray:
    """Where ``status`` (codes of :class:`ModelResult`) holds a valid state (`VALID`): ``np.isin(status,
    VALID)``, by comparisons (a tenth of isin's time on the blocks a solve returns)."""
    status = np.asarray(status)
    out = status == VALID[0]
    for code in VALID[1:]:
        out |= status == code
    return out


#: One line per status code, for the ``model_status`` variable's ``long_name``.
STATUS_LEGEND = ", ".join(f"{code} {name.split(' (')[0]}" for code, name in sorted(STATUS_NAMES.items()))


class ModelNotApplicable(UserError):
    """The model does not describe this specimen (e.g. 3R, a model of a roll's rings, on a strip)."""


class StretchBelowOneError(UserError):
    """A stretch below 1: the roll is compressed, which Assumption 1 of [1] excludes."""


def prepare_inputs(stretch, voltage):
    """Broadcast and check stretch and voltage (once per solve).

    Parameters
    ----------
    stretch : array_like
        Axial stretch ``lambda1 = l1 / L1`` [-], >= 1.
    voltage : array_like
        Voltage [V].

    Returns
    -------
    l1, v : numpy.ndarray
        1-D float arrays; bad samples replaced by the unloaded state
        (``l1 = 1``, ``v = 0``) so that solvers never see them.
    bad : numpy.ndarray of bool
        True where an input was NaN or infinite.
    shape : tuple
        Broadcast shape of the inputs (results are reshaped to it).
    raw : tuple of numpy.ndarray
        The flattened inputs as given, for the result: the caller's own arrays (not copies) where they
        are float64 of the broadcast shape and contiguous; ``l1`` and ``v`` are those too where no
        sample is bad (nothing is copied that the solve does not change).

    Raises
    ------
    StretchBelowOneError
        If any finite stretch is below 1 (Assumption 1 of [1]: the roll is
        always in tension, ``l1 >= L1``).
    """
    return check_inputs(*broadcast_inputs(stretch, voltage))


def broadcast_inputs(stretch, voltage):
    """``(l1, v, shape)``: stretch and voltage as 1-D float arrays of their broadcast ``shape`` (the
    caller's own arrays where they are float64 of that shape and contiguous), not checked yet
    (`check_inputs`)."""
    l1, v = np.asarray(stretch, dtype=float), np.asarray(voltage, dtype=float)
    if l1.shape != v.shape:
        l1, v = (np.ascontiguousarray(a) for a in np.broadcast_arrays(l1, v))
    return l1.reshape(-1), v.reshape(-1), l1.shape


def check_inputs(l1, v, shape):
    """`prepare_inputs` of `broadcast_inputs`' arrays: the checks and the unloaded state at bad samples."""
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(l1)
        finite &= np.isfinite(v)
    bad = ~finite
    if (l1 < 1.0).any():
        low = np.flatnonzero(finite & (l1 < 1.0))
        if low.size:
            i = int(low[0])
            raise StretchBelowOneError(
                f"stretch {l1[i]:.12g} at sample {i} is below 1 ({low.size} samples in all): "
                "the roll must stay in tension (Assumption 1 of Prechtl et al. 2021)"
            )
    raw = (l1, v)
    if not finite.all():
        l1, v = l1.copy(), v.copy()
        l1[bad] = 1.0
        v[bad] = 0.0
    return l1, v, bad, shape, raw


@dataclass(frozen=True)
class ModelResult:
    """Quasi-static response of a roll to arrays of stretch and voltage.

    A result may compute some fields when they are first read (`DeferredResult`: SU by the compiled
    kernels computes the status, convergence and tension in its solve, the stress and the other fields,
    then the slack rolls' free states, when read); each reads the same either way. Arrays a result shares
    (the caller's inputs, one array for several fields, the arrays later fields are computed from) are
    read-only: copy one to change it (a compiled SU result's arrays are all read-only).

    Attributes
    ----------
    model : str
        ``"su"``, ``"1r"``, ``"3r"`` or ``"cr"``.
    stretch, voltage : numpy.ndarray
        The inputs [-], [V]: read-only views of the caller's own arrays where those are contiguous
        float64 of the result's shape (not copied: a later change to the caller's array shows here).
    sigma1 : numpy.ndarray
        Axial true stress, eq. (16) [Pa]; 0 where slack; NaN where ``converged`` is False.
    force : numpy.ndarray
        Axial force ``sigma1 pi (Ro**2 - Ri**2) / lambda1`` [N], >= 0 for a roll.
    tension : numpy.ndarray
        The axial stress the equilibrium at the given stretch needs [Pa]: ``sigma1``
        where taut, negative where slack (what a clamp would have to push with);
        the quasi-static stress a viscoelastic overstress adds to.
    lambda2a, lambda2b, lambda2c : numpy.ndarray
        Circumferential stretch of rings a, b, c [-] (all equal for SU, 1R, where they may be one array).
    capacitance : numpy.ndarray
        Capacitance, eqs. (29), (34), (41) [F].
    converged : numpy.ndarray of bool
        True where the sample has a stable equilibrium on the physical branch.
    status : numpy.ndarray of int8
        One of ``OK``, ``SNAPPED``, ``SLACK`` (all converged), ``LIMIT_POINT``,
        ``OUTSIDE_RANGE``, ``BAD_INPUT``, ``NOT_CONVERGED``, ``OVERFLOW``.
    critical_voltage : numpy.ndarray
        Voltage of the fold [V] at the sample's stretch, where ``status`` is
        ``LIMIT_POINT`` or ``SNAPPED`` (the fold crossed); NaN elsewhere: never
        the end of the solved range.
    range_voltage : numpy.ndarray
        Where ``status`` is ``OUTSIDE_RANGE``: the largest voltage the admissible
        range solves at that stretch [V]; NaN elsewhere.
    free_stretch : numpy.ndarray
        Axial stretch of the material [-]: the given stretch where taut, the
        free (F = 0) stretch where slack (NaN where that lies beyond what the
        model solves).
    r_i : numpy.ndarray
        Deformed inner radius [m] (3R only; for SU and 1R it follows
        from the uniform ring, ``Ri lambda2``).
    end : object or None
        For a path (``solve(..., path=True)``): the state after the last sample,
        to pass as ``start`` for the next block.
    """

    model: str
    stretch: np.ndarray
    voltage: np.ndarray
    sigma1: np.ndarray
    force: np.ndarray
    lambda2a: np.ndarray
    lambda2b: np.ndarray
    lambda2c: np.ndarray
    capacitance: np.ndarray
    converged: np.ndarray
    status: np.ndarray
    critical_voltage: np.ndarray
    r_i: np.ndarray
    tension: np.ndarray
    range_voltage: np.ndarray
    free_stretch: np.ndarray
    end: object = None

    @property
    def all_converged(self) -> bool:
        return bool(np.all(self.converged))

    def summary(self) -> str:
        """One line on the samples that have no valid equilibrium, or ``"all converged"``."""
        n = self.status.size
        parts = []
        for code in (LIMIT_POINT, SNAPPED, OUTSIDE_RANGE, SLACK, BAD_INPUT, NOT_CONVERGED, OVERFLOW):
            sel = self.status == code
            if not np.any(sel):
                continue
            text = f"{int(sel.sum())} of {n} samples {STATUS_NAMES[code]}"
            if code in (LIMIT_POINT, SNAPPED):
                i = int(np.flatnonzero(sel)[0])
                text += (f" (first at sample {i}: stretch {self.stretch.flat[i]:.4g}, voltage "
                         f"{self.voltage.flat[i]:.4g} V, fold at {self.critical_voltage.flat[i]:.4g} V)")
            elif code == OUTSIDE_RANGE:
                i = int(np.flatnonzero(sel)[0])
                text += (f" (first at sample {i}: stretch {self.stretch.flat[i]:.4g}, voltage "
                         f"{self.voltage.flat[i]:.4g} V; solved up to {self.range_voltage.flat[i]:.4g} V there)")
            parts.append(text)
        if not parts:
            return f"all {n} samples converged"
        return "; ".join(parts)


#: The fields of a `ModelResult`, in order.
FIELDS = tuple(ModelResult.__dataclass_fields__)


class DeferredResult(ModelResult):
    """A `ModelResult` some of whose fields are computed when first read (then kept): a solve that
    computes what every caller needs (the status, the tension) and leaves the rest (the free state of a
    slack roll, the force, the stretches) to the caller that reads them.

    Every field reads as it would on a `ModelResult` built at once; the arrays the deferred ones are
    computed from are read-only, and their memory itself not writeable (a view of them cannot be made
    writeable). Fields computed together are held together when the first of them is read; threads that
    read one first at once get the same arrays (the solve's ``derive`` locks). `pickle` and `copy` give a
    `ModelResult`, `dataclasses.replace` a result of this class, each with every field computed. ``==``
    compares a result with one of its own class only. Built by `deferred` only.
    """

    def __getattr__(self, name):  # only for what the instance does not hold yet
        derive = self.__dict__.get("_derive")
        if derive is None or name not in FIELDS:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        for key, value in derive(name).items():  # the fields computed with it too: held from now on
            object.__setattr__(self, key, value)
        return self.__dict__[name]

    def __reduce__(self):
        return ModelResult, tuple(getattr(self, name) for name in FIELDS)


def deferred(fields: dict, derive) -> DeferredResult:
    """A `DeferredResult` holding ``fields`` (names of `FIELDS`) and computing each other field ``name``
    when first read: ``derive(name)`` is a dict of it and the fields computed with it (names of `FIELDS`),
    each the same object whenever asked for."""
    out = object.__new__(DeferredResult)
    for name, value in fields.items():
        object.__setattr__(out, name, value)
    object.__setattr__(out, "_derive", derive)
    return out


@dataclass(frozen=True)
class PathEnd:
    """Where a path left off: the model, its free coordinate after the last sample and,
    if that sample had no state, its ``(status, K_crit)`` (a lost run goes on with it)."""

    model: str
    y: float | None
    label: tuple | None = None


_NAN = np.array(np.nan)
_NAN.flags.writeable = False


def nan_field(shape) -> np.ndarray:
    """A read-only NaN field of ``shape`` that allocates nothing (a broadcast view of one NaN, itself not
    writeable: the view cannot be made writeable, as the broadcast of a writeable NaN could, which would
    write every sample of every field that shares it). A fresh view of one kept per shape (`np.broadcast_to`
    costs some 10 us a call, a view well under 1 us): no two results share an array object."""
    out = _NAN_FIELDS.get(shape)
    if out is None:
        out = np.broadcast_to(_NAN, shape)
        if len(_NAN_FIELDS) >= 64:  # a bounded cache: a process that solves many shapes keeps the last ones
            _NAN_FIELDS.clear()
        _NAN_FIELDS[shape] = out
    return out.view()


_NAN_FIELDS: dict = {}


def read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (``a`` itself keeps its flags): a result's array that is shared (the
    caller's input, one array for several fields) cannot be changed through the result."""
    view = a.view()
    view.flags.writeable = False
    return view


def finish(model, geom, l1, bad, shape, raw, fields, status, critical_voltage, range_voltage, free_stretch,
           end=None) -> ModelResult:
    """Assemble a :class:`ModelResult`: force from stress, NaN where not converged.

    ``fields`` holds ``sigma1`` (0 where slack), ``tension``, ``lambda2a``,
    ``lambda2b``, ``lambda2c``, ``capacitance`` and ``r_i`` per sample. The
    arrays given are the solve's own: where every sample converged they are
    the result's as they are (no copies); ``status`` may be changed in place.
    """
    n = l1.size
    status = np.asarray(status).astype(np.int8, copy=False)
    if bad.any():
        status = np.where(bad, BAD_INPUT, status).astype(np.int8)
    sigma1 = np.asarray(fields["sigma1"], float)
    with np.errstate(invalid="ignore", over="ignore"):
        force = sigma1 * geom.area / l1
        finite = np.isfinite(force)  # so sigma1 too: a stress not finite gives a force not finite, any area or l1
        if fields["tension"] is not fields["sigma1"]:
            finite &= np.isfinite(np.asarray(fields["tension"], float))
    valid = is_valid(status)
    ok = valid & finite
    all_ok = bool(ok.all())
    if not all_ok:
        status = np.where(valid & ~finite, OVERFLOW, status).astype(np.int8)
    out = {}
    for name in ("sigma1", "tension", "lambda2a", "lambda2b", "lambda2c", "capacitance", "r_i"):
        arr = np.asarray(fields[name], float)
        if arr.shape != (n,):
            arr = np.broadcast_to(arr, (n,))
        out[name] = (arr if all_ok else np.where(ok, arr, np.nan)).reshape(shape)
    if np.may_share_memory(out["tension"], out["sigma1"]):
        out["tension"] = out["tension"].copy()  # two fields, two arrays
    if np.may_share_memory(out["lambda2a"], out["lambda2b"]):  # one array for the three rings (SU, 1R):
        for name in ("lambda2a", "lambda2b", "lambda2c"):  # read-only, so no write to one changes another
            out[name] = read_only(out[name])
    out["force"] = (force if all_ok else out["sigma1"].reshape(-1) * geom.area / l1).reshape(shape)
    # None: no sample has a fold or a range end (SU): one read-only NaN view, nothing allocated
    nan = nan_field((n,))
    crit = nan if critical_voltage is None else np.where((status == LIMIT_POINT) | (status == SNAPPED),
                                                         np.asarray(critical_voltage, float), np.nan)
    rng = nan if range_voltage is None else np.where(status == OUTSIDE_RANGE, np.asarray(range_voltage, float),
                                                     np.nan)
    free_stretch = np.asarray(free_stretch, float)
    return ModelResult(
        model=model, stretch=read_only(raw[0].reshape(shape)), voltage=read_only(raw[1].reshape(shape)),
        converged=ok.reshape(shape), status=status.reshape(shape),
        critical_voltage=crit.reshape(shape), range_voltage=rng.reshape(shape),
        free_stretch=(free_stretch if all_ok else np.where(ok, free_stretch, np.nan)).reshape(shape), end=end,
        **out,
    )
