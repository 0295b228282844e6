"""Physical constants used by the models (SI)."""

#: Vacuum permittivity [F/m]: CODATA 2022 (8.8541878188(14) pF/m), as
#: ``scipy.constants.epsilon_0`` gives it (scipy 1.17; tests/physics/test_constants.py
#: compares the two). Written out so that importing the models does not import scipy
#: (0.17 s). Table 1 of [1] rounds it to 8.85 pF/m.
EPS0: float = 8.8541878188e-12
