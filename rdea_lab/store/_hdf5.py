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

A writer's temporary file ``<out>.tmp`` is made by `create` and renamed by `publish` only while it is still
the file made, so that two writers given one output never cost each other what they measured.
"""

from __future__ import annotations

import contextlib
import errno
import os

try:
    import fcntl
except ImportError:  # Windows: no flock, and no fork to copy a descriptor
    fcntl = None


def identity(path) -> tuple[int, int] | None:
    """``(device, inode)`` of the file at ``path``, None where there is none."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _descriptors_of(ident) -> list[int]:
    """This process's descriptors open on the file ``ident`` (`identity`), from /proc/self/fd or /dev/fd; none
    where neither lists them."""
    if ident is None:
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
            if (here.st_dev, here.st_ino) == ident:
                fds.append(fd)
        return fds
    return []


def unlock(nc, ident=None) -> None:
    """Flush ``nc``, a netCDF4.Dataset this process opened for writing, and undo HDF5's ``flock`` on it (for
    every copy of its descriptor): the last step before closing it (call it holding xarray's ``HDF5_LOCK``).
    ``ident``: the file's `identity` as made (the path may name another file by now), else its path's."""
    if fcntl is None:
        return
    nc.sync()
    for fd in _descriptors_of(identity(nc.filepath()) if ident is None else ident):
        try:
            fcntl.flock(fd, fcntl.LOCK_UN)
        except OSError:  # not a descriptor of ours any more; nothing to undo there
            pass


def close_unlocked(nc, ident=None) -> None:
    """`unlock` ``nc``, then close it (closed whatever `unlock` raised)."""
    try:
        unlock(nc, ident)
    finally:
        nc.close()


# --- a writer's temporary file ``<out>.tmp``: one writer at a time, never another's removed or renamed


class TmpTaken(OSError):
    """Another writer of the same output replaced this writer's temporary file while it was written: nothing
    is renamed to the output (a run's journal stays, for `recover`)."""


def _locked_by_other(path) -> bool | None:
    """Whether a live writer holds a lock on the file at ``path`` (HDF5's, while it has the file open), None
    where there is no file there. Tested with a non-blocking lock of this call's own."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    try:
        if fcntl is None:
            return False
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        return False
    finally:
        os.close(fd)  # (the lock taken, if any, goes with it)


def claim(tmp) -> None:
    """Make way for a new ``tmp``: whatever file is there is removed, unread. It is a writer's that died (the
    writer's source, a journal or data in memory, is the record), or one whose lock a process it forked still
    holds for a moment, or, where two writers were given one output, the other's: that one's `publish` then
    finds its file gone and raises `TmpTaken`, its source kept, so nothing measured is lost either way. The
    caller then makes the file exclusively (netCDF's ``clobber=False``): of two writers that both made way,
    only one makes it."""
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)


def drop_unmade(tmp) -> None:
    """After this writer failed to make ``tmp`` (a full disk, Ctrl-C, another writer made it first): remove a
    file there that no live writer holds (what the failed make left), never a live one's."""
    with contextlib.suppress(OSError):  # (called while the failure is raised: never one of its own instead)
        if _locked_by_other(tmp) is False:
            os.unlink(tmp)


def create(tmp, lock=None):
    """``(nc, ident)``: a new netCDF4 file at ``tmp``, open for writing, and its `identity`. Way made first
    (`claim`), then made exclusively (``clobber=False``; under ``lock``, xarray's ``HDF5_LOCK``, where given);
    a make that fails leaves nothing behind but a live writer's file (`drop_unmade`)."""
    import netCDF4

    claim(tmp)
    try:
        with lock if lock is not None else contextlib.nullcontext():
            nc = netCDF4.Dataset(tmp, "w", clobber=False, format="NETCDF4")
    except BaseException:
        drop_unmade(tmp)  # what a failed make left (a full disk, Ctrl-C), never a live writer's
        raise
    return nc, identity(tmp)


def remove_own(tmp, ident) -> None:
    """Remove ``tmp`` if it is still the file this writer made (``ident``: its `identity`)."""
    if ident is not None and identity(tmp) == ident:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def publish(tmp, out, ident) -> None:
    """fsync ``tmp`` and rename it to ``out``, if it is still the file this writer made (``ident``), else raise
    `TmpTaken` (nothing renamed: another writer's half file never becomes ``out``)."""
    try:
        fd = os.open(tmp, os.O_RDONLY)
    except FileNotFoundError:
        st = None  # removed by another writer's `claim`
    else:
        try:
            os.fsync(fd)
            st = os.fstat(fd)
        finally:
            os.close(fd)
    if st is None or (st.st_dev, st.st_ino) != ident:
        raise TmpTaken(errno.EBUSY, "another process replaced this output's temporary file while it was written; "
                       "nothing was written", str(out))
    os.replace(tmp, out)
