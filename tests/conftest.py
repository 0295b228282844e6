"""Fixtures for every test.

No backend is chosen here: without a DISPLAY matplotlib picks Agg by itself.
"""

import sys

import pytest


@pytest.fixture(autouse=True)
def _close_figures():
    """Close every pyplot figure a test left open (pyplot imported only if the test did)."""
    yield
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")
