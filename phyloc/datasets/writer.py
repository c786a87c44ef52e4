"""Sharded, resumable generation of waveform datasets (``phyloc generate``): the driver.

:func:`generate` validates a ``kind = "dataset"`` recipe completely
(:func:`~phyloc.datasets.plan.plan_dataset`), then runs one task per shard of ``[dataset]
shard_size`` realizations (:func:`~phyloc.datasets.shard.write_shard`) — in this process
(``workers`` None or 1), on an embedded Dask ``LocalCluster`` (``workers`` > 1) or on an
existing Dask cluster (``scheduler``) — and shows their progress. Meanwhile this process holds
the output's lock (:func:`~phyloc.datasets.files.output_lock`) and keeps the master file
``OUT.h5`` up to date (:func:`~phyloc.datasets.master.write_master`): at the start, at most
every two seconds while shards complete, and at the end, also when shards failed or the run is
interrupted, so an interrupted run loses no finished shard.

Resume: with ``resume=True`` every existing shard is checked (file checksum against the
master's record, every array against its checksum, recipe fingerprint, realization range;
:func:`~phyloc.datasets.master.scan_shards`); sound shards are kept untouched, missing or
corrupt ones are generated again. The result is identical, array by array, to an uninterrupted
run. Without ``resume`` an existing output is never overwritten.

The parts are :mod:`~phyloc.datasets.plan` (what to write), :mod:`~phyloc.datasets.shard`
(one shard file) and :mod:`~phyloc.datasets.master` (the master file over the shards); this
module drives them.

References
----------
M. Rocklin, "Dask: Parallel computation with blocked algorithms and task scheduling," Proc.
14th Python in Science Conference (SciPy 2015), pp. 130–136, 2015.

The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS),
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import time
import uuid
from pathlib import Path

from tqdm.auto import tqdm

from phyloc import _validate as v
from phyloc.datasets import schema as sc
from phyloc.datasets.files import output_lock
from phyloc.datasets.master import (
    previous_master,
    remove_stale,
    scan_shards,
    utc_now,
    write_master,
)
from phyloc.datasets.plan import (
    DatasetPlan,
    plan_dataset,
)
from phyloc.datasets.shard import ShardTask, crash_modes, write_shard
from phyloc.errors import ValidationError
from phyloc.parallel import _Failed, threads_per_task

_MASTER_EVERY_S = 2.0  # rewrite the master at most this often while shards complete


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


def _generate(plan: DatasetPlan, out, sdir, t0, workers, scheduler, resume, progress) -> dict:
    """The body of :func:`generate` once the output folder exists."""
    dspec = plan.dataset
    S = dspec.n_shards
    with output_lock(sdir, out):
        created, known = previous_master(out, plan, sdir)
        created = created or utc_now()
        records: list = [None] * S
        if resume:
            records = scan_shards(plan, sdir, known)
        reused = sum(rec is not None for rec in records)
        write_master(out, plan, records, created=created)
        crash = crash_modes()
        threads = None  # in-process: the kernels may use every core
        if scheduler is not None:
            threads = 1  # Dask's model: parallel tasks, one thread each
        elif workers and workers > 1:
            threads = threads_per_task(workers)
        directory = sdir.resolve()
        tasks = [
            ShardTask.of(plan, j, directory, crash=crash.get(j), threads=threads)
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
            """Record one finished shard; False stops the run (a full disk)."""
            if exc is not None:
                failures.append((task.index, exc))
                if is_disk_full(exc):
                    bar.update(1)
                    return False
            else:
                records[task.index] = rec
                written.append(rec)
                links = sum(r["n_links"] for r in written)
                bar.set_postfix(links_per_s=f"{links / (time.perf_counter() - t_run):.0f}")
                if time.perf_counter() - last[0] > _MASTER_EVERY_S:
                    try:
                        write_master(out, plan, records, created=created)
                    except OSError as err:  # the previous master stays (written atomically)
                        if not is_disk_full(err):
                            raise
                        failures.append(("master", err))
                        bar.update(1)
                        return False
                    last[0] = time.perf_counter()
            bar.update(1)
            return True

        try:
            if in_process:
                _run_here(tasks, done)
            elif tasks:
                _run_dask(client, tasks, done)
        finally:
            bar.close()
            stack.close()  # stops the embedded cluster's workers, mid-write ones included
            remove_stale(sdir)
            try:
                write_master(out, plan, records, created=created)
            except OSError as exc:  # the previous master stays in place (written atomically)
                if not (failures and is_disk_full(exc)):
                    raise
    full = [(j, exc) for j, exc in failures if is_disk_full(exc)]
    if full:
        j, exc = full[0]
        kept = len(list(sdir.glob("shard-*.h5")))  # published whole (os.replace) or not at all
        where = getattr(exc, "filename", None) or sdir
        what = getattr(exc, "strerror", None) or _first_line(exc)
        raise sc.ShardGenerationError(
            f"the disk is full at {where} ({_name(j)}: {what}); stopped with {kept} of {S} "
            "shards complete, all kept. Free space and rerun the same command with --resume"
        ) from exc
    if failures:
        j, exc = failures[0]
        kept = sum(rec is not None for rec in records)
        raise sc.ShardGenerationError(
            f"{len(failures)} of {S} shards failed (shard {j}: {type(exc).__name__}: {exc}); "
            f"the {kept} complete shards are kept in {sdir}. Fix the cause and rerun with "
            "--resume (resume=True) to generate only the missing ones"
        ) from exc
    return _summary(out, dspec, records, written, reused, t0, workers, scheduler)


def _summary(out, dspec, records, written, reused, t0, workers, scheduler) -> dict:
    """The summary :func:`generate` returns (see there)."""
    seconds = time.perf_counter() - t0
    links = sum(rec["n_links"] for rec in written)
    bytes_written = sum(rec["bytes"] for rec in written)
    write_s = sum(rec["write_seconds"] for rec in written)
    total = out.stat().st_size + sum(rec["bytes"] for rec in records if rec is not None)
    return {
        "path": str(out),
        "shards": dspec.n_shards,
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


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` reports a full disk: ``errno.ENOSPC``, or HDF5's message carrying
    ``errno = 28`` (h5py raises those as ``RuntimeError``/``OSError`` without an errno)."""
    if isinstance(exc, OSError) and exc.errno == errno.ENOSPC:
        return True
    text = str(exc)
    return "errno = 28" in text or "No space left on device" in text


