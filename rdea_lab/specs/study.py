"""Design-study files: which rolls to evaluate, against what, for which objectives (`rdea-lab design`).

A study is YAML; paths are relative to its folder::

    name: stroke_spring
    model: su                                  # su | 1r | 3r | cr (the quasi-static model)
    params: ../params/paper2021_table3.yaml    # the material (fixed unless a variable)
    specimen: ../specimens/specimen2.yaml      # what the variables leave as it is
    variables:                                 # name: [low, high] with units, or {range: [...], levels: 5}
      L1: [20 mm, 60 mm]
      L3: [30 um, 80 um]
      prestretch: [1.05, 1.5]
    sampling: {method: sobol, n: 1024, seed: 1}  # sobol | lhs (n designs) | grid (levels per variable)
    voltage: 2.6 kV                            # the operating point (unless a variable)
    bias: {kind: spring, stiffness: 200 N/m, preload: 1 N}
    objectives: [{maximize: stroke}, {maximize: blocking_force}]
    constraints: {field: {max: 80 V/um}, outer_radius: {max: 4 mm}}
    tolerances: {radii: 1 %, samples: 32, seed: 7}   # Monte Carlo: Rie, Roe, Ro x (1 + N(0, 1 %))
    sensitivity: {n: 128, seed: 3}             # Sobol indices (SALib, Saltelli's sampling)
    optimize: {objective: stroke, starts: 4}   # scipy SLSQP from the best feasible sweep points
    protocol: ../protocols/tensile_ramp_sine_2.6kV.yaml   # optional: every design also runs it
    chunk: 256                                 # designs per task (fixed, so results never depend on workers)

Variables (`VARIABLES`): the membrane ``L1, L1e, L2, L2e, Lp1, Lp2, L3`` (what is not varied keeps the
card's passive lengths: the ends ``L1 - L1e``, ``Lp1`` and ``Lp2 = L2 - Lp1 - L2e``); the bias
``stiffness, preload, mass`` or ``prestretch`` (the preload or mass that holds the roll at that stretch
at 0 V); the operating ``voltage``; the material ``C10, C20, C30`` (not 1R) and ``eps_r``.
Biases: ``none`` (free stroke), ``mass``, ``spring`` (as in target files), and ``curve``: a user's
force [N] against the extension ``(lambda1 - 1) L1`` of the roll, linear between points, its end values
beyond them.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from pydantic import ConfigDict, Field, ValidationError

from .base import SpecModel, spec_error_from_validation
from .errors import SpecError
from .params import ParameterSet
from .protocol import ProtocolSpec
from .specimen import SpecimenCard
from .study_file import _StudyFile, _int
from .study_terms import (  # noqa: F401  (the study's vocabulary, imported from here)
    BIAS_VARIABLES, DENSITY_METRICS, DESIGN_MODELS, MATERIAL, MEMBRANE, METRICS, PROTOCOL_METRICS, SAMPLINGS,
    VARIABLES, Bound, CurveBias, Goal, Variable,
)
from .target import BIAS_KINDS, MassBias, NoBias, SpringBias


class Study(SpecModel):
    """A validated design study (SI). `source` is the file, for messages; paths are resolved.

    ``Study.load(path)`` reads a study file (its paths relative to its folder) and keeps its text;
    ``Study.from_mapping(mapping, source, folder=...)`` validates a mapping (paths relative to ``folder``,
    by default the folder of `source`).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=True)
    spec_kind = "studies"

    name: str
    source: str
    model: str
    params: ParameterSet
    specimen: SpecimenCard
    variables: tuple[Variable, ...]
    method: str
    n: int
    seed: int
    voltage: float
    bias: NoBias | MassBias | SpringBias | CurveBias
    objectives: tuple[Goal, ...]
    constraints: tuple[Bound, ...]
    description: Any = None
    radii_tolerance: float = 0.0
    mc_samples: int = 0
    mc_seed: int = 0
    sensitivity_n: int = 0
    sensitivity_seed: int = 0
    optimize: dict | None = None
    protocol: ProtocolSpec | None = None
    protocol_path: str | None = None
    chunk: int = 256
    density: float | None = None
    text: str = Field("", repr=False)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.variables)

    @property
    def metrics(self) -> tuple[str, ...]:
        """Every metric the study computes (protocol ones only with a protocol, mass ones with a density)."""
        return _metrics(self.protocol, self.bias.kind, self.density)

    @classmethod
    def _from_form(cls, mapping: dict, source: str, folder: str | os.PathLike | None = None) -> "Study":
        folder = Path(source).parent if folder is None else Path(folder)
        try:
            f = _StudyFile.model_validate(mapping, context={"source": source, "folder": folder})
        except ValidationError as exc:  # the first problem, as the file's checks are ordered
            raise _first(exc, source) from None
        var, _ = f.variables
        (method, n, seed), (radii_tol, mc, mc_seed), (sens_n, sens) = f.sampling, f.tolerances, f.sensitivity
        sens_seed = _int(sens.get("seed", 0), source, "sensitivity.seed", 0, 2**32 - 1)
        protocol, protocol_path = f.protocol
        study = cls(name=f.name, source=source, model=f.model, params=f.params, specimen=f.specimen, variables=var,
                    method=method, n=n, seed=seed, voltage=f.voltage, bias=f.bias, objectives=f.objectives,
                    constraints=f.constraints, description=f.description, radii_tolerance=radii_tol,
                    mc_samples=mc if radii_tol else 0, mc_seed=mc_seed, sensitivity_n=sens_n,
                    sensitivity_seed=sens_seed, optimize=f.optimize, protocol=protocol, protocol_path=protocol_path,
                    chunk=f.chunk, density=f.density)
        kind = study.bias.kind
        for what, metric in [(f"objectives[{i}]", g.metric) for i, g in enumerate(study.objectives)] \
                + [(f"constraints.{b.metric}", b.metric) for b in study.constraints]:
            if metric not in study.metrics:
                need = {"preload": "a spring bias", "bias_mass": "a mass bias"}.get(metric, "what this study lacks")
                raise SpecError(source, what, f"{metric}: only with {need}")
            if kind == "none" and metric in ("blocking_force", "rest_force"):
                raise SpecError(source, what, f"{metric}: with no bias the roll rests at its own length, where it "
                                "carries no force; give a bias")
        return study

    def _read_from(self, text: str) -> "Study":
        return self.model_copy(update={"text": text})


