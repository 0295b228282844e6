"""The per-sample status codes of a model's solution: one vocabulary for the solvers and the data.

The solvers return them (`rdea_lab.physics.result`, which re-exports them), the twin and the emulator
record them, and every dataset holds them as the ``model_status`` variable, whose CF ``flag_values`` and
``flag_meanings`` (`rdea_lab.specs.variables`) are these codes and names. Declared here, in the lowest
layer, so that the variable table below the twin and the store can name them.
"""

#: Per-sample status codes of :class:`~rdea_lab.physics.result.ModelResult`.
OK = 0
#: The voltage is past a limit point: the branch folded (a true fold, pull-in)
#: and no stable equilibrium follows it in the admissible range.
#: ``critical_voltage`` holds the fold's voltage.
LIMIT_POINT = 1
#: Stretch or voltage was NaN or infinite.
BAD_INPUT = 2
#: The iteration did not reach its tolerance.
NOT_CONVERGED = 3
#: A valid, stable equilibrium, but reached through a snap-through: the branch
#: from the unloaded state folded at ``critical_voltage`` and the roll jumped
#: to the next stable state (e.g. the inner hole of a 3R roll with ``Ri = 0``
#: opening abruptly at a subcritical bifurcation).
SNAPPED = 4
#: The inputs are finite but the stress or force is not representable (a stretch so large that the
#: Yeoh energy overflows double precision, e.g. beyond about 1e51): no number, never a silent inf.
OVERFLOW = 5
#: No fold, but the equilibrium lies beyond the range the model is solved for (the
#: active ring's hoop stretch above ``HOOP_STRETCH_CAP`` times the uniaxial value):
#: ``range_voltage`` holds the largest voltage solved at that stretch. Not a limit point.
OUTSIDE_RANGE = 6
#: A valid state: the roll would push (its tensile force is negative), so it is slack,
#: buckled at the clamps: force 0, stress 0, and the stretches and capacitance of the
#: free (F = 0) state at ``free_stretch`` (Assumption 1 of [1]: a roll carries no compression);
#: where the free state lies beyond what the model solves, those of the clamped state, and
#: ``free_stretch`` NaN.
SLACK = 7

STATUS_NAMES = {OK: "ok", LIMIT_POINT: "past limit point", BAD_INPUT: "NaN or infinite input",
                NOT_CONVERGED: "not converged", SNAPPED: "reached by a snap-through",
                OVERFLOW: "stress overflows (stretch too large)", OUTSIDE_RANGE: "outside solved range",
                SLACK: "slack (the roll would push)"}

__all__ = ["BAD_INPUT", "LIMIT_POINT", "NOT_CONVERGED", "OK", "OUTSIDE_RANGE", "OVERFLOW", "SLACK", "SNAPPED",
           "STATUS_NAMES"]
