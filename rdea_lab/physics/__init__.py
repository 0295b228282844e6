"""Physics: pure, vectorized numpy functions in SI, no I/O.

`geometry` (the Appendix's radii, volume fractions, C0; `geometry_from_card`),
`yeoh` (energy and derivatives), `models` (`solve("su"|"1r"|"3r"|"cr", geom,
material, stretch, voltage)` -> `ModelResult` with a per-sample status),
`viscoelastic` (eq. 44: `overstress_step`, exact over each interval),
`selection` (`select_model`: the cheapest model within a tolerance of CR),
`branch` (the equilibrium rules: a rising ramp, or the path of a time series).
Functions take loaded objects, never paths (the application layer reads files).

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

