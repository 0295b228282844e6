"""The calibration record: the ``calibration:`` section of a parameter file, which says how the set was
obtained (``rdea-lab calibrate``) and, after ``--holdout``, how it predicts the runs held out.

`CalibrationRecord` is the only reader and writer of that section: `rdea_lab.calibration.record` builds
one from a fit and appends `CalibrationRecord.block` to the parameter file, `add_record_section` adds
the holdout's ``validation`` to a record written before, and the reports read a file's record with
`CalibrationRecord.of_file`. Statistics keep lmfit's names (``chisqr``, ``redchi``, ``aic``, ``bic``,
``nfev``, ``nvarys``, ``nfree`` = ``ndata - nvarys``). Quantities are text with units (``"239.132 kPa"``)
as the fit's report gives them; ``null`` where a value is not finite or does not apply.
``hyperelastic`` is the fit's choice of Yeoh coefficients (``yeoh``, ``yeoh-monotone``, ``neo-hookean``;
a record written before it was recorded has none: the paper's Yeoh).

The section is written in the order its fields are declared here (the order of the files committed so
far); keys not declared are kept, after them. Only what was given is written (``None`` included).
"""

from __future__ import annotations

import os
from pathlib import Path

import yaml
from pydantic import ConfigDict

from .base import SpecModel
from .errors import DOCUMENT, SpecError
from .yamlio import dump_yaml

#: The top-level key of the record in a parameter file.
KEY = "calibration"


class _Section(SpecModel):
    """A part of a record: what a newer rdea-lab adds is kept (extra keys allowed), numbers as text coerced."""

    model_config = ConfigDict(frozen=True, extra="allow", coerce_numbers_to_str=True)

    def mapping(self) -> dict:
        """The YAML form: the keys that were given, in the declared order, then any others."""
        return self.model_dump(exclude_unset=True)


class FitParameter(_Section):
    """One parameter of the fit: value and start as text with units; for a free one its standard error
    (or why there is none), its bounds (``null`` for an open side) and lmfit-style flags."""

    value: str | None = None
    init_value: str | None = None
    free: bool | None = None
    stderr: str | None = None
    bounds: list[str | None] | None = None
    flags: list[str] | None = None


class Matrix(_Section):
    """The correlation or covariance of the free parameters (``units`` says the covariance's)."""

    names: list[str]
    matrix: list[list[float | None]]
    units: str | None = None


class FitRun(_Section):
    """A run the set was fitted on, with its goodness of fit and the file's sha256 (its identity)."""

    file: str | None = None
    protocol: str | None = None
    specimen: str | None = None
    samples: int | None = None
    excluded_samples: int | None = None
    rms_error_N: float | None = None
    r2: float | None = None
    max_rel_error: float | None = None
    rms_rel_error: float | None = None
    p99_rel_error: float | None = None
    sha256: str | None = None


class Statistics(_Section):
    """The fit's statistics, with lmfit's names and meanings."""

    ndata: int | None = None
    nvarys: int | None = None
    nfree: int | None = None
    chisqr: float | None = None
    redchi: float | None = None
    aic: float | None = None
    bic: float | None = None
    nfev: int | None = None
    nit: int | None = None
    restarts: int | None = None
    wall_time_s: float | None = None


class Validation(_Section):
    """What ``rdea-lab calibrate --holdout`` adds: the held-out runs' errors, the calibration envelope
    (`rdea_lab.calibration.envelope.Envelope.mapping`), the legend of the error measures and the held-out
    misfit a prediction band learns from (`rdea_lab.calibration.bands.misfit_mapping`)."""

    held_out: list[dict] | None = None
    envelope: dict | None = None
    measures: str | None = None
    misfit: dict | None = None


class CalibrationRecord(_Section):
    """The ``calibration:`` section of a parameter file (see the module docstring).

    ``warm_start`` (only where Nelder-Mead started from a least-squares optimum) says how it got
    there, with the evaluations of each; ``branch_choice`` (only where the number of Maxwell branches
    was chosen from the data) the criterion, each count tried with its objective and criterion, and
    why the count was chosen.
    """

    model: str | None = None
    viscoelastic_law: str | None = None
    hyperelastic: str | None = None
    metric: str | None = None
    method: str | None = None
    warm_start: str | None = None
    objective: float | None = None
    converged: bool | None = None
    message: str | None = None
    parameters: dict[str, FitParameter] | None = None
    correlation: str | Matrix | None = None
    covar: str | Matrix | None = None
    runs: list[FitRun] = []
    skipped: list[dict] | None = None
    statistics: Statistics | None = None
    stages: list[dict] | None = None
    branch_choice: dict | None = None
    budgets: dict | None = None
    notes: str | None = None
    software: str | None = None
    versions: dict | None = None
    weighting: dict | None = None
    spectrum: dict | None = None
    validation: Validation | None = None

    @classmethod
    def _from_form(cls, mapping: dict, source: str) -> "CalibrationRecord":
        try:
            return cls(**mapping)
        except SpecError as err:
            field = KEY if err.field == DOCUMENT else f"{KEY}.{err.field}"
            raise SpecError(source, field, err.message) from None

    def _form(self) -> dict:
        return self.mapping()

    def block(self) -> str:
        """The record as the YAML a parameter file ends with (``calibration:`` and the section under it)."""
        return dump_yaml({KEY: self.mapping()})

    def with_section(self, key: str, section: dict) -> "CalibrationRecord":
        """The same record with ``key: section`` added (validated: ``validation`` is a `Validation`)."""
        return type(self).from_mapping({**self.mapping(), key: section})

    @classmethod
    def of_file(cls, path: str | os.PathLike) -> "CalibrationRecord | None":
        """The record of the parameter file `path`, or None if it has none (or is not a YAML mapping).

        Raises
        ------
        SpecError
            The section is there but a field is not what a record holds (naming ``calibration.<field>``).
        """
        try:
            doc = yaml.safe_load(Path(path).read_text())
        except yaml.YAMLError:
            return None
        section = doc.get(KEY) if isinstance(doc, dict) else None
        return cls.from_mapping(section, os.fspath(path)) if isinstance(section, dict) else None


def add_record_section(path: str | os.PathLike, section: dict, key: str = "validation") -> None:
    """Add ``key: section`` to the record of the parameter file `path` (written with `CalibrationRecord.block`).

    The file's text is kept as it is when ``calibration`` is its last top-level key (the section is
    appended, indented under it); otherwise the document is written again from its parsed form.

    Raises
    ------
    ValueError
        The file has no calibration section.
    """
    text = Path(path).read_text()
    doc = yaml.safe_load(text)
    if not isinstance(doc, dict) or not isinstance(doc.get(KEY), dict):
        raise ValueError(f"{path}: no calibration section to add {key!r} to")
    record = CalibrationRecord.from_mapping(doc[KEY], os.fspath(path)).with_section(key, section)
    value = record.mapping()[key]
    block = dump_yaml({key: value})
    if list(doc)[-1] == KEY and key not in doc[KEY]:
        new = text.rstrip("\n") + "\n" + "".join("  " + ln + "\n" for ln in block.splitlines())
        if (yaml.safe_load(new).get(KEY) or {}).get(key) == yaml.safe_load(block)[key]:
            Path(path).write_text(new)
            return
    doc[KEY] = record.mapping()
    Path(path).write_text(dump_yaml(doc))


__all__ = ["CalibrationRecord", "FitParameter", "FitRun", "KEY", "Matrix", "Statistics", "Validation",
           "add_record_section"]
