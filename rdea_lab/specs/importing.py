"""What ``rdea-lab import`` accepts: file formats, protocol kinds, and the stretch taken as noise below 1."""

from .names import KINDS

#: File formats ``import`` reads.
FORMATS = ("csv", "tdms", "mat")
#: A measured stretch below this is a compressed specimen (an error); between it and 1, noise at zero load.
MIN_STRETCH = 0.999

__all__ = ["FORMATS", "KINDS", "MIN_STRETCH"]
