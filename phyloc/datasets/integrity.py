"""Integrity of a waveform dataset: the master's own checksum and every shard's checksums, and
the summary ``phyloc info`` prints (:func:`info`, with ``verify`` these checks added).

A dataset is sound when its master holds what it should and matches its own SHA-256
(:func:`check_master`) and every shard is complete, present, belongs to the dataset and
matches its checksums. :func:`verify_dataset` (``phyloc info --verify``,
``phyloc.datasets.verify``) checks all of it and lists every problem;
:func:`check_shard_files` (what ``phyloc evaluate`` runs before reading) checks each shard
file's SHA-256 against the master's record in one pass over its bytes and stops at the first
problem, naming the command that repairs it. Checksums are those of
:mod:`phyloc.datasets.schema`.

References
----------
The HDF Group, *HDF5 User's Guide*, https://docs.hdfgroup.org/; the h5py documentation,
https://docs.h5py.org/; NIST FIPS 180-4, *Secure Hash Standard* (SHA-256), 2015.
"""

from __future__ import annotations

import time

import h5py

from phyloc.datasets import schema as sc
from phyloc.datasets.reader import Dataset, _master_read, open_dataset


def _axis_sizes(ds: Dataset) -> dict:
    """The axis sizes a shard's arrays may declare (``link`` an upper bound), from the
    master's attributes (:func:`~phyloc.datasets.schema.check_shard`)."""
    return {
        "snapshot": ds.n_snapshots,
        "node": ds.n_nodes,
        "coordinate": ds.dim,
        "link": ds.max_links,
        "end": 2,
        "subcarrier": ds.system.n_subcarriers,
        "sample": ds.system.n_samples,
    }


def check_master(ds: Dataset) -> str | None:
    """What is wrong with an open dataset's master file itself, or None: an expected array,
    group or dimension scale missing, or content that differs from the master's own SHA-256
    (:func:`~phyloc.datasets.schema.master_digest`; files before schema 1.1 have none), or a
    schema 1.2 master without its byte checksum header."""
    f = ds.file
    for name in (*ds.array_names, "system", "shards"):
        if name not in f:
            return f"master: {name} is missing"
    version = tuple(int(x) for x in ds.schema_version.split(".")[:2])
    if version >= (1, 2):
        with open(ds.path, "rb") as fh:
            if fh.read(len(sc.HDF5_SIGNATURE)) == sc.HDF5_SIGNATURE:
                return "master: its byte checksum header is missing"
    stored = sc._text(f.attrs.get(sc.MASTER_DIGEST_ATTR, ""))
    if not stored:
        return None if version < (1, 1) else "master: its content checksum is missing"
    if sc.master_digest(f) != stored:
        return "master: content differs from its SHA-256 (altered or corrupt)"
    return None


def verify_dataset(path) -> dict:
    """Check every shard of a dataset completely (``phyloc info --verify``).

    A shard is sound when its file exists, its SHA-256 equals the master's record, it belongs
    to this dataset (recipe fingerprint, realization range) and every array's SHA-256 matches
    its data. Truncated and bit-flipped shards are reported as corrupt;
    ``phyloc generate ... --resume`` regenerates corrupt and missing shards.

    Returns
    -------
    dict
        ``verified`` (True), ``ok`` (every shard complete and sound), ``shards_ok``,
        ``missing_shards`` (not complete in the master, or file absent), ``corrupt_shards``
        (lists of shard indices), ``problems`` (shard index → reason) and ``shards``: per
        shard ``index``, ``file``, ``status`` (``"ok"``, ``"missing"`` or ``"corrupt"``),
        ``sha256`` (the file digest the master records, which a sound file has) and
        ``reason`` (empty when sound).
    """
    with open_dataset(path) as ds, _master_read(ds.path):
        fp = sc._text(ds.file.attrs["recipe_fingerprint"])
        arrays = [sc.spec_of(n) for n in ds.array_names]
        sh = ds.shards
        missing, corrupt, problems, ok, each = [], [], {}, 0, []
        dims = _axis_sizes(ds)
        master = check_master(ds)
        if master:
            problems["master"] = master
        for j in range(ds.n_shards):
            file = ds.path.parent / sh["file"][j]
            entry = {"index": j, "file": sc._text(sh["file"][j])}
            entry["sha256"] = sc._text(sh["file_sha256"][j])
            each.append(entry)
            if not sh["complete"][j]:
                missing.append(j)
                problems[j] = "not complete (generation unfinished or failed)"
                entry.update(status="missing", reason=problems[j])
                continue
            rec, kind, reason = sc.check_shard(
                file,
                index=j,
                start=int(sh["realization_start"][j]),
                stop=int(sh["realization_stop"][j]),
                fingerprint=fp,
                arrays=arrays,
                file_sha256=sh["file_sha256"][j],
                dims={**dims, "path": int(sh["n_paths"][j])},
            )
            if rec is not None:
                ok += 1
                entry.update(status="ok", reason="")
                continue
            (missing if kind == "missing" else corrupt).append(j)
            problems[j] = reason
            entry.update(status="missing" if kind == "missing" else "corrupt", reason=reason)
    return {
        "verified": True,
        "ok": not missing and not corrupt and not master,
        "master_ok": not master,
        "shards_ok": ok,
        "missing_shards": missing,
        "corrupt_shards": corrupt,
        "problems": problems,
        "shards": each,
    }


