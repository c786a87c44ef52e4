"""Waveform datasets: HDF5 schema, sharded resumable generation on Dask, reading.

A dataset recipe (``kind = "dataset"``: ``[system]``, ``[network]`` with ``[network.motion]``,
``[channel]``, ``[dataset]``, ``seed``) is turned into a master HDF5 file and a folder of shard
files by :func:`generate` (``phyloc generate``); :func:`open` reads it lazily, :func:`info` and
:func:`verify` summarize and check it (``phyloc info [--verify]``). The layout is documented,
with its version :data:`SCHEMA_VERSION`, in ``datasets/README.md``.

Examples
--------
>>> import phyloc.datasets as pds                                    # doctest: +SKIP
>>> pds.generate("datasets/quickstart_c2.toml", "c2.h5", workers=2)   # doctest: +SKIP
>>> with pds.open("c2.h5") as ds:                                     # doctest: +SKIP
...     snap = ds.snapshot(0, 0)
...     snap.received.shape, snap.tx_index.shape
"""

from phyloc.datasets.reader import Dataset, Snapshot, info, open, open_dataset, verify
from phyloc.datasets.schema import (
    SCHEMA_VERSION,
    DatasetBusyError,
    DatasetError,
    DatasetExistsError,
    DatasetMismatchError,
    SchemaVersionError,
    ShardGenerationError,
)
from phyloc.datasets.simulate import Realization, simulate_realization
from phyloc.datasets.spec import DatasetSpec
from phyloc.datasets.writer import (
    DatasetPlan,
    generate,
    plan_dataset,
    realization_seed,
    simulate_recipe_realization,
)

__all__ = [
    "SCHEMA_VERSION",
    "Dataset",
    "DatasetBusyError",
    "DatasetError",
    "DatasetExistsError",
    "DatasetMismatchError",
    "DatasetPlan",
    "DatasetSpec",
    "Realization",
    "SchemaVersionError",
    "ShardGenerationError",
    "Snapshot",
    "generate",
    "info",
    "open",
    "open_dataset",
    "plan_dataset",
    "realization_seed",
    "simulate_realization",
    "simulate_recipe_realization",
    "verify",
]
