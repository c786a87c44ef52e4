"""Slow, obviously correct references for the range estimators (one loop per sum).

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
