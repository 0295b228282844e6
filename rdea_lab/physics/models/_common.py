"""Helpers shared by the three quasi-static models."""

from __future__ import annotations

from ..constants import EPS0

#: Upper end of the admissible range of the active ring's circumferential
#: stretch, as a multiple of the uniaxial value ``lambda1**-0.5``. Voltage
#: states beyond it are reported as past the limit point.
HOOP_STRETCH_CAP = 4.0


def yeoh_coefficients(material):
    """``(C10, C20, C30)`` [Pa] of a parameter set."""
    return (float(material.C10), float(material.C20), float(material.C30))


def kappa(geom, material):
    """Electrical load factor ``eps0 eps_r alpha_e1 eta_b / (2 L3**2)`` [F/m^3 = Pa/V^2].

    The electrical part of the free enthalpy density is
    ``-C v**2 / (2 Omega) = -kappa v**2 lambda1**2 lambda2b**2``, since
    ``C0 / Omega = eps0 eps_r alpha_e1 eta_b / L3**2`` (ERRATA, "Things the
    paper leaves implicit").
    """
    return EPS0 * float(material.eps_r) * geom.alpha_e1 * geom.eta_b / (2.0 * geom.L3**2)
