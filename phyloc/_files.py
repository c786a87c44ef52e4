"""Writing files so that a failure names its path and leaves nothing half-written.

* :func:`write_atomic` — bytes to a temporary name next to the target, then ``os.replace``; an
  error (a full disk, a denied permission) carries the target's path, and the temporary file
  is removed.
* :func:`reserve_space` — allocate a file's estimated size on disk before HDF5 writes into it.
* :func:`require_space` — refuse work that would not fit: a :class:`DiskFullError` (an
  ``OSError`` with ``errno.ENOSPC``) naming the folder, the bytes needed and the bytes free,
  raised *before* anything is written. HDF5 cannot always recover from a write that fails
  half-way (the library may crash on the next close), so phyloc checks first where it knows
  a file's size.

References
----------
The Open Group, POSIX.1-2017, ``rename()`` and ``statvfs()``,
https://pubs.opengroup.org/onlinepubs/9699919799/; Python, :func:`shutil.disk_usage`.
"""

from __future__ import annotations

import errno
import os
import shutil
import uuid
from pathlib import Path

#: Bytes kept free beyond a file's estimate (file-system metadata, HDF5 free-space slack).
SPACE_MARGIN_BYTES = 1 << 20


class DiskFullError(OSError):
    """Not enough free space for a file phyloc is about to write (``errno.ENOSPC``)."""

    def __init__(self, folder, need: int, free: int, what: str):
        self.need, self.free, self.what = int(need), int(free), what
        super().__init__(
            errno.ENOSPC,
            f"not enough space for {what} (about {_mb(need)} needed, {_mb(free)} free)",
            str(folder),
        )
        self._init = (str(folder), self.need, self.free, what)

    def __reduce__(self):  # across processes (Dask workers) with its own arguments
        return (type(self), self._init)


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n < 10**9 else f"{n / 1e9:.2f} GB"


def free_bytes(folder) -> int:
    """Bytes free for this user in the file system that holds ``folder``."""
    return int(shutil.disk_usage(folder).free)


def require_space(folder, need: int, what: str) -> None:
    """Raise :class:`DiskFullError` unless ``folder``'s file system has ``need`` bytes free
    (plus :data:`SPACE_MARGIN_BYTES`).

    >>> require_space(".", 1, "a test file")
    >>> require_space(".", 10**30, "a huge file")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    phyloc._files.DiskFullError: [Errno 28] not enough space for a huge file (about ...
    """
    free = free_bytes(folder)
    if free < need + SPACE_MARGIN_BYTES:
        raise DiskFullError(folder, need + SPACE_MARGIN_BYTES, free, what)


def reserve_space(path, nbytes: int, what: str) -> None:
    """Allocate ``nbytes`` on disk for the existing file ``path`` (``posix_fallocate``), so
    that writes into that much of it cannot fail for want of space, also when another
    process fills the disk meanwhile. The file grows to ``nbytes``; HDF5 truncates its files
    to their end-of-allocation on close. Raises :class:`DiskFullError` when the space is not
    there. Where the file system cannot allocate (or the platform has no
    ``posix_fallocate``), the free space is checked instead (:func:`require_space`)."""
    path = Path(path)
    allocate = getattr(os, "posix_fallocate", None)
    if allocate is None:
        require_space(path.parent, nbytes, what)
        return
    fd = os.open(path, os.O_RDWR)
    try:
        allocate(fd, 0, max(int(nbytes), 1))
    except OSError as exc:
        if exc.errno == errno.ENOSPC:
            raise DiskFullError(path.parent, nbytes, free_bytes(path.parent), what) from None
        if exc.errno not in (errno.EINVAL, errno.EOPNOTSUPP, errno.ENOSYS):
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        require_space(path.parent, nbytes, what)
    finally:
        os.close(fd)


def temp_name(final) -> Path:
    """A unique temporary name next to ``final``: ``.NAME.tmp-<pid>-<8 random hex digits>``
    (hidden, in the same folder, so that the rename stays on one file system)."""
    final = Path(final)
    return final.with_name(f".{final.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")


def write_atomic(path, data: bytes, *, mode: int | None = None, check_space: bool = True):
    """Write ``data`` to ``path`` through a temporary file and ``os.replace``.

    A reader sees the old file or the new one. With ``check_space`` the free space is
    checked first (:func:`require_space`). Any ``OSError`` is raised with ``path`` as its
    filename, after the temporary file is removed. ``mode``: the new file's permission bits
    (default: what ``open()`` gives under the process umask). Returns ``path``.
    """
    path = Path(path)
    data = bytes(data) if not isinstance(data, bytes) else data
    tmp = temp_name(path)
    try:
        if check_space:
            require_space(path.parent, len(data), path.name)
        with open(tmp, "wb") as fh:
            if mode is not None:
                os.fchmod(fh.fileno(), mode)
            fh.write(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, DiskFullError):
            raise
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


__all__ = [
    "SPACE_MARGIN_BYTES",
    "DiskFullError",
    "free_bytes",
    "require_space",
    "reserve_space",
    "temp_name",
    "write_atomic",
]
