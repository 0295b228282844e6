"""Every metric of a study for a table of designs, vectorized over the designs (one call per chunk).

A design is one row of the table: the study's variables (SI), on top of the
specimen card's membrane, the parameter set's material and the study's bias and
voltage. The roll's operating points are quasi-static equilibria with the bias,
``F_roll(lambda, v) = F_bias(lambda)``, found by bisection over all designs at
once (the roll's force rises with stretch at fixed voltage; a bias that pulls
less as the roll lengthens keeps the root unique). The roll's force is
`rdea_lab.physics.designs.solve_designs`: the models' own solve over designs
(SU and 1R mapped onto one roll, 3R and CR each design with its own radii).
A protocol, when the study gives one, runs on every design through the twin's
composition (`rdea_lab.twin.simulate.compose`: the quasi-static
stress plus the viscoelastic overstress of the parameter set).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics.designs import Material, design_geometry, solve_designs
from ..physics.geometry import RollGeometry, radii_from_membrane
from ..physics.result import VALID
from ..specs.limits import field_estimate
from ..specs.study import MEMBRANE, PROTOCOL_METRICS, Study
from ..specs.target import G, MassBias, SpringBias
from ..twin.simulate import compose, viscous

#: design_status codes (flag_values / flag_meanings in the dataset)
STATUS = {0: "ok", 1: "no_roll", 2: "no_equilibrium", 3: "model_failed", 4: "radii_out_of_order",
          5: "protocol_limits"}
OK, NO_ROLL, NO_EQUILIBRIUM, MODEL_FAILED, RADII_ORDER, PROTOCOL_LIMITS = range(6)
#: largest stretch the equilibrium search looks at [-]
MAX_STRETCH = 2.5
_BISECTIONS = 64
_SIMPSON = 33


@dataclass(frozen=True)
class Fixed:
    """What every chunk of a study shares: the study and the protocol's sampled history (or None)."""

    study: Study
    history: tuple | None  # (t, stretch, voltage, limits)

    @classmethod
    def of(cls, study: Study) -> "Fixed":
        history = None
        if study.protocol is not None:
            from ..protocols import as_plan
            plan = as_plan(study.protocol)
            history = (np.array(plan.time), np.array(plan.stretch), np.array(plan.voltage), plan.limits)
        return cls(study, history)


def membrane(study: Study, table: dict) -> dict:
    """The membrane of each design [m]: the variables, the card's values, and the card's passive lengths
    (ends ``L1 - L1e``, ``Lp1``, ``Lp2``) for what the variables derive (module docstring of
    `rdea_lab.specs.study`)."""
    m = study.specimen.membrane
    n = len(next(iter(table.values())))
    card = {"L1": m.L1, "L1e": m.L1e, "L2": m.L2, "L2e": m.L2e, "Lp1": m.Lp1, "Lp2": m.Lp2, "L3": m.L3}
    given = {k: np.asarray(table[k], float) for k in MEMBRANE if k in table}
    out = {k: np.asarray(given.get(k, np.full(n, v)), float) for k, v in card.items()}
    ends = m.L1 - m.L1e
    if "L1" in given and "L1e" not in given:
        out["L1e"] = out["L1"] - ends
    elif "L1e" in given and "L1" not in given:
        out["L1"] = out["L1e"] + ends
    if "L2" not in given:
        out["L2"] = out["Lp1"] + out["L2e"] + out["Lp2"]
    elif "L2e" not in given:
        out["L2e"] = out["L2"] - out["Lp1"] - out["Lp2"]
    elif "Lp2" not in given:
        out["Lp2"] = out["L2"] - out["Lp1"] - out["L2e"]
    else:
        out["Lp1"] = out["L2"] - out["L2e"] - out["Lp2"]
    out["Ri"] = np.full(n, m.Ri)
    return out


def radii_factors(study: Study, index) -> np.ndarray:
    """Monte Carlo radius factors ``(designs, samples, 3)`` for Rie, Roe, Ro: ``1 + tol N(0, 1)``, each
    design's own stream (seeded by the study's seed and the design's index, so no chunking changes it)."""
    index = np.asarray(index, np.int64)
    out = np.empty((index.size, study.mc_samples, 3))
    for j, i in enumerate(index.tolist()):  # one small draw per design (not per sample)
        out[j] = 1.0 + study.radii_tolerance * np.random.default_rng([study.mc_seed, i]).standard_normal(
            (study.mc_samples, 3))
    return out


def _bias(study: Study, table: dict, n: int):
    """Each design's bias (the target files' models, with arrays over designs for their parameters)."""
    bias = study.bias
    if bias.kind == "spring":
        return SpringBias.model_construct(kind="spring", stiffness=_column(table, "stiffness", bias.stiffness, n),
                                          preload=_column(table, "preload", bias.preload, n))
    if bias.kind == "mass":
        return MassBias.model_construct(kind="mass", mass=_column(table, "mass", bias.mass, n))
    return bias


