"""Optional dependencies: what each extra of ``pip install rdea-lab[...]`` brings, and the refusal
a command gets when its extra is missing (exit status 2, with the pip command that brings it).

=========  ==========================================  =========================================
extra      brings                                       for
=========  ==========================================  =========================================
fast       numba                                        compiled kernels, `rdea_lab.TwinStep`
design     dask[distributed], bokeh, SALib              ``rdea-lab design`` (sweeps, Sobol, SLSQP)
monitor    bokeh                                        ``rdea-lab monitor`` (live runs in the browser)
import     npTDMS                                       importing LabVIEW TDMS files
=========  ==========================================  =========================================
"""

from __future__ import annotations

import importlib
import importlib.util

from .specs.errors import UserError

#: The distribution each optional module comes from, and the extra that installs it.
EXTRAS = {"numba": ("numba", "fast"), "distributed": ("dask[distributed]", "design"),
          "dask": ("dask[distributed]", "design"), "SALib": ("SALib", "design"), "bokeh": ("bokeh", "design"),
          "nptdms": ("npTDMS", "import")}


class MissingExtra(UserError):
    """An optional dependency that a command needs is not installed (exit status 2)."""

    def __init__(self, module: str, what: str, extra: str | None = None):
        dist, default = EXTRAS.get(module, (module, "all"))
        extra = extra or default
        self.module, self.extra = module, extra
        super().__init__(f"{what} needs {dist}, which is not installed; install it with: "
                         f"python3 -m pip install 'rdea-lab[{extra}]'")


def require(module: str, what: str, extra: str | None = None):
    """``import module``, or `MissingExtra` naming ``what`` needs it and the extra that brings it (``extra``:
    that one, where several extras bring the module)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtra(module, what, extra) from None


def available(module: str) -> bool:
    """Whether ``module`` can be imported (without importing it)."""
    return importlib.util.find_spec(module) is not None


__all__ = ["EXTRAS", "MissingExtra", "available", "require"]
