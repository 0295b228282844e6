"""Store: the netCDF schema, crash-safe streaming, reading and cataloguing runs.

``open_run`` (a run's Dataset), ``catalog`` (a pandas DataFrame of a folder's
runs, with the users' metadata as ``md.<key>`` columns), ``recover`` (a killed
run's journal to a dataset), ``importers.import_files`` (CSV, TDMS, .mat).

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

from .catalog import catalog, describe_run, iter_chunks, open_run
from .journal import (DiskFull, EmptyJournal, JournalInUse, JournalWriter, RunInProgress, journal_path,
                      journal_writer, read_journal, recover, write_dataset)
from .schema import REQUIRED_ATTRS, VARIABLES

__all__ = ["DiskFull", "EmptyJournal", "JournalInUse", "RunInProgress", "journal_writer", "JournalWriter",
           "REQUIRED_ATTRS", "VARIABLES", "catalog", "describe_run", "iter_chunks", "journal_path", "open_run",
           "read_journal", "recover", "write_dataset"]
