"""Tests of rdea_lab.specs.units: quantities with units to SI floats and back."""

from decimal import Decimal

import pytest
from hypothesis import given, strategies as st

from rdea_lab.specs import SpecError, format_quantity, parse_quantity


def parse(value, dimension):
    return parse_quantity(value, dimension, source="test.yaml", field="x")


# Decimal prefixes are applied in decimal arithmetic, so the result is the
# float nearest to the exact SI value: the same float Python makes from the
# literal on the right. Exact equality is therefore the right tolerance.
@pytest.mark.parametrize(
    "text, dimension, si",
    [
        ("48 um", "length", 48e-6),
        ("48 µm", "length", 48e-6),  # U+00B5 micro sign
        ("48 μm", "length", 48e-6),  # U+03BC greek mu
        ("48um", "length", 48e-6),
        ("1.8 mm", "length", 1.8e-3),
        ("0.81 mm", "length", 0.81e-3),
        ("1e-3 m", "length", 1e-3),
        ("242 kPa", "pressure", 242e3),
        ("-69 kPa", "pressure", -69e3),
        ("-33.2 kPa", "pressure", -33.2e3),
        ("8271 kPa", "pressure", 8271e3),
        ("86 kPa s", "viscosity", 86000.0),
        ("86 kPa*s", "viscosity", 86000.0),
        ("86 kPa·s", "viscosity", 86000.0),
        ("2.6 kV", "voltage", 2600.0),
        ("3.5 kV", "voltage", 3500.0),
        ("0.1 Hz", "frequency", 0.1),
        ("10 ms", "time", 0.01),
        ("1 min", "time", 60.0),
        ("1.5 N", "force", 1.5),
        ("100 pF", "capacitance", 1e-10),
        ("50 V/um", "electric_field", 5e7),
        (2.8, "dimensionless", 2.8),
        (3, "dimensionless", 3.0),
        ("2.8", "dimensionless", 2.8),
        ("280 %", "dimensionless", 2.8),
    ],
)
def test_parse_to_si(text, dimension, si):
    value = parse(text, dimension)
    assert type(value) is float
    assert value == si


def test_non_decimal_unit():
    # 1 inch = 25.4 mm by definition; one multiplication, so one rounding
    assert parse("1 inch", "length") == pytest.approx(0.0254, rel=1e-15)


def test_error_names_source_field_and_allowed_unit():
    with pytest.raises(SpecError) as info:
        parse_quantity("48 kg", "length", source="specimens/x.yaml", field="membrane.L3", example_unit="um")
    err = info.value
    assert (err.source, err.field) == ("specimens/x.yaml", "membrane.L3")
    assert str(err) == (
        "specimens/x.yaml: membrane.L3: '48 kg' is not a length; give it with a length unit, e.g. '48 um'"
    )


@pytest.mark.parametrize(
    "value, dimension, match",
    [
        (34, "length", r"'34' has no unit; give a length, e.g. '34 mm'"),
        ("34", "length", r"'34' has no unit; give a length, e.g. '34 mm'"),
        (242000.0, "pressure", r"has no unit; give a pressure"),
        (True, "length", r"True is not a quantity"),
        (False, "dimensionless", r"False is not a quantity"),
        (None, "length", r"no value given; give a length"),
        ([48], "length", r"\[48\] is not a quantity"),
        ("abc", "length", r"'abc' is not a number followed by a unit"),
        ("mm", "length", r"'mm' is not a number followed by a unit"),
        ("nan mm", "length", r"'nan mm' is not a finite number"),
        ("-inf kPa", "pressure", r"is not a finite number"),
        ("1e400 m", "length", r"is not a finite number"),
        ("1e306 km", "length", r"is not a finite number"),  # finite text, overflows in SI
        (float("nan"), "dimensionless", r"nan is not a finite number"),
        (float("inf"), "dimensionless", r"inf is not a finite number"),
        ("48 kg", "length", r"'48 kg' is not a length; give it with a length unit"),
        ("48 foo", "length", r"unknown unit 'foo'"),
        ("48 m)", "length", r"'m\)' is not a unit"),
        ("48 m/0", "length", r"'m/0' is not a unit"),
        ("3 kV*10**10**10", "voltage", r"is not a unit .*no arithmetic"),  # pint would evaluate it for ever
        ("3 kV*1e300", "voltage", r"is not a unit"),
        ("86 kPa", "viscosity", r"is not a viscosity \(pressure times time\)"),
        ("2.8 kPa", "dimensionless", r"is not a dimensionless number; give a plain number"),
        ("1 rad/s", "frequency", r"angle unit"),
        ("60 rpm", "frequency", r"angle unit"),
    ],
)
def test_parse_errors(value, dimension, match):
    with pytest.raises(SpecError, match=match) as info:
        parse(value, dimension)
    assert str(info.value).startswith("test.yaml: x: ")
    assert "\n" not in str(info.value)


