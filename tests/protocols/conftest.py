"""Helpers for the protocol tests: build small protocols from segment lists."""

import pytest

from rdea_lab.protocols import expand
from rdea_lab.specs import protocol_from_mapping


def make_plan(stretch, voltage, rate="100 Hz", **top):
    """A plan from YAML-form segment lists (quantities as strings with units)."""
    mapping = {"name": "t", "kind": "custom", "sample_rate": rate, "stretch": stretch, "voltage": voltage, **top}
    return expand(protocol_from_mapping(mapping, "<test>"))


@pytest.fixture
def plan_of():
    return make_plan
