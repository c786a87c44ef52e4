"""The plan of a waveform dataset: the validated recipe, its shards and their random streams.

:func:`plan_dataset` validates a ``kind = "dataset"`` recipe completely before any work: its
sections, the sizes it implies (an HDF5 chunk of ``received`` within 4 GiB, a shard within this
machine's memory) and the first realization's network. The resulting :class:`DatasetPlan`
fixes everything a generation needs: the shards (``[dataset] shard_size`` realizations each,
:meth:`~phyloc.datasets.spec.DatasetSpec.shard_range`), the stored arrays and their axis sizes,
and the recipe fingerprint that shards and master carry.

Realization ``i`` draws from its own stream :func:`realization_seed` ``(seed, i)`` =
``SeedSequence(seed).spawn(R)[i]``, so the data do not depend on the shard size, the worker
count or the order in which shards complete; :func:`simulate_recipe_realization` draws one
realization in memory.

References
----------
NumPy, "Parallel random number generation" (``SeedSequence.spawn``),
https://numpy.org/doc/stable/reference/random/parallel.html.

The HDF Group, *HDF5 User's Guide* (the 4 GiB chunk size limit), https://docs.hdfgroup.org/.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.channels import ChannelSpec
from phyloc.config import Recipe, dumps_toml, load_recipe
from phyloc.datasets import schema as sc
from phyloc.datasets.simulate import Realization, check_heights, simulate_realization
from phyloc.datasets.spec import DatasetSpec
from phyloc.errors import ValidationError
from phyloc.network import IsolatedNodesWarning, NetworkSpec, make_network
from phyloc.phy.system import OFDMSystem


@dataclass(frozen=True)
class DatasetPlan:
    """Everything a dataset generation needs, validated from a recipe before any work.

    Attributes
    ----------
    recipe : Recipe
    system : OFDMSystem
    network : NetworkSpec
    channel : ChannelSpec
    dataset : DatasetSpec
    fingerprint : str
        SHA-256 of the canonical JSON of the validated sections and the seed; shards and master
        carry it, so a resume with a different recipe is refused.
    flags : dict
        Optional arrays stored (``velocities``, ``accelerations``).
    """

    recipe: Recipe
    system: OFDMSystem
    network: NetworkSpec
    channel: ChannelSpec
    dataset: DatasetSpec
    fingerprint: str
    flags: dict

    @property
    def seed(self) -> int:
        """The recipe seed."""
        return self.recipe.seed

    @property
    def arrays(self) -> tuple:
        """The :class:`~phyloc.datasets.schema.ArraySpec` of every stored array."""
        return sc.arrays_for(self.flags)

    def dims(self, n_realizations: int, max_links: int, n_paths: int = 0) -> dict:
        """Axis sizes (see :class:`~phyloc.datasets.schema.ArraySpec`)."""
        return array_dims(self.system, self.network, n_realizations, max_links, n_paths)

    def recipe_text(self) -> str:
        """The recipe's TOML text (reconstructed from the sections if it has none)."""
        if self.recipe.text.strip():
            return self.recipe.text
        doc = {
            "kind": "dataset",
            "name": self.recipe.name,
            "seed": self.seed,
            "system": self.system.to_dict(),
            "network": self.network.to_dict(),
            "channel": self.channel.to_dict(),
            "dataset": self.dataset.to_dict(),
        }
        return dumps_toml(doc)


def array_dims(
    system: OFDMSystem, network: NetworkSpec, n_realizations: int, max_links: int, n_paths=0
) -> dict:
    """The size of every axis of the stored arrays (the keys of
    :class:`~phyloc.datasets.schema.ArraySpec` ``axes``) for ``n_realizations`` realizations
    whose snapshots have at most ``max_links`` links and ``n_paths`` paths in all."""
    return {
        "realization": n_realizations,
        "snapshot": network.motion.n_snapshots,
        "node": network.n_nodes,
        "coordinate": network.dim,
        "link": max_links,
        "end": 2,
        "subcarrier": system.n_subcarriers,
        "sample": system.n_samples,
        "path": n_paths,
    }


def _gib(n_bytes: float) -> str:
    return f"{n_bytes / 2**30:.3g} GiB"


