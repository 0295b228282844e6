"""rdea-lab: rolled dielectric elastomer actuators, from protocol to validated model.

The physics follows [1]; see ``paper/ERRATA.md`` in the shared folder for the
equations that are corrected here.

Quick start (the one in the package; ``tests/api/test_package_docstrings.py`` runs it)::

    >>> import rdea_lab
    >>> card = rdea_lab.load_specimen("specimen2")             # a packaged card, or a path
    >>> params = rdea_lab.load_params("paper2021_table3")
    >>> ds = rdea_lab.run_protocol("blocking_force", card, rdea_lab.Twin(params, "su"), out="demo.nc")
    >>> ds.attrs["status"]
    'complete'
    >>> twin = ds.rdea.predict(params, "su")                   # the twin on the run's own history
    >>> bool(abs(twin["force"] - ds["force"]).max() < 1e-9)    # the twin run is the twin
    True
    >>> fig = ds.rdea.plot(prediction=twin)                    # the run and the prediction: a Figure

The public names, about thirty, in `__all__`: runs (`run_protocol`,
`prepare_run`, `run_campaign`, the backends `Twin`, `Emulator`, `Rig`, the
live views `LiveTable`, `LivePlot`), data (`open_run`, `catalog`, `recover`,
`import_files`), the twin (`predict`, `simulate`, `TwinStep`, `geometry`),
calibration and reports (`calibrate_runs`, `cross_validate`,
`validation_report`, `reproduce`), planning and design (`plan_target`,
`run_study`), inputs and errors (`load_specimen`, `load_params`,
`load_protocol`, `load_study`, `SpecError`, `LimitError`) and `RigServer`.
The rest lives in the subpackages, bottom to top: `specs` (cards, parameters,
protocols, units), `physics` (geometry, Yeoh, SU/1R/3R, viscoelasticity),
`twin`, `protocols` (plans), `emulator` (the rig's stand-in), `backends`,
`store` (netCDF, journal, catalogue, import), `runs` (engine, run_protocol,
campaigns), `calibration`, `reports`, `design`, `api`, `cli`.

[1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello,
    "Modeling and experimental validation of thin, tightly rolled dielectric
    elastomer actuators", Smart Mater. Struct. 31 (2022) 015008 (2021 online),
    doi:10.1088/1361-665X/ac34be.
"""

from ._version import __version__  # noqa: E402,F401

from . import api as _api  # noqa: E402

__all__ = ["__version__", *_api.__all__]


_SUBPACKAGES = ("specs", "physics", "twin", "protocols", "emulator", "backends", "store", "runs", "calibration",
                "reports", "design", "api", "cli", "paths", "signals")


def __getattr__(name):
    if name in _SUBPACKAGES:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    return getattr(_api, name)


def __dir__():
    return sorted(set(globals()) | set(_api.__all__))
