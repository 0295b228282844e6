"""Target files: a desired force history at a fixed stretch (blocking), or a desired stretch
history against a bias (a mass, a linear spring), for a voltage planned from the twin.

A target is YAML (settings, and the samples inline or in a CSV file beside it)
or a bare CSV (the samples; the settings then come from the caller)::

    name: spring_stroke
    target: stretch                 # force (at the fixed 'stretch') | stretch (against 'bias')
    sample_rate: 500 Hz             # of the protocol planned
    bias: {kind: spring, stiffness: 200 N/m, preload: 1 N}
    approach: 5 s                   # stretch ramp from 1 to the first target stretch, at 0 V
    settle: 2 s                     # hold there while the voltage ramps to its first planned value
    limits: {max_voltage: 3 kV}     # the planned protocol's limits
    samples: spring_stroke.csv      # header 'time [s],stretch [-]'; or inline:
    # samples: {units: {time: s, stretch: "1"}, time: [0, 1, 2], stretch: [1.052, 1.058, 1.052]}

Biases (the force the bias pulls the roll with at stretch ``lambda1``):
``none`` (blocking: only with ``target: force``); ``mass`` ``m g``; ``spring``
``preload - stiffness (lambda1 - 1) L1``: a tension spring between the roll's
free end and the frame, pulling with ``preload`` when the roll is at its rest
length ``L1`` and relaxing as the roll lengthens.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import ConfigDict, field_validator, model_validator

from ..paths import resolve

from .base import Identifier, SpecModel
from .errors import DOCUMENT, SpecError, show
from .yamlio import MAX_NODES, MAX_SPEC_BYTES, check_file_size
from .limits import Limits
from .protocol_segments import Duration, MAX_TABLE_VALUES, SampleRate, Stretch, sample_count
from .units import format_quantity, parse_quantity, quantity

#: standard gravity [m/s^2] (a mass bias pulls with m g)
G = 9.80665
TARGETS = ("force", "stretch")
BIAS_KINDS = ("none", "mass", "spring")
#: the quantity of each target and its dimension, SI unit and example header
COLUMNS = {"force": ("force", "N"), "stretch": ("dimensionless", "-")}
#: The largest samples CSV [bytes]: `MAX_TABLE_VALUES` lines of two numbers of full precision are about 40 MB.
MAX_CSV_BYTES = 64_000_000


class NoBias(SpecModel):
    """No bias: a blocking test (the rig holds the stretch)."""

    kind: Literal["none"] = "none"

    def force(self, stretch, L1):
        """0 N: nothing pulls but the rig."""
        return np.zeros_like(np.asarray(stretch, float))

    def slope(self, L1) -> float:
        """``-dF/dlambda1`` [N]: 0."""
        return 0.0


class MassBias(SpecModel):
    """A hanging mass ``mass`` [kg]: a constant pull ``m g`` [N]."""

    kind: Literal["mass"] = "mass"
    mass: quantity("mass", "g", gt=0.0, le=100.0)

    def force(self, stretch, L1):
        """Bias force [N] at stretch [-]: ``m g``."""
        return np.full(np.shape(stretch), self.mass * G)

    def slope(self, L1) -> float:
        """``-dF/dlambda1`` [N]: 0 for a dead load."""
        return 0.0


class SpringBias(SpecModel):
    """A linear tension spring: ``stiffness`` [N/m], ``preload`` [N] at the roll's rest length."""

    kind: Literal["spring"] = "spring"
    stiffness: quantity("stiffness", "N/m", gt=0.0, le=1e7)
    preload: quantity("force", "N", ge=0.0, le=1e3)

    def force(self, stretch, L1):
        """Bias force [N] at stretch [-]: ``preload - stiffness (lambda1 - 1) L1`` (L1 [m])."""
        return self.preload - self.stiffness * (np.asarray(stretch, float) - 1.0) * L1

    def slope(self, L1) -> float:
        """``-dF/dlambda1 = stiffness L1`` [N]."""
        return self.stiffness * L1


BIASES = {"none": NoBias, "mass": MassBias, "spring": SpringBias}


def bias_from_mapping(value: Any, field: str = "bias"):
    """A bias model from ``{kind: spring, stiffness: 200 N/m, preload: 1 N}`` (or a bias model)."""
    if isinstance(value, tuple(BIASES.values())):
        return value
    if not isinstance(value, Mapping):
        raise SpecError("", field, f"expected a mapping with a kind ({', '.join(BIAS_KINDS)}), got {show(value)}")
    kind = value.get("kind")
    if kind not in BIASES:
        raise SpecError("", f"{field}.kind", f"{show(kind)}; allowed: {', '.join(BIAS_KINDS)}")
    data = {str(k): v for k, v in value.items()}
    try:
        return BIASES[kind](**data)
    except SpecError as err:
        raise SpecError("", f"{field}.{err.field}" if err.field else field, err.message) from None


