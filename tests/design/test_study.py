"""`rdea_lab.design.study`: a study's result does not depend on where it ran; Pareto, sampling, errors.

The required test runs one small study (Monte Carlo tolerances, Sobol
sensitivity, an optimization, a constraint) twice, in this process with dask's
synchronous scheduler and on a LocalCluster of two spawned worker processes,
and wants identical datasets. The rest check the pieces against independent
references: the Pareto front against a brute-force O(n^2) dominance check,
the samplers against the properties that define them, and each way a study
file can be wrong against its one-line SpecError.
"""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr
import yaml

from rdea_lab.design import SchedulerError, StudyError, evaluate_table, pareto, run_study, sample
from rdea_lab.design.study import table_of
from rdea_lab.specs import SpecError
from rdea_lab.specs.study import Goal, load_study


def study_mapping(root, **changes):
    """A small spring study on specimen 2 (absolute paths); ``changes`` replace keys (None drops one)."""
    m = {
        "name": "small",
        "model": "su",
        "params": str(root / "params" / "paper2021_table3.yaml"),
        "specimen": str(root / "specimens" / "specimen2.yaml"),
        "variables": {"L1": ["20 mm", "60 mm"], "L3": ["30 um", "80 um"], "stiffness": ["50 N/m", "500 N/m"]},
        "sampling": {"method": "sobol", "n": 32, "seed": 1},
        "voltage": "2.6 kV",
        "bias": {"kind": "spring", "stiffness": "200 N/m", "preload": "1 N"},
        "objectives": [{"maximize": "stroke"}, {"maximize": "blocking_force"}],
        "chunk": 8,
    }
    for k, v in changes.items():
        if v is None:
            m.pop(k, None)
        else:
            m[k] = v
    return m


def write_study(tmp_path, mapping, name="study.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(mapping, sort_keys=False), encoding="utf-8")
    return path


# ------------------------------------------------------------------ the required test
@pytest.mark.slow
def test_synchronous_and_two_workers_give_identical_datasets(root, tmp_path, monkeypatch):
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)  # a local cluster, not someone's scheduler
    # 32 designs in 4 chunks of 8, 3 Monte Carlo rolls each, and Saltelli's 8 (2 + 2) = 32 for the indices:
    # small, since most of the time is the cluster's start and its workers' first imports (~6 s of ~10 s).
    # No optimize: it runs in the client either way, so it says nothing about where the tasks ran.
    path = write_study(tmp_path, study_mapping(
        root, variables={"L1": ["20 mm", "60 mm"], "stiffness": ["50 N/m", "500 N/m"]},
        constraints={"field": {"max": "80 V/um"}}, tolerances={"radii": "1 %", "samples": 3, "seed": 7},
        sensitivity={"n": 8, "seed": 3}))
    study = load_study(path)
    local = run_study(study, synchronous=True)
    cluster = run_study(study, workers=2)
    ds = local.dataset
    # the study did what it was asked to: the designs, the Monte Carlo, the indices
    assert ds.sizes["design"] == 32 and ds.sizes["mc"] == 3 and ds.sizes["variable"] == 2
    assert {"stroke_mc", "stroke_mean", "feasible_fraction", "sobol_S1", "sobol_ST"} <= set(ds.data_vars)
    assert int(ds["feasible"].sum()) > 0 and int(ds["pareto"].sum()) > 0
    assert np.isfinite(ds["sobol_ST"].values).all()
    xr.testing.assert_identical(local.dataset, cluster.dataset)


def test_chunk_size_changes_nothing_but_rounding(root, tmp_path):
    """Each design's Monte Carlo rolls are seeded by its own index, not its chunk's: chunks of 8 or of 3
    give the same metrics (to rounding: each chunk maps its rolls onto its own first roll, 1e-12)."""
    mapping = study_mapping(root, sampling={"method": "sobol", "n": 8, "seed": 2},
                            tolerances={"radii": "2 %", "samples": 3, "seed": 5})
    a = load_study(write_study(tmp_path, mapping, "a.yaml"))
    b = load_study(write_study(tmp_path, dict(mapping, chunk=3), "b.yaml"))
    table = table_of(a, sample(a))
    ma, mb = evaluate_table(a, table), evaluate_table(b, table)
    assert set(ma) == set(mb) and "stroke_mc" in ma
    for key in ma:
        if key.startswith("design_status"):
            np.testing.assert_array_equal(ma[key], mb[key])
        else:
            np.testing.assert_allclose(ma[key], mb[key], rtol=1e-12, atol=0, err_msg=key)
    # and the Monte Carlo rolls do differ from each other (a roll whose drawn radii are out of order is NaN)
    mc = ma["outer_radius_mc"]
    assert np.all(np.nanmax(mc, axis=1) > np.nanmin(mc, axis=1))