def _check_sizes(network, system, dataset) -> None:
    """Refuse sizes that cannot be written or held, naming the keys that drive them: an HDF5
    chunk of ``received`` beyond 4 GiB, and a shard whose waveforms exceed this machine's
    memory."""
    links = sc.max_possible_links(network.n_agents, network.n_anchors)
    drivers = (
        f"network.n_agents = {network.n_agents}, network.anchors = {network.n_anchors}, "
        f"system.n_subcarriers = {system.n_subcarriers}, system.oversampling = "
        f"{system.oversampling}"
    )
    per_chunk = dataset.chunk_links or links
    if per_chunk * system.n_samples * 8 >= 2**32:
        if dataset.chunk_links:
            raise ValidationError(
                "dataset.chunk_links",
                dataset.chunk_links,
                f"a chunk of {per_chunk} links x {system.n_samples} samples (complex64) is "
                f"{_gib(per_chunk * system.n_samples * 8)}, beyond the 4 GiB HDF5 chunk limit; "
                "set chunk_links to fewer links",
            )
        raise ValidationError(
            "network.n_agents",
            network.n_agents,
            f"one snapshot has up to {links} links x {system.n_samples} samples = "
            f"{_gib(links * system.n_samples * 8)} (complex64; {drivers}), beyond the 4 GiB "
            "HDF5 chunk limit: set dataset.chunk_links to split it, or use a smaller network",
        )
    # a shard's waveforms in memory: complex128 spectra + complex64 samples per link
    shard = dataset.shard_size * network.motion.n_snapshots * links * system.n_samples * 24
    memory = sc.physical_memory()
    if memory and shard > memory:
        raise ValidationError(
            "dataset.shard_size",
            dataset.shard_size,
            f"a shard of {dataset.shard_size} realizations x {network.motion.n_snapshots} "
            f"snapshots x up to {links} links x {system.n_samples} samples needs about "
            f"{_gib(shard)} of memory ({drivers}) and this machine has {_gib(memory)}: lower "
            "shard_size or the network size",
        )


def plan_dataset(recipe) -> DatasetPlan:
    """Validate a dataset recipe completely (before any work) and return its plan.

    Parameters
    ----------
    recipe : Recipe, path or TOML text
        A recipe of ``kind = "dataset"`` with ``[system]``, ``[network]`` (with
        ``[network.motion]``), ``[channel]`` and ``[dataset]`` sections.

    Raises
    ------
    ValidationError
        Wrong kind, unknown key (naming the closest valid one), wrong type or impossible value,
        a missing section, or a network that isolates nodes at realization 0 (when
        ``network.on_isolated = "error"``).
    """
    if not isinstance(recipe, Recipe):
        recipe = load_recipe(recipe)
    if recipe.kind != "dataset":
        raise ValidationError(
            "kind", recipe.kind, 'phyloc generate needs a recipe with kind = "dataset"'
        )
    network = recipe.section("network", NetworkSpec, required=True)
    channel = recipe.section("channel", ChannelSpec)
    check_heights(network, channel)
    dataset = recipe.section("dataset", DatasetSpec, required=True)
    system = recipe.system
    _check_sizes(network, system, dataset)
    canon = {
        "schema_major": sc.SCHEMA_MAJOR,
        "seed": recipe.seed,
        "system": system.to_dict(),
        "network": network.to_dict(),
        "channel": channel.to_dict(),
        "dataset": dataset.to_dict(),
    }
    fingerprint = hashlib.sha256(
        json.dumps(canon, sort_keys=True, separators=(",", ":")).encode()
    ).hexdigest()
    flags = {
        "velocities": network.motion.tracks_velocity,
        "accelerations": network.motion.tracks_acceleration,
    }
    plan = DatasetPlan(recipe, system, network, channel, dataset, fingerprint, flags)
    # a cheap pre-flight: the first realization's network (isolated nodes, anchor layout)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IsolatedNodesWarning)
        make_network(network, np.random.default_rng(realization_seed(recipe.seed, 0)))
    return plan


def realization_seed(seed: int, index: int) -> np.random.SeedSequence:
    """The stream of realization ``index``: equal to ``SeedSequence(seed).spawn(n)[index]``
    for any ``n > index`` (:func:`phyloc.parallel.task_seeds`)."""
    return np.random.SeedSequence(int(seed), spawn_key=(int(index),))


def simulate_recipe_realization(recipe, index: int) -> Realization:
    """Realization ``index`` of a dataset recipe, simulated in memory (what the dataset stores,
    before the complex64 time-domain conversion).

    Parameters
    ----------
    recipe : Recipe, path or TOML text, or DatasetPlan
    index : int
        0 <= index < ``[dataset] realizations``.
    """
    plan = recipe if isinstance(recipe, DatasetPlan) else plan_dataset(recipe)
    i = v.integer("index", index, minimum=0)
    if i >= plan.dataset.realizations:
        raise ValidationError("index", index, f"must be < {plan.dataset.realizations}")
    rng = np.random.default_rng(realization_seed(plan.seed, i))
    return simulate_realization(plan.system, plan.network, plan.channel, rng)


__all__ = [
    "DatasetPlan",
    "array_dims",
    "plan_dataset",
    "realization_seed",
    "simulate_recipe_realization",
]
