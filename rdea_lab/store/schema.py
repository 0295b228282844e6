"""The dataset schema: one run = one netCDF file (DESIGN.md, "Data")."""

from __future__ import annotations

#: Variables of every run, in journal column order after ``time``:
#: name -> (units, long_name). SI units, CF ``units`` strings.
VARIABLES: dict[str, tuple[str, str]] = {
    "stretch": ("1", "axial stretch lambda1 = l1 / L1"),
    "position": ("m", "displacement of the moving end from the unstretched length, l1 - L1"),
    "voltage": ("V", "voltage across the electrodes"),
    "force": ("N", "axial force"),
    "capacitance": ("F", "capacitance (NaN where not measured)"),
    "stretch_setpoint": ("1", "commanded axial stretch"),
    "voltage_setpoint": ("V", "commanded voltage"),
}

#: Optional per-backend variables: name -> (units, long_name, netCDF dtype).
EXTRA_VARIABLES: dict[str, tuple[str, str, str]] = {
    "model_status": ("1", "twin model status: 0 ok, 1 past limit point, 2 NaN input, 3 not converged, "
                          "4 reached by a snap-through, 5 stress overflows", "i1"),
}

TIME = ("s", "time since the start of the run")

#: Values of the ``status`` attribute.
STATUSES = ("running", "complete", "aborted", "interrupted")

#: Attributes every dataset carries (DESIGN.md); none may be None.
REQUIRED_ATTRS = (
    "Conventions", "title", "rdea_lab_version", "run_id", "backend", "specimen_id", "specimen",
    "protocol_name", "protocol_kind", "protocol", "sample_rate", "seed", "created", "status",
    "status_reason", "history",
)


def is_emulated(attrs) -> bool:
    """Whether a dataset's attributes say it comes from the rig emulator.

    Reads ``emulated`` as written now (the integer 1; 0 for a physical rig)
    and as written by rdea-lab 0.1 (a sentence starting with ``yes``).
    """
    value = attrs.get("emulated", 0)
    if isinstance(value, str):
        return value.strip().lower().startswith("yes") or value.strip() == "1"
    try:
        return int(value) == 1
    except (TypeError, ValueError):
        return False
