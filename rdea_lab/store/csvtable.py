"""CSV as instruments write it, read into a `Table`.

What real exports do, and how each is handled:

* header lines in a non-UTF-8 encoding: the text is decoded with the first
  of utf-8, utf-8-sig, gbk, cp1252, latin-1 that works (or the given one);
* a separator that is a comma, a semicolon or a tab: the first of tab, ``;``,
  ``,`` that splits most of the last lines of the file into two fields or more;
* decimal commas (``1,5``) when the separator is ``;`` or a tab;
* preamble lines, a header row, and a units row under it (a row where no
  field is a number and most fields are units, e.g. ``(s),(mm),(N)``); a
  header name may carry its unit too (``force (N)``, ``position [mm]``);
* quoted numbers, CRLF line ends, blank lines, trailing empty columns.

The data rows are parsed by pandas in one go; only the preamble is read
line by line.
"""

from __future__ import annotations

import collections
import csv
import io
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from ..specs import SpecError, ureg
from ..specs.errors import show
from .tables import Table, unit_text

ENCODINGS = ("utf-8", "utf-8-sig", "gbk", "cp1252", "latin-1")
SEPARATORS = ("\t", ";", ",")
_SEP_NAMES = {"\t": "tab", ";": "semicolon", ",": "comma"}
#: lines at the end of the file that decide the separator and the data's width
_TAIL = 50
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_DECIMAL_COMMA = re.compile(r"\s*[+-]?(?:\d+,\d*|,\d+)(?:[eE][+-]?\d+)?\s*")
_HEADER_UNIT = re.compile(r"^(.*?)\s*[(\[]([^()\[\]]*)[)\]]\s*$")
_NAN_WORDS = ("nan", "+nan", "-nan")


def decode(raw: bytes, source: str, encoding: str | None = None) -> tuple[str, str]:
    """Text of the file and the encoding that decoded it."""
    if encoding is not None:
        try:
            return raw.decode(encoding), encoding
        except LookupError:
            raise SpecError(source, "--encoding", f"unknown encoding {encoding!r}; e.g. utf-8, gbk, cp1252") \
                from None
        except UnicodeDecodeError as exc:
            raise SpecError(source, "--encoding", f"the file is not {encoding} text (byte {exc.start}: "
                                                  f"{raw[exc.start:exc.start + 4]!r})") from None
    for enc in ENCODINGS:
        try:
            text = raw.decode(enc)
        except UnicodeDecodeError:
            continue
        if enc == "utf-8" and text.startswith("\ufeff"):
            return text[1:], "utf-8-sig"
        return text, enc
    raise AssertionError("latin-1 decodes any bytes")


def _split(line: str, sep: str) -> list[str]:
    """The fields of one line; a field may be as long as the line (the csv module's default limit of
    131072 characters is no limit of a data file: a preamble comment or a garbage cell is refused for what
    it is, not for its length)."""
    if len(line) >= csv.field_size_limit():
        csv.field_size_limit(len(line) + 1)
    return next(csv.reader([line], delimiter=sep, quotechar='"'), [])


def _width(fields: list[str]) -> int:
    """Number of fields without the trailing empty ones."""
    n = len(fields)
    while n and not fields[n - 1].strip():
        n -= 1
    return n


def _is_number(text: str, decimal_comma: bool) -> bool:
    text = text.strip()
    if decimal_comma:
        text = text.replace(",", ".")
    return bool(_NUMBER.fullmatch(text))


def _is_unit(text: str) -> bool:
    unit = unit_text(text)
    if unit is None:
        return False
    try:
        ureg.parse_units(unit)
    except Exception:  # pint raises several kinds on text that is no unit
        return False
    return True


def _is_units_row(fields: list[str], decimal_comma: bool) -> bool:
    """No field is a number and most name a unit: ``(s),(mm),(N)``, ``s;mm;N;°C``."""
    filled = [f for f in fields if f.strip()]
    if not filled or any(_is_number(f, decimal_comma) for f in filled):
        return False
    return 2 * sum(_is_unit(f) for f in filled) > len(filled)


def _sniff(lines: list[str], source: str) -> tuple[str, int]:
    """Separator and data width from the file's last lines: the first of tab,
    ';', ',' that splits most of them into two fields or more, and the
    fewest fields (without trailing empty ones) a row of them has."""
    tail = [ln for ln in lines if ln.strip()][-_TAIL:]
    for sep in SEPARATORS:
        widths = [w for w in (_width(_split(ln, sep)) for ln in tail) if w > 1]
        if len(widths) >= 0.8 * len(tail):
            return sep, min(widths)
    raise SpecError(source, "<document>", "cannot tell the column separator: the last lines do not split into "
                                          "two fields or more by a tab, ';' or ','")


