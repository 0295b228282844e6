"""Shared fixtures of the physics tests (the materials and geometries: `physics_cases`)."""

import pytest

from physics_cases import CORES, core


@pytest.fixture(params=sorted(CORES))
def any_core(request):
    return core(request.param)
