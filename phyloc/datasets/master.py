"""The master file of a waveform dataset: virtual datasets over the shards, the shard table.

The master ``OUT.h5`` holds no waveform itself. :func:`write_master` writes, from the shard
table (one row per complete shard, as :func:`~phyloc.datasets.shard.write_shard` or
:func:`~phyloc.datasets.schema.check_shard` return it):

* the dataset's attributes (recipe text and fingerprint, sizes, system, scenario, progress);
* the shard table ``/shards`` (which shards are complete, their realization ranges, the
  SHA-256 of every file and of every array);
* every array of the schema as an HDF5 virtual dataset mapping the complete shards' arrays
  (missing shards read as the array's fill value), the path arrays concatenated over shards;
* HDF5 dimension scales on every array (named dimensions for netCDF readers);
* last, its own content SHA-256 (:func:`~phyloc.datasets.schema.master_digest`).

It is rewritten atomically (temporary file + rename) and can always be rebuilt from the shards.
For a resume, :func:`previous_master` reads back what an earlier run recorded (creation time,
the shards' file checksums; refusing an output of another recipe) and :func:`scan_shards`
checks every existing shard, keeping the sound ones.

References
----------
The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS) and dimension scales,
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.
"""

from __future__ import annotations

import contextlib
import math
from datetime import UTC, datetime
from pathlib import Path

import h5py
import numpy as np

from phyloc._files import write_atomic
from phyloc.datasets import schema as sc
from phyloc.datasets.files import temp_path
from phyloc.datasets.plan import DatasetPlan


def utc_now() -> str:
    """The current UTC time as the master records it (``2024-05-01T12:00:00Z``)."""
    return datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")


def write_master(
    out, plan: DatasetPlan, records, *, created: str | None = None, attrs: dict | None = None
) -> Path:
    """Write the master file of ``out`` from the shard table ``records`` (atomically).

    ``records[j]`` is shard j's row (as returned by a shard task or
    :func:`~phyloc.datasets.schema.check_shard`) or None when the shard is not complete.
    ``attrs`` are root attributes set last (an imported dataset's provenance). The file's
    bytes carry their SHA-256 in a user block (:func:`~phyloc.datasets.schema.stamp_master`).
    """
    out = Path(out)
    sdir = sc.shard_dir(out)
    R = plan.dataset.realizations
    done = [rec for rec in records if rec is not None]
    L = max([1, *(rec["max_links"] for rec in done)])
    path_offset, P = {}, 0
    for rec in done:
        path_offset[rec["index"]] = P
        P += rec["n_paths"]
    dims = plan.dims(R, L, P)
    arrays = plan.arrays
    # built in memory, then written in one piece: a full disk then fails in plain Python with
    # the master's path, never inside HDF5 half-way through a file (phyloc._files)
    with h5py.File(temp_path(out), "w", driver="core", backing_store=False) as f:
        f.attrs.update(_master_attributes(plan, L, len(done), created, sdir.name))
        g = f.create_group("system")
        g.attrs.update(plan.system.to_dict())
        g.attrs.update(
            {
                "bandwidth_hz": plan.system.bandwidth_hz,
                "sample_period_s": plan.system.sample_period_s,
                "symbol_duration_s": plan.system.symbol_duration_s,
                "noise_power_w": plan.system.noise_power_w,
            }
        )
        _write_shard_table(f, plan, records, arrays, sdir.name)
        for a in arrays:
            _write_master_array(f, a, dims, done, path_offset, sdir.name)
        _write_dimension_scales(f, plan, dims, arrays)
        f.attrs.update(attrs or {})
        f.attrs[sc.MASTER_DIGEST_ATTR] = sc.master_digest(f)  # last: covers the rest
        f.flush()
        image = f.id.get_file_image()
    write_atomic(out, sc.stamp_master(image))
    return out


def _master_attributes(plan: DatasetPlan, L: int, n_done: int, created, sdir_name) -> dict:
    """The root attributes of the master: what the dataset is, its sizes and its progress."""
    from phyloc import __version__

    dspec, net, system = plan.dataset, plan.network, plan.system
    S = dspec.n_shards
    return {
        "format": sc.MASTER_FORMAT,
        "schema_version": sc.SCHEMA_VERSION,
        "phyloc_version": __version__,
        "created_utc": created or utc_now(),
        "modified_utc": utc_now(),
        "name": plan.recipe.name,
        "description": plan.recipe.description,
        "recipe": plan.recipe_text(),
        "recipe_fingerprint": plan.fingerprint,
        "seed": plan.seed,
        "seed_scheme": sc.SEED_SCHEME,
        "n_realizations": dspec.realizations,
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
        "shards_complete": n_done,
        "complete": int(n_done == S),
        "shard_directory": sdir_name,
    }


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
        a.annotate(d)
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
    a.annotate(d)


def previous_master(out: Path, plan: DatasetPlan, sdir: Path):
    """Creation time and recorded file checksums of an existing master (checked to belong to
    this recipe); (None, {}) when there is none or it is unreadable (it is rebuilt).

    Returns
    -------
    (created, known)
        ``created_utc`` of the master (None if there is none) and, by shard index, the file
        SHA-256 it records for every complete shard.

    Raises
    ------
    DatasetMismatchError
        The master belongs to another recipe (or seed).
    SchemaVersionError
        The master was written with a newer schema.
    DatasetError
        ``out`` is some other file, not an HDF5 file phyloc can rebuild.
    """
    if not out.exists():
        return None, {}
    try:
        if sc.master_bytes_problem(out):
            raise OSError("damaged master")  # HDF5 may crash on it: never opened
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


def remove_stale(sdir: Path) -> None:
    """Remove the temporary shard files of interrupted or stopped writers in ``sdir`` (the
    caller holds the output lock, so no live writer of this output owns one)."""
    for stale in Path(sdir).glob(".shard-*.tmp-*"):
        with contextlib.suppress(OSError):
            stale.unlink()


def scan_shards(plan: DatasetPlan, sdir: Path, known: dict) -> list:
    """Check every shard file of ``plan`` in ``sdir`` (a resume): return the shard table, the
    row of every sound shard and None for a missing or corrupt one (generated again). Deletes
    stale temporary files of interrupted runs.

    ``known`` maps shard indices to the file SHA-256 the previous master recorded
    (:func:`previous_master`).

    Raises
    ------
    DatasetMismatchError
        A shard was generated from another recipe.
    """
    remove_stale(sdir)
    records = []
    net = plan.network
    links = sc.max_possible_links(net.n_agents, net.n_anchors)
    for j in range(plan.dataset.n_shards):
        start, stop = plan.dataset.shard_range(j)
        n_links = (stop - start) * net.motion.n_snapshots * links
        rec, kind, reason = sc.check_shard(
            sdir / sc.shard_name(j),
            index=j,
            start=start,
            stop=stop,
            fingerprint=plan.fingerprint,
            arrays=plan.arrays,
            file_sha256=known.get(j),
            dims=plan.dims(stop - start, links, n_links * sc.MAX_PATHS_PER_LINK),
        )
        if kind == "foreign":
            raise sc.DatasetMismatchError(
                f"{sdir / sc.shard_name(j)}: {reason}; resume needs the recipe the output was "
                "generated from. Choose another output path to generate this one"
            )
        records.append(rec)
    return records


__all__ = ["previous_master", "scan_shards", "utc_now", "write_master"]
