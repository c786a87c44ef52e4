"""One shard of a waveform dataset: synthesize its realizations, write, checksum, publish.

A shard holds the realizations ``[start, stop)`` of a dataset under the array names of the
master (``datasets/README.md``). :func:`write_shard` runs one :class:`ShardTask` — anywhere: in
the generating process or on a Dask worker; it needs nothing but the task — and

1. draws realization ``i`` with :func:`~phyloc.datasets.simulate.simulate_realization` from
   its own stream :func:`~phyloc.datasets.plan.realization_seed` ``(seed, i)``;
2. writes the arrays to a temporary file in ``OUT.h5.shards/``: the received waveforms
   (complex64 time samples, :func:`~phyloc.phy.waveform.to_time_domain`) and the pilots as each
   realization is drawn, hashing them as they go, then the truth arrays at once;
3. records the SHA-256 of every array as an attribute, flushes the file to disk and renames it
   into place atomically (``shard-00000.h5``, ...).

It returns the shard's row of the master's shard table (:func:`shard_attributes` are the
file's own attributes). Shards are bit-identical for any worker count on one platform (the
Numba kernels run per link, FFTs are batched pocketfft transforms); workers on different CPUs
may compile the kernels differently, which can change the last bits of a few samples.

References
----------
The HDF Group, *HDF5 User's Guide*, https://docs.hdfgroup.org/; the h5py documentation,
https://docs.h5py.org/.

NumPy, "Parallel random number generation" (``SeedSequence.spawn``),
https://numpy.org/doc/stable/reference/random/parallel.html.
"""

from __future__ import annotations

import hashlib
import os
import signal
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from phyloc._files import require_space, reserve_space
from phyloc.channels import ChannelSpec
from phyloc.datasets import schema as sc
from phyloc.datasets.files import fsync, fsync_dir, staged
from phyloc.datasets.plan import DatasetPlan, array_dims, realization_seed
from phyloc.datasets.simulate import simulate_realization
from phyloc.datasets.spec import DatasetSpec
from phyloc.network import IsolatedNodesWarning, NetworkSpec, make_network
from phyloc.parallel import limit_threads
from phyloc.phy.system import OFDMSystem
from phyloc.phy.waveform import to_time_domain

#: Test hook: ``"k"`` makes shard k fail with an exception after writing part of its temporary
#: file; ``"k:kill"`` kills the generating process there with SIGKILL (a crash).
CRASH_ENV = "PHYLOC_TEST_CRASH_SHARD"
_STREAMED = ("received", "symbols")  # written per realization/snapshot, hashed as they go


@dataclass(frozen=True)
class ShardTask:
    """Everything :func:`write_shard` needs for shard ``index`` (realizations ``[start, stop)``),
    small enough to send to a Dask worker. ``directory`` is the shard folder, ``crash`` the
    :data:`CRASH_ENV` test mode of this shard and ``threads`` the kernels' thread limit."""

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

    @classmethod
    def of(cls, plan: DatasetPlan, index: int, directory, *, crash=None, threads=None):
        """The task of shard ``index`` of ``plan``, written into folder ``directory``."""
        return cls(
            plan.system,
            plan.network,
            plan.channel,
            plan.dataset,
            plan.seed,
            plan.fingerprint,
            plan.flags,
            index,
            *plan.dataset.shard_range(index),
            str(directory),
            crash,
            threads,
        )


def crash_modes() -> dict:
    """The shards :data:`CRASH_ENV` makes fail, by index: ``"raise"`` or ``"kill"``."""
    raw = os.environ.get(CRASH_ENV, "").strip()
    out = {}
    for item in filter(None, (s.strip() for s in raw.split(","))):
        idx, _, mode = item.partition(":")
        out[int(idx)] = "kill" if mode == "kill" else "raise"
    return out


def shard_attributes(*, fingerprint, seed, index, start, stop, max_links, n_links, n_paths) -> dict:
    """The root attributes of a shard file (but ``complete``, which is set last)."""
    from phyloc import __version__

    return {
        "format": sc.SHARD_FORMAT,
        "schema_version": sc.SCHEMA_VERSION,
        "phyloc_version": __version__,
        "recipe_fingerprint": fingerprint,
        "seed": seed,
        "shard_index": index,
        "realization_start": start,
        "realization_stop": stop,
        "max_links": max_links,
        "n_links": n_links,
        "n_paths": n_paths,
    }


