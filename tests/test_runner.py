"""Monte Carlo task runner: per-task streams make results independent of the worker count."""

import numpy as np

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
