"""Edit a dataset master as a tool other than phyloc would, then stamp its bytes again.

Since schema 1.2 a master carries the SHA-256 of its bytes in its HDF5 user block and any
edit is refused by that alone; tests of the checks behind it (the content digest, the shard
table, declared sizes) edit the master through :func:`edited_master`, which stamps it again as
a deliberate writer would.
"""

import contextlib
from pathlib import Path

import h5py

from phyloc.datasets import schema as sc


def restamp(path) -> None:
    """Recompute the byte checksum in the user block of the master ``path``."""
    data = Path(path).read_bytes()
    assert data.startswith(sc.MASTER_HEADER_MAGIC), "not a stamped master"
    Path(path).write_bytes(sc.stamp_master(data[sc.MASTER_HEADER_BYTES :]))


@contextlib.contextmanager
def edited_master(path):
    """``with edited_master(path) as f:`` edits the master with h5py and stamps it again."""
    with h5py.File(path, "r+") as f:
        yield f
    restamp(path)