def _link_counts(task: ShardTask, seeds) -> np.ndarray:
    """Links per (realization, snapshot) from the networks alone (the first draws of each
    stream): the pre-pass that sizes the link axis before any waveform is drawn."""
    K = task.network.motion.n_snapshots
    counts = np.zeros((len(seeds), K), np.int64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IsolatedNodesWarning)
        for k, ss in enumerate(seeds):
            net = make_network(task.network, np.random.default_rng(ss))
            counts[k] = [net.links_at(t).shape[0] for t in range(K)]
    return counts


#: Paths per link budgeted when a shard's size is estimated before it is simulated.
PATHS_PER_LINK_ESTIMATE = 32


def _shard_bytes(r, K, L, M, n, N, small) -> int:
    """An estimate of a shard's size before it is written [bytes]: the uncompressed received
    samples and symbols (complex64), the per-link arrays, and :data:`PATHS_PER_LINK_ESTIMATE`
    paths (a float64 delay and a complex128 gain) per link. HDF5 cannot recover from a write
    that fails half-way, so :func:`write_shard` allocates this much before it writes."""
    per_link_paths = PATHS_PER_LINK_ESTIMATE * 24
    return int(
        1.02  # HDF5's chunk index and attributes
        * (
            8 * r * K * L * M
            + 8 * r * n * N
            + sum(a.nbytes for a in small.values())
            + per_link_paths * r * K * L
        )
    )


def write_shard(task: ShardTask) -> dict:
    """Generate, write, checksum and atomically publish one shard; return its table row.

    The row holds ``index``, ``start``, ``stop``, ``file``, ``file_sha256``, ``bytes``,
    ``max_links``, ``n_links``, ``n_paths``, ``path_base``, ``arrays`` (SHA-256 by name) — as
    :func:`~phyloc.datasets.schema.shard_record` reads them back from the file — and the
    timings ``seconds``, ``simulate_seconds``, ``convert_seconds`` and ``write_seconds``.
    """
    t_begin = time.perf_counter()
    if task.threads:
        limit_threads(task.threads)
    system, net_spec, chan_spec, dspec = task.system, task.network, task.channel, task.dataset
    r = task.stop - task.start
    K = net_spec.motion.n_snapshots
    seeds = [realization_seed(task.seed, i) for i in range(task.start, task.stop)]
    counts = _link_counts(task, seeds)
    L = max(1, int(counts.max()))
    arrays = sc.arrays_for(task.flags)
    dims = array_dims(system, net_spec, r, L)
    small = {
        a.name: np.full(a.shape(dims), a.fill, dtype=a.dtype)
        for a in arrays
        if a.name not in _STREAMED and a.role != "path"
    }
    hashes = {name: hashlib.sha256() for name in _STREAMED}
    directory = Path(task.directory)
    final = directory / sc.shard_name(task.index)
    filt = dspec.h5_filter()
    t_sim = t_conv = t_write = 0.0
    noise_w = system.noise_power_w
    M, N, n = system.n_samples, system.n_subcarriers, net_spec.n_nodes
    need = _shard_bytes(r, K, L, M, n, N, small)
    require_space(directory, need, f"shard {task.index}")
    with staged(final) as tmp:
        tw = time.perf_counter()
        # HDF5 may crash on close after a write that failed for want of space, so the space
        # is allocated first: a full disk is then a clean DiskFullError, before any data
        h5py.File(tmp, "w").close()
        reserve_space(tmp, need, f"shard {task.index}")
        f = h5py.File(tmp, "r+")
        with f:
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
                a.annotate(d)
            f.attrs.update(
                shard_attributes(
                    fingerprint=task.fingerprint,
                    seed=task.seed,
                    index=task.index,
                    start=task.start,
                    stop=task.stop,
                    max_links=L,
                    n_links=int(counts.sum()),
                    n_paths=n_paths,
                )
            )
            f.attrs["complete"] = 1
        fsync(tmp)
        t_write += time.perf_counter() - tw
        digest = sc.sha256_file(tmp)
        os.replace(tmp, final)
        fsync_dir(directory)
    return {  # the row sc.shard_record would read back from the file
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
        "seconds": time.perf_counter() - t_begin,
        "simulate_seconds": t_sim,
        "convert_seconds": t_conv,
        "write_seconds": t_write,
    }


def _fill_links(small: dict, k: int, t: int, lk, draw, noise_w: float, local: int) -> None:
    """The per-link truth of realization ``k``, snapshot ``t`` into the shard's arrays."""
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


def _crash(task: ShardTask) -> None:
    if task.crash == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
    raise RuntimeError(f"simulated crash of shard {task.index} ({CRASH_ENV})")


__all__ = ["CRASH_ENV", "ShardTask", "crash_modes", "shard_attributes", "write_shard"]
