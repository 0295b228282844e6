"""Closing a netCDF file this process wrote so that HDF5's lock on it does not outlive the close.

HDF5 takes an ``flock`` on every file it opens (exclusive when writing, shared when reading) and lets go of
it only by closing its descriptor. An ``flock`` belongs to the open file description, not to the descriptor:
a process forked by another thread while the file is open (a subprocess starting: fork, ``preexec_fn``,
closing its descriptors, exec) holds a copy of the description, and with it the lock, until it closes that
copy. Meanwhile HDF5 refuses every other open of the file, a read included, in this process too ("NetCDF:
HDF error"): the catalogue's row of a run just written, `open_run`, a figure. ``HDF5_USE_FILE_LOCKING`` is
read once, when the library starts, not per open (setting it later changes nothing), and disabling locking
for the whole process would drop it for every file, other processes' writers included.

`unlock` lets go of the writer's lock itself, just before the file is closed (`close_unlocked`):
``flock(LOCK_UN)`` on this process's descriptors of the file undoes the lock of their description, which
every copy shares, so no copy keeps it. Only for a file this process made and alone writes (a ``.tmp``
renamed into place when whole): between the unlock and the close no other process opens it.
"""

from __future__ import annotations

import os

try:
    import fcntl
except ImportError:  # Windows: no flock, and no fork to copy a descriptor
    fcntl = None


def _descriptors_of(path) -> list[int]:
    """This process's descriptors open on the file at ``path`` (the same inode), from /proc/self/fd or /dev/fd;
    none where neither lists them."""
    try:
        st = os.stat(path)
    except OSError:
        return []
    for folder in ("/proc/self/fd", "/dev/fd"):
        try:
            names = os.listdir(folder)
        except OSError:
            continue
        fds = []
        for name in names:
            try:
                fd = int(name)
                here = os.fstat(fd)
            except (ValueError, OSError):  # the listing's own descriptor, closed meanwhile
                continue
            if (here.st_dev, here.st_ino) == (st.st_dev, st.st_ino):
                fds.append(fd)
        return fds
    return []


def unlock(nc) -> None:
    """Flush ``nc``, a netCDF4.Dataset this process opened for writing, and undo HDF5's ``flock`` on it (for
    every copy of its descriptor): the last step before closing it (call it holding xarray's ``HDF5_LOCK``)."""
    if fcntl is None:
        return
    nc.sync()
    for fd in _descriptors_of(nc.filepath()):
        try:
            fcntl.flock(fd, fcntl.LOCK_UN)
        except OSError:  # not a descriptor of ours any more; nothing to undo there
            pass


def close_unlocked(nc) -> None:
    """`unlock` ``nc``, then close it (closed whatever `unlock` raised)."""
    try:
        unlock(nc)
    finally:
        nc.close()
