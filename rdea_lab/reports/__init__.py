"""Reports: tables and figures that compare models and measurements.

``validation.validation_report`` (the Table 4 analogue with Figures 11-16 and
index.html), ``speed.speed_study`` (speed against error), ``reproduce``
(the paper campaign end to end), ``plots`` (``plot_run``, ``plot_plan``: take
``ax=``, return the Figure; no backend is chosen here).

The quick start is `rdea_lab`'s (one, run as a doctest).
"""
