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

PACKAGE = Path(__file__).resolve().parents[1] / "phyloc"

PROBE = r"""
import hashlib
import numpy as np
from phyloc.localization._kernels import peak_laplace_kernel
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
