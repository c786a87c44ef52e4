"""Running independent Monte Carlo tasks serially or on Dask, with per-task random streams.

Every task gets its own ``numpy.random.SeedSequence``, spawned from the recipe's seed in task
order (:func:`task_seeds`), so a result never depends on how many workers run the tasks or in
which order they finish. :func:`run_tasks` runs ``fn(payload, seed_sequence)`` for every task:

* ``workers`` None or 1 and no ``scheduler``: in this process, one after another;
* ``workers`` N > 1: on an embedded Dask ``LocalCluster`` of N single-threaded worker processes;
* ``scheduler`` ADDRESS: on an existing Dask cluster.

Results come back in task order. A progress bar (tqdm) shows completed tasks.

Inside :func:`task_store` every finished task's result is also kept on disk as it arrives, so
an interrupted run (a full paper setting takes hours to days) resumes where it stopped: the
tasks already done are read back instead of run again. The store is keyed by the run's inputs
(task function, payloads, seed) and by a fingerprint of phyloc's source, so results computed
by other code or for another recipe are never mixed in.

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
import hashlib
import json
import os
import pickle
import shutil
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

from phyloc import _validate as v
from phyloc._files import write_atomic
from phyloc.errors import PhylocError


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


class _Failed:
    """A task's :class:`~phyloc.errors.PhylocError` returned as its value from a Dask worker
    (raised again in the client): a user's error is reported once, in phyloc's one line,
    not also in the worker's "Compute Failed" log."""

    def __init__(self, error):
        self.error = error


class _ReportErrors:
    """``fn(payload, seed)``, a :class:`~phyloc.errors.PhylocError` it raises returned as
    :class:`_Failed` (picklable for Dask)."""

    def __init__(self, fn):
        self.fn = fn

    def __call__(self, payload, seed):
        try:
            return self.fn(payload, seed)
        except PhylocError as exc:
            return _Failed(exc)


def _quiet_progress() -> bool:
    return bool(os.environ.get("PHYLOC_NO_PROGRESS"))


def _stderr_is_terminal() -> bool:
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


COMPILING = (
    "phyloc: compiling its kernels (once after an install; later runs load them from the "
    "cache), about a minute before the progress moves"
)
_announced = False


def announce_compilation() -> None:
    """Print :data:`COMPILING` once per process to a terminal when Numba's cache holds no
    kernel of phyloc yet (:func:`~phyloc._jit.kernel_cache_empty`): on a first run the progress
    bar otherwise sits at 0 for a minute without a word. Not to a pipe or a file, whose reader
    (a script, a test) expects phyloc's output only."""
    global _announced
    from phyloc._jit import kernel_cache_empty

    if not _announced and _stderr_is_terminal() and kernel_cache_empty():
        _announced = True
        print(COMPILING, file=sys.stderr, flush=True)


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
    if show and payloads:
        announce_compilation()
    serial = scheduler is None and (
        workers is None or v.integer("workers", workers, minimum=1) == 1
    )
    store = _STORE.get(fn, payloads, seed) if _STORE is not None else _NoStore()
    results = [store.load(i) for i in range(len(payloads))]
    todo = [i for i, r in enumerate(results) if r is _MISSING]
    if serial:
        fn = _OneBlasThread(fn)
        for i in tqdm(todo, desc=desc, disable=not show, leave=False):
            results[i] = fn(payloads[i], seeds[i])
            store.save(i, results[i])
        return results
    # several tasks side by side: each keeps to its share of the cores (a remote cluster's
    # workers run one task per thread, so one thread each)
    fn = _OneBlasThread(fn, 1 if scheduler is not None else threads_per_task(workers))
    if todo:
        done = _run_dask(
            fn,
            [payloads[i] for i in todo],
            [seeds[i] for i in todo],
            workers=workers,
            scheduler=scheduler,
            desc=desc,
            show=show,
            on_result=lambda j, r: store.save(todo[j], r),
        )
        for i, r in zip(todo, done, strict=True):
            results[i] = r
    return results


#: Environment of embedded Dask workers. Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536``,
#: which also freezes glibc's mmap threshold at 128 KiB: every array above that is then a fresh
#: ``mmap`` whose pages fault in on first touch, and the conversions to the time domain ran 3×
#: slower in a worker than in this process (2 workers reached 0.5 of twice one worker's
#: throughput). Arrays below 64 MiB come from the heap again, and freed memory is kept.
WORKER_MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": 2**26, "MALLOC_TRIM_THRESHOLD_": 2**30}