def test_unknown_dimension_is_a_programming_error():
    with pytest.raises(ValueError, match="unknown dimension 'luminosity'"):
        parse("1 cd", "luminosity")


@pytest.mark.parametrize(
    "value, unit, text",
    [
        (242000.0, "kPa", "242 kPa"),
        (-69000.0, "kPa", "-69 kPa"),
        (4.8e-5, "um", "48 um"),
        (0.034, "mm", "34 mm"),
        (0.0, "mm", "0 mm"),
        (86000.0, "kPa s", "86 kPa s"),
        (2600.0, "kV", "2.6 kV"),
        (2.8, "", "2.8"),
    ],
)
def test_format_quantity(value, unit, text):
    assert format_quantity(value, unit) == text


def test_format_quantity_fixed_digits_for_messages():
    assert format_quantity(-85205.6336, "kPa", digits=4) == "-85.21 kPa"


def test_format_quantity_unknown_unit_kind():
    with pytest.raises(ValueError, match="matches none"):
        format_quantity(1.0, "cd")


_UNITS = {"mm": "length", "um": "length", "kPa": "pressure", "kPa s": "viscosity",
          "kV": "voltage", "pF": "capacitance", "Hz": "frequency", "": "dimensionless"}


@given(
    value=st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False),
    unit=st.sampled_from(sorted(_UNITS)),
)
def test_format_then_parse_round_trips_exactly(value, unit):
    text = format_quantity(value, unit)
    assert parse(text, _UNITS[unit]) == value
    assert "\n" not in text


@given(st.floats(min_value=1e-9, max_value=1e3))
def test_parse_is_exact_for_short_decimals(x):
    # a 6-digit decimal in mm parses to the float nearest to its SI value
    text = f"{x:.6g}"
    nearest = float(str(Decimal(text).scaleb(-3)))  # exact shift, then one correctly rounded conversion
    assert parse(f"{text} mm", "length") == nearest


def test_the_unit_registry_is_built_on_first_use_only():
    """Importing the specs (every ``rdea-lab`` command does) builds no pint registry; the first quantity does,
    and it is the one registry: pint refuses to mix quantities of two registries."""
    import subprocess
    import sys

    code = ("import sys; import rdea_lab.specs as s; assert 'pint' not in sys.modules, 'pint at import'; "
            "from rdea_lab.specs.units import ureg, unit_registry; "
            "assert s.parse_quantity('2.6 kV', 'voltage', source='', field='') == 2600.0; "
            "import pint; r = unit_registry(); assert isinstance(r, pint.UnitRegistry) and r is ureg.get(); "
            "q = ureg.Quantity(1.0, 'mm') + r.Quantity(1.0, 'm'); "
            "assert q.to('mm').magnitude == 1001.0")  # exact in floats
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


# ------------------------------------------------------------ temperature
@pytest.mark.parametrize("text, kelvin", [
    ("60 degC", 333.15), ("60 °C", 333.15), ("333 K", 333.0), ("0 K", 0.0), ("-40 degC", 233.15),
])
def test_temperature_is_kelvin_and_degc_an_offset_unit(text, kelvin):
    # 60 degC = 60 + 273.15 K: a factor would give 60 K (or 60 * 274.15); the offset is exact in decimals,
    # so only the float rounding of the sum is allowed
    assert parse(text, "temperature") == pytest.approx(kelvin, rel=1e-15, abs=0)


def test_temperature_in_fahrenheit():
    assert parse("140 degF", "temperature") == pytest.approx(333.15, rel=1e-12)  # (140 - 32) * 5/9 + 273.15


def test_a_temperature_writes_back_in_degc_and_round_trips():
    assert format_quantity(333.15, "degC") == "60 degC"
    assert parse(format_quantity(300.0, "degC"), "temperature") == 300.0


@pytest.mark.parametrize("text, match", [
    ("60 delta_degC", r"a temperature difference"),
    ("-300 degC", r"below absolute zero"),
    ("60 C", r"'60 C' is not a temperature"),  # coulomb
    ("60", r"has no unit; give a temperature, e.g. '60 degC'"),
])
def test_bad_temperatures(text, match):
    with pytest.raises(SpecError, match=rf"^test\.yaml: x: .*{match}"):
        parse(text, "temperature")


def test_voltage_rate():
    assert parse("1 kV/s", "voltage_rate") == 1000.0
    assert parse("500 V/s", "voltage_rate") == 500.0
    with pytest.raises(SpecError, match=r"'1000' has no unit; give a voltage rate, e.g. '1000 V/s' or '1 kV/s'"):
        parse(1000, "voltage_rate")
    with pytest.raises(SpecError, match=r"'1 kV' is not a voltage rate \(voltage per time\)"):
        parse("1 kV", "voltage_rate")
