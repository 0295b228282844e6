"""Viscoelastic overstress: M Maxwell branches and a parallel damper, eq. (44) of [1] and its finite-strain form.

Two laws, chosen by the parameter set (``law``):

``linear`` (eq. (44) of [1], the default)
    ``d xi_j/dt = (k_j / eta_j) (lambda1 - xi_j)`` and
    ``sigma_irr = sum_j k_j (lambda1 - xi_j) + eta_v0 d lambda1/dt``.
    With ``q_j = lambda1 - xi_j`` and ``tau_j = eta_j / k_j``, a stretch that is
    linear over a sample interval (slope ``s``, length ``dt``) gives the exact
    update ``q(t + dt) = q(t) exp(-dt / tau) + s tau (1 - exp(-dt / tau))``:
    stable for every ``tau / dt`` (the factor never exceeds 1) and exact for
    piecewise-linear stretch, however stiff.

``finite_strain``
    Each branch a neo-Hookean spring (shear modulus ``mu_j``) in series with a
    Newtonian dashpot (viscosity ``eta_j``), the rheology of refs. [36] and
    [40] of [1] (Hong 2011; Zhao, Koh & Suo 2011) for the uniaxial branch that
    eq. (44) stands for. Multiplicative split ``lambda1 = lambda_e xi`` (elastic
    times viscous stretch, both incompressible). The spring's energy per
    volume ``W_e = mu/2 (lambda_e**2 + 2/lambda_e - 3)`` gives the branch's
    true stress ``sigma_j = lambda_e dW_e/dlambda_e = mu (lambda_e**2 - 1/lambda_e)``.
    The work per volume of a uniaxial incompressible stretch is
    ``sigma d(ln lambda1)``, so the dissipation inequality (42) per branch reads
    ``D = sigma_j d(ln lambda1)/dt - dW_e/dt = sigma_j d(ln xi)/dt >= 0``.
    A Newtonian dashpot (deviatoric stress ``2 eta`` times the viscous rate of
    deformation ``diag(1, -1/2, -1/2) d(ln xi)/dt``) carries the uniaxial stress
    with ``(2/3) sigma_j = 2 eta d(ln xi)/dt``: the flow rule
    ``d(ln xi)/dt = sigma_j / (3 eta)``, whose dissipation ``sigma_j**2 / (3 eta)``
    is never negative. In the elastic log-stretch ``u = ln(lambda1 / xi)``::

        du/dt = d(ln lambda1)/dt - f(u) / tau,   f(u) = (exp(2u) - exp(-u)) / 3,
        sigma_j = 3 mu f(u),   tau = eta / mu.

    Small strain: ``f(u) = u + u**2/2 + ...`` and ``u = lambda1 - xi + O(strain**2)``,
    so the law is eq. (44) with ``k = 3 mu`` and eq. (44)'s ``eta = 3 eta``
    (``k`` a Young's modulus, ``eta`` of eq. (44) an extensional viscosity, three
    times the shear one, Trouton's ratio); both have the relaxation time
    ``tau = eta / mu``, and differ at second order in the strain.

    The branch ODE is nonlinear and stiff where ``tau`` is short: each sample
    interval is integrated with the 3-stage Radau IIA collocation (order 5,
    L-stable, stiffly accurate; Hairer & Wanner, Solving ODEs II, IV.5), its
    stage equations solved by Newton's method to rounding (the 3x3 Jacobian
    ``I + h/tau A diag(f'(U))`` exact), on substeps graded from the sample
    (where the stretch rate jumps and a boundary layer of width ``tau``
    starts): ``h kappa <= 0.1 exp(x/4)`` with ``kappa = f'(u)/tau`` and ``x``
    the decay ``kappa`` integrated since the sample, and the stretch changing by
    at most 2 % per substep. Against ``solve_ivp`` at rtol 1e-13 the stress is
    right to within 2e-9 of its peak for ``tau/dt`` from 1e-4 to 1e4 on harsh
    histories (steps, ramps to stretch 3, sines; tested to 1e-8; about 1e-11
    where ``tau/dt >= 100``).

The linear law's update is the affine recurrence ``q_{n+1} = a_n q_n + b_n``
(``a_n = exp(-dt_n / tau)``, ``b_n = s_n tau (1 - a_n)``, `_linear_update`).
The reference evaluates it for all samples at once by a parallel prefix scan
over the composition of affine maps (``log2(n)`` vectorized numpy passes);
with numba it runs in sequence, compiled (`rdea_lab.physics.kernels.linear_strains`,
the same `_linear_update` compiled as it is, 1e-12 of the scan): for calls
of `AUTO_MIN_SAMPLES` samples or more, and for a `History`. A precomputed
`History` (the calibration's: its runs' time axes never change) spares the
data-only work of each evaluation, down to the distinct interval lengths
(a run sampled at a fixed rate has a few: the exponentials are computed for
those alone); it is evaluated for many parameter sets, so it pays numba's
loading (about 0.5-1.5 s once per process) back within a few hundred
evaluations (the prefix scan over a 5401-sample run took about 0.25 ms, the
compiled update 0.02 ms). Plain arrays of a single short call keep the scan
and import no numba. The finite-strain branches run
sequentially in time, compiled with numba (``rdea_lab.physics._branch_kernels``, ``cache=True``):
the first call in a fresh install compiles for about 5 s, and every later
process pays about 2.5 s once (importing numba, loading the cached machine
code).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._backend import AUTO_MIN_SAMPLES, compiled

#: The viscoelastic laws a parameter set can choose.
LAWS = ("linear", "finite_strain")

_S6 = math.sqrt(6.0)
#: Radau IIA, 3 stages: nodes and coefficients (Hairer & Wanner II, Table IV.5.6).
_RADAU_C = ((4 - _S6) / 10, (4 + _S6) / 10, 1.0)
_RADAU_A = (((88 - 7 * _S6) / 360, (296 - 169 * _S6) / 1800, (-2 + 3 * _S6) / 225),
            ((296 + 169 * _S6) / 1800, (88 + 7 * _S6) / 360, (-2 - 3 * _S6) / 225),
            ((16 - _S6) / 36, (16 + _S6) / 36, 1 / 9))
#: Substep rule of the finite-strain integrator (see the module docstring).
_FS_STEP, _FS_GROW, _FS_STRETCH_STEP = 0.1, 1 / 4, 0.02


def _affine_prefix(a, b):
    """Inclusive prefix composition of ``q -> a_n q + b_n`` along the last axis.

    Returns ``(A, B)`` with ``q_{n+1} = A_n q_0 + B_n`` (Hillis-Steele scan: ``log2(n)``
    vectorized passes, no Python loop over samples).
    """
    A, B = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    A = A.copy()
    B = B.copy()
    n = A.shape[-1]
    shift = 1
    while shift < n:
        B[..., shift:] = A[..., shift:] * B[..., :-shift] + B[..., shift:]
        A[..., shift:] = A[..., shift:] * A[..., :-shift]
        shift *= 2
    return A, B


def _intervals(t, lam):
    """Sample intervals [s] and the stretch's slope over each [1/s]."""
    dt = np.diff(t)
    return dt, np.diff(lam) / dt


