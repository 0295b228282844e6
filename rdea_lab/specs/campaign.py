"""Campaign files: a list of experiments (specimens x protocols) run in one go."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from pydantic import PrivateAttr, model_validator

from .base import Identifier, SpecModel
from .errors import DOCUMENT, MAX_SEED, SpecError, show
from ..paths import resolve
from .suspenders import Suspender, suspenders_problem
from .truth import MODEL_CHOICES, Seed


class CampaignSpec(SpecModel):
    """A campaign: every protocol on every specimen, on one backend.

    Input paths are relative to ``root``, itself relative to the campaign file's
    folder (default ``..``: a file in ``campaigns/`` names ``specimens/...``), or
    name packaged inputs (``specimens/specimen2.yaml``, `rdea_lab.paths.resolve`);
    `load_campaign` gives them back as absolute paths. ``out`` is relative to the
    working directory. ``suspend:`` (a list as a protocol's, `rdea_lab.specs.suspenders`) applies to
    every run, in addition to its protocol's own (`rdea_lab.specs.suspenders.merged_suspenders`).
    """

    name: Identifier
    description: str | None = None
    source: str | None = None
    root: str = ".."
    backend: Literal["twin", "emulator"] = "emulator"
    truth: str | None = None
    params: str | None = None
    model: Literal[MODEL_CHOICES] = "auto"
    seed: Seed = 0
    out: str
    specimens: tuple[str, ...]
    protocols: tuple[str, ...]
    suspend: tuple[Suspender, ...] = ()
    _origin: str = PrivateAttr("<python>")

    spec_kind = "campaigns"

    @property
    def origin(self) -> str:
        """Where the campaign was read from (a file path, or ``"<python>"``), for messages about it."""
        return self._origin

    @property
    def folder(self) -> Path:
        """The folder the campaign's input paths are relative to (``root`` from the file's folder)."""
        return (Path(self._origin).parent / self.root).resolve()

    @model_validator(mode="after")
    def _distinct_suspenders(self) -> "CampaignSpec":
        problem = suspenders_problem(self.suspend)
        if problem is not None:
            raise problem
        return self

    @classmethod
    def _from_form(cls, mapping: dict, source: str) -> "CampaignSpec":
        """The campaign with its input paths found (under `folder`, else packaged) and made absolute."""
        spec = cls.from_yaml_mapping(mapping, source)
        for key in ("specimens", "protocols"):
            if not getattr(spec, key):
                raise SpecError(source, key, "an empty list; give at least one file")
        root = (Path(source).parent / spec.root).resolve()
        if spec.backend == "twin" and spec.truth is not None:
            raise SpecError(source, "truth", "a truth file is for the emulator; the twin takes 'params'")

        def found(rel, kind, where):  # under root, else a packaged input of that name
            path = root / rel
            path = path if path.is_file() else resolve(rel, kind)
            if not path.is_file():
                raise SpecError(source, where, f"{show(rel)} not found under {root} (nor a packaged {kind} file)")
            return str(path)

        update = {key: tuple(found(rel, key, f"{key}[{i}]") for i, rel in enumerate(getattr(spec, key)))
                  for key in ("specimens", "protocols")}
        for key, kind in (("truth", "truth"), ("params", "params")):
            if getattr(spec, key) is not None:
                update[key] = found(getattr(spec, key), kind, key)
        spec = spec.model_copy(update=update)
        spec._origin = source
        return spec

    def check_run_seeds(self, names) -> None:
        """Refuse a ``seed`` whose run ``i`` (of the `names`, in order) would get a seed above `MAX_SEED`
        (each run's seed is ``seed + i``), naming the campaign file and the first such run."""
        for i, name in enumerate(names):
            if self.seed + i > MAX_SEED:
                raise SpecError(self.origin, "seed", f"run {i + 1} of {len(names)} ({name}) would get seed "
                                f"{self.seed} + {i}, above 2**63 - 1; allowed: seed 0 to {MAX_SEED - len(names) + 1} "
                                f"for {len(names)} runs")


def load_campaign(path: str | os.PathLike) -> tuple[CampaignSpec, Path]:
    """`CampaignSpec.load`: read a campaign file; returns the spec and the folder its paths are relative to."""
    return (spec := CampaignSpec.load(path)), spec.folder


__all__ = ["CampaignSpec", "DOCUMENT", "load_campaign"]
