"""Where the tests find the real VHB 4910 files, and what they say when the files are not there.

The files are raw tensile-machine exports from the public GitHub repository Chongran-Zhao/VHB4910_data
(https://github.com/Chongran-Zhao/VHB4910_data, folder uniaxial-loading-unloading/original_data; data by its
authors, no licence stated, so they are not copied into this repository). The tests expect them in
``../shared/data/vhb4910`` beside the checkout (the folder's README says which files and what they are).
"""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The shared VHB 4910 folder, beside the checkout.
VHB = ROOT.parent / "shared" / "data" / "vhb4910"
#: The five loading-unloading exports, ``0dRR_SdS[_k].csv`` (rate 0.RR 1/s to stretch S.S). The folder also
#: holds a step-and-hold test (relax_2d0.csv), which the loading-unloading tests are not about.
LOADING_UNLOADING = sorted(VHB.glob("0d*.csv")) if VHB.is_dir() else []
#: Why a test that needs the files is skipped.
MISSING = (f"needs the real VHB 4910 data in {VHB}, which is absent: put the CSV files of the public GitHub "
           f"repository Chongran-Zhao/VHB4910_data (uniaxial-loading-unloading/original_data/0d*.csv) there, "
           f"beside the checkout")
needs_vhb = pytest.mark.skipif(not LOADING_UNLOADING, reason=MISSING)
