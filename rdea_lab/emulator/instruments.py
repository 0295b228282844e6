"""Instrument effects of the emulated rig: pure, vectorized, state carried across chunks.

The DAQ samples at ``t_k = k / rate``. Setpoint ``k`` is the target for
sample ``k``: it is commanded over the interval ``(t_{k-1}, t_k]`` and held
there (zero-order hold). A first-order element ``tau dy/dt = u - y`` then
has the exact update ``y_k = a y_{k-1} + (1 - a) u_k``, ``a = exp(-dt / tau)``,
stable for every ``tau / dt`` and an ideal follower (``y = u``) at ``tau = 0``.
A step of the setpoint at sample ``k0`` is seen as ``1 - exp(-(t - t_{k0-1}) / tau)``.
"""

from __future__ import annotations

import math

import numpy as np

from ..physics.viscoelastic import affine_recurrence


class FirstOrderLag:
    """First-order lag ``tau dy/dt = u - y`` on a zero-order-held input, sample by sample.

    Parameters
    ----------
    tau : float
        Time constant [s], >= 0 (0: ``y = u``).
    dt : float
        Sample interval [s], > 0.
    y0 : float
        Output before the first sample (the state at ``t_{-1}``).
    """

    def __init__(self, tau: float, dt: float, y0: float):
        if not (tau >= 0.0 and math.isfinite(tau)) or not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"need tau >= 0 and dt > 0, got tau = {tau!r} s, dt = {dt!r} s")
        self.a = math.exp(-dt / tau) if tau > 0.0 else 0.0
        self.y = float(y0)

    def __call__(self, u) -> np.ndarray:
        """Outputs at the next ``len(u)`` samples for setpoints `u`."""
        u = np.asarray(u, float)
        if u.size == 0:
            return u.copy()
        if self.a == 0.0:
            y = u.copy()
        else:
            # in the lag e_k = y_k - u_k = a (e_{k-1} + u_{k-1} - u_k), by the scan, all samples at once: a
            # setpoint held is followed exactly (e stays 0), the rounding is of the lag, not of the level
            d = np.empty_like(u)
            d[0] = self.y - u[0]
            d[1:] = u[:-1] - u[1:]
            y = u + affine_recurrence(self.a, self.a * d, 0.0)
        self.y = float(y[-1])
        return y

    def reset(self, y: float) -> None:
        """Jump the output to `y` (voltage off, actuator back to start)."""
        self.y = float(y)


def tau_of_bandwidth(bandwidth: float) -> float:
    """Time constant ``1 / (2 pi f)`` [s] of a first-order low-pass of -3 dB bandwidth `f` [Hz]."""
    return 1.0 / (2.0 * math.pi * bandwidth)


def load_cell(force, offset, noise: float, rng: np.random.Generator) -> np.ndarray:
    """Load-cell reading [N]: true force [N] + offset [N] (a number, or one per sample: a drift)
    + Gaussian noise of std `noise` [N].

    Draws one normal variate per sample whatever `noise` is, so the stream
    of `rng` advances by the number of samples (chunking does not matter).
    """
    force = np.asarray(force, float)
    return force + offset + noise * rng.standard_normal(force.shape)


def lcr_bridge(capacitance, voltage, parasitic: float, noise: float, rng: np.random.Generator,
               enabled: bool = True, max_voltage: float = 1.0) -> np.ndarray:
    """LCR-bridge reading [F]: true capacitance [F] + parasitic [F] + noise (std `noise` [F]).

    The bridge measures at 0 V only (as on the paper's rig): NaN where
    ``|voltage| >= max_voltage`` [V] or where the channel is not `enabled`.
    One normal variate is drawn per sample in every case.
    """
    capacitance = np.asarray(capacitance, float)
    reading = capacitance + parasitic + noise * rng.standard_normal(capacitance.shape)
    measured = enabled & (np.abs(np.asarray(voltage, float)) < max_voltage)
    return np.where(measured, reading, np.nan)


class CurrentMonitor:
    """The amplifier's current monitor, sampled by an integrating (averaging) ADC, block by block.

    Sample ``k`` is the mean current over ``(t_{k-1}, t_k]``: the charge the
    amplifier delivered, ``(q_k - q_{k-1}) / dt`` with ``q = C v`` (whatever
    the voltage does between samples, the charge at the sample instants
    decides it: exact, not a finite-difference approximation), plus the
    leakage through the film, ``(v_k + v_{k-1}) / (2 R)`` (trapezoid: exact
    for a linear voltage over the interval), plus Gaussian noise of std
    `noise` [A]. Before the first sample the roll holds no charge (0 V).

    Parameters
    ----------
    dt : float
        Sample interval [s].
    leakage_resistance : float
        [ohm], > 0.
    noise : float
        Standard deviation per sample [A], >= 0.
    rng : numpy.random.Generator
        One normal variate per sample (chunking does not matter).
    """

    def __init__(self, dt: float, leakage_resistance: float, noise: float, rng: np.random.Generator):
        self.dt, self.R, self.noise, self.rng = float(dt), float(leakage_resistance), float(noise), rng
        self.q, self.v = 0.0, 0.0

    def __call__(self, capacitance, voltage) -> np.ndarray:
        """Current samples [A] for the next samples' capacitance [F] and voltage [V]."""
        C = np.asarray(capacitance, float)
        v = np.asarray(voltage, float)
        q = C * v
        q_prev = np.concatenate(([self.q], q[:-1]))
        v_prev = np.concatenate(([self.v], v[:-1]))
        i = (q - q_prev) / self.dt + 0.5 * (v + v_prev) / self.R + self.noise * self.rng.standard_normal(v.shape)
        if v.size:
            self.q, self.v = float(q[-1]), float(v[-1])
        return i

    def reset(self) -> None:
        """Voltage off: the roll discharged."""
        self.q, self.v = 0.0, 0.0


__all__ = ["CurrentMonitor", "FirstOrderLag", "lcr_bridge", "load_cell", "tau_of_bandwidth"]