def read_csv(path: Path, raw: bytes | None = None, encoding: str | None = None) -> "CsvTable":
    """Read a delimited text file into a `CsvTable`.

    Raises
    ------
    SpecError
        An empty file, a file without data rows, an unknown separator, a row
        with more fields than the data, an encoding that does not decode it.
    """
    source = str(path)
    raw = Path(path).read_bytes() if raw is None else raw
    if not raw.strip():
        raise SpecError(source, "<document>", "the file is empty")
    text, enc = decode(raw, source, encoding)
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    sep, width = _sniff(lines, source)
    tail = [ln for ln in lines if ln.strip()][-_TAIL:]
    decimal_comma = sep != "," and any(_DECIMAL_COMMA.fullmatch(f) for ln in tail for f in _split(ln, sep))

    # the preamble, line by line until the first data row
    block: list[tuple[int, list[str]]] = []  # rows at least as wide as the data, right above it
    start = None
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        fields = _split(line, sep)
        if _width(fields) < width:  # a preamble line ("Operator: ...") ends the block
            block = []
            continue
        filled = [f for f in fields if f.strip()]
        if 2 * sum(_is_number(f, decimal_comma) for f in filled) > len(filled):
            start = i
            break
        block.append((i, fields))
    if start is None:
        raise SpecError(source, "<document>", f"no data rows: no line of {width} or more fields that are mostly "
                                              "numbers")
    header, units_row = None, None
    if len(block) >= 2 and _is_units_row(block[-1][1], decimal_comma):
        header, units_row = block[-2], block[-1]
    elif block:
        header = block[-1]

    tail_fields = collections.Counter(len(_split(ln, sep)) for ln in tail).most_common(1)[0][0]
    frame = _data_frame(lines, start, sep, source, max(tail_fields, len(header[1]) if header else 0))
    n_cols = frame.shape[1]
    names = [""] * n_cols
    units: list[str | None] = [None] * n_cols
    if header is not None:
        for j, name in enumerate(header[1][:n_cols]):
            names[j] = name.strip()
            m = _HEADER_UNIT.match(names[j])
            if m and m.group(2).strip():
                units[j] = m.group(2).strip()
    if units_row is not None:
        for j, u in enumerate(units_row[1][:n_cols]):
            units[j] = unit_text(u) or units[j]
    details = {"encoding": enc, "separator": _SEP_NAMES[sep], "decimal": "comma" if decimal_comma else "point",
               "header_line": header[0] + 1 if header else 0, "units_line": units_row[0] + 1 if units_row else 0,
               "first_data_line": start + 1}
    table = CsvTable(source, names, units, details, frame, decimal_comma)
    table.aliases = {}
    for j, name in enumerate(names):  # 'force (N)' is found as 'force' too
        m = _HEADER_UNIT.match(name)
        if m and m.group(1):
            table.aliases.setdefault(Table.normalize(m.group(1)), j)
    return table


def _data_frame(lines: list[str], start: int, sep: str, source: str, n_fields: int) -> pd.DataFrame:
    """Data rows as text, index = 1-based file line; blank lines dropped.

    A row may have more fields than `n_fields` (the data's and the header's)
    only if the extra ones are empty (a trailing separator)."""
    rows = lines[start:]
    wide = int(pd.Series(rows, dtype=object).str.count(re.escape(sep)).max()) + 1  # >= the widest row
    with warnings.catch_warnings():
        warnings.simplefilter("error", pd.errors.ParserWarning)  # pandas would drop fields silently
        try:
            frame = pd.read_csv(io.StringIO("\n".join(rows)), sep=sep, header=None,
                                names=range(max(wide, n_fields)), index_col=False, dtype=str, keep_default_na=False,
                                skip_blank_lines=False, quotechar='"', engine="c")
        except (pd.errors.ParserError, pd.errors.ParserWarning) as exc:
            raise SpecError(source, "<document>", f"cannot split the data rows: {exc}") from None
    frame.index = np.arange(start + 1, start + 1 + len(frame))
    empty = np.column_stack([(frame[c].str.strip() == "").to_numpy() for c in frame.columns])
    extra = ~empty[:, n_fields:].all(axis=1)
    if extra.any():
        i = int(np.argmax(extra))
        found = _width(_split(rows[i], sep))
        raise SpecError(source, f"line {start + 1 + i}", f"{found} fields where the data rows have {n_fields}")
    return frame.iloc[:, :n_fields][~empty.all(axis=1)]


class CsvTable(Table):
    """Columns of a delimited text file: text cells parsed to floats on demand."""

    def __init__(self, source, names, file_units, details, frame: pd.DataFrame, decimal_comma: bool):
        super().__init__(source, names, file_units, details)
        self.frame = frame
        self.decimal_comma = decimal_comma
        self.lines = frame.index.to_numpy()

    @property
    def n_rows(self) -> int:
        return len(self.frame)

    def where(self, i: int) -> str:
        return f"line {self.lines[i]}"

    def text(self, j: int, i: int) -> str:
        return str(self.frame.iloc[i, j])

    def values(self, j: int) -> np.ndarray:
        cells = self.frame.iloc[:, j].str.strip()
        if self.decimal_comma:
            cells = cells.str.replace(",", ".", regex=False)
        values = pd.to_numeric(cells, errors="coerce").to_numpy(dtype=np.float64, na_value=np.nan)
        bad = np.isnan(values) & (cells != "").to_numpy() & ~cells.str.lower().isin(_NAN_WORDS).to_numpy()
        if bad.any():
            i = int(np.argmax(bad))
            raise SpecError(self.source, f"{self.where(i)}, {self.label(j)}",
                            f"{show(self.text(j, i))} is not a number")
        return values
