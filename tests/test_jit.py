"""The Numba helpers of phyloc._jit: a parallel kernel and its serial twin behind one name,
the normalized arguments of a kernel call, and the clock of time spent in the JIT."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from numba import njit, prange

from phyloc._jit import ByThreads, by_threads, call_arguments, jit_seconds, numba_threads


@by_threads
@njit(cache=True, parallel=True)
def _scaled_rows(x, rows, out, scale=2.0, shift=0.0):
    """``out[i] = scale·x[rows[i]] + shift`` (a stand-in kernel for these tests)."""
    for i in prange(rows.size):
        out[i] = scale * x[rows[i]] + shift


def _naive_scaled_rows(x, rows, scale=2.0, shift=0.0):
    return scale * np.asarray(x)[np.asarray(rows)] + shift


def test_both_variants_compute_the_reference_values():
    x = np.linspace(-1.0, 1.0, 7)
    rows = np.array([6, 0, 3, 3], np.int64)
    for kernel in (_scaled_rows, _scaled_rows.parallel, _scaled_rows.serial):
        out = np.empty(rows.size)
        kernel(x, rows, out, 3.0, 1.0)
        np.testing.assert_array_equal(out, _naive_scaled_rows(x, rows, 3.0, 1.0))


def test_by_threads_refuses_a_serial_kernel():
    with pytest.raises(TypeError, match="not a parallel=True kernel"):
        ByThreads(njit(lambda x: x))


def test_left_out_arguments_are_passed_with_their_defaults():
    params = _scaled_rows.parameters
    x, rows, out = np.zeros(2), np.zeros(1, np.int64), np.zeros(1)
    full = call_arguments(params, (x, rows, out), {})
    assert full[3:] == (2.0, 0.0)
    assert call_arguments(params, (x, rows, out), {"shift": 5.0})[3:] == (2.0, 5.0)
    assert call_arguments(params, (x, rows), {"out": out, "scale": 1.5})[2:] == (out, 1.5, 0.0)
    with pytest.raises(TypeError, match="missing argument 'out'"):
        call_arguments(params, (x, rows), {})
    with pytest.raises(TypeError, match="unexpected"):
        call_arguments(params, (x, rows, out), {"bogus": 1})


def test_read_only_index_arrays_are_passed_as_writeable_copies():
    rows = np.arange(4, dtype=np.int64)
    rows.setflags(write=False)
    values = np.ones(3)
    values.setflags(write=False)
    args = call_arguments(_scaled_rows.parameters, (values, rows, np.empty(4)), {})
    assert args[1].flags.writeable and args[1] is not rows
    np.testing.assert_array_equal(args[1], rows)
    assert args[0] is values  # data arrays are passed as they are


def test_one_signature_serves_every_call_pattern():
    """Calls with and without the optional arguments, and with a read-only index, all run the
    same compiled signature."""
    x = np.arange(5.0)
    rows = np.array([4, 1], np.int64)
    frozen = rows.copy()
    frozen.setflags(write=False)
    out = np.empty(2)
    kernel = _scaled_rows.serial if numba_threads() == 1 else _scaled_rows.parallel
    before = len(kernel.signatures)
    _scaled_rows(x, rows, out)
    _scaled_rows(x, frozen, out, 2.0)
    _scaled_rows(x, rows, out, shift=0.0)
    assert len(kernel.signatures) == max(before, 1)
    np.testing.assert_array_equal(out, _naive_scaled_rows(x, rows))


def test_the_serial_only_twin_takes_the_same_arguments():
    x = np.arange(3.0)
    rows = np.array([2, 2], np.int64)
    out = np.empty(2)
    _scaled_rows.serial_only()(x, rows, out, shift=1.0)
    np.testing.assert_array_equal(out, _naive_scaled_rows(x, rows, shift=1.0))


PROBE = r"""
import sys
import numba
import numpy as np
import test_jit as t

if sys.argv[1] == "set_one":
    numba.set_num_threads(1)
t._scaled_rows(np.arange(3.0), np.array([1, 2], np.int64), np.empty(2))
print(len(t._scaled_rows.parallel.signatures), len(t._scaled_rows.serial.signatures))
"""


@pytest.mark.parametrize(
    ("env_threads", "mode", "expected"),
    [("1", "default", "0 1"), ("2", "set_one", "0 1"), ("2", "default", "1 0")],
)
def test_the_variant_follows_the_thread_count(tmp_path, env_threads, mode, expected):
    """On one thread (NUMBA_NUM_THREADS=1, or set_num_threads(1) as a Dask worker of a
    2-core machine does) only the serial twin is compiled; on more, only the parallel kernel."""
    here = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), NUMBA_NUM_THREADS=env_threads)
    env["PYTHONPATH"] = os.pathsep.join([here, env.get("PYTHONPATH", "")])
    done = subprocess.run(
        [sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.split() == expected.split()


def test_one_thread_loads_a_cached_parallel_kernel_instead_of_compiling_the_twin(tmp_path):
    """Dask workers (one thread each) after an in-process run (all threads) that compiled and
    cached the parallel kernel load it instead of compiling the twin; once the twin is cached
    too, one thread runs the twin."""
    here = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), NUMBA_NUM_THREADS="2")
    env["PYTHONPATH"] = os.pathsep.join([here, env.get("PYTHONPATH", "")])

    def probe(mode):
        done = subprocess.run(
            [sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True, check=True
        )
        return done.stdout.split()

    assert probe("default") == ["1", "0"]  # two threads: the parallel kernel, now cached
    assert probe("set_one") == ["1", "0"]  # one thread: the cached parallel kernel is loaded
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "other")
    assert probe("set_one") == ["0", "1"]  # nothing cached: the twin is compiled


def test_jit_seconds_counts_compilation_and_not_compiled_calls():
    @njit
    def fresh(a):  # a new function: compiled on its first call (not cached)
        return a + 1.0

    t0 = jit_seconds()
    fresh(1.0)
    t1 = jit_seconds()
    assert t1 > t0
    for _ in range(100):
        fresh(2.0)
    assert jit_seconds() == t1


def test_a_kernel_pickles_by_reference():
    import pickle

    from phyloc.localization.direct import _kernels

    k = _kernels.gauss_loglik_kernel
    assert pickle.loads(pickle.dumps(k)) is k