class TargetSettings(SpecModel):
    """Everything of a target file but its samples (SI)."""

    name: Identifier
    description: str | None = None
    target: str
    sample_rate: SampleRate = 1e3
    stretch: Stretch | None = None
    bias: Any = NoBias()
    approach: Duration = 5.0
    settle: Duration = 2.0
    limits: Limits = Limits()

    @field_validator("target", mode="before")
    @classmethod
    def _known(cls, value):
        if value not in TARGETS:
            raise SpecError("", "", f"{show(value)}; allowed: force (at a fixed stretch), stretch (against a bias)")
        return value

    @field_validator("bias", mode="before")
    @classmethod
    def _bias(cls, value):
        try:
            return bias_from_mapping(value, "")
        except SpecError as err:
            raise SpecError("", err.field.lstrip("."), err.message) from None

    @model_validator(mode="after")
    def _consistent(self):
        if self.target == "force":
            if self.stretch is None:
                raise SpecError("", "stretch", "missing; a force target is at a fixed stretch (blocking), "
                                "e.g. 'stretch: 1.5'")
            if self.bias.kind != "none":
                raise SpecError("", "bias", f"{self.bias.kind}: a force target is a blocking test; allowed: none "
                                "(give a stretch target to move against a bias)")
        else:
            if self.stretch is not None:
                raise SpecError("", "stretch", "a stretch target gives its stretch as samples; leave 'stretch' out")
            if self.bias.kind == "none":
                raise SpecError("", "bias", "none (or missing); a stretch target moves against a bias; allowed: "
                                "{kind: mass, mass: 70 g} or {kind: spring, stiffness: 200 N/m, preload: 1 N}")
        for key in ("approach", "settle"):
            periods = getattr(self, key) * self.sample_rate
            if abs(periods - round(periods)) > 1e-9 * max(1.0, periods):
                raise SpecError("", key, f"{format_quantity(getattr(self, key), 's', 6)} is not a whole number of "
                                f"sample periods at {format_quantity(self.sample_rate, 'Hz', 6)}; the planned "
                                "voltage starts on a sample")
        if self.stretch is not None and self.stretch > self.limits.max_stretch:
            raise SpecError("", "stretch", f"{self.stretch:g} is above limits.max_stretch "
                            f"{self.limits.max_stretch:g}")
        return self


