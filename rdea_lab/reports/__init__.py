"""Reports: tables and figures that compare models and measurements.

``validation.validation_report`` (the Table 4 analogue with Figures 11-16 and
index.html), ``speed.speed_study`` (speed against error), ``reproduce``
(the paper campaign end to end), ``plots`` (``plot_run``, ``plot_plan``: take
``ax=``, return the Figure; no backend is chosen here).

Quick start (the whole library: see `rdea_lab`)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")
"""
