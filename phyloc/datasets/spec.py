"""The ``[dataset]`` section of a ``kind = "dataset"`` recipe.

Example (see ``datasets/quickstart_c2.toml``)::

    [dataset]
    realizations = 4        # Monte Carlo realizations (networks) to store, >= 1
    shard_size = 1          # realizations per shard file (one Dask task each)
    chunk_links = 0         # links per HDF5 chunk of `received`; 0: all links of a snapshot
    compression = "none"    # "none", "gzip" or "lzf" (received samples, pilots, path sets)
    compression_level = 4   # gzip level 0-9 (ignored otherwise)

References
----------
The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS),
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from phyloc import _validate as v
from phyloc._validate import check_keys, from_table
from phyloc.errors import ValidationError

COMPRESSIONS = ("none", "gzip", "lzf")


@dataclass(frozen=True)
class DatasetSpec:
    """How many realizations to store and how to lay them out on disk.

    Parameters
    ----------
    realizations : int
        Number of Monte Carlo realizations, >= 1 (required in a recipe). Realization ``i`` is
        drawn from the stream ``SeedSequence(seed).spawn(realizations)[i]``.
    shard_size : int
        Realizations per shard, >= 1. A shard is one file in ``OUT.h5.shards/`` and one Dask
        task; it is the unit of work that a resumed generation keeps or redoes. Default 8.
    chunk_links : int
        Links per HDF5 chunk of the received samples, >= 0; 0 (default) puts all links of one
        (realization, snapshot) in one chunk, so that reading a snapshot reads one chunk.
    compression : {"none", "gzip", "lzf"}
        HDF5 filter for the received samples, pilot symbols and path sets. Noise-like samples
        hardly compress; default ``"none"``.
    compression_level : int
        gzip level 0–9 (only used with ``"gzip"``). Default 4.

    Examples
    --------
    >>> DatasetSpec.from_dict({"realizations": 4, "shard_size": 2}).n_shards
    2
    """

    realizations: int
    shard_size: int = 8
    chunk_links: int = 0
    compression: str = "none"
    compression_level: int = 4

    def __post_init__(self):
        s = "dataset"
        object.__setattr__(
            self, "realizations", v.integer(f"{s}.realizations", self.realizations, minimum=1)
        )
        object.__setattr__(
            self, "shard_size", v.integer(f"{s}.shard_size", self.shard_size, minimum=1)
        )
        object.__setattr__(
            self, "chunk_links", v.integer(f"{s}.chunk_links", self.chunk_links, minimum=0)
        )
        if self.compression not in COMPRESSIONS:
            raise ValidationError(
                f"{s}.compression", self.compression, f"one of {', '.join(COMPRESSIONS)}"
            )
        level = v.integer(f"{s}.compression_level", self.compression_level, minimum=0)
        if level > 9:
            raise ValidationError(f"{s}.compression_level", level, "gzip levels are 0 to 9")
        object.__setattr__(self, "compression_level", level)

    @property
    def n_shards(self) -> int:
        """Number of shards, ``ceil(realizations / shard_size)``."""
        return -(-self.realizations // self.shard_size)

    def shard_range(self, index: int) -> tuple[int, int]:
        """Realizations ``[start, stop)`` of shard ``index``."""
        start = index * self.shard_size
        return start, min(start + self.shard_size, self.realizations)

    def h5_filter(self) -> dict:
        """Keyword arguments for ``h5py.Group.create_dataset`` (compression settings)."""
        if self.compression == "none":
            return {}
        if self.compression == "gzip":
            return {"compression": "gzip", "compression_opts": self.compression_level}
        return {"compression": "lzf"}

    @classmethod
    def from_dict(cls, d: dict, *, section: str = "dataset") -> DatasetSpec:
        """Build from the ``[dataset]`` table; unknown keys name the closest valid key."""
        if not isinstance(d, dict):
            raise ValidationError(section, d, "must be a table of dataset settings")
        check_keys(d, [f.name for f in dataclasses.fields(cls)], section)  # typos first
        if "realizations" not in d:
            raise ValidationError(
                f"{section}.realizations", None, "is required (number of realizations, >= 1)"
            )
        return from_table(cls, d, section)

    def to_dict(self) -> dict:
        """The fields as a plain dict (recipe form)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
