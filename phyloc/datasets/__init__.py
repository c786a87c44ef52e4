"""Waveform datasets: HDF5 schema, sharded resumable generation on Dask, reading.

A dataset recipe (``kind = "dataset"``: ``[system]``, ``[network]`` with ``[network.motion]``,
``[channel]``, ``[dataset]``, ``seed``) is turned into a master HDF5 file and a folder of shard
files by :func:`generate` (``phyloc generate``); :func:`open` reads it lazily, :func:`info` and
:func:`verify` summarize and check it (``phyloc info [--verify]``). The layout is documented,
with its version :data:`SCHEMA_VERSION`, in ``datasets/README.md``.

Examples
--------
A tiny dataset (2 agents and 1 anchor in AWGN, 33 subcarriers, one realization), written to a
temporary folder and read back:

>>> import tempfile, pathlib
>>> import phyloc.datasets as pds
>>> from phyloc.phy.correlation import correlation_tables
>>> recipe = '''
... kind = "dataset"
... seed = 1
... [system]
... n_subcarriers = 33
... [network]
... n_agents = 2
... anchors = 1
... [channel]
... scenario = "awgn"
... [dataset]
... realizations = 1
... '''
>>> with tempfile.TemporaryDirectory() as tmp:
...     out = pathlib.Path(tmp) / "tiny.h5"
...     summary = pds.generate(recipe, out, progress=False)
...     with pds.open(out) as ds:
...         snap = ds.snapshot(0, 0)
...         table = correlation_tables(snap.received, snap.symbols, ds.system,
...                                    tx_index=snap.tx_index)
...         shapes = (ds["received"].shape, snap.received.shape, table.n_links)
>>> summary["links"], shapes  # 6 directed links: 2 agent-agent, 4 agent-anchor
(6, ((1, 1, 6, 33), (6, 33), 6))

References
----------
The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS),
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.
"""

from phyloc.datasets.importer import export_arrays, import_arrays
from phyloc.datasets.integrity import info, verify
from phyloc.datasets.plan import (
    DatasetPlan,
    plan_dataset,
    realization_seed,
    simulate_recipe_realization,
)
from phyloc.datasets.reader import Dataset, Snapshot, open, open_dataset, open_xarray
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
from phyloc.datasets.writer import generate

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
    "export_arrays",
    "generate",
    "import_arrays",
    "info",
    "open",
    "open_dataset",
    "open_xarray",
    "plan_dataset",
    "realization_seed",
    "simulate_realization",
    "simulate_recipe_realization",
    "verify",
]
