"""Fixtures of the design-study tests: where the project's parameter sets, cards and protocols are."""

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def root() -> Path:
    """The project root (the folder holding params/, specimens/, protocols/), found from this file."""
    here = Path(__file__).resolve()
    for folder in here.parents:
        if (folder / "params" / "paper2021_table3.yaml").is_file() and (folder / "specimens").is_dir():
            return folder
    raise RuntimeError(f"no project root above {here}")
