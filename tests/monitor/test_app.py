"""The page's points: display units, and the paused spans from the run's pause phases."""

import numpy as np
import pytest

pytest.importorskip("bokeh", reason="the monitor's page needs bokeh (pip install 'rdea-lab[monitor]')")


def test_points_in_display_units_and_the_paused_shade():
    from rdea_lab.monitor.app import shown

    points = {"time": np.arange(5.0), "voltage": np.full(5, 2600.0), "paused": np.array([0, 1, 2, 3, np.nan])}
    out = shown(points, ("time", "voltage", "force", "paused", "paused_on"))
    np.testing.assert_allclose(out["voltage"], 2.6)  # kV
    assert np.isnan(out["force"]).all()  # a channel the run does not record: NaN, the columns stay aligned
    np.testing.assert_array_equal(out["paused_on"], [0, 1, 1, 1, 0])  # ramping down, held, ramping up