def _column(table, key, default, n):
    return np.asarray(table[key], float) if key in table else np.full(n, float(default))


def protocol_needed(study: Study) -> bool:
    """Whether an objective or a constraint is a protocol's metric (then the Monte Carlo rolls and the
    sensitivity's designs run the protocol too; otherwise only the nominal designs do)."""
    return any(m in PROTOCOL_METRICS for m in [g.metric for g in study.objectives]
               + [b.metric for b in study.constraints])


def evaluate(fixed: Fixed, table: dict, factors=None, *, protocol: bool = True) -> dict:
    """Metrics of the designs ``table`` (``{variable: array(n)}``, SI).

    ``factors`` ``(n, 3)``: radius factors of Rie, Roe, Ro (a Monte Carlo sample); None: nominal.
    ``protocol=False`` leaves the protocol's metrics out (NaN).
    Returns ``{metric: array(n)}`` and ``design_status`` (codes of `STATUS`).
    """
    study = fixed.study
    n = len(next(iter(table.values())))
    mem = membrane(study, table)
    status = np.zeros(n, np.int8)
    with np.errstate(invalid="ignore"):
        shape_ok = (mem["L1e"] > 0) & (mem["L1e"] <= mem["L1"] * (1 + 1e-12)) & (mem["Lp1"] >= 0) \
            & (mem["Lp2"] >= -1e-12 * mem["L2"]) & (mem["L2e"] > 0) & (mem["L3"] > 0)
    r = radii_from_membrane(mem["L2"], mem["L3"], np.maximum(mem["Lp1"], 0.0), mem["L2e"], mem["Ri"], check=False)
    radii = np.stack([r["Rie"], r["Roe"], r["Ro"]], axis=1)
    good = shape_ok & np.all(np.isfinite(radii), axis=1)
    status[~good] = NO_ROLL
    if factors is not None:
        radii = radii * factors
        ordered = (mem["Ri"] <= radii[:, 0]) & (radii[:, 0] < radii[:, 1]) & (radii[:, 1] <= radii[:, 2])
        status[good & ~ordered] = RADII_ORDER
        good &= ordered
    # a placeholder roll where a design is no roll, so every array keeps its length (NaN out at the end)
    first = int(np.argmax(good)) if good.any() else None
    if first is None:
        return _empty(study, n, status)
    pick = np.where(good, np.arange(n), first)
    L1, L1e, L3 = mem["L1"][pick], np.minimum(mem["L1e"], mem["L1"])[pick], mem["L3"][pick]
    geom = design_geometry(Ri=mem["Ri"][pick], Rie=radii[pick, 0], Roe=radii[pick, 1], Ro=radii[pick, 2], L1=L1,
                           L1e=L1e, L3=L3)
    over = {k: np.asarray(table[k], float)[pick] for k in ("C10", "C20", "C30", "eps_r") if k in table}
    mat = Material.of(study.params, **over)
    volt = np.asarray(table.get("voltage", np.full(n, study.voltage)), float)[pick]
    tab = {k: np.asarray(v, float)[pick] for k, v in table.items()}

    def roll_force(stretch, voltage):
        res = solve_designs(study.model, geom, mat, stretch[:, None], voltage[:, None])
        return res, res.force[:, 0]

    bias = _bias(study, tab, n)
    if "prestretch" in tab:
        lam_p = tab["prestretch"]
        f0 = roll_force(lam_p, np.zeros(n))[1]
        if study.bias.kind == "spring":
            k = bias.stiffness
            bias = SpringBias.model_construct(kind="spring", stiffness=k, preload=f0 + k * (lam_p - 1.0) * L1)
        else:
            bias = MassBias.model_construct(kind="mass", mass=f0 / G)

    def bias_force(stretch):
        # (n,) or (n, k) stretches; the bias's parameters are (n,): broadcast over the last axis
        return np.broadcast_to(bias.force(np.asarray(stretch).T, L1).T, np.shape(stretch))

    def excess(stretch, voltage, idx=None):
        # the roll's pull at the equilibrium at this stretch (negative where it would be slack: slack=False)
        # minus the bias's; (n,) or (n, k) stretches, or the designs idx
        g, m, v = (geom, mat, voltage) if idx is None else (*_subset(geom, mat, idx), voltage[idx])
        x = np.asarray(stretch, float)
        res = solve_designs(study.model, g, m, x if x.ndim == 2 else x[:, None], v[:, None], slack=False)
        pull = res.force if x.ndim == 2 else res.force[:, 0]
        return pull - (bias_force(x) if idx is None else bias_force_at(x, idx))

    def bias_force_at(stretch, idx):
        return np.asarray(_take_bias(bias, idx).force(stretch, L1[idx]), float) * np.ones_like(stretch)

    def equilibrium(voltage):
        lam, reach = _first_root(lambda x, idx=None: excess(x, voltage, idx), n)
        res = solve_designs(study.model, geom, mat, lam[:, None], voltage[:, None])
        return lam, reach, res

    zero = np.zeros(n)
    lam0, reach0, res0 = equilibrium(zero)
    lam1, reach1, res1 = equilibrium(volt)
    status[good & ~(reach0 & reach1)] = NO_EQUILIBRIUM
    model_ok = np.isin(res0.status[:, 0], VALID) & np.isin(res1.status[:, 0], VALID)
    status[(status == OK) & ~model_ok] = MODEL_FAILED
    # at the rest length, with and without the voltage: the blocking force
    res_b = solve_designs(study.model, geom, mat, np.stack([lam0, lam0], 1), np.stack([zero, volt], 1))
    # work on the bias over the stroke: Simpson's rule (exact for a spring or a mass)
    s = np.linspace(0.0, 1.0, _SIMPSON)
    lam_s = lam0[:, None] + (lam1 - lam0)[:, None] * s
    w = np.ones(_SIMPSON)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    work = (bias_force(lam_s) @ w) / (3.0 * (_SIMPSON - 1)) * (lam1 - lam0) * L1
    volume = geom.volume
    out = {
        "stroke": (lam1 - lam0) * L1, "strain": lam1 / lam0 - 1.0,
        "blocking_force": res_b.force[:, 0] - res_b.force[:, 1], "work": work, "energy_density": work / volume,
        "field": nominal_field(volt, res1.free_stretch[:, 0], res1.lambda2b[:, 0], L3),
        "stress": np.maximum(res0.sigma1[:, 0], res1.sigma1[:, 0]), "rest_stretch": lam0, "on_stretch": lam1,
        "rest_force": bias_force(lam0), "capacitance": res0.capacitance[:, 0], "outer_radius": geom.Ro,
        "volume": volume,
    }
    if study.bias.kind == "spring":
        out["preload"] = bias.preload
    elif study.bias.kind == "mass":
        out["bias_mass"] = bias.mass
    if study.density is not None:
        out["mass"] = volume * study.density
        out["specific_energy"] = work / out["mass"]
    if fixed.history is not None and protocol:
        out.update(_protocol(study, fixed.history, geom, mat, L1, L3))
        # a design the protocol could not test: its field estimate or its force past the protocol's limits
        status[(status == OK) & ~out.pop("within_limits")] = PROTOCOL_LIMITS
    out = {k: np.where(status == OK, np.asarray(out[k], float), np.nan) if k in out else np.full(n, np.nan)
           for k in study.metrics}
    out["design_status"] = status
    return out


