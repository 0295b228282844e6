"""Fixtures of the design-study tests: where the packaged parameter sets, cards and protocols are."""

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def root() -> Path:
    """The packaged reference inputs (``rdea_lab/data``: params/, specimens/, protocols/)."""
    return Path(__file__).resolve().parents[2] / "rdea_lab" / "data"
