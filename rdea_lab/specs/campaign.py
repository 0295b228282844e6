"""Campaign files: a list of experiments (specimens x protocols) run in one go."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from .errors import DOCUMENT, Identifier, SpecError, SpecModel, read_yaml_mapping, show
from .truth import MODEL_CHOICES


class CampaignSpec(SpecModel):
    """A campaign: every protocol on every specimen, on one backend.

    Paths are relative to ``root``, itself relative to the campaign file's
    folder (default ``..``: a file in ``campaigns/`` names ``specimens/...``).
    """

    name: Identifier
    description: str | None = None
    source: str | None = None
    root: str = ".."
    backend: Literal["twin", "emulator"] = "emulator"
    truth: str | None = None
    params: str | None = None
    model: Literal[MODEL_CHOICES] = "auto"
    seed: int = 0
    out: str
    specimens: tuple[str, ...]
    protocols: tuple[str, ...]


def load_campaign(path: str | os.PathLike) -> tuple[CampaignSpec, Path]:
    """Read a campaign file; returns the spec and the folder its paths are relative to."""
    mapping, source = read_yaml_mapping(path)
    spec = CampaignSpec.from_yaml_mapping(mapping, source)
    for key in ("specimens", "protocols"):
        if not getattr(spec, key):
            raise SpecError(source, key, "an empty list; give at least one file")
    root = (Path(path).parent / spec.root).resolve()
    for key in ("specimens", "protocols"):
        for i, rel in enumerate(getattr(spec, key)):
            if not (root / rel).is_file():
                raise SpecError(source, f"{key}[{i}]", f"{show(rel)} not found under {root}")
    for key in ("truth", "params"):
        rel = getattr(spec, key)
        if rel is not None and not (root / rel).is_file():
            raise SpecError(source, key, f"{show(rel)} not found under {root}")
    if spec.backend == "twin" and spec.truth is not None:
        raise SpecError(source, "truth", "a truth file is for the emulator; the twin takes 'params'")
    return spec, root


__all__ = ["CampaignSpec", "DOCUMENT", "load_campaign"]