def dask_setup(worker) -> None:
    """Worker preload of phyloc's embedded cluster: its worker processes ignore Ctrl-C.

    Ctrl-C in a terminal reaches every process of the foreground group; the workers of the
    embedded ``LocalCluster`` would each print a KeyboardInterrupt traceback before phyloc's
    one-line message. The interrupt is the client's to handle: it stops the run and closes the
    cluster, which ends the workers (Dask preloads: ``distributed.preloading``)."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


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
            # phyloc reports every failure of a task itself, in one line (a task's exception
            # reaches the client); the workers' own ERROR logs only repeat it, or, when Ctrl-C
            # closes the cluster, print a heartbeat traceback of the closing scheduler
            silence_logs=50,
            preload=["phyloc.parallel"],  # dask_setup: the workers leave Ctrl-C to the client
        )


@contextlib.contextmanager
def _quiet_dask_logs():
    """Silence this process's ``distributed`` loggers (the embedded scheduler and nannies) for
    the life of an embedded cluster, its teardown included, and restore them after.

    phyloc reports every failure of a task itself, in one line. When Ctrl-C closes the cluster
    while tasks run, the closing scheduler logs a CRITICAL "Closed comm ... lost-data" with a
    traceback; ``silence_logs`` of ``LocalCluster`` does not cover it, because it restores the
    handlers' level before the scheduler has finished closing."""
    import logging

    names = ["distributed"] + [
        name
        for name, logger in logging.root.manager.loggerDict.items()
        if name.startswith("distributed.") and getattr(logger, "level", 0)  # own level set
    ]
    loggers = [logging.getLogger(name) for name in names]
    old = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for logger, level in zip(loggers, old, strict=True):
            logger.setLevel(level)


@contextlib.contextmanager
def dask_client(*, workers=None, scheduler=None):
    """A Dask client: on an embedded ``LocalCluster`` of ``workers`` single-threaded processes,
    or connected to ``scheduler`` (an address); closed (and the cluster stopped) on exit."""
    from dask.distributed import Client

    with contextlib.ExitStack() as stack:
        if scheduler is None:
            stack.enter_context(_quiet_dask_logs())  # entered first: it also covers the teardown
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

    try:
        return Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise PhylocError(
            f"cannot connect to the Dask scheduler at {scheduler!r} ({why}); start one with "
            "`dask scheduler` (it prints its tcp://host:port address) or check the address"
        ) from None


class WorkerDiedError(PhylocError):
    """Dask gave up on a task whose workers kept dying (``KilledWorker``): most often the task
    needs more memory than a worker may use (an embedded cluster splits the machine's memory
    between its workers and restarts one that exceeds its share)."""

    def __init__(self, index: int, n: int, workers, scheduler):
        where = f"the workers of {scheduler}" if scheduler else f"{workers} embedded workers"
        super().__init__(
            f"task {index + 1} of {n} killed its Dask worker every time it ran ({where}); most "
            "often it needs more memory than a worker's share of the machine. Run it with "
            "--workers 1 (in this process, the whole memory) or on machines with more memory; "
            "finished tasks are kept: add --resume"
        )