def _metrics(protocol, kind: str, density) -> tuple[str, ...]:
    out = [m for m in METRICS if m not in PROTOCOL_METRICS or protocol is not None]
    out = [m for m in out if m not in ("preload", "bias_mass")
           or (m == "preload") == (kind == "spring") and kind in ("spring", "mass")]
    return tuple(m for m in out if m not in DENSITY_METRICS or density is not None)


def _first(exc: ValidationError, source: str) -> SpecError:
    """The `SpecError` a study's check raised (its field is the file's, not pydantic's location)."""
    err = exc.errors(include_url=False)[0]
    inner = (err.get("ctx") or {}).get("error")
    return inner if isinstance(inner, SpecError) else spec_error_from_validation(exc, source=source, model=_StudyFile)


def study_from_mapping(mapping: Any, source: str = "<mapping>", folder: str | os.PathLike = ".") -> Study:
    """`Study.from_mapping`: a study given as a mapping (paths relative to ``folder``)."""
    return Study.from_mapping(mapping, source, folder=folder)


def load_study(path: str | os.PathLike) -> Study:
    """`Study.load`: read and validate a study file, keeping its text.

    Parameters
    ----------
    path : str or path-like
        The YAML file; a path that does not exist may name a packaged study (``"stroke_spring"``).
        The files it names (specimen, parameters, protocol) are relative to its folder.

    Returns
    -------
    Study
        Frozen, in SI units, with the files it names read and validated.

    Raises
    ------
    SpecError
        Naming the file, the field and what is allowed (unknown variable, empty range, inverted bounds,
        a metric that needs what the study does not give, ...).
    """
    return Study.load(path)


__all__ = ["BIAS_KINDS", "METRICS", "SAMPLINGS", "VARIABLES", "Bound", "CurveBias", "Goal", "Study", "Variable",
           "load_study", "study_from_mapping"]