# ------------------------------------------------------------------ Pareto front
def dominated_brute_force(y):
    """y: (n, k), larger is better. Point i is dominated if some j is >= in every objective and > in one."""
    n = len(y)
    out = np.zeros(n, bool)
    for i in range(n):
        for j in range(n):
            if j != i and np.all(y[j] >= y[i]) and np.any(y[j] > y[i]):
                out[i] = True
                break
    return out


@pytest.mark.parametrize("senses", [(1, 1), (1, -1), (-1, 1, 1), (1, -1, -1)])
@pytest.mark.parametrize("seed", range(4))
def test_pareto_equals_brute_force_dominance(senses, seed):
    rng = np.random.default_rng([seed, len(senses), senses[1] + 2])
    n = 60
    names = [f"m{j}" for j in range(len(senses))]
    # small integers: many ties in single objectives and some fully duplicated points
    metrics = {name: rng.integers(0, 6, n).astype(float) for name in names}
    if seed % 2:
        metrics = {name: v + rng.normal(0, 1e-3, n) * (rng.random(n) < 0.5) for name, v in metrics.items()}
    study = SimpleNamespace(objectives=tuple(Goal(name, s) for name, s in zip(names, senses)))
    mask = rng.random(n) < 0.8
    got = pareto(study, metrics, mask)
    y = np.stack([s * metrics[name] for name, s in zip(names, senses)], axis=1)
    idx = np.flatnonzero(mask)
    expected = np.zeros(n, bool)
    expected[idx] = ~dominated_brute_force(y[idx])
    np.testing.assert_array_equal(got, expected)
    assert not got[~mask].any()
    if seed % 2 == 0:  # integers: duplicates exist; a duplicated optimum is kept twice
        assert len({tuple(r) for r in y[idx]}) < idx.size


def test_pareto_of_nothing_feasible_is_empty():
    study = SimpleNamespace(objectives=(Goal("a", 1),))
    assert not pareto(study, {"a": np.arange(5.0)}, np.zeros(5, bool)).any()


# ------------------------------------------------------------------ sampling
def test_grid_sampling_is_the_product_of_levels_and_covers_the_bounds(root, tmp_path):
    path = write_study(tmp_path, study_mapping(
        root, sampling={"method": "grid"},
        variables={"L1": {"range": ["20 mm", "60 mm"], "levels": 3}, "L3": {"range": ["30 um", "80 um"], "levels": 4},
                   "stiffness": {"range": ["10 N/m", "1000 N/m"], "levels": 3, "scale": "log"}}))
    study = load_study(path)
    unit = sample(study)
    assert unit.shape == (3 * 4 * 3, 3) and study.n == 36
    table = table_of(study, unit)
    for name, levels in (("L1", np.linspace(20e-3, 60e-3, 3)), ("L3", np.linspace(30e-6, 80e-6, 4)),
                         ("stiffness", np.array([10.0, 100.0, 1000.0]))):  # the log scale: geometric levels
        np.testing.assert_allclose(np.unique(table[name]), levels, rtol=1e-12)
    # every combination exactly once
    assert len({tuple(r) for r in unit}) == 36


@pytest.mark.parametrize("method", ["lhs", "sobol"])
def test_lhs_and_sobol_are_in_bounds_stratified_and_reproducible(root, tmp_path, method):
    n = 64
    study = load_study(write_study(tmp_path, study_mapping(root, sampling={"method": method, "n": n, "seed": 11})))
    unit = sample(study)
    assert unit.shape == (n, 3)
    assert np.all((unit >= 0.0) & (unit < 1.0))
    # both stratify each variable: one point in each of the n equal intervals (LHS by construction; the
    # first 2**m points of a scrambled Sobol sequence are a (0, m, 1)-net in every coordinate)
    for j in range(3):
        np.testing.assert_array_equal(np.sort(np.floor(unit[:, j] * n)), np.arange(n))
    table = table_of(study, unit)
    for v in study.variables:
        assert np.all((table[v.name] >= v.low) & (table[v.name] <= v.high)), v.name
    np.testing.assert_array_equal(sample(study), unit)  # same seed, same designs
    again = load_study(write_study(tmp_path, study_mapping(root, sampling={"method": method, "n": n, "seed": 11}),
                                   "again.yaml"))
    np.testing.assert_array_equal(sample(again), unit)
    assert not np.array_equal(sample(study, seed=12), unit)


