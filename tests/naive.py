"""Slow, obviously correct references for the kernels and public functions (one loop per sum).

Nothing here is fast or clever: each function is a direct transcription of the defining
equation, so a test that compares phyloc with it checks the mathematics, not the code twice.
"""

from __future__ import annotations

import math

import numpy as np

C0 = 299_792_458.0  # the tests keep their own copy of the constant


def subcarriers(N: int) -> np.ndarray:
    """n = -(N-1)/2 … (N-1)/2."""
    return np.arange(N) - (N - 1) // 2


def symbol_samples(S, N, fsc, os, delay_s):
    """s(iT − τ), i = 0 … os·N − 1, by the direct sum of DiPNet eq. (5)."""
    T = 1.0 / (os * N * fsc)
    omega = 2 * math.pi * fsc
    out = np.zeros(os * N, dtype=complex)
    for i in range(os * N):
        t = i * T - delay_s
        acc = 0j
        for j, n in enumerate(subcarriers(N)):
            acc += S[j] * np.exp(1j * omega * n * t)
        out[i] = acc / math.sqrt(N)
    return out


def received_samples(S, delays, gains, N, fsc, os):
    """Σ_l α_l s(iT − τ_l) (noise-free eq. (6)), one delayed symbol at a time."""
    r = np.zeros(os * N, dtype=complex)
    for tau, a in zip(delays, gains, strict=True):
        r += a * symbol_samples(S, N, fsc, os, tau)
    return r


def cross_correlation(r, S, N, fsc, os, d_m):
    """f(d) = r^H s(d/c0) (DiPNet eq. (23)) as an explicit inner product."""
    s = symbol_samples(S, N, fsc, os, d_m / C0)
    return sum(np.conj(r[i]) * s[i] for i in range(r.size))


def lagrange(values_row, x, order):
    """Lagrange interpolation through `order` periodic grid values around x (grid units)."""
    L = values_row.size
    base = math.floor(x)
    nodes = [base + m - order // 2 + 1 for m in range(order)]
    acc = 0j
    for a in nodes:
        w = 1.0
        for b in nodes:
            if b != a:
                w *= (x - b) / (a - b)
        acc += values_row[a % L] * w
    return acc


def trapezoid_zzb(pc_snr, one_minus_rho, D, n=200_001):
    """ZZB without valley filling by a dense uniform trapezoid rule (distance units)."""
    from scipy.stats import norm

    h = np.linspace(0.0, D, n)
    g = h * (1 - h / D) * norm.sf(np.sqrt(pc_snr * one_minus_rho(h)))
    return float(np.sum((g[1:] + g[:-1]) / 2 * np.diff(h)))
