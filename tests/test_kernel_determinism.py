"""Numba kernels compute the same bits whether compiled in this process or loaded from the cache.

A Dask worker loads the kernels an in-process run has just compiled and cached, so a kernel whose
compiled-fresh and cached copies round differently makes results depend on the worker count.
That happened once: helpers compiled with ``fastmath`` (reassociation) were called from other
kernels, and a freshly compiled caller ran different code than the same caller loaded from the
cache (1e-16 in a peak position, 1e-8 relative after a particle filter's resampling).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "phyloc"

PROBE = r"""
import hashlib
import numpy as np
from phyloc.localization.direct._kernels import peak_laplace_kernel
from phyloc.ranging import _kernels as rk

rng = np.random.default_rng(1)
N, L, P = 257, 5, 3
n0, w = -128, 2 * np.pi * 1.0e6 / 299792458.0
spec = rng.standard_normal((L, N)) + 1j * rng.standard_normal((L, N))
rows = np.arange(L, dtype=np.int64)
d0 = rng.uniform(5.0, 40.0, L)
parts = []
od, oh, oc = np.empty(L), np.empty(L), np.empty(L)
peak_laplace_kernel(spec, rows, n0, w, d0, 0.3, 4, np.ones(L), od, oh, oc)
parts += [od, oh, oc]
out = np.empty(L)
rk.refine_kernel(spec, n0, w, d0, 0.3, 4, out)
parts.append(out)
f = np.empty(L, dtype=np.complex128)
rk.correlate_kernel(spec, n0, w, d0, f)
parts.append(f.view(np.float64))
power = rng.uniform(0.5, 1.5, (2, N))
tx = np.array([0, 1, 0, 1, 0], dtype=np.int64)
dist = np.sort(rng.uniform(5.0, 40.0, (L, P)), axis=1)
gain = rng.standard_normal((L, P)) + 1j * rng.standard_normal((L, P))
res = np.empty_like(spec)
rk.residual_kernel(spec, power, tx, n0, w, dist, gain, res)
parts.append(res.view(np.float64).ravel())
energy = power[tx].sum(axis=1)
rk.sage_kernel(spec, power, tx, energy, n0, w, dist, gain,
               np.full(L, P, dtype=np.int64), 2, 0.3, 2, 3)
parts += [dist.ravel(), gain.view(np.float64).ravel()]
from phyloc.phy import _gauss as g
z = np.empty((3, 4000))
g.normal_rows_kernel(np.arange(3, dtype=np.uint64), np.ones(3), g.ZIG_X, g.ZIG_F, g.ZIG_K, z)
parts.append(z.ravel())
print(hashlib.sha256(np.concatenate(parts).tobytes()).hexdigest())
"""


def _probe(cache_dir: Path) -> str:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    done = subprocess.run(
        [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True
    )
    return done.stdout.strip()


def test_fresh_and_cached_kernels_give_the_same_bits(tmp_path):
    """First run compiles (and writes the cache), second run loads: identical outputs."""
    fresh = _probe(tmp_path)
    assert any(tmp_path.rglob("*.nbi")), "the probe did not populate the Numba cache"
    cached = _probe(tmp_path)
    assert fresh == cached


def _fastmath(fn: ast.FunctionDef) -> bool:
    for dec in fn.decorator_list:
        if isinstance(dec, ast.Call) and any(
            k.arg == "fastmath" and not (isinstance(k.value, ast.Constant) and not k.value.value)
            for k in dec.keywords
        ):
            return True
    return False


def _jitted(fn: ast.FunctionDef) -> bool:
    for dec in fn.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit"):
            return True
    return False


def _functions():
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and _jitted(node):
                yield path, node


def test_no_kernel_calls_a_fastmath_kernel():
    """``fastmath`` is allowed only on kernels that no other kernel calls (the cause above)."""
    functions = list(_functions())
    assert len(functions) > 20, "the scan found too few kernels to be meaningful"
    fast = {node.name for _, node in functions if _fastmath(node)}
    offenders = []
    for path, node in functions:
        for call in ast.walk(node):
            if isinstance(call, ast.Call):
                f = call.func
                name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
                if name in fast:
                    offenders.append(f"{path.name}:{node.name} calls {name}")
    assert not offenders, offenders


TWINS = r"""
import os, sys
import numpy as np
from phyloc.phy import _gauss as g
from phyloc.phy import _kernels as K

g.splitmix64(1)  # the first compiled call starts a helper thread; count after it
n, N = 16, 8
S = np.ones((1, N), complex)
tx = np.zeros(n, np.int64)
calls = {
    "spectrum": lambda k: k(np.ones((n, N), complex), S, tx, np.empty((n, N), complex)),
    "synthesize": lambda k: k(S, tx, np.zeros(n), np.ones(n, complex), np.arange(n + 1), 1.0,
                              -3.0, np.zeros((n, N), complex), np.zeros((n, N), complex)),
    "normal_rows": lambda k: k(np.arange(n, dtype=np.uint64), np.ones(n), g.ZIG_X, g.ZIG_F,
                               g.ZIG_K, np.empty((n, N))),
}
kernels = {
    "spectrum": (K.spectrum_kernel.parallel, K.spectrum_serial_kernel),
    "synthesize": (K.synthesize_kernel.parallel, K.synthesize_serial_kernel),
    "normal_rows": (g.normal_rows_kernel.parallel, g.normal_rows_serial_kernel),
}
tasks = lambda: len(os.listdir("/proc/self/task"))
name, order = sys.argv[1], sys.argv[2]
parallel, serial = kernels[name]
counts = [tasks()]
for k in ((serial, parallel) if order == "serial_first" else (serial,)):
    calls[name](k)
    counts.append(tasks())
print(*counts)
"""


def _threads_after(cache_dir, name, order):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), NUMBA_NUM_THREADS="2")
    done = subprocess.run(
        [sys.executable, "-c", TWINS, name, order],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return [int(x) for x in done.stdout.split()]


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads in /proc")
@pytest.mark.parametrize("name", ["spectrum", "synthesize", "normal_rows"])
def test_serial_twins_are_cached_apart_from_their_parallel_kernels(tmp_path, name):
    """Numba's cache does not tell a ``parallel=True`` kernel from a serial copy of the same
    Python function (numba issue #6845): the copy compiled first was loaded for both. With
    :func:`phyloc._jit.serial_twin` each has its own cache files. Process 1 compiles and caches
    only the twin; process 2 loads the twin (no thread starts) and then calls the parallel
    kernel, which must start the thread pool, i.e. must not be the twin's cached code."""
    _threads_after(tmp_path, name, "serial_only")
    before, after_serial, after_parallel = _threads_after(tmp_path, name, "serial_first")
    assert after_serial == before
    assert after_parallel > after_serial


@pytest.mark.parametrize(
    ("env", "expected"),
    [({}, "10000"), ({"GOMP_SPINCOUNT": "5"}, "5"), ({"OMP_WAIT_POLICY": "active"}, None)],
)
def test_importing_phyloc_bounds_openmp_spinning_unless_the_user_chose(env, expected):
    """libgomp reads its spin count when Numba first starts threads: the package sets it on
    import (the default spins for milliseconds and takes a core from FFTW), keeping any value
    or wait policy the user set."""
    base = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    code = "import os, phyloc; print(os.environ.get('GOMP_SPINCOUNT'))"
    done = subprocess.run(
        [sys.executable, "-c", code], env=base | env, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == str(expected)