class Target(SpecModel):
    """A validated target: settings and samples (SI).

    ``Target.load(path)`` reads a YAML target (samples inline or in a CSV beside it);
    `load_target` also takes a bare CSV with the settings as options.

    Attributes
    ----------
    settings : TargetSettings
    time : numpy.ndarray
        Sample times [s], strictly increasing, from 0.
    values : numpy.ndarray
        Target force [N] (> 0) or stretch [-] (>= 1, at most the limit).
    source : str
        The file, for messages.
    field : str
        Where the samples are (``samples.force`` or, in a CSV, ``force``), for messages.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=True)
    spec_kind = "targets"

    settings: TargetSettings
    time: np.ndarray
    values: np.ndarray
    source: str
    field: str

    #: compared and hashed as the object it is (its samples are arrays), as before
    __eq__ = object.__eq__
    __hash__ = object.__hash__

    @classmethod
    def _from_form(cls, mapping: dict, source: str, folder: str | os.PathLike | None = None) -> "Target":
        """The target from its file's form; a CSV ``samples`` is read from `folder` (by default the file's)."""
        folder = Path(source).parent if folder is None else folder
        mapping = dict(mapping)
        if "samples" not in mapping:
            raise SpecError(source, "samples", "missing; give a CSV file name or {units: ..., time: [...], ...}")
        samples = mapping.pop("samples")
        settings = TargetSettings.from_yaml_mapping(mapping, source)
        quantity = settings.target
        if isinstance(samples, str):
            csv_path = Path(folder) / samples
            time, values, _, rows = read_csv_samples(csv_path, quantity)
            src, where = str(csv_path), ""
        else:
            (time, values, rows), src, where = _inline_samples(samples, quantity, source), source, "samples."
        _check_samples(time, values, quantity, settings, src, where, rows)
        return cls(settings=settings, time=_from_zero(time), values=values, source=src,
                   field=f"{where}{quantity}")

    @property
    def quantity(self) -> str:
        return self.settings.target

    @property
    def duration(self) -> float:
        return float(self.time[-1])


def _check_samples(time, values, quantity, settings, source, where, rows=None):
    """Increasing finite time, finite values in range; `rows` maps a sample to its CSV line."""

    def name(col, i):
        return f"{where}{col} (line {rows[i]})" if rows is not None else f"{where}{col}[{i}]"

    n = time.size
    if n < 2:
        raise SpecError(source, f"{where}{quantity}", f"{n} samples; give at least 2 (time and {quantity})")
    if n > MAX_TABLE_VALUES:
        raise SpecError(source, f"{where}{quantity}", f"{n} samples; allowed: at most {MAX_TABLE_VALUES}")
    for col, arr in (("time", time), (quantity, values)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise SpecError(source, name(col, bad[0]), f"{arr[bad[0]]} is not a finite number")
    step = np.diff(time)
    bad = np.flatnonzero(~(step > 0.0))
    if bad.size:
        raise SpecError(source, name("time", bad[0] + 1), f"{format_quantity(time[bad[0] + 1], 's', 6)} does not "
                        f"come after {format_quantity(time[bad[0]], 's', 6)}; times must increase strictly")
    if quantity == "force":
        bad = np.flatnonzero(~(values > 0.0))
        if bad.size:
            raise SpecError(source, name(quantity, bad[0]), f"{values[bad[0]]:g} N; allowed: > 0 N (a roll only "
                            "pulls; at 0 N it is slack and no voltage is defined)")
    else:
        lim = settings.limits.max_stretch
        bad = np.flatnonzero(~((values >= 1.0) & (values <= lim)))
        if bad.size:
            raise SpecError(source, name(quantity, bad[0]), f"{values[bad[0]]:g}; allowed: 1 to {lim:g} "
                            "(in tension, within limits.max_stretch)")
    duration = time[-1] - time[0]
    m = sample_count(duration, settings.sample_rate)
    if m > MAX_TABLE_VALUES:
        raise SpecError(source, "sample_rate", f"{format_quantity(duration, 's', 6)} at "
                        f"{format_quantity(settings.sample_rate, 'Hz', 6)} gives {m} planned samples; "
                        f"allowed: at most {MAX_TABLE_VALUES}; lower the sample rate")
    if m < 2:
        raise SpecError(source, "sample_rate", f"the target lasts {format_quantity(duration, 's', 6)}: less than "
                        "one sample period; raise the sample rate")


def _unit_factor(unit, dimension, source, field):
    if dimension == "dimensionless" and str(unit).strip() in ("", "-", "1"):
        return 1.0
    return parse_quantity(f"1 {unit}", dimension, source=source, field=field)


def _inline_samples(data, quantity, source):
    if not isinstance(data, Mapping):
        raise SpecError(source, "samples", f"expected a CSV file name or a mapping with units, time and "
                        f"{quantity}, got {show(data)}")
    extra = set(map(str, data)) - {"units", "time", quantity}
    if extra:
        raise SpecError(source, f"samples.{sorted(extra)[0]}", f"unknown key; allowed: units, time, {quantity}")
    units = data.get("units")
    if not isinstance(units, Mapping) or set(map(str, units)) != {"time", quantity}:
        raise SpecError(source, "samples.units", f"give the unit of each column, e.g. "
                        f"{{time: s, {quantity}: {COLUMNS[quantity][1]}}}; got {show(units)}")
    out = []
    for col, dim in (("time", "time"), (quantity, COLUMNS[quantity][0])):
        factor = _unit_factor(units[col], dim, source, f"samples.units.{col}")
        values = data.get(col)
        if not isinstance(values, (list, tuple)):
            raise SpecError(source, f"samples.{col}", f"expected a list of numbers, got {show(values)}")
        bad = [i for i, v in enumerate(values) if isinstance(v, bool) or not isinstance(v, (int, float))]
        if bad:
            raise SpecError(source, f"samples.{col}[{bad[0]}]", f"{show(values[bad[0]])} is not a plain number "
                            "(the unit is given once, in samples.units)")
        out.append(np.asarray(values, float) * factor)
    if out[0].size != out[1].size:
        raise SpecError(source, f"samples.{quantity}", f"{out[1].size} values for {out[0].size} times; give one "
                        "per time")
    return out[0], out[1], None


def _read_text(source):
    """A target file's text; a missing, unreadable or too large file is a SpecError naming it."""
    if str(source).lower().endswith(".csv"):
        check_file_size(source, MAX_CSV_BYTES, f"a samples file holds at most {MAX_TABLE_VALUES} lines")
    else:
        check_file_size(source, MAX_SPEC_BYTES, f"a spec holds at most {MAX_NODES} values")
    try:
        return Path(source).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(source, DOCUMENT, "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(source, DOCUMENT, f"cannot read the file as UTF-8 text ({type(exc).__name__})") from None


def read_csv_samples(path, quantity=None):
    """``(time [s], values, quantity, rows)`` of a CSV with a header ``time [s],force [N]`` (or ``stretch [-]``).

    Lines starting with ``#`` are comments; `rows` gives each sample's line number.
    """
    source = os.fspath(path)
    text = _read_text(source)
    lines = [(i + 1, line) for i, line in enumerate(text.splitlines()) if line.strip() and
             not line.lstrip().startswith("#")]
    if not lines:
        raise SpecError(source, DOCUMENT, "no header; the first line must be e.g. 'time [s],force [N]'")
    longest = max(len(line) for _, line in lines)
    if longest >= csv.field_size_limit():  # a field may be as long as its line: refused for what it holds
        csv.field_size_limit(longest + 1)
    header = next(csv.reader(io.StringIO(lines[0][1])))
    names, units = [], []
    for cell in header:
        name, _, rest = cell.strip().partition("[")
        if not rest.endswith("]"):
            raise SpecError(source, "header", f"{show(cell.strip())} has no unit in brackets; the header must be "
                            "'time [s],force [N]' or 'time [s],stretch [-]'")
        names.append(name.strip())
        units.append(rest[:-1].strip())
    allowed = [q for q in TARGETS if q == quantity] if quantity else list(TARGETS)
    if len(names) != 2 or names[0] != "time" or names[1] not in allowed:
        raise SpecError(source, "header", f"{show(','.join(header))}; allowed: " +
                        " or ".join(f"'time [s],{q} [{COLUMNS[q][1]}]'" for q in allowed))
    quantity = names[1]
    factors = [_unit_factor(units[0], "time", source, "header (time)"),
               _unit_factor(units[1], COLUMNS[quantity][0], source, f"header ({quantity})")]
    rows, data = [], []
    for number, line in lines[1:]:
        cells = next(csv.reader(io.StringIO(line)))
        try:
            if len(cells) != 2:
                raise ValueError
            data.append((float(cells[0]), float(cells[1])))
        except ValueError:
            raise SpecError(source, f"line {number}", f"{show(line.strip())} is not two numbers (time, "
                            f"{quantity})") from None
        rows.append(number)
    arr = np.asarray(data, float).reshape(-1, 2)
    return arr[:, 0] * factors[0], arr[:, 1] * factors[1], quantity, rows


def _from_zero(time):
    return time - time[0]


def target_from_mapping(mapping: Any, source: str = "<mapping>", folder: str | os.PathLike = ".") -> Target:
    """`Target.from_mapping`: a target given as a mapping (as read from YAML); a CSV ``samples`` is read from
    `folder`."""
    return Target.from_mapping(mapping, source, folder=folder)


def load_target(path: str | os.PathLike, **settings) -> Target:
    """Read and validate a target file: YAML (settings and samples) or a bare CSV.

    Parameters
    ----------
    path : path
        ``.yaml``/``.yml``: a target file (see the module docstring); ``.csv``: samples only, with a
        header ``time [s],force [N]`` or ``time [s],stretch [-]``.
    **settings
        For a CSV only: the settings a YAML would give (``name``, ``stretch``, ``bias``,
        ``sample_rate``, ``approach``, ``settle``, ``limits``), as quantities with units.

    Raises
    ------
    SpecError
        Naming the file, the field (a CSV's line) and what is allowed.
    """
    source = os.fspath(resolve(path, "targets"))
    settings = {k: v for k, v in settings.items() if v is not None}
    if source.lower().endswith(".csv"):
        time, values, quantity, rows = read_csv_samples(source)
        if isinstance(settings.get("bias"), str):
            try:
                settings["bias"] = yaml.safe_load(settings["bias"])
            except yaml.YAMLError:
                raise SpecError("command line", "--bias", f"{show(settings['bias'])} is not a YAML mapping; e.g. "
                                "'{kind: spring, stiffness: 200 N/m, preload: 1 N}'") from None
        name = "".join(c if c.isalnum() or c in "-_." else "_" for c in Path(source).stem).lstrip(".") or "target"
        mapping = {"name": name, "target": quantity, **settings}
        try:
            opts = TargetSettings.from_yaml_mapping(mapping, "command line")
        except SpecError as err:
            head, dot, rest = err.field.partition(".")
            option = "--" + head.replace("_", "-") if head in settings else head
            raise SpecError(f"{source} (options for a CSV target)", option + dot + rest, err.message) from None
        _check_samples(time, values, quantity, opts, source, "", rows)
        return Target(settings=opts, time=_from_zero(time), values=values, source=source, field=quantity)
    if settings:
        raise SpecError(source, DOCUMENT, f"the target file gives its own settings; {', '.join(settings)} "
                        "only go with a bare CSV target")
    text = _read_text(source)
    return Target.from_yaml(text, source)


__all__ = ["BIASES", "BIAS_KINDS", "G", "MassBias", "NoBias", "SpringBias", "TARGETS", "Target", "TargetSettings",
           "bias_from_mapping", "load_target", "read_csv_samples", "target_from_mapping"]