def check_shard_files(path) -> dict:
    """Check, before reading a dataset, that every shard is complete and that its file's
    SHA-256 equals the master's record (what ``phyloc evaluate`` does unless ``--no-verify``).

    Lighter than :func:`verify_dataset` (one pass over each shard's bytes, no per-array
    hashes), and enough to refuse a flipped bit or a truncated shard anywhere.

    Returns
    -------
    dict
        ``shards`` (how many were checked), ``bytes`` (their size) and ``seconds``.

    Raises
    ------
    DatasetError
        The first shard that is not complete, is missing or differs from its checksum, named,
        with the command that repairs it.
    """
    t0 = time.perf_counter()
    n_bytes = 0
    with open_dataset(path) as ds:
        sh = ds.shards
        with _master_read(ds.path):
            master = check_master(ds)
        if master:
            raise sc.DatasetError(
                f"dataset {ds.path}: {master}; `phyloc generate RECIPE -o {ds.path} --resume` "
                "rebuilds the master from its shards"
            )
        repair = f"run `phyloc info {ds.path} --verify` to list every problem and "
        repair += "`phyloc generate RECIPE -o DATASET --resume` to regenerate the shard"
        for j in range(ds.n_shards):
            file = ds.path.parent / sh["file"][j]
            if not sh["complete"][j]:
                raise sc.DatasetError(
                    f"dataset {ds.path}: shard {j} ({sh['file'][j]}) is not complete; {repair}"
                )
            if not file.is_file():
                raise sc.DatasetError(f"dataset {ds.path}: shard {j} ({file}) is missing; {repair}")
            if sc.sha256_file(file) != sh["file_sha256"][j]:
                raise sc.DatasetError(
                    f"dataset {ds.path}: shard {j} ({sh['file'][j]}) differs from its SHA-256 "
                    f"in the master (corrupt or truncated); {repair}"
                )
            with h5py.File(file, "r") as f:  # HDF5 would follow these when reading it
                outside = sc.outside_references(f, allow_virtual=False)
            if outside:
                raise sc.DatasetError(
                    f"dataset {ds.path}: shard {j} ({sh['file'][j]}): {outside}; a dataset "
                    "reads only its own files (refusing it)"
                )
            n_bytes += file.stat().st_size
        n = ds.n_shards
    return {"shards": n, "bytes": n_bytes, "seconds": time.perf_counter() - t0}


#: ``phyloc.datasets.verify``.
verify = verify_dataset


__all__ = ["check_master", "check_shard_files", "verify", "verify_dataset"]


def _disk_bytes(ds: Dataset) -> int:
    total = ds.path.stat().st_size
    for name in ds.shards["file"]:
        p = ds.path.parent / name
        if p.is_file():
            total += p.stat().st_size
    return total


def info(path, *, verify: bool = False) -> dict:
    """Summarize a dataset (``phyloc info``): sizes, shards complete, bytes; optionally verify.

    Parameters
    ----------
    path : str or Path
        The master file.
    verify : bool
        Also check every shard (:func:`verify_dataset`): its
        file checksum against the master's record and the SHA-256 of every array; adds the
        keys of that function.

    Returns
    -------
    dict
        ``path``, ``name``, ``schema_version``, ``phyloc_version``, ``created_utc``, ``seed``,
        ``scenario``, ``ranging``, ``n_realizations``, ``n_snapshots``, ``n_nodes``,
        ``n_agents``, ``n_anchors``, ``dim``, ``max_links``, ``n_subcarriers``,
        ``oversampling``, ``n_samples``, ``bandwidth_hz``, ``n_shards``, ``shard_size``,
        ``shards_complete``, ``complete`` (bool), ``realizations_available``, ``links``
        (stored received waveforms), ``paths``, ``bytes`` (master + shard files on disk).

    Raises
    ------
    DatasetError, SchemaVersionError
        As :func:`open_dataset`.
    """
    with open_dataset(path) as ds:
        a = ds.file.attrs
        sh = ds.shards
        avail = int(
            sum(
                b - s
                for s, b, c in zip(
                    sh["realization_start"], sh["realization_stop"], sh["complete"], strict=True
                )
                if c
            )
        )
        out = {
            "path": str(ds.path),
            "name": ds.name,
            "schema_version": ds.schema_version,
            "phyloc_version": ds.phyloc_version,
            "created_utc": ds.created_utc,
            "seed": ds.seed,
            "scenario": ds.scenario,
            "ranging": ds.ranging,
            "n_realizations": ds.n_realizations,
            "n_snapshots": ds.n_snapshots,
            "n_nodes": ds.n_nodes,
            "n_agents": int(a["n_agents"]),
            "n_anchors": int(a["n_anchors"]),
            "dim": ds.dim,
            "max_links": ds.max_links,
            "n_subcarriers": ds.system.n_subcarriers,
            "oversampling": ds.system.oversampling,
            "n_samples": ds.system.n_samples,
            "bandwidth_hz": ds.system.bandwidth_hz,
            "n_shards": ds.n_shards,
            "shard_size": ds.shard_size,
            "shards_complete": int(sh["complete"].sum()),
            "complete": ds.complete,
            "realizations_available": avail,
            "links": int(sh["n_links"][sh["complete"]].sum()),
            "paths": int(sh["n_paths"][sh["complete"]].sum()),
            "bytes": _disk_bytes(ds),
        }
    if verify:
        out.update(verify_dataset(path))
    return out
