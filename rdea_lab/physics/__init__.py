"""Physics: pure, vectorized numpy functions in SI, no I/O.

`geometry` (the Appendix's radii, volume fractions, C0; `geometry_from_card`),
`yeoh` (energy and derivatives), `models` (`solve("su"|"1r"|"3r"|"cr", geom,
material, stretch, voltage)` -> `ModelResult` with a per-sample status),
`viscoelastic` (eq. 44: `overstress_step`, exact over each interval),
`selection` (`select_model`: the cheapest model within a tolerance of CR),
`branch` (the equilibrium rules: a rising ramp, or the path of a time series).
Functions take loaded objects, never paths (the application layer reads files).

Quick start (the whole library: see `rdea_lab`)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")
"""

