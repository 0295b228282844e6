"""rdea-lab: rolled dielectric elastomer actuators, from protocol to validated model.

The physics follows [1]; see ``paper/ERRATA.md`` in the shared folder for the
equations that are corrected here.

Quick start::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")       # the twin on the run's own history
    ds.rdea.plot(prediction=twin)                    # the run and the prediction, as a Figure

The public functions (`run_protocol`, `calibrate_runs`, `predict`, `catalog`,
`open_run`, `validation_report`, ...) are those of `rdea_lab.api`, loaded on
first use. Subpackages, bottom to top: `specs` (cards, parameters, protocols,
units), `physics` (geometry, Yeoh, SU/1R/3R, viscoelasticity), `twin`,
`protocols` (plans), `emulator` (the rig's stand-in), `backends`, `store`
(netCDF, journal, catalogue, import), `runs` (engine, run_protocol,
campaigns), `calibration`, `reports`, `api`, `cli`.

[1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello,
    "Modeling and experimental validation of thin, tightly rolled dielectric
    elastomer actuators", Smart Mater. Struct. 31 (2022) 015008 (2021 online),
    doi:10.1088/1361-665X/ac34be.
"""

from ._version import __version__  # noqa: E402,F401

import importlib.abc  # noqa: E402
import importlib.machinery  # noqa: E402
import sys  # noqa: E402

from . import api as _api  # noqa: E402


class _RegisterAccessorWithXarray(importlib.abc.MetaPathFinder):
    """Registers ``ds.rdea`` right after xarray is imported, so that ``import rdea_lab`` (and every
    ``rdea-lab`` command that needs no dataset) does not pay for importing xarray."""

    def find_spec(self, name, path=None, target=None):
        if name != "xarray":
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)  # the ordinary search, without this hook
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec
        run = spec.loader.exec_module

        def exec_module(module):  # only a real import gets here (a find_spec probe does not)
            run(module)
            if self in sys.meta_path:
                sys.meta_path.remove(self)
            importlib.import_module("rdea_lab.api.accessor")

        spec.loader.exec_module = exec_module
        return spec


if "xarray" in sys.modules:
    from .api import accessor as _accessor  # noqa: F401  (registers ds.rdea)
elif not any(isinstance(f, _RegisterAccessorWithXarray) for f in sys.meta_path):
    sys.meta_path.insert(0, _RegisterAccessorWithXarray())

__all__ = ["__version__", *_api.__all__]


_SUBPACKAGES = ("specs", "physics", "twin", "protocols", "emulator", "backends", "store", "runs", "calibration",
                "reports", "api", "cli", "paths")


def __getattr__(name):
    if name in _SUBPACKAGES:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    return getattr(_api, name)


def __dir__():
    return sorted(set(globals()) | set(_api.__all__))
