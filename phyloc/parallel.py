"""Running independent Monte Carlo tasks serially or on Dask, with per-task random streams.

Every task gets its own ``numpy.random.SeedSequence``, spawned from the recipe's seed in task
order (:func:`task_seeds`), so a result never depends on how many workers run the tasks or in
which order they finish. :func:`run_tasks` runs ``fn(payload, seed_sequence)`` for every task:

* ``workers`` None or 1 and no ``scheduler``: in this process, one after another;
* ``workers`` N > 1: on an embedded Dask ``LocalCluster`` of N single-threaded worker processes;
* ``scheduler`` ADDRESS: on an existing Dask cluster.

Results come back in task order. A progress bar (tqdm) shows completed tasks.

Tasks are the unit of parallelism: each runs with its BLAS library limited to one thread
(``threadpoolctl``). When several tasks run side by side, each also keeps its Numba kernels and
FFTs to its share of the cores (:func:`threads_per_task`: ``max(1, cpus // workers)``), so
workers × threads never exceeds the cores; a task alone in this process uses them all. The
linear algebra inside a task is small (joint states of at most a few hundred dimensions), where
a multi-threaded BLAS gains little and, on a busy machine, loses a lot: a PF-BP Scenario II
step took 15–22 s with OpenBLAS' default threads next to two other busy processes on 2 cores
and 2 s with one thread.

References
----------
M. Rocklin, "Dask: Parallel computation with blocked algorithms and task scheduling," Proc.
14th Python in Science Conference (SciPy 2015), pp. 130–136, 2015.

NumPy, "Parallel random number generation" (``SeedSequence.spawn``),
https://numpy.org/doc/stable/reference/random/parallel.html.
"""

from __future__ import annotations

import contextlib
import os

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

from phyloc import _validate as v


def task_seeds(seed: int, n_tasks: int) -> list[np.random.SeedSequence]:
    """``n_tasks`` independent streams spawned from ``seed`` (the same for any worker count)."""
    return np.random.SeedSequence(int(seed)).spawn(int(n_tasks))


def limit_threads(n: int) -> None:
    """Keep this process's Numba kernels and FFTs to ``n`` threads (BLAS is limited per task)."""
    import numba

    from phyloc.phy import fft

    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
    if fft.threads() != n:
        fft.set_backend(fft.backend(), threads=int(n))


