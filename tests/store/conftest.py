"""Fixtures of the store's tests: a PostgreSQL database for the catalogue's tests.

`postgresql_url` here is a stand-in until the suite's own (tests/conftest.py, which starts a server) is
merged: it reads the URL of an empty database from RDEA_LAB_TEST_POSTGRESQL and skips without it.
"""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session")
def postgresql_url():
    url = os.environ.get("RDEA_LAB_TEST_POSTGRESQL", "").strip()
    if not url:
        pytest.skip("no PostgreSQL server: set RDEA_LAB_TEST_POSTGRESQL=postgresql://USER@HOST:PORT/DB to run this")
    return url