def _name(j) -> str:
    return "the master" if j == "master" else f"shard {j}"


def _first_line(exc: BaseException) -> str:
    return (str(exc).splitlines() or [type(exc).__name__])[0]


def _run_here(tasks, done) -> None:
    """Write the shards of ``tasks`` one after the other in this process; ``done`` as each
    ends (a failed shard does not stop the others; a full disk does)."""
    for task in tasks:
        try:
            rec = write_shard(task)
        except Exception as exc:  # kept; reported after the rest
            if done(task, None, exc) is False:
                return
        else:
            if done(task, rec, None) is False:
                return


def _write_reporting(task):
    """:func:`write_shard`, its expected failures (``OSError``: a full disk, a denied folder;
    ``PhylocError``) returned as the runner's :class:`~phyloc.parallel._Failed`: reported once,
    in phyloc's one line, not also in the worker's "Compute Failed" log."""
    from phyloc.errors import PhylocError

    try:
        return write_shard(task)
    except (OSError, PhylocError) as exc:
        return _Failed(exc)


def _run_dask(client, tasks, done) -> None:
    """Write the shards of ``tasks`` on the workers of ``client``; ``done`` as each ends."""
    from dask.distributed import as_completed

    tag = uuid.uuid4().hex[:8]
    futures = {
        client.submit(_write_reporting, t, key=f"phyloc-shard-{t.index:05d}-{tag}", pure=False): t
        for t in tasks
    }
    for fut in as_completed(futures):
        task = futures[fut]
        try:
            rec = fut.result()
            if isinstance(rec, _Failed):
                raise rec.error
        except Exception as exc:  # kept; reported after the rest
            ok = done(task, None, exc)
        else:
            ok = done(task, rec, None)
        if ok is False:  # a full disk: no further shard is tried
            client.cancel([f for f in futures if not f.done()])
            return


__all__ = ["generate"]
