"""Fit parameters: names, bounds and the change of variables Nelder-Mead works in.

Positive parameters (C10, k_vj or mu_vj, eta_vj) are fitted in log space; signed or
non-negative ones (C20, C30, eta_v0) through ``asinh(x / scale)``, which is
linear near zero and logarithmic far from it. Bounds then enter through a
sine map of that variable onto its bounded interval (as lmfit does), so the
unconstrained simplex can never leave them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..specs import MODULUS, ParameterSet, SpecError, ViscoBranch

#: Units of each kind of parameter, for records.
UNITS = {"C": "Pa", "k": "Pa", "mu": "Pa", "eta": "Pa s"}


@dataclass(frozen=True)
class FitParameter:
    """One parameter of a fit.

    Attributes
    ----------
    name : str
        ``C10``, ``C20``, ``C30``, ``k_v<j>`` (law linear) or ``mu_v<j>`` (finite strain), ``eta_v<j>`` or
        ``eta_v0``.
    start : float
        Start value [SI].
    lo, hi : float
        Bounds [SI].
    kind : {"log", "asinh"}
        Change of variables.
    scale : float
        Scale of the asinh map [SI].
    free : bool
        Fitted (True) or held at ``start``.
    unit : str
    """

    name: str
    start: float
    lo: float
    hi: float
    kind: str
    scale: float
    free: bool
    unit: str

    def _u(self, x):
        return np.log(x) if self.kind == "log" else np.arcsinh(x / self.scale)

    def _x(self, u):
        return np.exp(u) if self.kind == "log" else self.scale * np.sinh(u)

    def to_internal(self, x: float) -> float:
        """Physical value -> unconstrained internal variable."""
        ulo, uhi = self._u(self.lo), self._u(self.hi)
        r = (self._u(np.clip(x, self.lo, self.hi)) - ulo) / (uhi - ulo)
        return float(np.arcsin(np.clip(2.0 * r - 1.0, -1.0, 1.0)))

    def to_physical(self, z: float) -> float:
        ulo, uhi = self._u(self.lo), self._u(self.hi)
        return float(self._x(ulo + (np.sin(z) + 1.0) * 0.5 * (uhi - ulo)))

    def at_bound(self, x: float, rtol=1e-6) -> bool:
        span = self._u(self.hi) - self._u(self.lo)
        return bool(min(abs(self._u(x) - self._u(self.lo)), abs(self._u(self.hi) - self._u(x))) <= rtol * span)


def names_for(M: int, law: str = "linear") -> list[str]:
    """Parameter names of a Yeoh material with ``M`` Maxwell branches of ``law`` and the parallel damper."""
    spring = MODULUS[law]
    return ["C10", "C20", "C30", *[f"{p}_v{j}" for j in range(1, M + 1) for p in (spring, "eta")], "eta_v0"]


def values_of(params: ParameterSet) -> dict[str, float]:
    spring = MODULUS[params.law]
    out = {"C10": params.C10, "C20": params.C20, "C30": params.C30, "eta_v0": params.eta_v0}
    for j, b in enumerate(params.branches, start=1):
        out[f"{spring}_v{j}"], out[f"eta_v{j}"] = b.modulus, b.eta
    return out


def with_values(base: ParameterSet, values: dict[str, float], M: int, name: str | None = None) -> ParameterSet:
    """A new parameter set (of ``base``'s law); raises SpecError if it is not physical."""
    spring = MODULUS[base.law]
    branches = tuple(ViscoBranch.of(base.law, values[f"{spring}_v{j}"], values[f"eta_v{j}"])
                     for j in range(1, M + 1))
    return base.replace(C10=values["C10"], C20=values["C20"], C30=values["C30"], branches=branches,
                        eta_v0=values["eta_v0"], **({"name": name} if name else {}))


def fit_parameters(start: ParameterSet, free: set[str]) -> list[FitParameter]:
    """The fit parameters of ``start`` (all of its Yeoh and viscoelastic parameters)."""
    values = values_of(start)
    c_scale = max(0.1 * start.C10, 1.0)
    out = []
    for name in names_for(start.M, start.law):
        x = values[name]
        if name == "C10":
            p = FitParameter(name, x, 1e2, 1e9, "log", 1.0, name in free, UNITS["C"])
        elif name in ("C20", "C30"):
            lo = -1e9 if name == "C20" else 0.0
            p = FitParameter(name, x, lo, 1e9, "asinh", c_scale, name in free, UNITS["C"])
        elif name == "eta_v0":
            p = FitParameter(name, x, 0.0, 1e10, "asinh", 1e3, name in free, UNITS["eta"])
        elif name.startswith(("k_v", "mu_v")):
            p = FitParameter(name, x, 1e2, 1e11, "log", 1.0, name in free, UNITS["k"])
        else:
            p = FitParameter(name, x, 1e-3, 1e11, "log", 1.0, name in free, UNITS["eta"])
        if not p.lo <= x <= p.hi:
            raise SpecError("--init", name,
                            f"start value {x:g} {p.unit} is outside the fit bounds [{p.lo:g}, {p.hi:g}]")
        out.append(p)
    return out
