"""The ``rdea-lab`` command line: module-level click commands that parse
arguments and call one function of the application layer (`rdea_lab.api`).

Exit status: 0 done, 1 internal error, 2 bad input, 3 a run ended by the rig or
a limit (aborted), 130 interrupted. Only the CLI picks matplotlib's backend
(Agg, for commands that write figures).

Quick start (the whole library: see `rdea_lab`)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")
"""

