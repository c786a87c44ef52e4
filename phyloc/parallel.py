"""Running independent Monte Carlo tasks serially or on Dask, with per-task random streams.

Every task gets its own ``numpy.random.SeedSequence``, spawned from the recipe's seed in task
order (:func:`task_seeds`), so a result never depends on how many workers run the tasks or in
which order they finish. :func:`run_tasks` runs ``fn(payload, seed_sequence)`` for every task:

* ``workers`` None or 1 and no ``scheduler``: in this process, one after another;
* ``workers`` N > 1: on an embedded Dask ``LocalCluster`` of N single-threaded worker processes;
* ``scheduler`` ADDRESS: on an existing Dask cluster.

Results come back in task order. A progress bar (tqdm) shows completed tasks.

Tasks are the unit of parallelism: each runs with its BLAS library limited to one thread
(``threadpoolctl``). The linear algebra inside a task is small (joint states of at most a few
hundred dimensions), where a multi-threaded BLAS gains little and, on a busy machine, loses a
lot: a PF-BP Scenario II step took 15–22 s with OpenBLAS' default threads next to two other busy
processes on 2 cores and 2 s with one thread.

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


class _OneBlasThread:
    """``fn(payload, seed)`` with BLAS limited to one thread (picklable for Dask)."""

    def __init__(self, fn):
        self.fn = fn

    def __call__(self, payload, seed):
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
    fn = _OneBlasThread(fn)
    show = progress and not _quiet_progress()
    if scheduler is None and (workers is None or v.integer("workers", workers, minimum=1) == 1):
        out = []
        for p, s in tqdm(
            list(zip(payloads, seeds, strict=True)), desc=desc, disable=not show, leave=False
        ):
            out.append(fn(p, s))
        return out
    return _run_dask(
        fn, payloads, seeds, workers=workers, scheduler=scheduler, desc=desc, show=show
    )


@contextlib.contextmanager
def dask_client(*, workers=None, scheduler=None):
    """A Dask client: on an embedded ``LocalCluster`` of ``workers`` single-threaded processes,
    or connected to ``scheduler`` (an address); closed (and the cluster stopped) on exit."""
    from dask.distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        if scheduler is None:
            cluster = stack.enter_context(
                LocalCluster(
                    n_workers=int(workers),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=40,
                )
            )
            yield stack.enter_context(Client(cluster))
        else:
            yield stack.enter_context(Client(scheduler))


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
