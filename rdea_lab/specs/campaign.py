"""Campaign files: a list of experiments (specimens x protocols) run in one go."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from .errors import DOCUMENT, Identifier, SpecError, SpecModel, read_yaml_mapping, show
from ..paths import resolve
from .truth import MODEL_CHOICES


class CampaignSpec(SpecModel):
    """A campaign: every protocol on every specimen, on one backend.

    Input paths are relative to ``root``, itself relative to the campaign file's
    folder (default ``..``: a file in ``campaigns/`` names ``specimens/...``), or
    name packaged inputs (``specimens/specimen2.yaml``, `rdea_lab.paths.resolve`);
    `load_campaign` gives them back as absolute paths. ``out`` is relative to the
    working directory.
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
    mapping, source = read_yaml_mapping(path, "campaigns")
    spec = CampaignSpec.from_yaml_mapping(mapping, source)
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
    return spec.model_copy(update=update), root


__all__ = ["CampaignSpec", "DOCUMENT", "load_campaign"]
