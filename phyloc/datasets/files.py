"""Crash-safe files of a dataset output: temporary names, atomic publication and the lock.

Every file phyloc writes into a dataset output (a shard, the master, an import or an export)
is written under a temporary name next to its final one (:func:`temp_path`), optionally flushed
to disk (:func:`fsync`) and renamed into place with ``os.replace``, which is atomic on POSIX
filesystems: a reader sees the old file or the new one, never a part of it, and a crash leaves
at most a stale temporary file. :func:`staged` removes the temporary file when writing fails.
:func:`output_lock` keeps two processes from writing the same output at once.

References
----------
The Open Group, POSIX.1-2017 (IEEE Std 1003.1-2017), base specifications: ``rename()`` and
``fsync()``, https://pubs.opengroup.org/onlinepubs/9699919799/; the Linux ``flock(2)`` manual
page, https://man7.org/linux/man-pages/man2/flock.2.html.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from phyloc._files import temp_name
from phyloc.datasets import schema as sc


def temp_path(final) -> Path:
    """A unique temporary name next to ``final`` (:func:`phyloc._files.temp_name`)."""
    return temp_name(final)


@contextlib.contextmanager
def staged(final):
    """Yield :func:`temp_path` ``(final)`` to write; the caller renames it into place
    (``os.replace``). On any error the temporary file is removed and the error propagates."""
    tmp = temp_path(final)
    try:
        yield tmp
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def fsync(path) -> None:
    """Flush a file's (or a folder's) data to disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(path) -> None:
    """Flush a folder (a rename inside it) to disk, where the platform allows it."""
    with contextlib.suppress(OSError):  # not every platform/filesystem syncs directories
        fsync(path)


@contextlib.contextmanager
def output_lock(sdir: Path, out: Path):
    """Hold an exclusive lock on ``sdir/.lock`` (released by the OS if the process dies).

    Raises
    ------
    DatasetBusyError
        Another process holds the lock (is writing ``out``).
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - non-POSIX: no locking
        yield
        return
    fh = (sdir / ".lock").open("a")
    try:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise sc.DatasetBusyError(
                f"another phyloc generate is writing {out} (lock {sdir / '.lock'}); wait for "
                "it to finish or stop it"
            ) from None
        yield
    finally:
        fh.close()


__all__ = ["fsync", "fsync_dir", "output_lock", "staged", "temp_path"]
