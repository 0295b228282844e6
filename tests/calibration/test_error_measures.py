"""The error measures beside Table 4's (issue 13): max, rms and 99th percentile of |error|, over the peak."""

from pathlib import Path

import numpy as np
import pytest

from rdea_lab.calibration import error_measures, goodness
from rdea_lab.calibration.objective import RunData
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.specs import load_specimen

ROOT = Path(__file__).resolve().parents[2]


def test_one_outlier_by_hand():
    """99 zeros and one 10 over a peak of 4: max 10/4; rms sqrt(100/100) = 1, so 1/4; the 99th
    percentile with linear interpolation sits at rank 0.99 * 99 = 98.01, 1 % of the way from 0 to 10,
    so 0.1/4. The outlier dominates the maximum, not the other two."""
    r = np.zeros(100)
    r[37] = -10.0
    m = error_measures(r, 4.0)
    assert m["max_rel_error"] == pytest.approx(2.5, rel=1e-15)
    assert m["rms_rel_error"] == pytest.approx(0.25, rel=1e-15)
    assert m["p99_rel_error"] == pytest.approx(0.025, rel=1e-12)  # 98.01 - 98 in floating point


def test_against_numpy_formulas_on_a_hand_made_residual():
    r = np.sin(np.linspace(0, 7, 501)) * np.linspace(0.1, 2, 501)
    r[250] = 5.0
    peak = 3.5
    m = error_measures(r, peak)
    assert m["max_rel_error"] == np.max(np.abs(r)) / peak
    assert m["rms_rel_error"] == pytest.approx(np.sqrt(np.sum(r**2) / r.size) / peak, rel=1e-14)
    # 501 samples: the 99th percentile's rank is 0.99 * 500 = 495, a sample itself (no interpolation)
    assert m["p99_rel_error"] == pytest.approx(np.sort(np.abs(r))[495] / peak, rel=1e-12)
    assert m["max_rel_error"] >= m["p99_rel_error"] and m["max_rel_error"] >= m["rms_rel_error"]


def test_goodness_reports_all_three_beside_the_old_fields():
    card = load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "vhb4910_strip.yaml")
    t = np.linspace(0, 10, 201)
    force = 2.0 + np.sin(t)
    run = RunData(Path("<hand>"), "", "hand", "tensile", card.id, geometry_from_card(card), t, 1 + 0.01 * t,
                  np.zeros_like(t), force, float(np.max(np.abs(force))))
    predicted = force + 0.1 * np.cos(3 * t)
    g = goodness(run, predicted)
    r = predicted - force
    assert g["max_rel_error"] == pytest.approx(np.max(np.abs(r)) / np.max(np.abs(force)), rel=1e-14)
    assert g["rms_rel_error"] == pytest.approx(g["rms_error_N"] / run.peak, rel=1e-14)
    assert g["p99_rel_error"] == pytest.approx(np.percentile(np.abs(r), 99) / run.peak, rel=1e-14)
    assert {"file", "protocol", "specimen", "samples", "excluded_samples", "rms_error_N", "r2"} <= set(g)
