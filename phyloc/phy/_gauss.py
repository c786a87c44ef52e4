"""Gaussian noise kernels: a 256-layer ziggurat fed by per-row xoshiro256** streams.

Each row of a noise array has its own 64-bit seed, expanded by SplitMix64 into a xoshiro256**
state. A row's numbers therefore depend on its seed only, not on the thread that fills it,
the batch it is in or the worker that runs it. That keeps datasets bit-identical on any number
of threads or workers while the rows are filled in parallel. The normal variates come from the
ziggurat method of Marsaglia and Tsang (2000) with 256 layers, using 52 bits for the
abscissa, 8 for the layer and 1 for the sign. The tail beyond ``r`` uses Marsaglia's
exponential method. The twin in ``tests/naive_phy.py`` repeats the same arithmetic in plain
Python integers and floats.

References
----------
G. Marsaglia and W. W. Tsang, "The ziggurat method for generating random variables," Journal
of Statistical Software 5(8), 2000.

D. Blackman and S. Vigna, "Scrambled linear pseudorandom number generators," ACM Trans.
Mathematical Software 47(4), 2021 (xoshiro256**, SplitMix64).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from phyloc._jit import by_threads

#: Ziggurat parameters for 256 layers: the start of the tail ``r`` and the common layer area
#: ``v`` of ``f(x) = exp(−x²/2)`` (Marsaglia and Tsang 2000, Sec. 2).
ZIG_R = 3.6541528853610088
ZIG_V = 0.00492867323399


def ziggurat_tables():
    """``(x, f, k)``: layer edges ``x[0..256]`` (decreasing, ``x[256] = 0``), ``f = f(x)``
    and the integer acceptance thresholds ``k[i] = ⌊2⁵² x[i+1]/x[i]⌋``.

    Layer 0 is the base strip of width ``v/f(r)``; layer ``i ≥ 1`` is the rectangle
    ``[0, x[i]] × [f(x[i]), f(x[i+1])]``; every layer has area ``v``.
    """
    x = np.empty(257)
    x[0] = ZIG_V / math.exp(-0.5 * ZIG_R * ZIG_R)
    x[1] = ZIG_R
    for i in range(1, 256):
        arg = ZIG_V / x[i] + math.exp(-0.5 * x[i] * x[i])
        x[i + 1] = math.sqrt(-2.0 * math.log(arg)) if arg < 1.0 else 0.0
    x[256] = 0.0
    f = np.exp(-0.5 * x * x)
    k = np.floor(2.0**52 * x[1:] / x[:-1]).astype(np.uint64)
    return x, f, k


ZIG_X, ZIG_F, ZIG_K = ziggurat_tables()
ZIG_K = ZIG_K.astype(np.int64)  # < 2⁵²: signed compares are exact and cheaper


@njit(cache=True, inline="always")
def _rotl(x, k):
    return (x << np.uint64(k)) | (x >> np.uint64(64 - k))


@njit(cache=True)
def splitmix64(z):
    """One SplitMix64 step: ``(new state, output)`` (``z`` is taken as uint64)."""
    z = np.uint64(z) + np.uint64(0x9E3779B97F4A7C15)
    o = z
    o = (o ^ (o >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    o = (o ^ (o >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z, o ^ (o >> np.uint64(31))


@njit(cache=True, inline="always")
def _xoshiro(s0, s1, s2, s3):
    """xoshiro256**: ``(output, new state)``; the state lives in registers."""
    out = _rotl(s1 * np.uint64(5), 7) * np.uint64(9)
    t = s1 << np.uint64(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = _rotl(s3, 45)
    return out, s0, s1, s2, s3


@njit(cache=True, inline="always")
def _unit(r):
    """A double in ``[0, 1)`` from the top 53 bits of ``r``."""
    return float(np.int64(r >> np.uint64(11))) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _wedge_or_tail(idx, x, s0, s1, s2, s3, zx, zf):
    """The rare ziggurat branch: ``(accepted, |value|, state)``.

    Layer 0: a draw from the tail beyond ``r`` by Marsaglia's method (always accepted).
    Layer ``i ≥ 1``: accept ``x`` when a uniform height in the layer lies under ``f(x)``.
    """
    if idx == 0:
        while True:
            r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
            xx = -math.log(1.0 - _unit(r)) / zx[1]
            r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
            yy = -math.log(1.0 - _unit(r))
            if yy + yy > xx * xx:
                return True, zx[1] + xx, s0, s1, s2, s3
    r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
    y = zf[idx] + _unit(r) * (zf[idx + 1] - zf[idx])
    return y < math.exp(-0.5 * x * x), x, s0, s1, s2, s3


@by_threads
@njit(cache=True, parallel=True)
def normal_rows_kernel(seeds, scale, zx, zf, zk, out):
    """``out[i, :] = scale[i] · N(0, 1)`` draws of the stream seeded by ``seeds[i]``.

    Parallel over rows; a row's values depend on its seed only. Each draw takes one 64-bit
    output: bits 0–7 pick the layer, bit 8 the sign, bits 12–63 the abscissa.
    """
    n, m = out.shape
    for i in prange(n):
        z = seeds[i]
        z, s0 = splitmix64(z)
        z, s1 = splitmix64(z)
        z, s2 = splitmix64(z)
        z, s3 = splitmix64(z)
        a = scale[i]
        for j in range(m):
            while True:
                r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
                idx = np.int64(r & np.uint64(0xFF))
                neg = (r & np.uint64(0x100)) != np.uint64(0)
                rabs = np.int64(r >> np.uint64(12))
                x = rabs * (zx[idx] * (1.0 / 4503599627370496.0))
                if rabs < zk[idx]:
                    break
                ok, x, s0, s1, s2, s3 = _wedge_or_tail(idx, x, s0, s1, s2, s3, zx, zf)
                if ok:
                    break
            out[i, j] = -a * x if neg else a * x


#: :func:`normal_rows_kernel` compiled without threads, for a few rows: starting the thread
#: pool costs more than it saves there, and on a busy machine a parallel region waits for
#: every thread (20–60× the median latency of one link). The same code, the same values.
normal_rows_serial_kernel = normal_rows_kernel.serial_only()
