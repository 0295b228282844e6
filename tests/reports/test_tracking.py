"""Tracking error of a blocking-force plan run on the built-in emulated rig (stretch-controlled: the planned
voltage at the fixed stretch, the measured force against the target force)."""

from pathlib import Path

from rdea_lab.reports.tracking import track_target
from rdea_lab.specs.target import target_from_mapping

ROOT = Path(__file__).resolve().parents[2]
BLOCKING = {"name": "blk", "target": "force", "stretch": 1.5, "sample_rate": "100 Hz", "approach": "5 s",
            "settle": "2 s", "samples": {"units": {"time": "s", "force": "N"}, "time": [0, 1, 2, 3],
                                         "force": [4.15, 3.95, 3.95, 4.15]}}


def test_blocking_plan_on_the_emulator_within_the_stated_error(tmp_path):
    r = track_target(target_from_mapping(BLOCKING, "blk.yaml"),
                     ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml",
                     ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml", out=tmp_path / "r.nc")
    assert r["plan"].twin_error < 1e-6
    t = r["tracking"]
    # Measured (seeds 0, 1, 2): rms 129 mN, max 175-180 mN, mean +126 mN: the emulated roll at stretch 1.5
    # pulls harder than the SU twin with Table 3 and its slow 1.5 s branch (absent from Table 3) still relaxes
    # 7 s after the approach (truth/paper2021.yaml). A third of margin over the measured figures, no more.
    assert t["samples"] == 301 and t["force_error_rms_N"] < 0.17 and t["force_error_max_N"] < 0.24
    assert 0.0 < t["force_error_mean_N"]  # the sign of the model error: the twin underestimates the force
