"""Store: the netCDF schema, crash-safe streaming, reading and cataloguing runs.

``open_run`` (a run's Dataset), ``catalog`` (a pandas DataFrame of a folder's
runs, with the users' metadata as ``md.<key>`` columns), ``recover`` (a killed
run's journal to a dataset), ``importers.import_files`` (CSV, TDMS, .mat).

Quick start (the whole library: see `rdea_lab`)::

    import rdea_lab
    card = rdea_lab.load_specimen("specimens/specimen2.yaml")
    params = rdea_lab.load_params("params/paper2021_table3.yaml")
    ds = rdea_lab.run_protocol("protocols/blocking_force.yaml", card, "twin", params=params, out="demo.nc")
    twin = rdea_lab.predict(ds, params, "su")
"""

from .catalog import catalog, describe_run, open_run
from .journal import (DiskFull, EmptyJournal, JournalInUse, JournalWriter, RunInProgress, journal_path,
                      journal_writer, read_journal, recover, write_dataset)
from .schema import REQUIRED_ATTRS, VARIABLES

__all__ = ["DiskFull", "EmptyJournal", "JournalInUse", "RunInProgress", "journal_writer", "JournalWriter",
           "REQUIRED_ATTRS", "VARIABLES", "catalog", "describe_run", "journal_path", "open_run", "read_journal",
           "recover", "write_dataset"]
