"""The shared VHB 4910 files (../shared/data), imported once for the calibration tests that use them."""

from pathlib import Path

import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli

ROOT = Path(__file__).resolve().parents[2]
VHB = ROOT.parent / "shared" / "data" / "vhb4910"


@pytest.fixture(scope="session")
def imported(tmp_path_factory):
    """A folder of the five VHB files as datasets, imported as the README shows."""
    if not VHB.is_dir():
        pytest.skip(f"{VHB} (the shared real-data folder) is absent")
    out = tmp_path_factory.mktemp("vhb")
    rc = run_cli(cli, ["import", *map(str, sorted(VHB.glob("*.csv"))), "--format", "csv", "--map",
                       "time=0,position=1,force=2", "--protocol-kind", "tensile", "--specimen",
                       str(ROOT / "specimens" / "vhb4910_strip.yaml"), "--credit",
                       "Chongran-Zhao/VHB4910_data (GitHub)", "--out", str(out)])
    assert rc == 0
    return out
