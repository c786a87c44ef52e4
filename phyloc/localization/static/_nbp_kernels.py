"""Numba kernels of the message KDEs (:mod:`phyloc.localization.static.kde`).

The O(N_S²) Gaussian KDE of a message (POA-NBP eq. (7)) evaluated at the proposal samples
(POA-NBP eq. (8)) and the least-squares cross-validation score of a message's bandwidth. Each
kernel is tested against a plain-NumPy reference twin, which is test code
(``tests/naive_static.py``, compared in ``tests/test_nbp.py``).

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Number of candidate bandwidths of the LSCV grid ``√2·h_S·2^{−t/2}``.
LSCV_GRID = 13
#: ``d²/4h_0²`` above which :func:`lscv_grid_kernel` drops a pair (``e^{−36}`` ≈ 2e-16).
LSCV_CUTOFF = 36.0
#: Log-domain cut-off of :func:`kde_logpdf_kernel` (terms below ``max − KDE_CUTOFF`` skipped).
KDE_CUTOFF = 36.0


# ---------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def kde_logpdf_kernel(points, centers, log_weights, bandwidths, out):
    """``out[m, p] = log Σ_k exp(log_weights[m, k]) N(points[p]; centers[m, k], h_m² I)``.

    The Gaussian-kernel density estimate of POA-NBP eq. (7) of message ``m`` (isotropic bandwidth
    ``h_m = bandwidths[m]``) in the log domain with a max-shift (no underflow far from every
    centre). ``log_weights`` rows are normalised (logsumexp 0); ``-inf`` marks a zero weight.
    Terms more than :data:`KDE_CUTOFF` below the largest are skipped: their total is below
    ``K·e^{−36}`` relative (≈ 1e-14 for K = 200), and far-away kernels cost no ``exp``.
    Serial: the callers evaluate one agent at a time, for which thread start-up costs more
    than it saves (and Monte Carlo runs are parallel over realizations).
    """
    M, Kc, _ = centers.shape
    P = points.shape[0]
    buf = np.empty(Kc)
    for m in range(M):
        h = bandwidths[m]
        c = 0.5 / (h * h)
        log_norm = np.log(2.0 * np.pi * h * h)
        for p in range(P):
            px = points[p, 0]
            py = points[p, 1]
            best = -np.inf
            for k in range(Kc):
                dx = px - centers[m, k, 0]
                dy = py - centers[m, k, 1]
                e = log_weights[m, k] - c * (dx * dx + dy * dy)
                buf[k] = e
                if e > best:
                    best = e
            if best == -np.inf:
                out[m, p] = -np.inf
                continue
            cut = best - KDE_CUTOFF
            s = 0.0
            for k in range(Kc):
                if buf[k] > cut:
                    s += np.exp(buf[k] - best)
            out[m, p] = best + np.log(s) - log_norm


@njit(cache=True, fastmath={"reassoc", "contract"})
def lscv_grid_kernel(samples, weights, h0, out):
    """LSCV scores of a 2-D Gaussian KDE for ``h_t = h0·2^{−t/2}``, ``t = 0 … out.size − 1``.

    ``LSCV(h) = ∫ f̂² − 2 Σ_i w_i f̂_{−i}(x_i)``, exactly for Gaussian kernels:
    ``[Σ_i w_i² + 2 Σ_{i<j} w_i w_j e^{−d²/4h²}]/(4πh²)
    − 2 Σ_{i<j} w_i w_j (1/(1−w_i) + 1/(1−w_j)) e^{−d²/2h²}/(2πh²)``
    (leave-one-out weights ``w_j/(1 − w_i)``). On this grid ``e^{−d²/4h_{t+1}²} =
    (e^{−d²/4h_t²})²`` and ``e^{−d²/2h_t²} = e^{−d²/4h_{t+1}²}``, so each pair costs one
    ``exp``; the sums over pairs then run as plain (vectorizable) multiply–adds per ``t``.
    Pairs with ``e^{−d²/4h_0²} < e^{−36}`` (negligible for every ``h``) are dropped.
    """
    n = samples.shape[0]
    T = out.size
    a0 = 0.25 / (h0 * h0)
    n_pairs = n * (n - 1) // 2
    e = np.empty(n_pairs)
    c1 = np.empty(n_pairs)
    c2 = np.empty(n_pairs)
    q = 0
    sw2 = 0.0
    for i in range(n):
        wi = weights[i]
        sw2 += wi * wi
        li = 1.0 / (1.0 - wi) if wi < 1.0 else 0.0
        for j in range(i + 1, n):
            dx = samples[i, 0] - samples[j, 0]
            dy = samples[i, 1] - samples[j, 1]
            x = (dx * dx + dy * dy) * a0
            if x > LSCV_CUTOFF:
                continue
            wj = weights[j]
            lj = 1.0 / (1.0 - wj) if wj < 1.0 else 0.0
            e[q] = np.exp(-x)
            c1[q] = wi * wj
            c2[q] = wi * wj * (li + lj)
            q += 1
    s1 = 0.0  # Σ w_i w_j E_{t−1}, E_t = exp(−d²/(4 h_t²)) (score t−1 needs E_{t−1} and E_t)
    for t in range(T + 1):
        s1_t = 0.0
        s2_t = 0.0
        for r in range(q):
            s1_t += c1[r] * e[r]
            s2_t += c2[r] * e[r]
            e[r] = e[r] * e[r]
        if t > 0:
            h2 = h0 * h0 * 0.5 ** (t - 1)
            out[t - 1] = (sw2 + 2.0 * s1) / (4.0 * np.pi * h2) - 2.0 * s2_t / (2.0 * np.pi * h2)
        s1 = s1_t