def _rate(slope):
    """``d lambda1 / dt`` [1/s] at each sample from the interval slopes (see `stretch_rate`)."""
    return np.concatenate([slope[:1], slope])


def _linear_update(dt, slope, tau):
    """``(a, b)`` of eq. (44)'s exact update ``q_{n+1} = a q_n + b`` over an interval ``dt`` [s] whose
    stretch slope is ``slope`` [1/s], for the relaxation time ``tau`` [s]: ``a = exp(-dt / tau)``,
    ``b = slope tau (1 - a)``.

    Elementwise: numpy arrays (broadcast) here, scalars in the compiled recurrence
    (`rdea_lab.physics.kernels.linear_strains` compiles this very function). ``b`` is the slope times
    ``b`` of a unit slope, to the last bit (the compiled update takes it so, per distinct interval).
    """
    decay = -np.expm1(-dt / tau)  # 1 - a, without cancellation; a from it (one exponential)
    return 1.0 - decay, slope * (tau * decay)


def _linear_coefficients(dt, slope, tau):
    """``(a, b)`` of eq. (44)'s exact update ``q_{n+1} = a_n q_n + b_n`` over each interval, per branch
    (`_linear_update` with ``tau`` along the first axis: shape (M, n - 1))."""
    return _linear_update(dt, slope, tau[:, None])


