"""Timing helpers shared by the benchmark modules (best of several runs, wall clock)."""

from __future__ import annotations

import time


def best_seconds(fn, *, repeat: int = 5, number: int = 1, min_time: float = 0.0) -> float:
    """Best wall time of one call of ``fn`` over ``repeat`` rounds of ``number`` calls.

    ``fn`` is called once before timing (warm-up: JIT compilation, FFT planning, caches).
    With ``min_time`` > 0, rounds continue until that much time has been spent.
    """
    fn()
    best = float("inf")
    spent = 0.0
    rounds = 0
    while rounds < repeat or spent < min_time:
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        dt = time.perf_counter() - t0
        spent += dt
        best = min(best, dt / number)
        rounds += 1
    return best


def best_seconds_interleaved(fns: dict, *, repeat: int = 5, clock=time.perf_counter) -> dict:
    """Best wall time of one call of each function in ``fns`` (``{name: fn}``), the functions
    called in turn in every round, so that a ratio of two of them compares runs made under the
    same load (on a shared machine the speed of one core drifts by tens of percent within
    seconds). Each function is called once before timing.

    ``clock=time.thread_time`` measures the CPU time of the calling thread instead: for work
    that runs on this thread alone (one Numba and one FFT thread) that is the cost of the work,
    without the time other processes held the CPU."""
    for fn in fns.values():
        fn()
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(repeat):
        for name, fn in fns.items():
            t0 = clock()
            fn()
            best[name] = min(best[name], clock() - t0)
    return best
