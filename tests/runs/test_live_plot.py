"""The live plot subscriber: PNG written at most once per interval, atomically, always at stop, no pyplot."""

import sys
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Mapping

import matplotlib.image
import numpy as np
import pytest

from rdea_lab.runs.live import LivePlot

try:
    from rdea_lab.runs.callbacks import RunBlock
except ImportError:  # the engine's callback module is not there yet: the same interface
    @dataclass(frozen=True)
    class RunBlock:
        data: Mapping[str, np.ndarray]
        first: int
        samples: int
        planned: int
        status: str

        def __getitem__(self, key):
            return self.data[key]

RATE = 100.0
PLANNED = 1000
ATTRS = {"protocol_name": "tensile_ramp_sine_0V", "specimen_id": "specimen-2", "backend": "twin",
         "sample_rate": RATE}


def blocks(n_blocks=10, size=100):
    """Synthetic blocks of a run: stretch a sine, force proportional to it, a voltage step."""
    for b in range(n_blocks):
        k = np.arange(b * size, (b + 1) * size)
        t = k / RATE
        stretch = 1.2 + 0.2 * np.sin(2 * np.pi * 0.5 * t)
        voltage = np.where(t > 2.0, 2600.0, 0.0)
        data = {"time": t, "stretch": stretch, "position": (stretch - 1) * 0.034, "voltage": voltage,
                "force": 10.0 * (stretch - 1), "capacitance": np.full(size, np.nan), "stretch_setpoint": stretch,
                "voltage_setpoint": voltage}
        yield RunBlock(data=data, first=int(k[0]), samples=int(k[-1] + 1), planned=PLANNED, status="running")


class Clock:
    """A clock the test moves by hand [s]."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


@pytest.fixture
def live(tmp_path):
    clock = Clock()
    plot = LivePlot(tmp_path / "live.png", interval=1.0, clock=clock)
    plot.start(ATTRS)
    return plot, clock


def png_ok(path):
    image = matplotlib.image.imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    return image


def test_first_block_writes_a_png(live):
    plot, clock = live
    plot(next(blocks()))
    assert plot.path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = png_ok(plot.path)
    assert image.shape[:2] == (650, 900)  # figsize (9, 6.5) in at 100 dpi


def test_not_rewritten_within_the_interval_then_rewritten(live):
    plot, clock = live
    it = blocks()
    plot(next(it))
    first = plot.path.stat().st_mtime_ns
    for _ in range(3):  # 0.9 s on the clock: inside the interval
        clock.now += 0.3
        plot(next(it))
    assert plot.draws == 1
    assert plot.path.stat().st_mtime_ns == first
    clock.now += 0.2  # 1.1 s since the first draw
    plot(next(it))
    assert plot.draws == 2
    clock.now += 0.5
    plot(next(it))
    assert plot.draws == 2


def test_stop_always_draws_the_final_status(live):
    plot, clock = live
    for block in blocks(4):
        plot(block)
    assert plot.draws == 1
    plot.stop(SimpleNamespace(status="aborted", reason="force 51 N above the limit 50 N", samples=400,
                              path="run.nc"))
    assert plot.draws == 2
    png_ok(plot.path)
    assert plot.title() == ("tensile_ramp_sine_0V on specimen-2 (twin): aborted (force 51 N above the limit 50 N), "
                            "400 / 1000 samples")


def test_drawn_data_are_the_samples(live):
    plot, clock = live
    sent = list(blocks(5))
    for block in sent:
        clock.now += 1.0
        plot(block)
    t = np.concatenate([b["time"] for b in sent])
    force = np.concatenate([b["force"] for b in sent])
    voltage = np.concatenate([b["voltage"] for b in sent])
    lines = [ax.lines[0] for ax in plot.fig.axes]
    np.testing.assert_array_equal(lines[0].get_xdata(), t)
    np.testing.assert_array_equal(lines[0].get_ydata(), force)
    np.testing.assert_array_equal(lines[2].get_ydata(), voltage / 1e3)  # drawn in kV


@pytest.mark.slow
def test_memory_and_window_are_capped(tmp_path):
    plot = LivePlot(tmp_path / "live.png", interval=0.0, clock=Clock(), window_seconds=2.0)
    plot.max_samples = 250
    for block in blocks(10):
        plot(block)
        assert sum(c.size for c in plot._chunks["time"]) <= 2 * plot.max_samples + 100
    assert plot.data()["time"].size <= 250
    t = plot.data()["time"]
    assert t[-1] == pytest.approx(9.99) and t[0] >= t[-1] - 2.0


def test_no_temporary_file_left(live, tmp_path):
    plot, clock = live
    for block in blocks(6):
        clock.now += 1.0
        plot(block)
    plot.stop(SimpleNamespace(status="complete", reason="", samples=600, path="run.nc"))
    assert [p.name for p in tmp_path.iterdir()] == ["live.png"]


def test_png_mode_opens_no_pyplot_figure(live):
    plot, clock = live
    for block in blocks(3):
        clock.now += 1.0
        plot(block)
    plot.stop(SimpleNamespace(status="complete", reason="", samples=300, path="run.nc"))
    if "matplotlib.pyplot" in sys.modules:
        assert sys.modules["matplotlib.pyplot"].get_fignums() == []
    assert type(plot.fig.canvas).__module__ == "matplotlib.backend_bases"  # a bare Figure, not a pyplot manager's


def test_start_forgets_the_previous_run(live):
    plot, clock = live
    for block in blocks(2):
        plot(block)
    plot.start({**ATTRS, "specimen_id": "specimen-3"})
    plot(next(blocks()))
    assert plot.data()["time"].size == 100
    assert "specimen-3" in plot.title()


@pytest.mark.parametrize("kwargs, match", [
    ({"path": "live.svg"}, r"'live.svg' is not a .png file"),
    ({"interval": -1.0}, r"interval -1.0 s must be >= 0 s"),
    ({"window_seconds": 0.0}, r"window_seconds 0.0 s must be > 0 s"),
])
def test_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LivePlot(**{"path": "live.png", **kwargs})
