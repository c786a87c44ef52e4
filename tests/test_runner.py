"""Monte Carlo task runner: per-task streams make results independent of the worker count."""

import logging

import numpy as np
import pytest

from phyloc.parallel import run_tasks, task_seeds


def _draw(payload, seed_seq):
    rng = np.random.default_rng(seed_seq)
    return payload, rng.standard_normal(3)


def test_streams_are_spawned_in_task_order():
    a, b = task_seeds(7, 3), task_seeds(7, 5)
    for x, y in zip(a, b[:3], strict=True):
        assert np.array_equal(
            np.random.default_rng(x).random(4), np.random.default_rng(y).random(4)
        )


def test_serial_and_two_dask_workers_give_identical_results():
    serial = run_tasks(_draw, range(6), 11, progress=False)
    dask = run_tasks(_draw, range(6), 11, workers=2, progress=False)
    assert [p for p, _ in dask] == list(range(6))
    for (_, x), (_, y) in zip(serial, dask, strict=True):
        np.testing.assert_array_equal(x, y)
    # and different tasks really got different streams
    assert not np.array_equal(serial[0][1], serial[1][1])


def _blas_threads(payload, seed_seq):
    from threadpoolctl import threadpool_info

    return [d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"]


def test_tasks_run_with_one_blas_thread():
    """Tasks are the unit of parallelism: inside a task BLAS runs on one thread, in process
    and on Dask workers alike."""
    for workers in (None, 2):
        for threads in run_tasks(_blas_threads, range(2), 3, workers=workers, progress=False):
            assert threads and all(t == 1 for t in threads)


def _task_environment(payload, seed_seq):
    import os

    import numba

    from phyloc.phy import fft

    return numba.get_num_threads(), fft.threads(), os.environ.get("MALLOC_MMAP_THRESHOLD_")


def test_thread_policy_keeps_workers_times_threads_within_the_cores():
    """Side by side, each task keeps Numba and FFTs to its share of the cores, and embedded
    workers allocate from the heap (the malloc settings of phyloc.parallel.WORKER_MALLOC_ENV)."""
    from phyloc.parallel import WORKER_MALLOC_ENV, _cpus, threads_per_task

    for w in (1, 2, 3, 8):
        assert threads_per_task(w) >= 1
        assert w * threads_per_task(w) <= max(_cpus(), w)
    res = run_tasks(_task_environment, range(2), 3, workers=2, progress=False)
    for numba_threads, fft_threads, mmap in res:
        assert numba_threads == fft_threads == threads_per_task(2)
        assert mmap == str(WORKER_MALLOC_ENV["MALLOC_MMAP_THRESHOLD_"])
    # a task alone in this process keeps every core
    import numba

    alone = run_tasks(_task_environment, range(1), 3, progress=False)[0]
    assert alone[0] == numba.get_num_threads()


def test_an_embedded_cluster_neither_needs_nor_warns_about_port_8787():
    """A second phyloc run on the machine (port 8787 taken) starts its cluster silently: the
    scheduler's HTTP routes take a free port and no dashboard is served."""
    import socket
    import warnings

    from phyloc.parallel import local_cluster

    holder = socket.socket()
    holder.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        holder.bind(("", 8787))
        holder.listen()
    except OSError:  # somebody else holds it already: the situation under test
        holder.close()
        holder = None
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with local_cluster(1) as cluster:
                port = cluster.scheduler.http_server.port
        assert port != 8787
        assert not [w for w in caught if "8787" in str(w.message)]
    finally:
        if holder is not None:
            holder.close()


def _sigint_handler_name():
    import signal

    return {signal.SIG_IGN: "ignored", signal.SIG_DFL: "default"}.get(
        signal.getsignal(signal.SIGINT), "handled"
    )


def test_embedded_workers_leave_ctrl_c_to_the_client():
    """The worker processes of phyloc's embedded cluster ignore SIGINT (a Ctrl-C reaches the
    whole foreground process group; each worker used to print a KeyboardInterrupt traceback
    before phyloc's one line): the client alone stops the run and closes the cluster."""
    from dask.distributed import Client

    from phyloc.parallel import local_cluster

    with local_cluster(2) as cluster, Client(cluster) as client:
        client.wait_for_workers(2, timeout=60)
        seen = client.run(_sigint_handler_name)
        levels = client.run(_worker_log_level)
    assert len(seen) == 2 and set(seen.values()) == {"ignored"}
    assert _sigint_handler_name() != "ignored"  # this process still takes Ctrl-C
    # the workers' ERROR logs only repeat what phyloc reports in one line (or, as Ctrl-C
    # closes the scheduler, print a heartbeat traceback): silenced
    assert set(levels.values()) == {logging.CRITICAL}


def test_the_embedded_scheduler_says_nothing_until_its_teardown_ends():
    """The embedded scheduler runs in phyloc's own process: while Ctrl-C closes it with tasks
    in flight it logs a CRITICAL "Closed comm ... lost-data" traceback, which the Ctrl-C test
    above saw on CI. Its loggers are silenced for the cluster's whole life, the teardown
    included (the exit stack unwinds the silencing last), and restored afterwards."""
    from phyloc.parallel import dask_client

    scheduler_log = logging.getLogger("distributed.scheduler")
    assert scheduler_log.isEnabledFor(logging.CRITICAL)
    with dask_client(workers=1) as client:
        client.wait_for_workers(1, timeout=60)
        assert not scheduler_log.isEnabledFor(logging.CRITICAL)
        assert not logging.getLogger("distributed.client").isEnabledFor(logging.CRITICAL)
    assert scheduler_log.isEnabledFor(logging.CRITICAL)


def _worker_log_level():
    """The least level a worker's ``distributed`` log handlers print (Dask's
    ``silence_logs`` sets the handlers, not the loggers)."""
    handlers = logging.getLogger("distributed").handlers
    return min((h.level for h in handlers), default=logging.CRITICAL)


def test_ctrl_c_on_generate_with_two_workers_prints_one_line(tmp_path):
    """Ctrl-C reaches the whole process group of ``generate --workers 2`` mid-run: exit 130 and
    phyloc's one line only (the closing scheduler used to make a worker log a heartbeat
    traceback); the shards finished before it are complete."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from test_datasets import TINY

    from phyloc.datasets import schema as sc

    PHYLOC = [sys.executable, "-m", "phyloc.cli"]
    recipe = tmp_path / "big.toml"
    big = TINY.replace("n_subcarriers = 65", "n_subcarriers = 1025")
    recipe.write_text(big.replace("realizations = 4", "realizations = 2000"))
    out = tmp_path / "x.h5"
    proc = subprocess.Popen(
        [*PHYLOC, "generate", str(recipe), "-o", str(out), "--workers", "2", "--no-progress"],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    sdir = sc.shard_dir(out)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(sdir.glob("shard-*.h5"))) < 3:
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == [
        "phyloc: interrupted; finished shards are kept: run the same command with --resume "
        "to finish it"
    ], err


def _kills_its_worker(payload, seed_seq):
    import os

    if payload == 2:
        os._exit(3)  # the worker process dies, as one killed for its memory does
    return payload


def test_a_task_that_kills_every_worker_it_runs_on_is_one_actionable_error():
    """Dask retries a task whose worker died, then gives up (``KilledWorker``). That used to
    reach the user as "internal error: KilledWorker ..."; it is phyloc's own error naming the
    task, the likely cause (memory per worker) and what to run instead."""
    import dask
    import pytest

    from phyloc.errors import PhylocError
    from phyloc.parallel import WorkerDiedError

    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        with pytest.raises(WorkerDiedError) as info:
            run_tasks(_kills_its_worker, [0, 1, 2, 3], 5, workers=2, progress=False)
    msg = str(info.value)
    assert isinstance(info.value, PhylocError) and "\n" not in msg
    assert "task 3 of 4" in msg and "--workers 1" in msg and "--resume" in msg


def test_a_first_run_says_that_it_compiles(tmp_path, monkeypatch, capsys):
    """With Numba's cache empty of phyloc's kernels, a run that shows progress on a terminal
    says once that it compiles them (its bar would sit at 0 for a minute without a word); with
    the cache filled, without progress, or to a pipe, it says nothing."""
    import numba

    from phyloc import _jit
    from phyloc import parallel as par

    monkeypatch.delenv("PHYLOC_NO_PROGRESS", raising=False)
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(par, "_announced", False)
    monkeypatch.setattr(par, "_stderr_is_terminal", lambda: True)  # capsys is no terminal
    assert _jit.kernel_cache_empty()
    par.run_tasks(_square, [1, 2], seed=1, progress=False)
    assert par.COMPILING not in capsys.readouterr().err
    par.run_tasks(_square, [1, 2], seed=1)
    par.run_tasks(_square, [1, 2], seed=1)
    assert capsys.readouterr().err.count(par.COMPILING) == 1  # once per process
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "k.synthesis-12.py311.nbi").write_bytes(b"")
    assert not _jit.kernel_cache_empty()
    monkeypatch.setattr(par, "_announced", False)
    par.run_tasks(_square, [1, 2], seed=1)
    assert par.COMPILING not in capsys.readouterr().err
    monkeypatch.setattr(par, "_stderr_is_terminal", lambda: False)
    (tmp_path / "sub" / "k.synthesis-12.py311.nbi").unlink()
    par.run_tasks(_square, [1, 2], seed=1)
    assert par.COMPILING not in capsys.readouterr().err


def _square(x, seed_seq):
    return x * x


def test_ctrl_c_inside_a_weakref_callback_is_not_lost():
    """Python only prints a KeyboardInterrupt raised inside a finalizer or weakref callback
    ("Exception ignored in …") and goes on; with phyloc's hook installed (as ``phyloc.cli``
    does for every command) it reaches the main thread again, so Ctrl-C still stops the
    command. Without the hook the loop below would run to its end."""
    import sys
    import time
    import weakref

    from phyloc.cli import redeliver_lost_interrupts

    class Node:
        pass

    def on_collect(_ref):
        raise KeyboardInterrupt  # Ctrl-C arriving while the callback runs

    previous, sys.unraisablehook = sys.unraisablehook, redeliver_lost_interrupts
    try:
        with pytest.raises(KeyboardInterrupt):
            node = Node()
            ref = weakref.ref(node, on_collect)  # noqa: F841
            del node  # the callback runs here; its KeyboardInterrupt is "ignored"
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:  # the command going on
                time.sleep(0.01)
    finally:
        sys.unraisablehook = previous
