"""Objects or paths: the library's functions take a card, a parameter set or a
protocol either as the loaded object or as the path of its YAML file."""

from __future__ import annotations

import os

from .params import ParameterSet
from .protocol import ProtocolSpec
from .specimen import SpecimenCard


def _wrong(what: str, expected: str, value) -> TypeError:
    return TypeError(f"{what}: expected {expected} or the path of its YAML file, got {type(value).__name__} "
                     f"{value!r:.60}")


def as_specimen(card, what: str = "specimen") -> SpecimenCard:
    """A `SpecimenCard`, or one loaded from the path ``card``."""
    if isinstance(card, (str, os.PathLike)):
        return SpecimenCard.load(card)
    if isinstance(card, SpecimenCard) or any(hasattr(card, a) for a in ("membrane", "radii", "thickness")):
        return card  # a card, or one in disguise (a roll by its membrane or radii, a strip)
    raise _wrong(what, "a SpecimenCard", card)


def as_params(params, what: str = "params") -> ParameterSet:
    """A `ParameterSet`, or one loaded from the path ``params``."""
    if isinstance(params, (str, os.PathLike)):
        return ParameterSet.load(params)
    if isinstance(params, ParameterSet) or hasattr(params, "C10"):  # a parameter set, or one in disguise
        return params
    raise _wrong(what, "a ParameterSet", params)


def as_protocol(protocol, what: str = "protocol") -> ProtocolSpec:
    """A `ProtocolSpec`, or one loaded from the path ``protocol``."""
    if isinstance(protocol, (str, os.PathLike)):
        return ProtocolSpec.load(protocol)
    if isinstance(protocol, ProtocolSpec):
        return protocol
    raise _wrong(what, "a ProtocolSpec", protocol)