# ------------------------------------------------------------------ study file errors
BAD = [
    ("unknown variable", dict(variables={"L9": ["1 mm", "2 mm"]}), "variables.L9", r"unknown variable"),
    ("empty range", dict(variables={"L1": ["30 mm", "30 mm"]}), "variables.L1", r"empty range"),
    ("inverted bounds", dict(variables={"L1": ["60 mm", "20 mm"]}), "variables.L1", r"inverted bounds"),
    ("L3 below a card's", dict(variables={"L3": ["1e-200 m", "2e-200 m"]}), "variables.L3[0]",
     r"1e-194 um is smaller than any real L3 \(0\.1 um at least"),
    ("L1 below a card's", dict(variables={"L1": ["0.5 um", "20 mm"]}), "variables.L1[0]",
     r"smaller than any real L1 \(0\.001 mm at least"),
    ("unknown metric", dict(objectives=[{"maximize": "speed"}]), "objectives[0].maximize", r"unknown metric"),
    ("unknown key", dict(colour="red"), "colour", r"unknown key"),
    ("missing voltage", dict(voltage=None), "voltage", r"missing"),
    ("prestretch with no bias", dict(bias={"kind": "none"}, variables={"prestretch": [1.05, 1.5]}),
     "variables.prestretch", r"not a variable of a none bias"),
    ("protocol metric without protocol", dict(objectives=[{"maximize": "peak_force"}]), "objectives",
     r"peak_force is a protocol's metric"),
]


@pytest.mark.parametrize("what, changes, field, match", BAD, ids=[b[0] for b in BAD])
def test_bad_study_files_name_the_file_and_the_field(root, tmp_path, what, changes, field, match):
    path = write_study(tmp_path, study_mapping(root, **changes))
    with pytest.raises(SpecError, match=match) as info:
        load_study(path)
    text = str(info.value)
    assert info.value.field == field
    assert text.startswith(f"{path}: {field}: "), text
    assert "\n" not in text


# ------------------------------------------------------------------ run errors
def test_constraints_nothing_meets_raise_study_error(root, tmp_path):
    # specimen 2's outer radius is 1.7 mm and L3 (30-80 um) only grows or shrinks it by its square root
    path = write_study(tmp_path, study_mapping(root, constraints={"outer_radius": {"max": "0.1 mm"}},
                                               sampling={"method": "sobol", "n": 8, "seed": 1}))
    with pytest.raises(StudyError, match=r"constraints: no design of the 8 sampled meets them") as info:
        run_study(load_study(path), synchronous=True)
    assert str(path) in str(info.value) and "outer_radius spans" in str(info.value)


@pytest.mark.slow  # the CLI tests (tests/cli/test_design.py) check the same path with its exit status
def test_unreachable_scheduler_raises_scheduler_error_quickly(root, tmp_path):
    study = load_study(write_study(tmp_path, study_mapping(root)))
    t0 = time.monotonic()
    with pytest.raises(SchedulerError, match=r"tcp://127\.0\.0\.1:9"):
        run_study(study, scheduler="tcp://127.0.0.1:9")  # port 9 (discard) on loopback: nothing listens
    assert time.monotonic() - t0 < 8.0


def test_malformed_scheduler_address_raises_scheduler_error(root, tmp_path):
    study = load_study(write_study(tmp_path, study_mapping(root)))
    with pytest.raises(SchedulerError, match=r"'localhost:8786' is not a scheduler address; give tcp://HOST:PORT"):
        run_study(study, scheduler="localhost:8786")


def test_result_is_frozen_and_its_tables_and_files_come_from_its_dataset(root, tmp_path):
    """`StudyResult`: the front table holds exactly the dataset's Pareto designs, best first, the Sobol
    table the dataset's indices, and ``write`` returns the files that are in the folder afterwards (and
    refuses to write over them)."""
    import csv
    import dataclasses
    import json

    study = load_study(write_study(tmp_path, study_mapping(
        root, variables={"L1": ["20 mm", "60 mm"], "stiffness": ["50 N/m", "500 N/m"]},
        sampling={"method": "sobol", "n": 16, "seed": 1}, sensitivity={"n": 8, "seed": 3})))
    result = run_study(study, synchronous=True)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.card = None
    ds = result.dataset
    assert sorted(result.front["design"]) == list(np.flatnonzero(ds["pareto"].values))
    first = study.objectives[0]
    from rdea_lab.specs.study import METRICS

    shown = result.front[f"{first.metric} [{METRICS[first.metric][0]}]"].to_numpy()
    assert (np.diff(first.sense * shown) <= 0).all()  # best first by the first objective
    sobol = result.sobol
    assert len(sobol) == ds.sizes["objective"] * ds.sizes["variable"]
    for row in sobol.itertuples():
        assert row.ST == float(ds["sobol_ST"].sel(objective=row.objective, variable=row.variable))
    out = tmp_path / "out"
    files = result.write(out, figures=False)
    assert sorted(files) == sorted(p.name for p in out.iterdir())
    assert all(p == out / name for name, p in files.items())
    assert json.loads(files["summary.json"].read_text()) == json.loads(json.dumps(result.summary(), default=float))
    with open(files["pareto.csv"], newline="") as fh:
        assert [int(r["design"]) for r in csv.DictReader(fh)] == list(result.front["design"])
    with pytest.raises(SpecError, match="already holds study.nc"):
        result.write(out)
    assert result.lines()[0].startswith(f"study {study.name}: 16 designs")
