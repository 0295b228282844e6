"""Fit parameters: names, bounds and the change of variables Nelder-Mead works in.

Positive parameters (C10, k_vj or mu_vj, eta_vj) are fitted in log space; signed or
non-negative ones (C20, C30, eta_v0) through ``asinh(x / scale)``, which is
linear near zero and logarithmic far from it. Bounds then enter through a
sine map of that variable onto its bounded interval (as lmfit does), so the
unconstrained simplex can never leave them.

The hyperelastic choice (`HYPERELASTIC`) restricts the Yeoh coefficients the fit may reach: the
paper's Yeoh (admissible: ``dW/dI1 > 0`` wherever the fit goes, `~rdea_lab.specs.params.material_problems`),
a Yeoh restricted to monotone stiffening, or neo-Hookean (:func:`constrain_start`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

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

    @cached_property
    def _ends(self):
        """``(g(lo), g(hi))`` of the log or asinh map ``g`` (`_u`): once, not per evaluation."""
        return self._u(self.lo), self._u(self.hi)

    def to_internal(self, x: float) -> float:
        """Physical value -> unconstrained internal variable."""
        ulo, uhi = self._ends
        r = (self._u(np.clip(x, self.lo, self.hi)) - ulo) / (uhi - ulo)
        return float(np.arcsin(np.clip(2.0 * r - 1.0, -1.0, 1.0)))

    def to_physical(self, z: float) -> float:
        ulo, uhi = self._ends
        return float(self._x(ulo + (np.sin(z) + 1.0) * 0.5 * (uhi - ulo)))

    def at_bound(self, x: float, rtol=1e-6) -> bool:
        span = self._u(self.hi) - self._u(self.lo)
        return bool(min(abs(self._u(x) - self._u(self.lo)), abs(self._u(self.hi) - self._u(x))) <= rtol * span)


#: The hyperelastic choices of a fit: the paper's Yeoh (the default), the Yeoh restricted to monotone
#: stiffening (C20 >= 0, C30 >= 0), neo-Hookean (C20 = C30 = 0, C10 alone).
HYPERELASTIC = ("yeoh", "yeoh-monotone", "neo-hookean")


def check_hyperelastic(choice: str) -> str:
    """``choice`` if it is one of `HYPERELASTIC`.

    Raises
    ------
    SpecError
        Another value (field ``hyperelastic``).
    """
    if choice not in HYPERELASTIC:
        raise SpecError("arguments", "hyperelastic", f"{choice!r}; allowed: {', '.join(HYPERELASTIC)}")
    return choice


def constrain_start(start: ParameterSet, choice: str = "yeoh") -> ParameterSet:
    """The start of a fit under the hyperelastic ``choice``: ``start`` projected onto what the choice allows.

    Parameters
    ----------
    start : ParameterSet
        Start values [SI].
    choice : {"yeoh", "yeoh-monotone", "neo-hookean"}
        ``yeoh``: the paper's Yeoh, ``W = C10 x + C20 x^2 + C30 x^3`` with ``x = I1 - 3``, any
        coefficients the physics admits (``dW/dI1 > 0`` on the stretches reached; ``C30 >= 0``);
        ``start`` unchanged. ``yeoh-monotone``: ``C20 >= 0`` and ``C30 >= 0`` (and ``C10 > 0``); a
        negative start C20 (or C30) starts at 0. ``neo-hookean``: ``C20 = C30 = 0``, held there.

    Returns
    -------
    ParameterSet
        ``start``, or a copy with C20, C30 projected (the record's ``init_value`` shows the start used).

    Raises
    ------
    SpecError
        An unknown ``choice``.

    Notes
    -----
    Why ``C20 >= 0, C30 >= 0`` is exactly monotone stiffening: ``d2W/dI1^2 = 2 C20 + 6 C30 x`` is affine
    in ``x = I1 - 3``, so it is >= 0 for every ``x >= 0`` if and only if it is at ``x = 0``
    (``C20 >= 0``) and its slope is (``C30 >= 0``; were ``C30 < 0`` it would turn negative for
    ``x > -C20 / (3 C30)``). The stiffness ``dW/dI1 = C10 + 2 C20 x + 3 C30 x^2`` is then >= C10 > 0
    for every ``x >= 0``: the material stiffens, never softens, at any stretch however far beyond the
    data, which is what a fit to small stretches may extrapolate. The paper's Yeoh allows ``C20 < 0``
    (an S-shaped curve), which a fit to stretch 1.5 can choose with a C30 that says nothing about 3.0.
    """
    check_hyperelastic(choice)
    if choice == "yeoh":
        return start
    if choice == "neo-hookean":
        C20 = C30 = 0.0
    else:
        C20, C30 = max(start.C20, 0.0), max(start.C30, 0.0)
    if (C20, C30) == (start.C20, start.C30):
        return start
    return start.replace(C20=C20, C30=C30)


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


def keep_relaxation_times(values: dict, base: dict) -> dict:
    """``values`` with each branch's relaxation time that of ``base``: where a modulus (``k_vj`` or ``mu_vj``)
    differs from ``base`` and its viscosity ``eta_vj`` does not, ``eta_vj = tau_j * modulus`` with
    ``tau_j = eta_vj / modulus`` of ``base``. A relaxation spectrum's covariance is of its moduli on a fixed
    grid of time scales (:mod:`~rdea_lab.calibration.spectrum`): a band or a sensitivity through it varies the
    moduli at fixed ``tau``."""
    out = dict(values)
    for name, x in values.items():
        head, _, j = name.partition("_v")
        if head in ("k", "mu") and j.isdigit() and f"eta_v{j}" in base and x != base[name] \
                and values.get(f"eta_v{j}") == base[f"eta_v{j}"] and base[name]:
            out[f"eta_v{j}"] = base[f"eta_v{j}"] * x / base[name]
    return out


def with_values(base: ParameterSet, values: dict[str, float], M: int, name: str | None = None) -> ParameterSet:
    """A new parameter set (of ``base``'s law); raises SpecError if it is not physical."""
    spring = MODULUS[base.law]
    branches = tuple(ViscoBranch.of(base.law, values[f"{spring}_v{j}"], values[f"eta_v{j}"])
                     for j in range(1, M + 1))
    return base.replace(C10=values["C10"], C20=values["C20"], C30=values["C30"], branches=branches,
                        eta_v0=values["eta_v0"], **({"name": name} if name else {}))


def fit_parameters(start: ParameterSet, free: set[str], hyperelastic: str = "yeoh") -> list[FitParameter]:
    """The fit parameters of ``start`` (all of its Yeoh and viscoelastic parameters).

    ``hyperelastic`` (`HYPERELASTIC`, see :func:`constrain_start`) sets the bounds of C20: ``yeoh``
    [-1e9, 1e9] Pa (the admissibility limit is the fit's, not a box), ``yeoh-monotone`` [0, 1e9] Pa;
    ``neo-hookean`` holds C20 and C30 (at the start's, which must be 0) whatever ``free`` says.
    C30 is in [0, 1e9] Pa under each.
    """
    check_hyperelastic(hyperelastic)
    if hyperelastic == "neo-hookean":
        free = set(free) - {"C20", "C30"}
    values = values_of(start)
    c_scale = max(0.1 * start.C10, 1.0)
    out = []
    for name in names_for(start.M, start.law):
        x = values[name]
        if name == "C10":
            p = FitParameter(name, x, 1e2, 1e9, "log", 1.0, name in free, UNITS["C"])
        elif name in ("C20", "C30"):
            lo = -1e9 if name == "C20" and hyperelastic == "yeoh" else 0.0
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
