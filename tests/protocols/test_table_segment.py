"""The ``table`` segment: sampled setpoints (a planned voltage), validated, rendered and written back exactly."""

import numpy as np
import pytest

from rdea_lab.protocols import expand
from rdea_lab.specs import SpecError
from rdea_lab.specs.protocol import dump_protocol, protocol_from_yaml

YAML = """
name: t
kind: custom
sample_rate: 10 Hz
stretch:
  - {kind: ramp, duration: 1 s, to: 1.2}
  - {kind: table, duration: 1 s, values: [1.2, 1.3, 1.25]}
voltage:
  - {kind: hold, duration: 1 s, value: 0 V}
  - {kind: table, duration: 1 s, unit: kV, values: [0, 1, 2.5]}
"""


def test_values_are_evenly_spaced_and_linear_in_between():
    plan = expand(protocol_from_yaml(YAML))
    # 3 values over 1 s at 10 Hz: 0, 1, 2.5 kV at 1.0, 1.5, 2.0 s; exact at the knots
    assert plan.voltage[10] == 0.0 and plan.voltage[15] == 1000.0 and plan.voltage[20] == 2500.0
    np.testing.assert_allclose(plan.voltage[16:20], [1300.0, 1600.0, 1900.0, 2200.0], rtol=1e-12)
    assert plan.stretch[15] == 1.3


def test_written_back_exactly():
    spec = protocol_from_yaml(YAML)
    values = (np.linspace(0.0, 2600.0, 7) / 3.0).tolist()  # floats with all their digits
    spec = protocol_from_yaml(YAML.replace("unit: kV, values: [0, 1, 2.5]",
                                           "unit: V, values: [" + ", ".join(repr(v) for v in values) + "]"))
    again = protocol_from_yaml(dump_protocol(spec))
    assert again == spec and again.voltage[1].values == tuple(values)


@pytest.mark.parametrize("bad, match", [
    ("{kind: table, duration: 1 s, values: [0, 1, 2.5]}", r"voltage\[1\]\.unit: missing"),
    ("{kind: table, duration: 1 s, unit: N, values: [0, 1]}", r"voltage\[1\]\.unit: 'N' is not allowed"),
    ("{kind: table, duration: 1 s, unit: V, values: [0, .nan]}", r"values\[1\]: .* not a finite number"),
    ("{kind: table, duration: 1 s, unit: V, values: [0, true]}", r"values\[1\]: True is not a number"),
    ("{kind: table, duration: 1 s, unit: V, values: [0]}", r"values: 1 values; allowed: 2 to"),
    ("{kind: table, duration: 1 s, unit: V, values: [0, '1 V']}", r"values\[1\]: .* not a plain number"),
    ("{kind: table, duration: 1 s, unit: V, values: 3}", r"values: expected a list"),
])
def test_bad_tables_are_refused(bad, match):
    with pytest.raises(SpecError, match=match) as info:
        protocol_from_yaml(YAML.replace("{kind: table, duration: 1 s, unit: kV, values: [0, 1, 2.5]}", bad), "f.yaml")
    assert str(info.value).startswith("f.yaml: ")


def test_stretch_table_stays_in_tension():
    with pytest.raises(SpecError, match=r"stretch\[1\]\.values\[1\]: stretch 0.9 is below 1"):
        protocol_from_yaml(YAML.replace("[1.2, 1.3, 1.25]", "[1.2, 0.9]"), "f.yaml")
