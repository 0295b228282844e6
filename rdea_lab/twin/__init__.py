"""The physics twin: a quasi-static model plus viscoelasticity over a time series."""

from .curves import quasi_static_curves
from .simulate import simulate

__all__ = ["quasi_static_curves", "simulate"]
