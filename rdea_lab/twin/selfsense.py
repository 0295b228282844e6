"""Self-sensing: the capacitance from the amplifier's voltage and current, and the stretch from it.

A roll's charge is ``q = C v``; the current into its electrodes is ``i =
d(C v)/dt + v / R_leak = C dv/dt + v (dC/dt + 1 / R_leak)``. Sampled by an
integrating current monitor (sample ``k`` the mean current over ``(t_{k-1},
t_k]``, as the emulator's `rdea_lab.emulator.instruments.CurrentMonitor`),
the balance is exact in discrete time::

    i_k = C_k (v_k - v_{k-1}) / dt + v_{k-1} ((C_k - C_{k-1}) / dt + 1 / R)      (*)

(up to the leakage's ``(v_k - v_{k-1}) / (2 R)``, a bias of ``dt / (2 R)`` on
``C``: 2.5e-15 F at 2 kHz and 100 Gohm). `capacitance_rls` fits it by
recursive least squares with exponential forgetting (time constant `tau`): the
solution at each sample of the exponentially weighted normal equations, whose
running sums are recursive filters (`scipy.signal.lfilter`), so the recursion
is vectorized. By default it fits ``C`` with its drift over the window (``C_k
+ dC/dt (t_j - t_k)``, and ``1/R``: no lag behind a changing capacitance). It
needs excitation: a voltage that moves (the actuation, or a small probe sine on
top, `rdea_lab.specs.protocol.Probe`); where ``dv/dt`` does not tell ``C`` from
the other terms (a constant voltage without probe) the estimate is flagged.

What the probe measures is the small-signal capacitance ``dq/dv = C + v
dC/dv``; the models' ``C(lambda1, v)`` is the secant one, ``q / v``.
`capacitance_secant` gets that from the charge (the integrated current less a
leakage fitted where the voltage is low). `SelfSenseStream` runs both block by
block with their states carried, for a control loop.

`rdea_lab.twin.capacitance_inverse.stretch_from_capacitance` (re-exported here) turns the
estimate into a stretch.

[1] J. Prechtl et al., Smart Mater. Struct. (2021), doi:10.1088/1361-665X/ac34be.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from .capacitance_inverse import stretch_from_capacitance

#: Settling of the estimator, in time constants: the weight of the (zero) start is exp(-5) < 1 %.
SETTLE_TAUS = 5.0
#: Least share of the ``dv/dt`` regressor's energy the others do not explain (``1 - rho**2`` for two regressors)
#: for a usable estimate.
MIN_EXCITATION = 1e-3


@dataclass(frozen=True)
class CapacitanceEstimate:
    """What `capacitance_rls` returns (arrays on the input's samples).

    Attributes
    ----------
    capacitance : numpy.ndarray
        ``C`` [F]; NaN where not `valid`.
    conductance : numpy.ndarray
        ``1 / R_leak`` with ``drift``; without, ``dC/dt + 1 / R_leak`` [F/s = S].
    excitation : numpy.ndarray
        The share of the ``dv/dt`` regressor's weighted energy the other regressors do not
        explain [-] (``1 - rho**2`` for two; 1: orthogonal, 0: ``C`` not identifiable).
    valid : numpy.ndarray of bool
        Settled (`SETTLE_TAUS` time constants after the start) and excited (`MIN_EXCITATION`).
    tau : float
        Forgetting time constant [s].
    """

    capacitance: np.ndarray
    conductance: np.ndarray
    excitation: np.ndarray
    valid: np.ndarray
    tau: float


class _Filters:
    """The estimators' running sums as recursive filters, their states carried from one block to the next.

    ``f(key, x, power)`` is ``sum_m m**power lam**m x_{k-m}`` (power 0, 1 or 2) over every sample
    given so far under `key`; in blocks it gives what one call on the whole record gives.
    """

    def __init__(self, lam: float):
        self.lam = float(lam)
        self.z: dict = {}

    def f(self, key: str, x: np.ndarray, power: int = 0) -> np.ndarray:
        lam = self.lam
        b, a = {0: ([1.0], [1.0, -lam]),
                1: ([0.0, lam], [1.0, -2.0 * lam, lam * lam]),
                2: ([0.0, lam, lam * lam], [1.0, -3.0 * lam, 3.0 * lam * lam, -lam**3])}[power]
        zi = self.z.get(key)
        if zi is None:
            zi = np.zeros(len(a) - 1)
        y, self.z[key] = lfilter(b, a, x, zi=zi)
        return y


def capacitance_rls(time, voltage, current, tau: float, *, drift: bool = True, scale=None) -> CapacitanceEstimate:
    """Online capacitance from voltage and current: RLS with forgetting on the charge balance (*).

    Parameters
    ----------
    time : array_like
        Sample times [s], uniformly spaced.
    voltage : array_like
        Voltage across the electrodes [V] (the amplifier's output, as measured).
    current : array_like
        Current into the electrodes [A], sample ``k`` the mean over ``(t_{k-1}, t_k]``.
    tau : float
        Forgetting time constant [s] (forgetting factor ``exp(-dt / tau)``); a probe period or two.
    drift : bool
        Fit ``C`` as ``C_k + dC/dt (t_j - t_k)`` over the window (three coefficients: ``C_k``,
        ``dC/dt``, ``1/R``), so the estimate does not lag a changing capacitance; False: ``C``
        constant over the window (two coefficients, ``C`` and ``dC/dt + 1/R``; lags by about `tau`).
    scale : (float, float), optional
        Scales of the two regressors, ``dv/dt`` [V/s] and ``v`` [V], for conditioning only (the
        estimate does not depend on them but for rounding); default their rms over the record.

    Returns
    -------
    CapacitanceEstimate
        Causal: sample ``k`` uses samples ``0 .. k`` only. The voltage before
        the first sample is taken as the first sample's (no step).

    Notes
    -----
    The exponentially weighted least-squares solution is what RLS with
    forgetting factor ``lam`` computes (with a vanishing initial
    information matrix); its normal equations' sums, weighted by ``lam**m``,
    ``m lam**m`` and ``m**2 lam**m`` for the sample ``m`` steps back, are
    written as recursive filters, and the small system is solved per sample.
    """
    t, v, i, dt = _checked(time, voltage, current)
    if not (tau > 0.0 and np.isfinite(tau)):
        raise ValueError(f"tau must be a finite time > 0 s, got {tau!r}")
    if scale is None:
        a = np.diff(v, prepend=v[0]) / dt
        scale = (np.sqrt(np.mean(a * a)), np.sqrt(np.mean(v * v)))
    state = _RlsState(_Filters(np.exp(-dt / tau)), float(t[0]), None, dt, float(tau), _scales(scale), drift)
    return _rls_block(state, t, v, i)


def _checked(time, voltage, current):
    t = np.asarray(time, float)
    v = np.asarray(voltage, float)
    i = np.asarray(current, float)
    if not (t.shape == v.shape == i.shape and t.ndim == 1 and t.size >= 2):
        raise ValueError(f"time, voltage and current must be 1-D of the same length >= 2, got {t.shape}, "
                         f"{v.shape}, {i.shape}")
    dt = float(np.median(np.diff(t)))
    if not (dt > 0.0 and np.allclose(np.diff(t), dt, rtol=1e-6, atol=0.0)):
        raise ValueError("time must be uniformly spaced and increasing")
    return t, v, i, dt


def _scales(scale) -> tuple:
    return tuple(max(float(x), 1e-300) if np.isfinite(x) else 1.0 for x in scale)


@dataclass
class _RlsState:
    filters: _Filters
    t0: float
    v_last: float | None
    dt: float
    tau: float
    scale: tuple
    drift: bool


def _rls_block(st: _RlsState, t, v, i) -> CapacitanceEstimate:
    """`capacitance_rls` on the next block of samples, the state carried on."""
    dt, tau = st.dt, st.tau
    F = st.filters
    v_prev = np.concatenate(([v[0] if st.v_last is None else st.v_last], v[:-1]))
    st.v_last = float(v[-1])
    a = (v - v_prev) / dt  # regressor of C [V/s]
    b = v_prev  # regressor of dC/dt + 1/R [V]
    # scaled, so the sums' products stay well within double range and the solve well conditioned
    sa, sb = st.scale
    a, b = a / sa, b / sb
    Saa, Sab, Sbb, Say, Sby = (F.f(k, x) for k, x in (("aa", a * a), ("ab", a * b), ("bb", b * b), ("ay", a * i),
                                                       ("by", b * i)))
    if not st.drift:
        det = Saa * Sbb - Sab * Sab
        with np.errstate(invalid="ignore", divide="ignore"):
            excitation = det / (Saa * Sbb)
            C = (Sbb * Say - Sab * Sby) / det / sa
            G = (Saa * Sby - Sab * Say) / det / sb
    else:
        # x1 = a, x2 = b - c m a (the drift of C times a, plus dC/dt's own b), x3 = b; c = dt sa / sb
        c = dt * sa / sb
        A1aa, A1ab, A1ay = F.f("aa1", a * a, 1), F.f("ab1", a * b, 1), F.f("ay1", a * i, 1)
        A2aa = F.f("aa2", a * a, 2)
        S = np.empty((t.size, 3, 3))
        S[:, 0, 0] = Saa
        S[:, 0, 1] = S[:, 1, 0] = Sab - c * A1aa
        S[:, 0, 2] = S[:, 2, 0] = Sab
        S[:, 1, 1] = Sbb - 2.0 * c * A1ab + c * c * A2aa
        S[:, 1, 2] = S[:, 2, 1] = Sbb - c * A1ab
        S[:, 2, 2] = Sbb
        rhs = np.stack([Say, Sby - c * A1ay, Sby], axis=1)
        C, G = np.full(t.size, np.nan), np.full(t.size, np.nan)
        excitation = np.zeros(t.size)
        good = np.isfinite(S).all(axis=(1, 2)) & (Saa > 0.0) & (Sbb > 0.0)
        if good.any():
            scale = np.sqrt(np.einsum("nii->ni", S[good]))  # Jacobi scaling before the solve
            Sg = S[good] / scale[:, :, None] / scale[:, None, :]
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                ok = np.abs(np.linalg.det(Sg)) > 1e-14
                theta = np.full((Sg.shape[0], 3), np.nan)
                theta[ok] = np.linalg.solve(Sg[ok], (rhs[good] / scale)[ok][..., None])[..., 0]
                theta = theta / scale
                inv11 = np.full(Sg.shape[0], np.inf)
                inv11[ok] = np.linalg.inv(Sg[ok])[:, 0, 0]
            C[good] = theta[:, 0] / sa
            G[good] = theta[:, 2] / sb
            excitation[good] = np.where(np.isfinite(inv11), 1.0 / inv11, 0.0)  # 1 - R^2 of a on the others
    excitation = np.where(np.isfinite(excitation), excitation, 0.0)
    valid = (t - st.t0 >= SETTLE_TAUS * tau) & (excitation >= MIN_EXCITATION) & np.isfinite(C)
    return CapacitanceEstimate(np.where(valid, C, np.nan), G, excitation, valid, float(tau))


@dataclass(frozen=True)
class ChargeEstimate:
    """What `capacitance_secant` returns (arrays on the input's samples).

    Attributes
    ----------
    capacitance : numpy.ndarray
        The secant capacitance ``q / v`` blended with the small-signal one near 0 V [F]; NaN where not `valid`.
    charge : numpy.ndarray
        ``q``: the integrated current less the estimated leakage [C].
    leakage_conductance : numpy.ndarray
        ``1 / R_leak`` as estimated so far [S].
    valid : numpy.ndarray of bool
        Where the small-signal estimate was valid.
    """

    capacitance: np.ndarray
    charge: np.ndarray
    leakage_conductance: np.ndarray
    valid: np.ndarray


#: Voltage [V] below which the small-signal capacitance stands for the secant one (its bias
#: ``v dC/dv`` vanishes with v) and which weighs the blend ``v**2 / (v**2 + V**2)``.
BLEND_VOLTAGE = 300.0
#: Memory of the leakage estimate [s].
LEAKAGE_TAU = 30.0
#: Regularization of the leakage fit, in integrated voltage [V s]: before the run has built up
#: this much, the fit keeps to no leakage.
LEAKAGE_PRIOR = 100.0
#: Weight of that prior, in seconds of low-voltage samples [s].
LEAKAGE_PRIOR_SECONDS = 0.01


def capacitance_secant(time, voltage, current, small_signal: CapacitanceEstimate, *,
                       blend_voltage: float = BLEND_VOLTAGE, leakage_tau: float = LEAKAGE_TAU,
                       leakage: float | None = None) -> ChargeEstimate:
    """The secant capacitance ``C = q / v`` from the charge, which is what the models' ``C(lambda1, v)`` is.

    The probe measures the small-signal capacitance ``dq/dv = C + v dC/dv``:
    under a bias voltage it differs from ``C`` wherever the capacitance
    depends on the voltage at fixed clamps (a compliant series element, passive
    ends, a slack roll; not in the models of the paper's solid rolls). The
    charge gives ``C`` itself: ``q_k = sum_j i_j dt - G int v dt`` (the roll
    starts discharged at 0 V), with the leakage conductance ``G`` fitted where
    the voltage is low (``|v| < blend_voltage``), there ``q = C_small v`` holds
    to ``v**2 dC/dv``: ``sum i dt - C_small v = G int v dt``, least squares with
    exponential forgetting (`leakage_tau`), regularized toward ``G = 0`` (as if
    `LEAKAGE_PRIOR_SECONDS` of samples at `LEAKAGE_PRIOR` volt-seconds said so). The result blends
    ``q / v`` (weight ``v**2 / (v**2 + blend_voltage**2)``) with the small-signal
    estimate. Until the leakage is learnt (the voltage has been high and come
    back below `blend_voltage`: the regularization weighs less than 1 %) only
    the small-signal estimate below `blend_voltage` is given, and no estimate
    above it. Causal; vectorized (cumulative sums and first-order filters).

    Parameters
    ----------
    time, voltage, current : array_like
        As for `capacitance_rls` [s], [V], [A].
    small_signal : CapacitanceEstimate
        `capacitance_rls` on the same samples.
    blend_voltage : float
        [V], > 0.
    leakage_tau : float
        [s], > 0.
    leakage : float, optional
        A known leakage conductance ``1 / R_leak`` [S] instead of the fit (0: none).

    Returns
    -------
    ChargeEstimate
    """
    t, v, i, dt = _checked(time, voltage, current)
    state = _ChargeState(_Filters(np.exp(-dt / leakage_tau)), 0.0, 0.0, 0.0, dt, float(blend_voltage), leakage)
    return _secant_block(state, v, i, small_signal)


@dataclass
class _ChargeState:
    filters: _Filters
    sum_i: float  # sum of the current so far [A]
    sum_v: float  # sum of the interval-mean voltages so far [V]
    v_last: float  # voltage of the previous sample [V] (0 before the first: discharged)
    dt: float
    blend_voltage: float
    leakage: float | None


def _secant_block(st: _ChargeState, v, i, small_signal: CapacitanceEstimate) -> ChargeEstimate:
    """`capacitance_secant` on the next block of samples, the state carried on."""
    dt, blend_voltage = st.dt, st.blend_voltage
    v_prev = np.concatenate(([st.v_last], v[:-1]))
    # running sums continued in the order one cumulative sum over the record adds them
    si = np.cumsum(np.concatenate(([st.sum_i], i)))[1:]
    sv = np.cumsum(np.concatenate(([st.sum_v], 0.5 * (v + v_prev))))[1:]
    st.sum_i, st.sum_v, st.v_last = float(si[-1]), float(sv[-1]), float(v[-1])
    Q = si * dt
    I = sv * dt  # integral of v [V s]
    Cs = small_signal.capacitance
    low = small_signal.valid & (np.abs(v) < blend_voltage)
    r = np.where(low, Q - np.where(low, Cs, 0.0) * v, 0.0)
    w = low.astype(float)
    S_II, S_Ir = st.filters.f("II", w * I * I), st.filters.f("Ir", w * I * r)
    if st.leakage is None:
        # the prior: as if LEAKAGE_PRIOR_SECONDS of low-voltage samples at int v dt = LEAKAGE_PRIOR said G = 0
        prior = LEAKAGE_PRIOR**2 * LEAKAGE_PRIOR_SECONDS / dt
        G = S_Ir / (S_II + prior)
        # learnt once the prior weighs less than 1 %: the voltage has been high and come back
        learnt = S_II >= 99.0 * prior
    else:
        G, learnt = np.full(v.shape, float(st.leakage)), np.ones(v.shape, bool)
    q = Q - G * I
    # before the leakage is learnt only the small-signal estimate near 0 V is used (the charge is off
    # by the unknown int v dt / R); above blend_voltage there is then no estimate
    s = np.where(learnt, v * v / (v * v + blend_voltage**2), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        C = np.where(s > 0.0, s * (q / np.where(v != 0.0, v, 1.0)), 0.0) + (1.0 - s) * Cs
    valid = small_signal.valid & np.isfinite(C) & (learnt | (np.abs(v) < blend_voltage))
    return ChargeEstimate(np.where(valid, C, np.nan), q, G, valid)


class SelfSenseStream:
    """Both estimators sample block by sample block, for a control loop: what the batch functions give.

    Parameters
    ----------
    rate : float
        DAQ sample rate [Hz].
    tau : float
        Forgetting time constant of `capacitance_rls` [s].
    scale : (float, float)
        Regressor scales ``dv/dt`` [V/s] and ``v`` [V] (e.g. ``2 pi f A`` of the probe and the
        largest voltage); conditioning only.
    blend_voltage, leakage_tau, leakage
        As for `capacitance_secant`.

    Notes
    -----
    ``step(t, v, i)`` takes the next samples (at least one; times continuing at ``1 / rate``) and
    returns ``(small_signal, charge)`` for them: `CapacitanceEstimate` and `ChargeEstimate`. In any
    blocks it gives what `capacitance_rls` (with the same `scale`) and `capacitance_secant` give on
    the whole record, to rounding.
    """

    def __init__(self, rate: float, tau: float, scale, *, blend_voltage: float = BLEND_VOLTAGE,
                 leakage_tau: float = LEAKAGE_TAU, leakage: float | None = None, drift: bool = True):
        if not (rate > 0.0 and np.isfinite(rate)) or not (tau > 0.0 and np.isfinite(tau)):
            raise ValueError(f"rate and tau must be finite and > 0, got {rate!r} Hz, {tau!r} s")
        dt = 1.0 / rate
        self._rls = _RlsState(_Filters(np.exp(-dt / tau)), None, None, dt, float(tau), _scales(scale), drift)
        self._charge = _ChargeState(_Filters(np.exp(-dt / leakage_tau)), 0.0, 0.0, 0.0, dt, float(blend_voltage),
                                    leakage)

    def step(self, t, v, i) -> tuple:
        t, v, i = (np.atleast_1d(np.asarray(x, float)) for x in (t, v, i))
        if not (t.shape == v.shape == i.shape and t.ndim == 1 and t.size >= 1):
            raise ValueError("t, v and i must be 1-D of the same length >= 1")
        if self._rls.t0 is None:
            self._rls.t0 = float(t[0])
        small = _rls_block(self._rls, t, v, i)
        return small, _secant_block(self._charge, v, i, small)


__all__ = ["BLEND_VOLTAGE", "CapacitanceEstimate", "ChargeEstimate", "MIN_EXCITATION", "SETTLE_TAUS",
           "SelfSenseStream", "capacitance_rls", "capacitance_secant", "stretch_from_capacitance"]
