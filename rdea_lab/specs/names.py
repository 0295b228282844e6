"""The specs' vocabularies as plain tuples: what a command line's choices need, with nothing to import."""

#: The quasi-static models, cheapest first (``rdea_lab.physics.models.MODELS`` implements them);
#: the true physics may be any of them.
MODELS = ("su", "1r", "3r", "cr")
#: What a twin, a calibration or a report accepts: a model, or ``auto`` (the cheapest within a tolerance).
MODEL_CHOICES = (*MODELS, "auto")
#: What a protocol (a run) is.
KINDS = ("tensile", "blocking", "capacitance", "custom")

__all__ = ["KINDS", "MODEL_CHOICES", "MODELS"]
