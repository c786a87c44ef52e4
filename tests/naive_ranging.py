"""Slow, obviously correct references for the range estimators (one loop per sum), and the
plain-NumPy twins of the ranging kernels (at the end).

Each function transcribes its defining equation directly, so a test comparing phyloc with it
checks the mathematics, not the same code twice.
"""

from __future__ import annotations

import cmath
import math

import numpy as np

C0 = 299_792_458.0  # the tests keep their own copy of the constant


def correlate(x, n, w, d):
    """(F, Σ n x e, Σ n² x e) with e = exp(−j w n d), one term at a time."""
    t0 = t1 = t2 = 0j
    for xk, nk in zip(x, n, strict=True):
        e = xk * cmath.exp(-1j * w * nk * d)
        t0 += e
        t1 += nk * e
        t2 += nk * nk * e
    return t0, t1, t2


def residual(c, power, n, w, dists, gains):
    """c_n − Σ_p |S_n|² conj(α_p) exp(+j w n d_p), one subcarrier and path at a time."""
    out = np.array(c, dtype=complex)
    for k in range(out.size):
        for d, a in zip(dists, gains, strict=True):
            out[k] -= power[k] * a.conjugate() * cmath.exp(1j * w * n[k] * d)
    return out


def first_peak_dense(c, n, w, lo, hi, rel_db, floor, step=0.01):
    """Earliest local maximum of the exact |F(d)|² on a dense grid over [lo, hi] that reaches
    max(10^(rel/10)·max|F|², floor): a brute-force first-peak detector (None if none)."""
    grid = np.arange(lo - step, hi + 2 * step, step)
    g = np.array([abs(correlate(c, n, w, d)[0]) ** 2 for d in grid])
    inside = (grid >= lo) & (grid <= hi)
    thr = max(10 ** (rel_db / 10) * g[inside].max(), floor)
    for i in range(1, grid.size - 1):
        if inside[i] and g[i] > g[i - 1] and g[i] >= g[i + 1] and g[i] >= thr:
            return float(grid[i])
    return None


def crb_unit_pilots(snr, N, fsc):
    """DiPNet eq. (24) for |S_n| = 1: c0² / (2 SNR ω² Σ n²), Σ n² = (N−1)N(N+1)/12."""
    omega = 2 * math.pi * fsc
    return C0**2 / (2 * snr * omega**2 * (N - 1) * N * (N + 1) / 12)


# -- plain-NumPy twins of the kernels in phyloc.ranging._kernels ---------------------------------
# Vectorized transcriptions of each Numba kernel (same arguments; they return new arrays instead
# of filling ``out``). tests/test_ranging.py compares the kernels with them and
# benchmarks/bench_ranging.py times sage_numpy through benchmarks._reference.naive.


def correlate_numpy(spectrum, n0, w, d):
    """Plain-NumPy twin of :func:`phyloc.ranging._kernels.correlate_kernel`."""
    n = n0 + np.arange(spectrum.shape[1], dtype=np.float64)
    return (spectrum * np.exp(-1j * w * d[:, None] * n[None, :])).sum(axis=1)


def residual_numpy(spectrum, power, tx_index, n0, w, dist, gain):
    """Plain-NumPy twin of :func:`phyloc.ranging._kernels.residual_kernel` (returns the array)."""
    n = n0 + np.arange(spectrum.shape[1], dtype=np.float64)
    phase = np.exp(1j * w * dist[:, :, None] * n[None, None, :])  # [n_links, P, N]
    contrib = (np.conj(gain)[:, :, None] * phase).sum(axis=1) * power[tx_index]
    return spectrum - contrib


def correlate_derivs_numpy(x, n, w, d):
    """Plain-NumPy twin of ``phyloc.ranging._kernels._correlate_derivs``: ``(T0, T1, T2)``,
    ``T_m = Σ n^m x e^{−jwnd}`` with the subcarriers ``n`` given as an array."""
    e = x * np.exp(-1j * w * n * d)
    return e.sum(), (n * e).sum(), (n * n * e).sum()


def sage_numpy(
    spectrum,
    power,
    tx_index,
    energy,
    n0,
    w,
    dist,
    gain,
    n_active,
    n_iter,
    spacing,
    n_search,
    n_newton,
):
    """Plain-NumPy twin of :func:`phyloc.ranging._kernels.sage_kernel` (returns new
    ``dist, gain``)."""
    dist = np.array(dist, dtype=np.float64)
    gain = np.array(gain, dtype=np.complex128)
    n = n0 + np.arange(spectrum.shape[1], dtype=np.float64)

    def contrib(i, d, a):
        return power[tx_index[i]] * np.conj(a) * np.exp(1j * w * n * d)

    for i in range(dist.shape[0]):
        d, a, P = dist[i], gain[i], int(n_active[i])
        e = spectrum[i] - sum((contrib(i, d[p], a[p]) for p in range(P)), 0j)
        for _ in range(n_iter):
            for p in range(P):
                e = e + contrib(i, d[p], a[p])
                cand = d[p] + spacing * np.arange(-n_search, n_search + 1)
                g = np.abs(np.exp(-1j * w * np.outer(cand, n)) @ e) ** 2
                d0 = cand[int(np.argmax(g))]
                dn = d0
                for _k in range(n_newton):
                    T0, T1, T2 = correlate_derivs_numpy(e, n, w, dn)
                    F1, F2 = -1j * w * T1, -(w * w) * T2
                    g1 = 2.0 * (np.conj(T0) * F1).real
                    g2 = 2.0 * (abs(F1) ** 2 + (np.conj(T0) * F2).real)
                    if not g2 < 0.0:
                        break
                    step = float(np.clip(-g1 / g2, -0.5 * spacing, 0.5 * spacing))
                    dn += step
                    if abs(step) < 1e-9 * spacing:
                        break
                if abs(dn - d0) > spacing:
                    dn = d0
                d[p] = dn
                a[p] = np.conj(correlate_derivs_numpy(e, n, w, dn)[0]) / energy[i]
                e = e - contrib(i, d[p], a[p])
    return dist, gain
