"""rdea-lab: rolled dielectric elastomer actuators, from protocol to validated model.

The physics follows [1]; see ``paper/ERRATA.md`` in the shared folder for the
equations that are corrected here.

[1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello,
    "Modeling and experimental validation of thin, tightly rolled dielectric
    elastomer actuators", Smart Mater. Struct. 31 (2022) 015008 (2021 online),
    doi:10.1088/1361-665X/ac34be.
"""

__version__ = "0.1.0"