def threads_per_task(workers: int) -> int:
    """The thread policy: ``workers`` tasks side by side share the CPUs this process may use,
    so each gets ``max(1, cpus // workers)`` Numba and FFT threads (workers × threads ≤ cores)."""
    return max(1, _cpus() // max(1, int(workers)))


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


class _OneBlasThread:
    """``fn(payload, seed)`` with BLAS limited to one thread and, when ``threads`` is given,
    Numba and FFTs limited to that many (picklable for Dask)."""

    def __init__(self, fn, threads: int | None = None):
        self.fn = fn
        self.threads = threads

    def __call__(self, payload, seed):
        if self.threads is not None:
            limit_threads(self.threads)
        with threadpool_limits(limits=1, user_api="blas"):
            return self.fn(payload, seed)


def _quiet_progress() -> bool:
    return bool(os.environ.get("PHYLOC_NO_PROGRESS"))


def run_tasks(
    fn,
    payloads,
    seed: int,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    desc: str = "tasks",
    progress: bool = True,
):
    """Run ``fn(payload, seed_sequence)`` for every payload; return the results in order.

    Parameters
    ----------
    fn : callable
        A module-level function (it must pickle for Dask).
    payloads : sequence
        One picklable argument per task.
    seed : int
        The recipe seed; task i gets ``SeedSequence(seed).spawn(n)[i]``.
    workers : int, optional
        Number of local worker processes (Dask ``LocalCluster``); None or 1 runs in-process.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``); overrides ``workers``.
    """
    payloads = list(payloads)
    seeds = task_seeds(seed, len(payloads))
    show = progress and not _quiet_progress()
    if scheduler is None and (workers is None or v.integer("workers", workers, minimum=1) == 1):
        fn = _OneBlasThread(fn)
        out = []
        for p, s in tqdm(
            list(zip(payloads, seeds, strict=True)), desc=desc, disable=not show, leave=False
        ):
            out.append(fn(p, s))
        return out
    # several tasks side by side: each keeps to its share of the cores (a remote cluster's
    # workers run one task per thread, so one thread each)
    fn = _OneBlasThread(fn, 1 if scheduler is not None else threads_per_task(workers))
    return _run_dask(
        fn, payloads, seeds, workers=workers, scheduler=scheduler, desc=desc, show=show
    )


#: Environment of embedded Dask workers. Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536``,
#: which also freezes glibc's mmap threshold at 128 KiB: every array above that is then a fresh
#: ``mmap`` whose pages fault in on first touch, and the conversions to the time domain ran 3×
#: slower in a worker than in this process (2 workers reached 0.5 of twice one worker's
#: throughput). Arrays below 64 MiB come from the heap again, and freed memory is kept.
WORKER_MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": 2**26, "MALLOC_TRIM_THRESHOLD_": 2**30}


def local_cluster(workers: int):
    """An embedded Dask ``LocalCluster`` of ``workers`` single-threaded processes, with
    :data:`WORKER_MALLOC_ENV` in their environment (a context manager)."""
    import dask
    from dask.distributed import LocalCluster

    key = "distributed.nanny.pre-spawn-environ"
    with dask.config.set({f"{key}.{k}": val for k, val in WORKER_MALLOC_ENV.items()}):
        return LocalCluster(
            n_workers=int(workers),
            threads_per_worker=1,
            processes=True,
            # no dashboard; the scheduler's HTTP routes (health, metrics) on a free port: with
            # ``dashboard_address=None`` Dask still binds 8787 and warns when another cluster
            # (a second phyloc run) holds it
            dashboard_address=":0",
            scheduler_kwargs={"dashboard": False},
            silence_logs=40,
        )


@contextlib.contextmanager
def dask_client(*, workers=None, scheduler=None):
    """A Dask client: on an embedded ``LocalCluster`` of ``workers`` single-threaded processes,
    or connected to ``scheduler`` (an address); closed (and the cluster stopped) on exit."""
    from dask.distributed import Client

    with contextlib.ExitStack() as stack:
        if scheduler is None:
            cluster = stack.enter_context(local_cluster(int(workers)))
            yield stack.enter_context(Client(cluster))
        else:
            yield stack.enter_context(connect(scheduler))


SCHEDULER_TIMEOUT_S = 10.0
"""Seconds to wait for an existing Dask scheduler before giving up (:func:`connect`)."""


def connect(scheduler: str):
    """A ``dask.distributed.Client`` connected to the scheduler at ``scheduler``.

    Raises
    ------
    PhylocError
        The address is malformed or no scheduler answers there within
        :data:`SCHEDULER_TIMEOUT_S` (one line saying which, instead of Dask's traceback).
    """
    from dask.distributed import Client

    from phyloc.errors import PhylocError

    try:
        return Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise PhylocError(
            f"cannot connect to the Dask scheduler at {scheduler!r} ({why}); start one with "
            "`dask scheduler` (it prints its tcp://host:port address) or check the address"
        ) from None


def _run_dask(fn, payloads, seeds, *, workers, scheduler, desc, show):
    from dask.distributed import as_completed

    with dask_client(workers=workers, scheduler=scheduler) as client:
        futures = client.map(fn, payloads, seeds, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        results = [None] * len(futures)
        bar = tqdm(total=len(futures), desc=desc, disable=not show, leave=False)
        for fut in as_completed(futures):
            results[index[fut.key]] = fut.result()
            bar.update(1)
        bar.close()
        return results
