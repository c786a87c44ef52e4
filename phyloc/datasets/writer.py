"""Sharded, resumable generation of waveform datasets (``phyloc generate``).

:func:`generate` validates a ``kind = "dataset"`` recipe completely, then splits its
realizations into shards of ``[dataset] shard_size`` realizations. Each shard is one task —
in this process (``workers`` None or 1), on an embedded Dask ``LocalCluster`` (``workers`` > 1)
or on an existing Dask cluster (``scheduler``) — which

1. draws realization ``i`` with :func:`~phyloc.datasets.simulate.simulate_realization` from
   its own stream :func:`realization_seed` ``(seed, i)`` = ``SeedSequence(seed).spawn(R)[i]``,
   so the data do not depend on the shard size, the worker count or the order of completion;
2. writes the shard to a temporary file in ``OUT.h5.shards/``, records the SHA-256 of every
   array as an attribute, flushes it to disk and renames it into place atomically
   (``shard-00000.h5``, ...).

The driver (this process) keeps the master file ``OUT.h5`` up to date: it joins the complete
shards with HDF5 virtual datasets and records, per shard, whether it is complete, the file's
SHA-256 and every array's SHA-256 (see ``datasets/README.md``). The master is rewritten
atomically (temporary file + rename) and can always be rebuilt from the shards.

Resume: with ``resume=True`` every existing shard is checked (file checksum against the
master's record, every array against its checksum, recipe fingerprint, realization range);
sound shards are kept untouched, missing or corrupt ones are generated again. The result is
identical, array by array, to an uninterrupted run. Without ``resume`` an existing output is
never overwritten.

Reproducibility: shards are bit-identical for any worker count on one platform (the Numba
kernels run per link, FFTs are batched pocketfft transforms). Workers on different CPUs may
compile the kernels differently, which can change the last bits of a few samples.

References
----------
The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS),
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.

M. Rocklin, "Dask: Parallel computation with blocked algorithms and task scheduling," Proc.
14th Python in Science Conference (SciPy 2015), pp. 130–136, 2015.

NumPy, "Parallel random number generation" (``SeedSequence.spawn``),
https://numpy.org/doc/stable/reference/random/parallel.html.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import signal
import time
import uuid
import warnings
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import h5py
import numpy as np
from tqdm.auto import tqdm

from phyloc import _validate as v
from phyloc.channels import ChannelSpec
from phyloc.config import Recipe, dumps_toml, load_recipe
from phyloc.datasets import schema as sc
from phyloc.datasets.simulate import Realization, simulate_realization
from phyloc.datasets.spec import DatasetSpec
from phyloc.errors import ValidationError
from phyloc.network import IsolatedNodesWarning, NetworkSpec, make_network
from phyloc.parallel import limit_threads, threads_per_task
from phyloc.phy.system import OFDMSystem
from phyloc.phy.waveform import to_time_domain

#: Test hook: ``"k"`` makes shard k fail with an exception after writing part of its temporary
#: file; ``"k:kill"`` kills the generating process there with SIGKILL (a crash).
CRASH_ENV = "PHYLOC_TEST_CRASH_SHARD"
_MASTER_EVERY_S = 2.0  # rewrite the master at most this often while shards complete
_STREAMED = ("received", "symbols")  # written per realization/snapshot, hashed as they go


# -- the validated plan ------------------------------------------------------------------------
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
        return {
            "realization": n_realizations,
            "snapshot": self.network.motion.n_snapshots,
            "node": self.network.n_nodes,
            "coordinate": self.network.dim,
            "link": max_links,
            "end": 2,
            "subcarrier": self.system.n_subcarriers,
            "sample": self.system.n_samples,
            "path": n_paths,
        }

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
    try:
        memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return
    if shard > memory:
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


# -- one shard ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class _ShardTask:
    system: OFDMSystem
    network: NetworkSpec
    channel: ChannelSpec
    dataset: DatasetSpec
    seed: int
    fingerprint: str
    flags: dict
    index: int
    start: int
    stop: int
    directory: str
    crash: str | None = None
    threads: int | None = None


def _h5_attrs(dset, a: sc.ArraySpec) -> None:
    dset.attrs["units"] = a.units
    dset.attrs["axes"] = ",".join(a.axes)
    dset.attrs["description"] = a.description


def _write_shard(task: _ShardTask) -> dict:
    """Generate, write, checksum and atomically publish one shard; return its table row."""
    t_begin = time.perf_counter()
    if task.threads:
        limit_threads(task.threads)
    system, net_spec, chan_spec, dspec = task.system, task.network, task.channel, task.dataset
    r = task.stop - task.start
    K = net_spec.motion.n_snapshots
    seeds = [realization_seed(task.seed, i) for i in range(task.start, task.stop)]
    # pre-pass: the networks alone (the first draws of each stream) give the link counts
    counts = np.zeros((r, K), np.int64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IsolatedNodesWarning)
        for k, ss in enumerate(seeds):
            net = make_network(net_spec, np.random.default_rng(ss))
            counts[k] = [net.links_at(t).shape[0] for t in range(K)]
    L = max(1, int(counts.max()))
    arrays = sc.arrays_for(task.flags)
    dims = {
        "realization": r,
        "snapshot": K,
        "node": net_spec.n_nodes,
        "coordinate": net_spec.dim,
        "link": L,
        "end": 2,
        "subcarrier": system.n_subcarriers,
        "sample": system.n_samples,
    }
    small = {
        a.name: np.full(a.shape(dims), a.fill, dtype=a.dtype)
        for a in arrays
        if a.name not in _STREAMED and a.role != "path"
    }
    hashes = {name: hashlib.sha256() for name in _STREAMED}
    directory = Path(task.directory)
    final = directory / sc.shard_name(task.index)
    tmp = directory / f".{final.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    filt = dspec.h5_filter()
    t_sim = t_conv = t_write = 0.0
    noise_w = system.noise_power_w
    try:
        tw = time.perf_counter()
        f = h5py.File(tmp, "w")
        with f:
            M, N, n = system.n_samples, system.n_subcarriers, net_spec.n_nodes
            cl = min(dspec.chunk_links or L, L)
            rx = f.create_dataset(
                "received",
                shape=(r, K, L, M),
                dtype=np.complex64,
                chunks=(1, 1, cl, M),
                fillvalue=np.complex64(0),
                **filt,
            )
            sym = f.create_dataset(
                "symbols", shape=(r, n, N), dtype=np.complex64, chunks=(1, n, N), **filt
            )
            t_write += time.perf_counter() - tw
            slab = np.zeros((L, M), dtype=np.complex64)
            n_paths = 0
            path_delays, path_gains = [np.zeros(0)], [np.zeros(0, np.complex128)]
            for k, ss in enumerate(seeds):
                ts = time.perf_counter()
                real = simulate_realization(system, net_spec, chan_spec, np.random.default_rng(ss))
                t_sim += time.perf_counter() - ts
                net = real.network
                small["nodes/positions"][k] = net.positions
                if task.flags.get("velocities"):
                    small["nodes/velocities"][k] = net.velocities
                if task.flags.get("accelerations"):
                    small["nodes/accelerations"][k] = net.accelerations
                small["nodes/is_anchor"][k] = net.is_anchor
                s64 = real.symbols.astype(np.complex64)
                tw = time.perf_counter()
                sym[k] = s64
                t_write += time.perf_counter() - tw
                hashes["symbols"].update(s64.data)
                small["channel/paths/base"][k] = n_paths
                local = 0
                for t in range(K):
                    lk, draw = real.links[t], real.channels[t]
                    nt = lk.shape[0]
                    if nt != counts[k, t]:  # pragma: no cover - guards the pre-pass
                        raise RuntimeError(
                            f"realization {task.start + k}: {nt} links at snapshot {t}, "
                            f"the network pre-pass found {counts[k, t]}"
                        )
                    _fill_links(small, k, t, lk, draw, noise_w, local)
                    ps = draw.paths
                    path_delays.append(ps.delays)
                    path_gains.append(ps.gains)
                    local += ps.delays.size
                    tc = time.perf_counter()
                    slab[:nt] = to_time_domain(real.received[t], system)
                    slab[nt:] = 0
                    t_conv += time.perf_counter() - tc
                    tw = time.perf_counter()
                    rx[k, t] = slab
                    t_write += time.perf_counter() - tw
                    hashes["received"].update(slab.data)
                n_paths += local
                del real
                if task.crash is not None and k == 0:
                    _crash(task)
            small["channel/paths/delays_s"] = np.concatenate(path_delays)
            small["channel/paths/gains"] = np.concatenate(path_gains)
            del path_delays, path_gains
            tw = time.perf_counter()
            sums = {}
            for a in arrays:
                if a.role == "path":
                    data = small[a.name]
                    d = f.create_dataset(a.name, data=data, **(filt if data.size else {}))
                    d.attrs["sha256"] = sums[a.name] = sc.sha256_array(data)
                elif a.name in small:
                    d = f.create_dataset(a.name, data=small[a.name])
                    d.attrs["sha256"] = sums[a.name] = sc.sha256_array(small[a.name])
                else:
                    d = f[a.name]
                    d.attrs["sha256"] = sums[a.name] = hashes[a.name].hexdigest()
                _h5_attrs(d, a)
            from phyloc import __version__

            f.attrs.update(
                {
                    "format": sc.SHARD_FORMAT,
                    "schema_version": sc.SCHEMA_VERSION,
                    "phyloc_version": __version__,
                    "recipe_fingerprint": task.fingerprint,
                    "seed": task.seed,
                    "shard_index": task.index,
                    "realization_start": task.start,
                    "realization_stop": task.stop,
                    "max_links": L,
                    "n_links": int(counts.sum()),
                    "n_paths": n_paths,
                }
            )
            f.attrs["complete"] = 1
        _fsync(tmp)
        t_write += time.perf_counter() - tw
        digest = sc.sha256_file(tmp)
        os.replace(tmp, final)
        _fsync_dir(directory)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    record = {  # the row sc.shard_record would read back from the file
        "index": task.index,
        "start": task.start,
        "stop": task.stop,
        "file": final.name,
        "file_sha256": digest,
        "bytes": final.stat().st_size,
        "max_links": L,
        "n_links": int(counts.sum()),
        "n_paths": n_paths,
        "path_base": [int(x) for x in small["channel/paths/base"]],
        "arrays": sums,
    }
    record.update(
        seconds=time.perf_counter() - t_begin,
        simulate_seconds=t_sim,
        convert_seconds=t_conv,
        write_seconds=t_write,
    )
    return record


def _fill_links(small: dict, k: int, t: int, lk, draw, noise_w: float, local: int) -> None:
    nt = lk.shape[0]
    small["links/count"][k, t] = nt
    small["links/pairs"][k, t, :nt] = lk
    small["links/valid"][k, t, :nt] = 1
    small["channel/los"][k, t, :nt] = np.asarray(draw.los, bool)
    small["channel/distance_m"][k, t, :nt] = draw.distances_m
    small["channel/nlos_bias_s"][k, t, :nt] = draw.nlos_bias_s
    small["channel/path_loss_db"][k, t, :nt] = draw.path_loss_db
    small["channel/shadowing_db"][k, t, :nt] = draw.shadowing_db
    small["channel/shadowing_std_db"][k, t, :nt] = draw.shadowing_std_db
    small["channel/received_power_w"][k, t, :nt] = draw.received_power_w
    with np.errstate(divide="ignore"):
        small["channel/snr_db"][k, t, :nt] = 10.0 * np.log10(draw.received_power_w / noise_w)
    small["channel/delay_spread_s"][k, t, :nt] = draw.delay_spread_s
    small["channel/k_factor_db"][k, t, :nt] = draw.k_factor_db
    off = draw.paths.offsets
    small["channel/paths/start"][k, t, :nt] = local + off[:-1]
    small["channel/paths/count"][k, t, :nt] = np.diff(off)


def _crash(task: _ShardTask) -> None:
    if task.crash == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
    raise RuntimeError(f"simulated crash of shard {task.index} ({CRASH_ENV})")


def _fsync(path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(path) -> None:
    with contextlib.suppress(OSError):  # not every platform/filesystem syncs directories
        _fsync(path)


# -- the master file -------------------------------------------------------------------------
def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")


def write_master(out, plan: DatasetPlan, records, *, created: str | None = None) -> Path:
    """Write the master file of ``out`` from the shard table ``records`` (atomically).

    ``records[j]`` is shard j's row (as returned by a shard task or
    :func:`~phyloc.datasets.schema.check_shard`) or None when the shard is not complete.
    """
    from phyloc import __version__

    out = Path(out)
    sdir = sc.shard_dir(out)
    dspec, net, system = plan.dataset, plan.network, plan.system
    R, S = dspec.realizations, dspec.n_shards
    done = [rec for rec in records if rec is not None]
    L = max([1, *(rec["max_links"] for rec in done)])
    path_offset, P = {}, 0
    for rec in done:
        path_offset[rec["index"]] = P
        P += rec["n_paths"]
    dims = plan.dims(R, L, P)
    arrays = plan.arrays
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs.update(
                {
                    "format": sc.MASTER_FORMAT,
                    "schema_version": sc.SCHEMA_VERSION,
                    "phyloc_version": __version__,
                    "created_utc": created or _now(),
                    "modified_utc": _now(),
                    "name": plan.recipe.name,
                    "description": plan.recipe.description,
                    "recipe": plan.recipe_text(),
                    "recipe_fingerprint": plan.fingerprint,
                    "seed": plan.seed,
                    "seed_scheme": sc.SEED_SCHEME,
                    "n_realizations": R,
                    "n_snapshots": net.motion.n_snapshots,
                    "n_nodes": net.n_nodes,
                    "n_agents": net.n_agents,
                    "n_anchors": net.n_anchors,
                    "dim": net.dim,
                    "max_links": L,
                    "n_subcarriers": system.n_subcarriers,
                    "n_samples": system.n_samples,
                    "scenario": str(plan.channel.scenario),
                    "ranging": plan.channel.ranging,
                    "ways": 2 if plan.channel.ranging == "two_way" else 1,
                    "comm_range_m": math.nan if net.comm_range_m is None else net.comm_range_m,
                    "dt_s": net.motion.dt_s if net.motion.n_snapshots > 1 else math.nan,
                    "shard_size": dspec.shard_size,
                    "n_shards": S,
                    "shards_complete": len(done),
                    "complete": int(len(done) == S),
                    "shard_directory": sdir.name,
                }
            )
            g = f.create_group("system")
            g.attrs.update(system.to_dict())
            g.attrs.update(
                {
                    "bandwidth_hz": system.bandwidth_hz,
                    "sample_period_s": system.sample_period_s,
                    "symbol_duration_s": system.symbol_duration_s,
                    "noise_power_w": system.noise_power_w,
                }
            )
            _write_shard_table(f, plan, records, arrays, sdir.name)
            for a in arrays:
                _write_master_array(f, a, dims, done, path_offset, sdir.name)
            _write_dimension_scales(f, plan, dims, arrays)
            f.attrs[sc.MASTER_DIGEST_ATTR] = sc.master_digest(f)  # last: covers the rest
        os.replace(tmp, out)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    return out


def _write_shard_table(f, plan, records, arrays, sdir_name) -> None:
    S = plan.dataset.n_shards
    g = f.create_group("shards")
    rng_ = [plan.dataset.shard_range(j) for j in range(S)]

    def col(key, default, dtype):
        return np.array(
            [default if rec is None else rec[key] for rec in records], dtype=dtype
        ).reshape(S)

    g.create_dataset("realization_start", data=np.array([a for a, _ in rng_], np.int64))
    g.create_dataset("realization_stop", data=np.array([b for _, b in rng_], np.int64))
    g.create_dataset("complete", data=np.array([rec is not None for rec in records], np.uint8))
    g.create_dataset(
        "file",
        data=np.array([f"{sdir_name}/{sc.shard_name(j)}" for j in range(S)], dtype=object),
        dtype=h5py.string_dtype(),
    )
    g.create_dataset("file_sha256", data=col("file_sha256", "", "S64"))
    g.create_dataset("bytes", data=col("bytes", 0, np.int64))
    g.create_dataset("max_links", data=col("max_links", 0, np.int32))
    g.create_dataset("n_links", data=col("n_links", 0, np.int64))
    g.create_dataset("n_paths", data=col("n_paths", 0, np.int64))
    sums = np.zeros((S, len(arrays)), dtype="S64")
    for j, rec in enumerate(records):
        if rec is not None:
            sums[j] = [rec["arrays"][a.name] for a in arrays]
    d = g.create_dataset("array_sha256", data=sums)
    d.attrs["arrays"] = [a.name for a in arrays]
    g.attrs["directory"] = sdir_name
    g["file"].attrs["description"] = "shard file, relative to the master file's folder"


def _write_dimension_scales(f, plan, dims, arrays) -> None:
    """HDF5 dimension scales (one root dataset per axis, with coordinate values where they
    exist) attached to every array of the master and of its shard table, so netCDF readers
    (``h5netcdf``, xarray) see named dimensions instead of ``phony_dim_*``."""
    system, net = plan.system, plan.network
    K, N = dims["snapshot"], dims["subcarrier"]
    dt = net.motion.dt_s if K > 1 else 0.0
    n = np.arange(N) - (N - 1) // 2
    coords = {
        "realization": (np.arange(dims["realization"]), "1", "realization index"),
        "snapshot": (np.arange(K) * dt, "s", "snapshot time"),
        "node": (np.arange(dims["node"]), "1", "node id"),
        "coordinate": (np.arange(dims["coordinate"]), "1", "position axis (0: x, 1: y, 2: z)"),
        "link": (np.arange(dims["link"]), "1", "link row (padded; links/valid marks real ones)"),
        "end": (np.arange(2), "1", "link end (0: receiver u, 1: transmitter v)"),
        "subcarrier": (
            n * system.subcarrier_spacing_hz,
            "Hz",
            "subcarrier frequency relative to the carrier, n f_sc, n = -(N-1)/2 .. (N-1)/2",
        ),
        "sample": (
            np.arange(dims["sample"]) * system.sample_period_s,
            "s",
            "sample time i T within the OFDM symbol",
        ),
        "path": (np.arange(dims["path"]), "1", "path row (all links' paths concatenated)"),
        "shard": (np.arange(plan.dataset.n_shards), "1", "shard index"),
        "array": (np.arange(len(arrays)), "1", "array (the order of shards/array_sha256)"),
    }
    scales = {}
    for name, (values, units, description) in coords.items():
        d = f.create_dataset(name, data=values)
        d.attrs["units"] = units
        d.attrs["description"] = description
        d.make_scale(name)
        scales[name] = d
    for a in arrays:
        for i, ax in enumerate(a.axes):
            f[a.name].dims[i].attach_scale(scales[ax])
    for d in f["shards"].values():
        d.dims[0].attach_scale(scales["shard"])
        if d.ndim == 2:
            d.dims[1].attach_scale(scales["array"])


def _write_master_array(f, a: sc.ArraySpec, dims, done, path_offset, sdir_name) -> None:
    shape = a.shape(dims)
    if a.role == "base":
        base = np.full(shape, -1, np.int64)
        for rec in done:
            base[rec["start"] : rec["stop"]] = path_offset[rec["index"]] + np.asarray(
                rec["path_base"], np.int64
            )
        d = f.create_dataset(a.name, data=base)
        _h5_attrs(d, a)
        return
    layout = h5py.VirtualLayout(shape=shape, dtype=np.dtype(a.dtype))
    for rec in done:
        fname = f"{sdir_name}/{rec['file']}"
        if a.role == "path":
            n = rec["n_paths"]
            if n:
                p0 = path_offset[rec["index"]]
                layout[p0 : p0 + n] = h5py.VirtualSource(fname, a.name, shape=(n,))
            continue
        sizes = dict(dims, realization=rec["stop"] - rec["start"], link=rec["max_links"])
        src_shape = a.shape(sizes)
        sel = tuple(
            slice(rec["start"], rec["stop"])
            if ax == "realization"
            else slice(0, rec["max_links"])
            if ax == "link"
            else slice(None)
            for ax in a.axes
        )
        layout[sel] = h5py.VirtualSource(fname, a.name, shape=src_shape)
    d = f.create_virtual_dataset(a.name, layout, fillvalue=np.array(a.fill, dtype=a.dtype))
    _h5_attrs(d, a)


# -- generation --------------------------------------------------------------------------------
def generate(
    recipe,
    out_path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> dict:
    """Generate a waveform dataset from a recipe into an HDF5 master file and its shards.

    Draws every realization of a ``kind = "dataset"`` recipe (network, channels, pilots,
    received waveforms), in shards of ``[dataset] shard_size`` realizations, and writes them to
    ``OUT.h5`` (master: metadata, shard table, virtual datasets) and ``OUT.h5.shards/`` (one
    file per shard). Every shard is written to a temporary file, checksummed (SHA-256 of every
    array) and renamed into place, so an interrupted run loses no finished shard. The data do
    not depend on the worker count. Schema: ``datasets/README.md``.

    Parameters
    ----------
    recipe : Recipe, path or TOML text
        A recipe of ``kind = "dataset"``; validated completely before any work starts.
    out_path : str or Path
        The master file to write (e.g. ``c2.h5``); the shards go to ``<out_path>.shards/``.
        With Dask workers on other machines, it must be on a filesystem they share.
    workers : int, optional
        Local worker processes: None or 1 runs the shards in this process; N > 1 starts an
        embedded Dask ``LocalCluster`` of N single-threaded processes.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``) to run the shards on
        (excludes ``workers``).
    resume : bool
        Finish or repair an existing output: keep every sound shard, generate missing or
        corrupt ones again. Without it an existing output is an error.
    progress : bool
        Show a progress bar (tqdm) of completed shards (also off when ``PHYLOC_NO_PROGRESS``
        is set).

    Returns
    -------
    summary : dict
        ``path``, ``shards`` (total), ``shards_written`` and ``shards_reused`` (this run),
        ``realizations``, ``links`` (received waveforms written, one per directed link and
        snapshot), ``seconds`` (wall time), ``links_per_s``, ``bytes`` (dataset size on disk),
        ``bytes_written``, ``write_seconds`` (time spent in HDF5 writes and flushes, summed
        over shards), ``write_mb_per_s`` (``bytes_written / write_seconds`` in 10⁶ B/s),
        ``workers``.

    Raises
    ------
    ValidationError
        A bad recipe or option (before any work).
    DatasetExistsError
        The output exists and ``resume`` is False.
    DatasetMismatchError
        ``resume`` on an output generated from a different recipe.
    SchemaVersionError
        ``resume`` on an output of a newer schema.
    DatasetBusyError
        Another process is generating the same output.
    ShardGenerationError
        Some shards failed (their error is chained); completed shards are kept, rerun with
        ``resume=True``.
    """
    t0 = time.perf_counter()
    plan = plan_dataset(recipe)
    if scheduler is not None and workers not in (None, 1):
        raise ValidationError("workers", workers, "give either workers or a scheduler, not both")
    if scheduler is not None and not isinstance(scheduler, str):
        raise ValidationError("scheduler", scheduler, "a Dask scheduler address (tcp://host:8786)")
    if workers is not None:
        workers = v.integer("workers", workers, minimum=1)
    out = Path(out_path)
    sdir = sc.shard_dir(out)
    if out.is_dir():
        raise ValidationError("out_path", str(out), "is a folder; give the path of an .h5 file")
    if (out.exists() or sdir.exists()) and not resume:
        raise sc.DatasetExistsError(out)
    fresh = not out.exists() and not sdir.exists()
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        sdir.mkdir(exist_ok=True)
        return _generate(plan, out, sdir, t0, workers, scheduler, resume, progress)
    except BaseException:
        if fresh:  # a run that failed before finishing any shard leaves nothing behind
            _remove_if_no_shard(out, sdir)
        raise


def _remove_if_no_shard(out: Path, sdir: Path) -> None:
    """Delete the master, lock and shard folder a failed first run created, unless a shard
    was finished (then ``--resume`` has something to keep)."""
    if sdir.is_dir() and any(sdir.glob("shard-*.h5")):
        return
    with contextlib.suppress(OSError):
        out.unlink(missing_ok=True)
        if sdir.is_dir():
            for p in sdir.iterdir():  # the lock and temporary files of this run
                p.unlink()
            sdir.rmdir()


def _generate(plan, out, sdir, t0, workers, scheduler, resume, progress) -> dict:
    """The body of :func:`generate` once the output folder exists."""
    dspec = plan.dataset
    S = dspec.n_shards
    with _lock(sdir, out):
        created, known = _previous_master(out, plan, sdir)
        created = created or _now()
        records: list = [None] * S
        if resume:
            records = _scan_shards(plan, sdir, known)
        reused = sum(rec is not None for rec in records)
        write_master(out, plan, records, created=created)
        crash = _crash_hook()
        threads = None  # in-process: the kernels may use every core
        if scheduler is not None:
            threads = 1  # Dask's model: parallel tasks, one thread each
        elif workers and workers > 1:
            threads = threads_per_task(workers)
        tasks = [
            _ShardTask(
                plan.system,
                plan.network,
                plan.channel,
                dspec,
                plan.seed,
                plan.fingerprint,
                plan.flags,
                j,
                *dspec.shard_range(j),
                str(sdir.resolve()),
                crash.get(j),
                threads,
            )
            for j in range(S)
            if records[j] is None
        ]
        in_process = scheduler is None and (workers is None or workers == 1)
        stack = contextlib.ExitStack()
        client = None
        if tasks and not in_process:  # connect first: a bad address fails before the bar
            from phyloc.parallel import dask_client

            client = stack.enter_context(dask_client(workers=workers, scheduler=scheduler))
        show = progress and not os.environ.get("PHYLOC_NO_PROGRESS")
        bar = tqdm(
            total=S,
            initial=reused,
            desc=f"generate {plan.recipe.name}",
            unit="shard",
            disable=not show,
            leave=False,
        )
        written, failures = [], []
        last = [time.perf_counter()]
        t_run = time.perf_counter()

        def done(task, rec, exc):
            if exc is not None:
                failures.append((task.index, exc))
            else:
                records[task.index] = rec
                written.append(rec)
                links = sum(r["n_links"] for r in written)
                bar.set_postfix(links_per_s=f"{links / (time.perf_counter() - t_run):.0f}")
                if time.perf_counter() - last[0] > _MASTER_EVERY_S:
                    write_master(out, plan, records, created=created)
                    last[0] = time.perf_counter()
            bar.update(1)

        try:
            if in_process:
                for task in tasks:
                    try:
                        rec = _write_shard(task)
                    except Exception as exc:  # kept; reported after the rest
                        done(task, None, exc)
                    else:
                        done(task, rec, None)
            elif tasks:
                _run_dask(client, tasks, done)
        finally:
            bar.close()
            stack.close()
            write_master(out, plan, records, created=created)
    if failures:
        j, exc = failures[0]
        kept = sum(rec is not None for rec in records)
        raise sc.ShardGenerationError(
            f"{len(failures)} of {S} shards failed (shard {j}: {type(exc).__name__}: {exc}); "
            f"the {kept} complete shards are kept in {sdir}. Fix the cause and rerun with "
            "--resume (resume=True) to generate only the missing ones"
        ) from exc
    seconds = time.perf_counter() - t0
    links = sum(rec["n_links"] for rec in written)
    bytes_written = sum(rec["bytes"] for rec in written)
    write_s = sum(rec["write_seconds"] for rec in written)
    total = out.stat().st_size + sum(rec["bytes"] for rec in records if rec is not None)
    return {
        "path": str(out),
        "shards": S,
        "shards_written": len(written),
        "shards_reused": reused,
        "realizations": dspec.realizations,
        "links": links,
        "seconds": seconds,
        "links_per_s": links / seconds if seconds > 0 else math.nan,
        "bytes": total,
        "bytes_written": bytes_written,
        "write_seconds": write_s,
        "write_mb_per_s": bytes_written / write_s / 1e6 if write_s > 0 else math.nan,
        "simulate_seconds": sum(rec["simulate_seconds"] for rec in written),
        "workers": scheduler if scheduler is not None else (workers or 1),
    }


def _run_dask(client, tasks, done) -> None:
    """Write the shards of ``tasks`` on the workers of ``client``; ``done`` as each ends."""
    from dask.distributed import as_completed

    tag = uuid.uuid4().hex[:8]
    futures = {
        client.submit(_write_shard, t, key=f"phyloc-shard-{t.index:05d}-{tag}", pure=False): t
        for t in tasks
    }
    for fut in as_completed(futures):
        task = futures[fut]
        try:
            rec = fut.result()
        except Exception as exc:  # kept; reported after the rest
            done(task, None, exc)
        else:
            done(task, rec, None)


def _crash_hook() -> dict:
    raw = os.environ.get(CRASH_ENV, "").strip()
    out = {}
    for item in filter(None, (s.strip() for s in raw.split(","))):
        idx, _, mode = item.partition(":")
        out[int(idx)] = "kill" if mode == "kill" else "raise"
    return out


@contextlib.contextmanager
def _lock(sdir: Path, out: Path):
    """Hold an exclusive lock on ``sdir/.lock`` (released by the OS if the process dies)."""
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


def _previous_master(out: Path, plan: DatasetPlan, sdir: Path):
    """Creation time and recorded file checksums of an existing master (checked to belong to
    this recipe); (None, {}) when there is none or it is unreadable (it is rebuilt)."""
    if not out.exists():
        return None, {}
    try:
        f = h5py.File(out, "r")
    except OSError:
        if any(sdir.glob("shard-*.h5")) or not out.stat().st_size:
            return None, {}  # a damaged master of ours: rebuilt from the shards
        raise sc.DatasetError(
            f"{out} exists and is not a readable HDF5 file; refusing to overwrite it"
        ) from None
    with f:
        sc.check_version(f.attrs, out, sc.MASTER_FORMAT)
        fp = sc._text(f.attrs.get("recipe_fingerprint", ""))
        if fp != plan.fingerprint:
            raise sc.DatasetMismatchError(
                f"{out} was generated from a different recipe (or seed) than "
                f"{plan.recipe.path or plan.recipe.name!s}; resume needs the same recipe. "
                "Choose another output path to generate this one"
            )
        created = sc._text(f.attrs.get("created_utc", "")) or None
        known = {}
        try:
            g = f["shards"]
            for j, (c, h) in enumerate(zip(g["complete"][:], g["file_sha256"][:], strict=True)):
                if c:
                    known[j] = h.decode()
        except (KeyError, OSError, ValueError):
            known = {}
    return created, known


def _scan_shards(plan: DatasetPlan, sdir: Path, known: dict) -> list:
    """Check every existing shard; keep the sound ones, delete stale temporary files."""
    for stale in sdir.glob(".shard-*.tmp-*"):
        with contextlib.suppress(OSError):
            stale.unlink()
    records = []
    for j in range(plan.dataset.n_shards):
        start, stop = plan.dataset.shard_range(j)
        rec, kind, reason = sc.check_shard(
            sdir / sc.shard_name(j),
            index=j,
            start=start,
            stop=stop,
            fingerprint=plan.fingerprint,
            arrays=plan.arrays,
            file_sha256=known.get(j),
        )
        if kind == "foreign":
            raise sc.DatasetMismatchError(
                f"{sdir / sc.shard_name(j)}: {reason}; resume needs the recipe the output was "
                "generated from. Choose another output path to generate this one"
            )
        records.append(rec)
    return records


__all__ = [
    "CRASH_ENV",
    "DatasetPlan",
    "generate",
    "plan_dataset",
    "realization_seed",
    "simulate_recipe_realization",
    "write_master",
]
