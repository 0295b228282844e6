"""What ``rdea-lab import`` accepts: file formats, protocol kinds, and the stretch taken as noise below 1."""

from .names import KINDS, MAX_STRETCH

#: File formats ``import`` reads.
FORMATS = ("csv", "tdms", "mat")
#: A measured stretch below this is a compressed specimen (an error); between it and 1, noise at zero load.
MIN_STRETCH = 0.999
#: `MAX_STRETCH` (20): the largest measured stretch taken as a stretch; above it the position's unit or zero
#: is wrong (positions in parsecs, a position column that is another quantity).

__all__ = ["FORMATS", "KINDS", "MAX_STRETCH", "MIN_STRETCH"]
