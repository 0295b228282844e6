"""The specs' vocabularies as plain tuples: what a command line's choices need, with nothing to import."""

#: The quasi-static models, cheapest first (``rdea_lab.physics.models.MODELS`` implements them);
#: the true physics may be any of them.
MODELS = ("su", "1r", "3r", "cr")
#: What a twin, a calibration or a report accepts: a model, or ``auto`` (the cheapest within a tolerance).
MODEL_CHOICES = (*MODELS, "auto")
#: What a protocol (a run) is.
KINDS = ("tensile", "blocking", "capacitance", "custom")

#: The largest stretch anything takes as one (an imported run, a protocol's limit): no elastomer film is
#: drawn to 20 times its length (VHB 4910, the stretchiest common one, tears near 8-10 in uniaxial tension);
#: above it, a unit or a zero is wrong.
MAX_STRETCH = 20.0

__all__ = ["KINDS", "MAX_STRETCH", "MODEL_CHOICES", "MODELS"]