def affine_recurrence(a, b, q0):
    """``q_1 .. q_n`` of ``q_{k+1} = a_k q_k + b_k`` from ``q_0 = q0`` (``a``, ``b`` broadcast along the last
    axis; ``q0`` one per leading index): every sample at once, by the prefix scan `_affine_prefix`.

    The first-order updates of eq. (44) (`overstress_step`) and of the emulated rig's first-order
    instruments (`rdea_lab.emulator.instruments.FirstOrderLag`) are this recurrence.
    """
    A, B = _affine_prefix(a, b)
    return A * np.asarray(q0, float)[..., None] + B


def _linear_branches(dt, slope, tau, q0, q, kernel="auto", distinct=None):
    """Eq. (44)'s exact update over the intervals ``dt`` [s] (stretch slopes ``slope`` [1/s]) for the
    relaxation times ``tau`` [s]: ``q[:, 0] = q0`` and ``q_{n+1} = a_n q_n + b_n`` into ``q[:, 1:]``.

    The reference: the coefficients of `_linear_coefficients` composed by the prefix scan
    (`affine_recurrence`). Compiled (``kernel`` as `rdea_lab.physics.models.solve`'s): the same update
    in sequence (`rdea_lab.physics.kernels.linear_strains`), with the coefficients of `_linear_update`
    computed once per distinct interval length: ``distinct``, ``(lengths, index)`` with
    ``dt == lengths[index]`` (`History.lengths`, `History.length_index`; without it every interval is
    its own). ``auto`` compiles a call of `AUTO_MIN_SAMPLES` samples or more, and one with ``distinct``
    (a `History`'s, evaluated for many parameter sets: the calibration's thousands of evaluations add
    up past that whatever the run's length, and pay numba's loading once).
    """
    repeated = distinct is not None
    fast = compiled(kernel, max(q.shape[1], AUTO_MIN_SAMPLES) if repeated else q.shape[1])
    if fast is not None:
        fast.linear_strains(*(distinct if repeated else (dt, None)), slope, tau, q0, q)
        return
    q[:, 0] = q0
    if dt.size:
        q[:, 1:] = affine_recurrence(*_linear_coefficients(dt, slope, tau), q[:, 0])


def _kernels():
    """The compiled kernels (numba: imported on first use; machine code cached on disk)."""
    from ._branch_kernels import KERNELS

    return KERNELS


def prepare(law: str) -> None:
    """Load `law`'s compiled kernel now (finite strain: numba, about 2.5 s once per process, from its
    disk cache), so that a caller with a deadline (a rig server's first reply) does not pay it later."""
    if law != "linear":
        overstress_step(np.array([0.0, 1e-3]), np.array([1.0, 1.001]), np.array([1.0]), np.array([1.0]), law=law)


def _stiffness_sum(k, q):
    """``sum_j k_j q_j`` [Pa], the linear branches' stress (``k @ q``), one vector operation per branch: a
    few branches over many samples are a matrix product BLAS does no faster than these (five times
    slower for one branch)."""
    out = k[0] * q[0]
    for j in range(1, k.size):
        out += k[j] * q[j]
    return out


def stress_of(law, modulus, q):
    """Branch stresses [Pa] from their internal strains ``q`` (shape (M, n)): ``k q`` or ``mu (e^{2q} - e^{-q})``."""
    modulus = np.asarray(modulus, float)[:, None]
    if law == "linear":
        return modulus * q
    return modulus * (np.expm1(2.0 * q) - np.expm1(-q))  # no cancellation at small strain


def dissipation_rate(law, modulus, eta, q):
    """Dissipation per volume and time [W/m^3] of each branch: ``eta xi'^2`` (linear) or ``sigma^2 / (3 eta)``."""
    sigma = stress_of(law, modulus, q)
    eta = np.asarray(eta, float)[:, None]
    return sigma**2 / eta if law == "linear" else sigma**2 / (3.0 * eta)


