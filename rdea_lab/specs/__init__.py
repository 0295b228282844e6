"""Units and specs: specimen cards, material parameter sets, protocols and the
emulator's truth files, as YAML with units, validated into frozen pydantic
models holding SI floats.

The lowest layer of rdea-lab: it imports nothing else from the package. Every
user mistake raises `SpecError`, whose ``str`` is one line
``"{source}: {field}: {message}"``.

Loaders take a path (``load_specimen``, ``load_params``, ``load_protocol``,
``load_truth``); ``as_specimen`` / ``as_params`` / ``as_protocol`` take an
object or a path. ``limit_violations`` checks stretch and voltage arrays
against a protocol's `Limits` (`LimitError`).

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

import importlib as _importlib

#: Where each public name lives. Loaded on first use (PEP 562), so that ``from rdea_lab.specs import
#: MODELS`` (a command line's choices) costs no pydantic, numpy or YAML; ``dir()`` lists them all.
_EXPORTS = {
    "coerce": ("as_params", "as_protocol", "as_specimen"),
    "errors": ("SpecError", "UserError"),
    "limits": ("LimitError", "check_limits", "field_estimate", "limit_violations"),
    "names": ("MODEL_CHOICES", "MODELS"),
    "params": ("LAWS", "MODULUS", "ParameterSet", "ViscoBranch", "dump_params", "load_params", "material_problems",
               "params_from_mapping", "params_from_yaml", "yeoh_slope_nonpositive_at"),
    "record": ("CalibrationRecord",),
    "protocol": ("Limits", "ProtocolSpec", "dump_protocol", "load_protocol", "protocol_from_mapping",
                 "protocol_from_yaml"),
    "protocol_pause": ("Pause",),
    "suspenders": ("Condition", "Suspender", "merged_suspenders", "parse_condition"),
    "specimen": ("Membrane", "Radii", "SpecimenCard", "dump_specimen", "load_specimen", "specimen_from_mapping",
                 "specimen_from_yaml"),
    "truth": ("Instrument", "RadiiFactors", "TruthSpec", "dump_truth", "load_truth", "truth_as_mapping",
              "truth_from_mapping", "truth_from_yaml", "truth_json"),
    "tokens": ("read_token",),
    "units": ("format_quantity", "parse_quantity", "ureg"),
}
_MODULE_OF = {name: module for module, names in _EXPORTS.items() for name in names}


def __getattr__(name):
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(_importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value  # the next look-up is an ordinary one
    return value


def __dir__():
    return sorted(set(globals()) | set(_MODULE_OF))


__all__ = [
    "as_params", "as_protocol", "as_specimen", "LimitError", "check_limits", "field_estimate", "limit_violations",
    "read_token", "UserError", "Limits", "ProtocolSpec", "dump_protocol", "load_protocol", "protocol_from_mapping",
    "protocol_from_yaml",
    "Membrane", "ParameterSet", "Radii", "SpecError", "SpecimenCard", "ViscoBranch",
    "dump_params", "dump_specimen", "format_quantity", "load_params", "load_specimen",
    "material_problems", "params_from_mapping", "params_from_yaml", "parse_quantity",
    "specimen_from_mapping", "specimen_from_yaml", "ureg", "yeoh_slope_nonpositive_at",
    "Instrument", "MODEL_CHOICES", "MODELS", "RadiiFactors", "TruthSpec", "dump_truth", "load_truth",
    "truth_as_mapping", "truth_from_mapping", "truth_from_yaml", "truth_json", "CalibrationRecord",
    "Pause", "Condition", "Suspender", "merged_suspenders", "parse_condition",
]
