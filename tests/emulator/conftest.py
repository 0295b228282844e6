"""Fixtures of the emulator tests: the shipped specimen card and truth, and a quiet truth."""

import pytest

from rdea_lab.specs import load_specimen
from rdea_lab.specs.truth import load_truth

from .helpers import ROOT, quiet_truth


@pytest.fixture(scope="session")
def card():
    return load_specimen(ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml")


@pytest.fixture(scope="session")
def truth():
    return load_truth(ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml")


@pytest.fixture(scope="session")
def quiet(truth):
    return quiet_truth(truth)
