"""Named presets: the paper's experiments as explicit segments.

Section 4.2 of [1]: tensile tests up to lambda1 = 1.5 at 0.1 Hz with a sine
whose amplitude grows along a ramp, at 0 V and 2.6 kV (Figs. 11-13);
blocking force at lambda1 = 1.5 under a 0-2.6 kV sine at 1 Hz (Fig. 15);
capacitance at 0 V over the tensile test (Fig. 16).

The settings (names, defaults, checks) and each preset's duration are
declared in `rdea_lab.specs.protocol.PRESETS`, so a file with an unknown
preset or setting, or one whose expansion would hold too many samples, fails
when it is read; this module only turns valid settings into segments.

[1] J. Prechtl et al., Smart Mater. Struct. (2021), doi:10.1088/1361-665X/ac34be.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ..specs.protocol import (
    PRESETS,
    BlockingForceSettings,
    CapacitanceSweepSettings,
    ProtocolSpec,
    StretchHold,
    StretchRamp,
    StretchRampSine,
    TensileRampSineSettings,
    VoltageHold,
    VoltageRamp,
    VoltageSine,
)

Channels = tuple[tuple, tuple]


def _ramp_sine_stretch(s: TensileRampSineSettings | CapacitanceSweepSettings) -> tuple:
    """Hold, ramp sine, hold: cycle k (0-based) tops out at min + (k + 1) (max - min) / cycles.

    The ramp sine's peak(t) is linear over the segment and the tops sit at
    t = (k + 1/2) / f, so peak_start and peak_end lie half a cycle's step
    outside the first and last tops: peak_start = min + step / 2,
    peak_end = max + step / 2 with step = (max - min) / cycles. The last
    sampled top is then max_stretch; because the amplitude keeps growing past
    each top, the continuous maximum is higher by about
    (max - min) / (4 pi^2 cycles^2) (5e-4 for the defaults).
    """
    step = (s.max_stretch - s.min_stretch) / s.cycles
    return (
        StretchHold(duration=s.settle, value=s.min_stretch),
        StretchRampSine(
            duration=s.cycles / s.frequency, frequency=s.frequency, base=s.min_stretch,
            peak_start=s.min_stretch + 0.5 * step, peak_end=s.max_stretch + 0.5 * step,
        ),
        StretchHold(duration=s.settle, value=s.min_stretch),
    )


def tensile_ramp_sine(s: TensileRampSineSettings) -> Channels:
    """Tensile test (Figs. 11-13 of [1]): the ramp sine stretch at a constant voltage.

    Voltage: ramp 0 -> voltage during the first settle, hold, ramp back to
    0 during the last settle (the amplifier never sees a step).
    """
    voltage = (
        VoltageRamp(duration=s.settle, to=s.voltage, **{"from": 0.0}),
        VoltageHold(duration=s.cycles / s.frequency, value=s.voltage),
        VoltageRamp(duration=s.settle, to=0.0),
    )
    return _ramp_sine_stretch(s), voltage


def capacitance_sweep(s: CapacitanceSweepSettings) -> Channels:
    """Capacitance test (Fig. 16 of [1]): the tensile ramp sine at 0 V (the LCR bridge works at 0 V only)."""
    voltage = (VoltageHold(duration=s.duration, value=0.0),)
    return _ramp_sine_stretch(s), voltage


def blocking_force(s: BlockingForceSettings) -> Channels:
    """Blocking force (Fig. 15 of [1]): fixed stretch, voltage sine from voltage_min to voltage_max.

    Stretch: ramp 1 -> stretch over approach, hold for settle + cycles /
    frequency, ramp back to 1 over approach. Voltage: 0 V for approach +
    settle, a sine with phase -90 deg (it starts and ends at voltage_min) for
    cycles / frequency, 0 V for approach.
    """
    sine = s.cycles / s.frequency
    stretch = (
        StretchRamp(duration=s.approach, to=s.stretch, **{"from": 1.0}),
        StretchHold(duration=s.settle + sine, value=s.stretch),
        StretchRamp(duration=s.approach, to=1.0),
    )
    voltage = (
        VoltageHold(duration=s.approach + s.settle, value=0.0),
        VoltageSine(
            duration=sine, mean=0.5 * (s.voltage_max + s.voltage_min),
            amplitude=0.5 * (s.voltage_max - s.voltage_min), frequency=s.frequency, phase=-0.5 * math.pi,
        ),
        VoltageHold(duration=s.approach, value=0.0),
    )
    return stretch, voltage


#: preset name -> settings -> (stretch segments, voltage segments)
BUILDERS: dict[str, Callable] = {
    "tensile_ramp_sine": tensile_ramp_sine,
    "blocking_force": blocking_force,
    "capacitance_sweep": capacitance_sweep,
}
assert set(BUILDERS) == set(PRESETS), "every preset declared in specs needs a builder here"


def expand_preset(spec: ProtocolSpec) -> ProtocolSpec:
    """The same protocol with its preset replaced by explicit segments.

    A spec without a preset is returned as is; the expansion keeps the
    spec's `origin`. The spec was checked whole when it was made (its
    expansion's sample count too, from the preset's declared duration).

    Parameters
    ----------
    spec : ProtocolSpec

    Returns
    -------
    ProtocolSpec
        With ``stretch`` and ``voltage`` segments, no ``preset`` or ``settings``.
    """
    if spec.preset is None:
        return spec
    stretch, voltage = BUILDERS[spec.preset](spec.settings)
    explicit = ProtocolSpec(
        name=spec.name, kind=spec.kind, description=spec.description, source=spec.source,
        sample_rate=spec.sample_rate, measure=spec.measure, limits=spec.limits,
        stretch=stretch, voltage=voltage, probe=spec.probe, pause=spec.pause, suspend=spec.suspend,
    )
    return explicit.with_origin(spec.origin)


__all__ = ["BUILDERS", "blocking_force", "capacitance_sweep", "expand_preset", "tensile_ramp_sine"]
