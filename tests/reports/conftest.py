"""What a browser would show of the reports' HTML, read with the standard library's parser (not the code
that writes it); the validation report computed and written, as the CLI does."""

from html.parser import HTMLParser
from pathlib import Path

import pytest


class Page(HTMLParser):
    """The text of a page, the text of each table cell (``<wbr>`` as a break), and every attribute."""

    def __init__(self, text: str):
        super().__init__(convert_charrefs=True)
        self.text, self.cells, self.attrs, self.links = [], [], [], []
        self._cell = None
        self.feed(text)
        self.text = "".join(self.text)

    def handle_starttag(self, tag, attrs):
        self.attrs += [v for _, v in attrs if v]
        if tag == "a":
            self.links += [v for k, v in attrs if k == "href"]
        if tag in ("td", "th"):
            self._cell = []
        elif tag == "wbr" and self._cell is not None:
            self._cell.append(" ")  # a break opportunity, as a space is

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.cells.append("".join(self._cell))
            self._cell = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)

    def longest_unbreakable(self) -> str:
        """The longest run of characters in a table cell without a space or ``<wbr>`` in it."""
        return max((w for c in self.cells for w in c.split()), key=len, default="")


@pytest.fixture
def read_page():
    return lambda path: Page(Path(path).read_text(encoding="utf-8"))


ROOT = Path(__file__).resolve().parents[2]
TABLE3 = ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml"
#: (specimen card, protocol) of the twin_folder fixture's runs
TWIN_RUNS = [("specimen1", "tensile_ramp_sine_0V"), ("specimen1", "tensile_ramp_sine_2.6kV"),
             ("specimen1", "blocking_force"), ("specimen1", "capacitance_sweep"),
             ("specimen2", "tensile_ramp_sine_0V")]


@pytest.fixture(scope="session")
def twin_folder(tmp_path_factory):
    """Five twin runs (SU, Table 3), written by `rdea-lab run`, in ``<card>/<protocol>.nc``."""
    from rdea_lab.cli.errors import run
    from rdea_lab.cli.main import cli

    folder = tmp_path_factory.mktemp("twin_runs")
    for card, proto in TWIN_RUNS:
        out = folder / card / f"{proto}.nc"
        argv = ["run", str(ROOT / "rdea_lab" / "data" / "protocols" / f"{proto}.yaml"),
                "--specimen", str(ROOT / "rdea_lab" / "data" / "specimens" / f"{card}.yaml"),
                "--backend", "twin", "--model", "su", "--params", str(TABLE3), "--out", str(out), "--quiet"]
        assert run(cli, argv) == 0
    return folder


class Written:
    """A `ValidationReport` and the files its ``write`` returned: the report's attributes, ``files`` and
    ``figures`` (the PNGs among the files)."""

    def __init__(self, report, files):
        self.report, self.files = report, files
        self.figures = [p for p in files.values() if p.suffix == ".png"]

    def __getattr__(self, name):
        return getattr(self.report, name)


@pytest.fixture(scope="session")
def validate():
    """``validate(params, folder, out, figures=, pdf=, executor=, **computing)``: compute the report, then
    write it into ``out``."""
    from rdea_lab.reports.validation import validation_report

    def run(params, folder, out, *, figures=True, pdf=True, executor=None, overwrite=False, **computing):
        report = validation_report(params, folder, executor=executor, **computing)
        return Written(report, report.write(out, figures=figures, pdf=pdf, executor=executor, overwrite=overwrite))

    return run