#: stretches at which the equilibrium search first looks for the excess to turn positive
SCAN = np.linspace(1.0, MAX_STRETCH, 31)


def nominal_field(voltage, stretch, lambda2b, L3):
    """The nominal field ``v lambda1 lambda2b / L3`` [V/m] across the active film (thickness
    ``L3 / (lambda1 lambda2b)``); at a slack sample the roll's own (free) stretch, not the clamps'."""
    return voltage * stretch * lambda2b / L3


def _first_root(excess, n, rtol=1e-15, max_iter=100):
    """The first stretch above 1 where ``excess`` (the roll's pull minus the bias's) turns from negative to
    positive, every design at once: a scan on `SCAN` brackets it (a stable equilibrium: the excess rises
    through it; a later one, past a snap, is not the one the roll reaches from rest), then the Illinois
    variant of regula falsi refines it on the active designs, bisection where the secant leaves the bracket
    or the excess is NaN. Returns ``(stretch, reached)``; ``reached`` False where no node of the scan has a
    positive excess after a negative one (no equilibrium up to `MAX_STRETCH`)."""
    e = excess(np.broadcast_to(SCAN, (n, SCAN.size)))
    pos = e > 0
    at_rest = e[:, 0] >= 0  # in equilibrium at stretch 1 (nothing pulls)
    turn = ~pos[:, :-1] & pos[:, 1:]
    reached = at_rest | turn.any(axis=1)
    j = np.argmax(turn, axis=1)
    a, b = SCAN[j].copy(), SCAN[j + 1].copy()
    fa, fb = e[np.arange(n), j], e[np.arange(n), j + 1]
    x = np.where(at_rest, 1.0, b)
    active = np.flatnonzero(reached & ~at_rest)
    fa = np.where(np.isfinite(fa), fa, -np.abs(fb))  # a node without an equilibrium: bisect from it
    side = np.zeros(n, np.int8)
    scale = np.abs(fa) + np.abs(fb)
    iterations = 0
    for iterations in range(1, max_iter + 1):
        if active.size == 0:
            break
        xa, xb, ya, yb = a[active], b[active], fa[active], fb[active]
        with np.errstate(invalid="ignore", divide="ignore"):
            xn = (xa * yb - xb * ya) / (yb - ya)
        xn = np.where((xn > xa) & (xn < xb), xn, 0.5 * (xa + xb))
        yn = excess(xn, active)
        nan = ~np.isfinite(yn)
        if nan.any():
            xn = np.where(nan, 0.5 * (xa + xb), xn)
            yn = np.where(nan, excess(xn, active), yn)
            yn = np.where(np.isfinite(yn), yn, 1.0)  # no equilibrium there: search below
        neg = yn < 0
        s = side[active]
        a[active], fa[active] = np.where(neg, xn, xa), np.where(neg, yn, np.where(s == 1, 0.5 * ya, ya))
        b[active], fb[active] = np.where(neg, xb, xn), np.where(neg, np.where(s == -1, 0.5 * yb, yb), yn)
        side[active] = np.where(neg, -1, 1)
        x[active] = xn
        done = (np.abs(yn) <= 1e-14 * scale[active]) | (b[active] - a[active] <= rtol * b[active])
        active = active[~done]
    _first_root.iterations = iterations
    return x, reached


