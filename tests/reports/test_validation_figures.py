"""Figures of the validation report: residual panels, 200 dpi PNG with a PDF beside, no voltage axis at 0 V.

The twin runs are made with Table 3's C10; the report's twin uses C10 x 1.1, so the residual is real and
its largest value is known from the files (measured force) and the report's prediction.
"""

from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
import xarray as xr

from rdea_lab.reports.validation import evaluate_run
from rdea_lab.reports.validation_figures import blocking_figure, tensile_figure
from rdea_lab.specs import load_params

ROOT = Path(__file__).resolve().parents[2]
TABLE3 = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"


@pytest.fixture(scope="module")
def stiffer():
    p = load_params(TABLE3)
    return p.replace(name="c10x1.1", C10=p.C10 * 1.1)


def evaluated(path, params):
    e = evaluate_run(path, params, "su", 0.01)[1]
    e["row"].update(role="other specimen", flags=())
    return e


def residual_axes(fig):
    return [ax for ax in fig.axes if ax.get_ylabel() == "twin − measured [N]"]


@pytest.mark.parametrize("proto, has_voltage_axis", [("tensile_ramp_sine_0V", False),
                                                      ("tensile_ramp_sine_2.6kV", True)])
def test_tensile_figure_has_residuals_and_a_voltage_axis_only_when_there_is_a_voltage(twin_folder, stiffer, proto,
                                                                                        has_voltage_axis):
    path = twin_folder / "specimen1" / f"{proto}.nc"
    e = evaluated(path, stiffer)
    fig = tensile_figure(e, "tab:red")
    fig.draw_without_rendering()  # the secondary axes take their limits when drawn
    assert any(ax.get_ylabel().startswith("voltage [kV]") for ax in fig.axes) == has_voltage_axis
    with xr.open_dataset(path) as ds:
        measured = ds["force"].values
    peak = np.max(np.abs(measured))
    history, loop = residual_axes(fig)
    largest = np.max(np.abs(e["series"]["force_pred"] - e["series"]["force"]))
    assert largest > 0.05 * peak  # C10 + 10 %: a real residual, not rounding
    for ax in (history, loop):
        # the drawn samples keep each bin's extremes: the largest residual is on the panel
        assert np.max(np.abs(ax.lines[0].get_ydata())) == pytest.approx(largest, rel=1e-12)
        (right,) = ax.child_axes
        assert right.get_ylabel() == "[% of peak]"
        np.testing.assert_allclose(right.get_ylim(), np.array(ax.get_ylim()) * 100 / peak, rtol=1e-9)
    assert history.get_xlabel() == "time [s]" and loop.get_xlabel() == "displacement [mm]"


def test_blocking_figure_has_a_residual_under_both_panels(twin_folder, stiffer):
    fig = blocking_figure([evaluated(twin_folder / "specimen1" / "blocking_force.nc", stiffer)],
                          {"specimen-1": "tab:red"})
    assert [ax.get_xlabel() for ax in residual_axes(fig)] == ["time [s]", "voltage [kV]"]


@pytest.mark.slow
def test_report_writes_png_at_200_dpi_and_a_pdf_beside(validate, twin_folder, tmp_path):
    result = validate(TABLE3, twin_folder / "specimen1", tmp_path, figures=True)
    assert len(result.figures) == 4  # two tensile runs, the blocking and the capacitance figure
    for png in map(Path, result.figures):
        pdf = png.with_suffix(".pdf")
        assert pdf.read_bytes()[:5] == b"%PDF-", pdf
        if png.name.startswith("tensile_"):
            assert matplotlib.image.imread(png).shape[:2] == (2000, 1600)  # (10 x 8) in at 200 dpi
    page = Path(result.files["html"]).read_text()
    assert page.count(">PDF</a>") == 4


@pytest.mark.slow
def test_report_without_pdf_writes_and_links_none(validate, twin_folder, tmp_path):
    result = validate(TABLE3, twin_folder / "specimen1", tmp_path, figures=True, pdf=False)
    assert len(result.figures) == 4 and not list(tmp_path.glob("*.pdf"))
    assert ">PDF</a>" not in Path(result.files["html"]).read_text()


@pytest.mark.slow
def test_report_on_a_process_pool_writes_the_same_table_and_figures(validate, twin_folder, tmp_path):
    from rdea_lab.reports.reproduce import process_pool

    serial = validate(TABLE3, twin_folder / "specimen1", tmp_path / "serial", pdf=False)
    with process_pool(2) as pool:  # (forked only where that is safe: numba's threads may run in this process)
        pooled = validate(TABLE3, twin_folder / "specimen1", tmp_path / "pool", pdf=False, executor=pool)
    assert pooled.rows == serial.rows
    assert [Path(f).name for f in pooled.figures] == [Path(f).name for f in serial.figures]
    for a, b in zip(serial.figures, pooled.figures):
        assert Path(a).read_bytes() == Path(b).read_bytes()
