"""Preset settings of protocols: the paper's tensile, blocking-force and capacitance experiments.

Each settings model declares its settings (defaults, checks) and the preset's `duration` [s], so that a
protocol file is checked whole when it is read (its sample count too); `rdea_lab.protocols.presets`
expands valid settings into segments (which last that duration: tests/protocols/test_presets.py).
"""

from typing import NamedTuple, Union

from pydantic import model_validator

from .base import SpecModel
from .errors import SpecError
from .protocol_segments import Cycles, Duration, Frequency, Stretch, Voltage
from .units import format_quantity


# -------------------------------------------------------------- presets
class _StretchSweep(SpecModel):
    """Stretch settings shared by the tensile and capacitance presets."""

    min_stretch: Stretch = 1.0
    max_stretch: Stretch = 1.5
    frequency: Frequency = 0.1
    cycles: Cycles = 5
    settle: Duration = 2.0

    @property
    def duration(self) -> float:
        """The preset's duration [s]: ``settle``, ``cycles / frequency`` of sweep, ``settle``."""
        return 2.0 * self.settle + self.cycles / self.frequency

    @model_validator(mode="after")
    def _ordered(self):
        if not self.max_stretch > self.min_stretch:
            raise SpecError(
                "", "max_stretch",
                f"max_stretch {self.max_stretch:g} is not above min_stretch {self.min_stretch:g}",
            )
        return self


class TensileRampSineSettings(_StretchSweep):
    """Settings of the ``tensile_ramp_sine`` preset (SI; Section 4.2, Figs. 11-13 of [1])."""

    voltage: Voltage = 0.0


class CapacitanceSweepSettings(_StretchSweep):
    """Settings of the ``capacitance_sweep`` preset: the tensile ramp sine at 0 V (Fig. 16 of [1])."""


class BlockingForceSettings(SpecModel):
    """Settings of the ``blocking_force`` preset (SI; Section 4.2, Fig. 15 of [1])."""

    stretch: Stretch = 1.5
    voltage_min: Voltage = 0.0
    voltage_max: Voltage = 2.6e3
    frequency: Frequency = 1.0
    cycles: Cycles = 10
    approach: Duration = 5.0
    settle: Duration = 5.0

    @property
    def duration(self) -> float:
        """The preset's duration [s]: ``approach``, ``settle`` plus ``cycles / frequency`` of sine, ``approach``."""
        return 2.0 * self.approach + (self.settle + self.cycles / self.frequency)

    @model_validator(mode="after")
    def _ordered(self):
        if self.voltage_max < self.voltage_min:
            raise SpecError(
                "", "voltage_max",
                f"voltage_max {format_quantity(self.voltage_max, 'kV')} is below "
                f"voltage_min {format_quantity(self.voltage_min, 'kV')}",
            )
        return self


class PresetSchema(NamedTuple):
    """What the specs layer knows of a preset: its kind, settings model, default measure."""

    kind: str
    settings: type[SpecModel]
    measure: tuple[str, ...]


PRESETS: dict[str, PresetSchema] = {
    "tensile_ramp_sine": PresetSchema("tensile", TensileRampSineSettings, ("force",)),
    "blocking_force": PresetSchema("blocking", BlockingForceSettings, ("force",)),
    "capacitance_sweep": PresetSchema("capacitance", CapacitanceSweepSettings, ("force", "capacitance")),
}
Settings = Union[TensileRampSineSettings, BlockingForceSettings, CapacitanceSweepSettings]