def _run_dask(fn, payloads, seeds, *, workers, scheduler, desc, show, on_result=None):
    from dask.distributed import as_completed

    with dask_client(workers=workers, scheduler=scheduler) as client:
        futures = client.map(_ReportErrors(fn), payloads, seeds, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        results = [None] * len(futures)
        bar = tqdm(total=len(futures), desc=desc, disable=not show, leave=False)
        for fut in as_completed(futures):
            i = index[fut.key]
            try:
                results[i] = fut.result()
            except Exception as exc:
                if type(exc).__name__ != "KilledWorker":
                    raise
                client.cancel(futures)
                bar.close()
                raise WorkerDiedError(i, len(futures), workers, scheduler) from None
            if isinstance(results[i], _Failed):
                client.cancel(futures)
                bar.close()
                raise results[i].error
            if on_result is not None:
                on_result(i, results[i])
            bar.update(1)
        bar.close()
        return results


# -- resumable runs --------------------------------------------------------------------------
_MISSING = object()


class _NoStore:
    def load(self, i):
        return _MISSING

    def save(self, i, result) -> None:
        pass


def source_fingerprint() -> str:
    """SHA-256 over phyloc's Python sources (path and bytes of every ``.py`` file): two runs
    with the same fingerprint ran the same code."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0")
        h.update(path.read_bytes() + b"\0")
    return h.hexdigest()


class TaskStoreMismatch(Exception):
    """The task store was written by another run (other code, recipe or setting)."""


class TaskStoreBusy(Exception):
    """Another process is working on the task store (the message names its process id)."""


class TaskStore:
    """Finished task results of one run, one file per task, in ``directory``.

    ``directory/run.json`` names the run (its ``identity``: recipe text, setting, code
    fingerprint) and accumulates its wall time over the invocations that worked on it. Each
    :func:`run_tasks` call inside the run gets a subfolder keyed by its task function, payloads
    and seed; task ``i``'s result is ``<key>/<i>.pkl``, written to a temporary name first and
    renamed, so a killed process leaves either the whole result or none.

    Results are pickles: read a store only from a run of your own.

    Raises
    ------
    FileExistsError
        ``directory`` holds a run and ``resume`` is false.
    TaskStoreMismatch
        ``resume`` is true but the stored run had another identity or ran other code (the
        message names the fields that differ).
    """

    def __init__(self, directory, identity: dict, *, resume: bool, discard: bool = False):
        self.dir = Path(directory)
        self.identity = dict(identity, code=source_fingerprint())
        self.reused = 0
        self.computed = 0
        self._calls: list[_CallStore] = []
        self._t0 = time.perf_counter()
        meta_path = self.dir / "run.json"
        self.wall_before = 0.0
        self.invocations = 1
        self.dir.mkdir(parents=True, exist_ok=True)
        self._lock = _lock_dir(self.dir)  # one process per store: a second would redo work
        if discard:  # start over: the old tasks go, under the lock (never a live run's)
            for entry in self.dir.iterdir():
                if entry.name != "lock":
                    shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
        if meta_path.exists():
            if not resume:
                self.close()
                raise FileExistsError(f"{self.dir} holds an unfinished run")
            meta = json.loads(meta_path.read_text())
            stored = meta.get("identity", {})
            differs = sorted(
                k for k in set(stored) | set(self.identity) if stored.get(k) != self.identity.get(k)
            )
            if differs:
                self.close()
                raise TaskStoreMismatch(", ".join(differs))
            self.wall_before = float(meta.get("wall_s", 0.0))
            self.invocations = int(meta.get("invocations", 0)) + 1
        self._write_meta()

    def finish(self) -> None:
        """The run is complete: delete its stored tasks and the store's folder, the lock file
        last and still held, so that no other process can take the folder in between."""
        for entry in self.dir.iterdir():
            if entry.name != "lock":
                shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
        with contextlib.suppress(FileNotFoundError):
            (self.dir / "lock").unlink()
        self.close()
        with contextlib.suppress(OSError):
            self.dir.rmdir()

    def close(self) -> None:
        """Release the store's lock (another process may then resume it)."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    @property
    def wall_s(self) -> float:
        """Wall time of this run over all its invocations so far [s]."""
        return self.wall_before + time.perf_counter() - self._t0

    def _write_meta(self) -> None:
        meta = {
            "identity": self.identity,
            "wall_s": self.wall_s,
            "invocations": self.invocations,
            # progress of every run_tasks call so far: a long run in the background is
            # followed with `cat OUT/.tasks/run.json`
            "calls": {c.dir.name: {"tasks": c.n, "done": c.done} for c in self._calls},
        }
        write_atomic(self.dir / "run.json", json.dumps(meta, indent=1).encode())

    def get(self, fn, payloads, seed) -> _CallStore:
        """The store of one :func:`run_tasks` call."""
        h = hashlib.sha256()
        h.update(f"{getattr(fn, '__module__', '')}.{getattr(fn, '__qualname__', fn)}".encode())
        h.update(str(int(seed)).encode())
        h.update(pickle.dumps(payloads, protocol=5))
        call = _CallStore(self, self.dir / h.hexdigest()[:24], len(payloads))
        self._calls.append(call)
        self._write_meta()
        return call


class _CallStore:
    def __init__(self, run: TaskStore, directory: Path, n: int):
        self.run = run
        self.dir = directory
        self.n = n
        self.done = len(list(directory.glob("*.pkl"))) if directory.is_dir() else 0

    def load(self, i):
        path = self.dir / f"{i}.pkl"
        if not path.exists():
            return _MISSING
        try:
            with open(path, "rb") as f:
                result = pickle.load(f)
        except (OSError, EOFError, pickle.UnpicklingError):  # damaged: run the task again
            return _MISSING
        self.run.reused += 1
        return result

    def save(self, i, result) -> None:
        self.dir.mkdir(parents=True, exist_ok=True)
        # a full disk fails here with the task file's path; earlier tasks stay (--resume)
        write_atomic(self.dir / f"{i}.pkl", pickle.dumps(result, protocol=5))
        self.done += 1
        self.run.computed += 1
        self.run._write_meta()


def _lock_dir(directory: Path):
    """An exclusive ``flock`` on ``directory/lock`` holding this process's id, or
    :class:`TaskStoreBusy` naming the process that holds it (None where ``fcntl`` is absent)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return None
    path = directory / "lock"
    while True:
        f = open(path, "a+")  # held open (and locked) for the run
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.seek(0)
            pid = f.read().strip() or "?"
            f.close()
            raise TaskStoreBusy(f"process {pid} is working on {directory}") from None
        try:  # the file locked is still the folder's lock (not one a finishing run removed)
            same = os.stat(path).st_ino == os.fstat(f.fileno()).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        f.close()
        directory.mkdir(parents=True, exist_ok=True)
    f.seek(0)
    f.truncate()
    f.write(str(os.getpid()))
    f.flush()
    return f


_STORE: TaskStore | None = None


@contextlib.contextmanager
def task_store(store: TaskStore, *, close: bool = True):
    """Keep every finished task of the :func:`run_tasks` calls inside the block in ``store``
    (a :class:`TaskStore`), reading back the ones already there. ``close=False`` keeps the
    store's lock after the block (the caller writes its results, then calls
    :meth:`TaskStore.finish` or :meth:`TaskStore.close`)."""
    global _STORE
    if _STORE is not None:
        raise RuntimeError("task stores do not nest")
    _STORE = store
    try:
        yield store
    finally:
        store._write_meta()
        if close:
            store.close()
        _STORE = None
