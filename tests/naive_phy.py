"""Plain-NumPy twins of the PHY kernels in :mod:`phyloc.phy._kernels`.

Each function is a vectorized NumPy transcription of one Numba kernel (same arguments, returns
the array instead of filling ``out``). Tests compare the kernels with these twins; the PHY
benchmark (``benchmarks/bench_phy.py``) times them through ``benchmarks._reference.naive``.
They are test code and are not installed with the package.
"""

from __future__ import annotations

import numpy as np


def synthesize_numpy(symbols, tx_index, delays, gains, offsets, omega, n_first, noise):
    """Plain-NumPy twin of :func:`phyloc.phy._kernels.synthesize_kernel` (returns the array)."""
    n_links, N = noise.shape
    n = n_first + np.arange(N, dtype=np.float64)
    link = np.repeat(np.arange(n_links), np.diff(offsets))
    H = np.zeros((n_links, N), dtype=np.complex128)
    if delays.size:
        contrib = gains[:, None] * np.exp(-1j * omega * np.outer(delays, n))
        np.add.at(H, link, contrib)
    return symbols[tx_index] * H + noise


def spectrum_numpy(R, symbols, tx_index):
    """Plain-NumPy twin of :func:`phyloc.phy._kernels.spectrum_kernel`: ``(spectrum, finite)``."""
    return np.conj(R.astype(np.complex128)) * symbols[tx_index], bool(np.all(np.isfinite(R)))


def symbol_moments_numpy(symbols, n_first):
    """Plain-NumPy twin of :func:`phyloc.phy._kernels.symbol_moments_kernel`."""
    p = np.abs(symbols) ** 2
    n = n_first + np.arange(symbols.shape[1], dtype=np.float64)
    return p.sum(axis=1), (p * n**2).sum(axis=1)


def interp_numpy(values, rows, x, order):
    """Plain-NumPy twin of :func:`phyloc.phy._kernels.interp_kernel`."""
    L = values.shape[1]
    fl = np.floor(x)
    t = x - fl
    base = fl.astype(np.int64)
    half = order // 2
    nodes = np.arange(order) - half + 1
    out = np.zeros(x.shape, dtype=np.complex128)
    for a, xa in enumerate(nodes):
        w = np.ones_like(t)
        for b, xb in enumerate(nodes):
            if b != a:
                w = w * (t - xb) / (xa - xb)
        out += values[rows, (base + xa) % L] * w
    return out


def refine_peaks_numpy(spectrum, n, w, d0, spacing, n_iter):
    """Plain-NumPy twin of :func:`phyloc.phy._kernels.refine_peaks_kernel`."""
    d = np.array(d0, dtype=np.float64)
    active = np.ones(d.size, dtype=bool)
    for _ in range(n_iter):
        wn = w * n[None, :]
        e = spectrum * np.exp(-1j * wn * d[:, None])
        F = e.sum(1)
        F1 = (-1j * wn * e).sum(1)
        F2 = (-(wn**2) * e).sum(1)
        g1 = 2.0 * (F.conj() * F1).real
        g2 = 2.0 * (np.abs(F1) ** 2 + (F.conj() * F2).real)
        ok = active & (g2 < 0.0)
        step = np.zeros_like(d)
        step[ok] = np.clip(-g1[ok] / g2[ok], -0.5 * spacing, 0.5 * spacing)
        d = d + step
        active = ok & (np.abs(step) >= 1e-9 * spacing)
        if not active.any():
            break
    far = np.abs(d - d0) > spacing
    d[far] = np.asarray(d0)[far]
    return d


# -- Gaussian noise (twin of phyloc.phy._gauss, in plain Python integers) ---------------------
M64 = (1 << 64) - 1


def splitmix64_py(z):
    """One SplitMix64 step (Blackman and Vigna): ``(new state, output)``."""
    z = (z + 0x9E3779B97F4A7C15) & M64
    o = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M64
    o = ((o ^ (o >> 27)) * 0x94D049BB133111EB) & M64
    return z, o ^ (o >> 31)


def xoshiro_py(s):
    """xoshiro256** on a list of four Python ints; returns the output, advances ``s``."""

    def rotl(x, k):
        return ((x << k) | (x >> (64 - k))) & M64

    out = (rotl((s[1] * 5) & M64, 7) * 9) & M64
    t = (s[1] << 17) & M64
    s[2] ^= s[0]
    s[3] ^= s[1]
    s[1] ^= s[2]
    s[0] ^= s[3]
    s[2] ^= t
    s[3] = rotl(s[3], 45)
    return out


def normal_rows_py(seeds, scale, zx, zf, zk, m):
    """Ziggurat normals row by row, exactly as ``normal_rows_kernel`` (slow; tests only)."""
    import math

    out = np.empty((len(seeds), m))
    for i, seed in enumerate(seeds):
        z, s = int(seed), []
        for _ in range(4):
            z, o = splitmix64_py(z)
            s.append(o)
        for j in range(m):
            while True:
                r = xoshiro_py(s)
                idx = r & 0xFF
                neg = bool(r & 0x100)
                rabs = r >> 12
                x = rabs * (float(zx[idx]) * (1.0 / 4503599627370496.0))
                if rabs < int(zk[idx]):
                    break
                if idx == 0:
                    while True:
                        xx = -math.log(1.0 - (xoshiro_py(s) >> 11) / 9007199254740992.0) / zx[1]
                        yy = -math.log(1.0 - (xoshiro_py(s) >> 11) / 9007199254740992.0)
                        if yy + yy > xx * xx:
                            x = float(zx[1] + xx)
                            break
                    break
                y = zf[idx] + (xoshiro_py(s) >> 11) / 9007199254740992.0 * (zf[idx + 1] - zf[idx])
                if y < math.exp(-0.5 * x * x):
                    break
            out[i, j] = -scale[i] * x if neg else scale[i] * x
    return out


# -- fused pipeline kernels (twins of phyloc.phy._pipeline_kernels) ---------------------------
def noisy_synthesize_numpy(
    seeds, scale, zx, zf, zk, symbols, tx_index, delays, gains, offsets, omega, n_first, N
):
    """Plain twin of :func:`phyloc.phy._pipeline_kernels.noisy_synthesize_kernel`: the noise
    rows of :func:`normal_rows_py` (real and imaginary parts interleaved) through
    :func:`synthesize_numpy` (returns ``[n_links, N]``)."""
    noise = normal_rows_py(seeds, scale, zx, zf, zk, 2 * N).view(np.complex128)
    return synthesize_numpy(symbols, tx_index, delays, gains, offsets, omega, n_first, noise)


def spectrum_padded_numpy(R, symbols, tx_index, a, b, L):
    """Plain twin of :func:`phyloc.phy._pipeline_kernels.spectrum_padded_kernel` for rows
    ``a … a + b − 1``: ``(spectrum rows, padded rows [b, L], finite)``; bin n at index n mod L."""
    N = R.shape[1]
    c = np.conj(R[a : a + b].astype(np.complex128)) * symbols[tx_index[a : a + b]]
    padded = np.zeros((b, L), dtype=np.complex128)
    n = np.arange(N) - (N - 1) // 2
    padded[:, n % L] = c
    return c, padded, bool(np.all(np.isfinite(R[a : a + b])))


def finite_nonzero_numpy(x):
    """Plain twin of :func:`phyloc.phy._pipeline_kernels.finite_nonzero_kernel` (on floats)."""
    if not np.all(np.isfinite(x)):
        return 1
    return 0 if np.any(x != 0) else 2
