"""Physical constants used by the models (SI)."""

from scipy.constants import epsilon_0

#: Vacuum permittivity [F/m]. Table 1 of [1] rounds it to 8.85 pF/m.
EPS0: float = float(epsilon_0)
