"""Store: the netCDF schema, crash-safe streaming, reading and cataloguing runs."""

from .catalog import catalog, describe_run, open_run
from .journal import JournalWriter, journal_path, read_journal, recover, write_dataset
from .schema import REQUIRED_ATTRS, VARIABLES

__all__ = ["JournalWriter", "REQUIRED_ATTRS", "VARIABLES", "catalog", "describe_run", "journal_path",
           "open_run", "read_journal", "recover", "write_dataset"]