def _subset(geom, mat, idx):
    g = design_geometry(**{k: np.asarray(getattr(geom, k))[idx] for k in ("Ri", "Rie", "Roe", "Ro", "L1", "L1e",
                                                                           "L3")})
    m = Material(*(np.asarray(getattr(mat, k))[idx] if np.ndim(getattr(mat, k)) else getattr(mat, k)
                   for k in ("C10", "C20", "C30", "eps_r")))
    return g, m


def _take_bias(bias, idx):
    if bias.kind == "spring":
        return SpringBias.model_construct(kind="spring", stiffness=bias.stiffness[idx], preload=bias.preload[idx])
    if bias.kind == "mass":
        return MassBias.model_construct(kind="mass", mass=bias.mass[idx])
    return bias


def _protocol(study, history, geom, mat, L1, L3) -> dict:
    """Protocol metrics: the twin's force and capacitance over the protocol's history, every design."""
    t, stretch, voltage, _ = history
    res = solve_designs(study.model, geom, mat, stretch, voltage, path=True)  # the twin's path, each design's own
    col = RollGeometry(**{k: np.asarray(getattr(geom, k))[:, None] for k in ("Ri", "Rie", "Roe", "Ro", "L1",
                                                                                "L1e", "L3")})
    _, _, force, _ = compose(col, viscous(study.params), t, stretch, res.tension)
    with np.errstate(invalid="ignore"):
        field = nominal_field(voltage, res.free_stretch, res.lambda2b, L3[:, None])
    dx = np.diff(stretch) * L1[:, None]
    limits = history[3]
    estimate = np.max(field_estimate(voltage, stretch, L3[:, None]), axis=1)
    within = (estimate <= limits.max_field) & (np.max(force, axis=1) <= limits.max_force)
    return {"within_limits": within, "limit_field": estimate,
        "peak_force": np.max(force, axis=1), "force_range": np.ptp(force, axis=1),
        "hysteresis": 0.5 * np.sum((force[:, 1:] + force[:, :-1]) * dx, axis=1),
        "peak_field": np.max(field, axis=1), "peak_capacitance": np.max(res.capacitance, axis=1),
    }


def _empty(study, n, status):
    out = {k: np.full(n, np.nan) for k in study.metrics}
    out["design_status"] = status
    return out


def evaluate_chunk(fixed: Fixed, index, table: dict) -> dict:
    """One task: the designs ``index`` (their rows ``table``), nominal and, with tolerances, each
    Monte Carlo sample. Returns ``{metric: (n,)}``, ``{metric + '_mc': (n, samples)}`` and the statuses."""
    study = fixed.study
    out = evaluate(fixed, table)
    if study.mc_samples:
        n, m = len(index), study.mc_samples
        f = radii_factors(study, index)  # (n, m, 3)
        # the manufactured roll meets the bias set for the nominal one (a prestretch fixes the preload)
        table = dict(table)
        if "prestretch" in table:
            key = "preload" if study.bias.kind == "spring" else "bias_mass"
            table["preload" if key == "preload" else "mass"] = out[key]
            del table["prestretch"]
        rep = {k: np.repeat(np.asarray(v, float), m) for k, v in table.items()}
        mc = evaluate(fixed, rep, f.reshape(n * m, 3), protocol=protocol_needed(study))
        for k, v in mc.items():
            out[f"{k}_mc"] = np.asarray(v).reshape(n, m)
    return out