def check_time(t, shape):
    """Check a time axis [s]: 1-D, finite, strictly increasing, matching ``shape``.

    Returns it as a float array; raises ValueError naming the first bad sample.
    """
    t = np.asarray(t, float)
    if t.ndim != 1 or t.shape != tuple(shape):
        raise ValueError(f"time and stretch must be 1-D arrays of one length, got {t.shape} and {tuple(shape)}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"time must be finite; t[{int(bad[0])}] = {float(t[bad[0]])!r}")
    dt = np.diff(t)
    if not np.all(dt > 0):
        i = int(np.flatnonzero(~(dt > 0))[0])
        raise ValueError(f"time must be strictly increasing; t[{i + 1}] = {float(t[i + 1])!r} "
                         f"follows t[{i}] = {float(t[i])!r}")
    return t


@dataclass(frozen=True, eq=False)
class History:
    """A time axis and stretch history with what eq. (44) needs of them alone, computed once.

    Build it with :meth:`History.of`; `overstress_step` (and so
    :func:`rdea_lab.twin.compose`) takes it in place of ``t`` when the same
    history is evaluated for many parameter sets (the calibration objective).
    The arrays are read-only.

    Attributes
    ----------
    t : numpy.ndarray, shape (n,)
        Sample times [s], checked by :func:`check_time`.
    stretch : numpy.ndarray, shape (n,)
        Axial stretch [-].
    finite : numpy.ndarray of bool, shape (n,)
        Samples whose stretch is finite (the branches see only these).
    t_finite, stretch_finite : numpy.ndarray, shape (m,)
        Those samples' times [s] and stretches [-].
    dt, slope : numpy.ndarray, shape (m - 1,)
        Intervals between them [s] and the stretch's slope over each [1/s].
    rate : numpy.ndarray, shape (m,)
        ``d lambda1 / dt`` [1/s] at each finite sample (:func:`stretch_rate`).
    lengths : numpy.ndarray, shape (d,)
        The distinct interval lengths [s], ascending (a run sampled at a fixed rate has a few:
        eq. (44)'s exponentials are computed for these alone).
    length_index : numpy.ndarray of intp, shape (m - 1,)
        Each interval's position in ``lengths`` (``dt == lengths[length_index]``).
    """

    t: np.ndarray
    stretch: np.ndarray
    finite: np.ndarray
    t_finite: np.ndarray
    stretch_finite: np.ndarray
    dt: np.ndarray
    slope: np.ndarray
    rate: np.ndarray
    lengths: np.ndarray
    length_index: np.ndarray

    @property
    def all_finite(self) -> bool:
        return self.t_finite.size == self.t.size

    @classmethod
    def of(cls, t, stretch) -> "History":
        """The history of sample times ``t`` [s] and stretch ``stretch`` [-] (checked as `overstress_step` does)."""
        lam = np.array(stretch, float)
        t = np.array(check_time(t, lam.shape))
        finite = np.isfinite(lam)
        tt, ll = np.ascontiguousarray(t[finite]), np.ascontiguousarray(lam[finite])
        dt, slope = _intervals(tt, ll)
        rate = _rate(slope) if tt.size > 1 else np.zeros_like(ll)
        lengths, index = np.unique(dt, return_inverse=True)
        index = np.ascontiguousarray(index.reshape(dt.shape), np.intp)
        for x in (t, lam, finite, tt, ll, dt, slope, rate, lengths, index):
            x.setflags(write=False)
        return cls(t, lam, finite, tt, ll, dt, slope, rate, lengths, index)


def branch_strains(t, stretch, tau, q0=None, law="linear"):
    """Internal strain of each Maxwell branch at every sample.

    Parameters
    ----------
    t : array_like, shape (n,), or History
        Sample times [s], strictly increasing; or a `History`, whose finite
        samples are used (``stretch`` is then ignored; pass None).
    stretch : array_like, shape (n,)
        Axial stretch [-], taken as linear between samples.
    tau : array_like, shape (M,)
        Relaxation times [s], > 0: ``eta_j / k_j`` (linear) or ``eta_j / mu_j`` (finite strain).
    q0 : array_like, shape (M,), optional
        Strains at ``t[0]`` [-]; default 0 (relaxed at the start).
    law : {"linear", "finite_strain"}

    Returns
    -------
    numpy.ndarray, shape (M, n)
        ``q_j = lambda1 - xi_j`` (linear: exact for piecewise-linear stretch) or
        the elastic log-stretch ``u_j = ln(lambda1 / xi_j)`` (finite strain).
        NaN from a sample on where the finite-strain step fails (a stretch
        history no spring survives).
    """
    if law not in LAWS:
        raise ValueError(f"law {law!r}; allowed: {', '.join(LAWS)}")
    history = t if isinstance(t, History) else None
    if history is not None:
        t, lam = history.t_finite, history.stretch_finite
    else:
        t = check_time(t, np.shape(stretch))
        lam = np.ascontiguousarray(stretch, float)
    tau = np.ascontiguousarray(np.atleast_1d(np.asarray(tau, float)))
    if not np.all(tau > 0):
        raise ValueError(f"relaxation times must be > 0, got {tau.ravel()}")
    q = np.empty((tau.shape[0], t.size))
    if t.size == 0 or tau.size == 0:  # no samples or no branches: nothing to integrate
        return q
    start = np.zeros(tau.size) if q0 is None else np.ascontiguousarray(np.broadcast_to(np.asarray(q0, float),
                                                                                        tau.shape))
    if law == "linear" and history is not None:
        _linear_branches(history.dt, history.slope, tau, start, q,
                         distinct=(history.lengths, history.length_index))
    elif law == "linear":
        _linear_branches(*_intervals(t, lam), tau, start, q)
    else:  # (a History's arrays are read-only: numba would compile the kernel again for those)
        t, lam = (np.array(t), np.array(lam)) if history is not None else (t, lam)
        _kernels()["finite_strain"](t, lam, tau, start, q, _FS_STEP, _FS_GROW, _FS_STRETCH_STEP)
    return q


def stress_basis(history: History, tau, law="linear") -> np.ndarray:
    """Stress [Pa per Pa of modulus] of each branch with a unit spring modulus, at every finite sample.

    With fixed relaxation times the overstress is linear in the moduli: ``sum_j m_j basis[j]`` (plus the
    damper's ``eta_v0`` times ``history.rate``), since each branch's strain depends on its ``tau_j`` alone
    (:func:`branch_strains`) and its stress is the modulus times a function of that strain (:func:`stress_of`).
    A relaxation spectrum is fitted on this basis (:mod:`rdea_lab.calibration.spectrum`).

    Parameters
    ----------
    history : History
        The run's times and stretch (:meth:`History.of`).
    tau : array_like, shape (M,)
        Relaxation times [s], > 0.
    law : {"linear", "finite_strain"}

    Returns
    -------
    numpy.ndarray, shape (M, m)
        ``q_j`` (linear) or ``exp(2 u_j) - exp(-u_j)`` (finite strain) at the history's samples (NaN where
        the stretch is not finite), as `overstress_step` composes them for a branch ``k = 1``, ``eta = tau``.
    """
    tau = np.atleast_1d(np.asarray(tau, float))
    # branch by branch through the one composition (a branch of modulus 1 and viscosity tau)
    return np.array([overstress_step(history, None, [1.0], [t], law=law)[0] for t in tau]).reshape(tau.size, -1)


def stretch_rate(t, stretch):
    """``d lambda1 / dt`` [1/s] at each sample: the slope of the interval that ends there.

    The first sample takes the slope of the first interval.
    """
    t = np.asarray(t, float)
    lam = np.asarray(stretch, float)
    if t.size < 2:
        return np.zeros_like(lam)
    return _rate(_intervals(t, lam)[1])


@dataclass(frozen=True)
class ViscoState:
    """Where the branches stand after the last finite sample of a block.

    Attributes
    ----------
    t : float
        Its time [s].
    stretch : float
        Its stretch [-].
    q : numpy.ndarray, shape (M,)
        Branch strains there [-] (:func:`branch_strains`: ``lambda1 - xi_j`` or ``ln(lambda1 / xi_j)``).
    """

    t: float
    stretch: float
    q: np.ndarray


def overstress_step(t, stretch, k, eta, eta_v0=0.0, *, q0=None, state=None, law="linear"):
    """Viscoelastic stress ``sigma_irr`` [Pa] of eq. (44) in [1] (or its finite-strain form) over one block.

    The one composition of the branches in rdea-lab: `overstress`, the twin and the
    calibration all come here.

    Parameters
    ----------
    t : array_like, shape (n,), or History
        Sample times [s], strictly increasing (and after ``state.t``); or a
        `History` (:meth:`History.of`), which carries its stretch and what
        depends on the data alone (``stretch`` is then None): nothing of that is
        recomputed. With a `state` a History is
        evaluated as its ``t`` and ``stretch``.
    stretch : array_like, shape (n,), or None
        Axial stretch [-].
    k : array_like, shape (M,)
        Branch moduli [Pa]: stiffnesses ``k_vj`` (linear) or spring shear moduli ``mu_j`` (finite strain).
    eta : array_like, shape (M,)
        Branch viscosities ``eta_vj`` [Pa s] (of eq. (44), or the dashpots' shear viscosities).
    eta_v0 : float
        Parallel damper ``eta_v0`` [Pa s].
    q0 : array_like, shape (M,), optional
        Branch strains at ``t[0]`` [-] when there is no `state`; default 0 (relaxed).
    law : {"linear", "finite_strain"}
        See the module docstring.
    state : ViscoState, optional
        The end of the previous block: the interval from it to ``t[0]`` is
        integrated exactly too, so a series cut into blocks gives the numbers of
        the whole series (except ``eta_v0``'s rate at a first block of a single
        finite sample, which has no interval yet and reads 0, where the whole
        series takes the first interval's slope).

    Returns
    -------
    sigma : numpy.ndarray, shape (n,)
        ``sum_j sigma_j + eta_v0 d lambda1/dt`` (:func:`stress_of`); vanishes as the rate goes to 0.
        NaN at samples whose stretch is NaN or infinite.
    state : ViscoState or None
        At the last finite sample (`state` unchanged if there is none).

    Notes
    -----
    A sample without a finite stretch has no stress; the branches carry on
    across it as if the stretch were linear between its finite neighbours, so
    one lost sample does not void the rest of a run.
    """
    history = t if isinstance(t, History) else None
    if history is not None and stretch is not None:
        raise ValueError("stretch must be None when t is a History (which carries its own)")
    if history is not None and state is not None:  # block continuation: evaluated as plain arrays
        t, stretch, history = history.t, history.stretch, None
    if history is None:
        lam = np.asarray(stretch, float)
        t = check_time(t, lam.shape)
        if state is not None and not t[0] > state.t:
            raise ValueError(f"block starts at t = {float(t[0])!r}, not after the previous block's end")
        ok = np.isfinite(lam)
        tt, ll = t[ok], lam[ok]
        if state is not None:
            tt, ll = np.concatenate([[state.t], tt]), np.concatenate([[state.stretch], ll])
            q0 = state.q
    else:
        lam, ok, tt, ll = history.stretch, history.finite, history.t_finite, history.stretch_finite
    k = np.atleast_1d(np.asarray(k, float))
    eta = np.atleast_1d(np.asarray(eta, float))
    q = None
    if k.size and tt.size:
        q = branch_strains(*((tt, ll) if history is None else (history, None)), eta / k, q0, law)
        part = _stiffness_sum(k, q) if law == "linear" else stress_of(law, k, q).sum(axis=0)
    else:
        part = np.zeros(tt.size)
    if eta_v0 and tt.size > 1:
        part += eta_v0 * (stretch_rate(tt, ll) if history is None else history.rate)
    if history is not None and history.all_finite:
        sigma = part
    else:
        sigma = np.full(lam.shape, np.nan)
        sigma[ok] = part[1:] if state is not None else part
    if tt.size:
        state = ViscoState(float(tt[-1]), float(ll[-1]), q[:, -1].copy() if q is not None else np.zeros(0))
    return sigma, state


def overstress(t, stretch, k, eta, eta_v0=0.0, q0=None, law="linear"):
    """Viscoelastic stress ``sigma_irr`` [Pa] of eq. (44) in [1] over a whole series.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], strictly increasing.
    stretch : array_like, shape (n,)
        Axial stretch [-].
    k : array_like, shape (M,)
        Branch stiffnesses ``k_vj`` [Pa].
    eta : array_like, shape (M,)
        Branch viscosities ``eta_vj`` [Pa s].
    eta_v0 : float
        Parallel damper ``eta_v0`` [Pa s].
    q0 : array_like, shape (M,), optional
        Initial branch strains [-]; default 0.
    law : {"linear", "finite_strain"}

    Returns
    -------
    numpy.ndarray, shape (n,)
        See `overstress_step`, of which this is the one-block case.
    """
    return overstress_step(t, stretch, k, eta, eta_v0, q0=q0, law=law)[0]
