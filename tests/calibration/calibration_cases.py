"""What several calibration tests share: the paper's specimen 2 runs (the committed datasets) and Table 3."""

from pathlib import Path

from rdea_lab.specs import load_params

ROOT = Path(__file__).resolve().parents[2]
SPECIMEN2 = ROOT / "datasets" / "paper2021" / "specimen-2"
TABLE3 = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
