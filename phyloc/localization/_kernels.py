"""Numba kernels of the shared particle machinery: weights, resampling, moves, priors.

Log-weight normalization, systematic resampling, the random-walk proposals and the
Metropolis–Hastings acceptance of a resample-move sweep (:mod:`phyloc.localization.particles`)
and the Gaussian prior density (:mod:`phyloc.localization.priors`). The link likelihoods of
the direct family have their kernels in :mod:`phyloc.localization.direct._kernels`. Each
kernel is tested against a plain-NumPy twin in ``tests/naive_direct.py`` or a SciPy reference.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from phyloc._jit import by_threads


@njit(cache=True)
def log_normalize_kernel(lw, out):
    """``out[a] = lw[a] − log Σ_q exp(lw[a, q])`` per row, computed as ``(lw − max) − log Σ
    exp(lw − max)`` so that rows sum to 1 at any magnitude of ``lw``; a row
    with no finite weight, a NaN or a +inf becomes uniform (``−log Q``). Returns how many
    rows fell back to uniform."""
    n, Q = lw.shape
    bad = 0
    uniform = -np.log(Q)
    for a in range(n):
        m = -np.inf
        ok = True
        for q in range(Q):
            x = lw[a, q]
            if x != x or x == np.inf:
                ok = False
            elif x > m:
                m = x
        if ok and m > -np.inf:
            s = 0.0
            for q in range(Q):
                s += np.exp(lw[a, q] - m)
            # (lw − m) − log s, not lw − (m + log s): at |m| ~ 1e24 (extreme SNR) m + log s
            # rounds to m and every particle at the maximum would get weight 1
            log_s = np.log(s)
            for q in range(Q):
                out[a, q] = (lw[a, q] - m) - log_s
        else:
            bad += 1
            for q in range(Q):
                out[a, q] = uniform
    return bad


@njit(cache=True)
def gaussian_log_prior_kernel(x, centers, std, out):
    """``out[a, q] = −‖x[a, q] − c_a‖²/(2σ_a²) − (dim/2)·ln(2πσ_a²)``: the isotropic Gaussian
    prior of each agent at its particles."""
    n, Q, dim = x.shape
    for a in range(n):
        h = 0.5 / (std[a] * std[a])
        norm = -0.5 * dim * np.log(2.0 * np.pi * std[a] * std[a])
        for q in range(Q):
            acc = 0.0
            for k in range(dim):
                t = x[a, q, k] - centers[a, k]
                acc += t * t
            out[a, q] = norm - h * acc


@njit(cache=True)
def systematic_resample_kernel(weights, u0, out):
    """Systematic resampling: ``out[i]`` = index of the particle covering ``(i + u0)/n``.

    ``weights`` are normalized (sum 1); ``u0`` is one uniform draw in [0, 1).
    """
    n = out.size
    c = weights[0]
    j = 0
    m = weights.size
    for i in range(n):
        u = (i + u0) / n
        while u > c and j < m - 1:
            j += 1
            c += weights[j]
        out[i] = j


@by_threads
@njit(cache=True, parallel=True)
def mh_propose_kernel(X, z, move_scale, min_std, out):
    """Random-walk proposals of a resample-move sweep: ``out = X + s·z`` per agent with
    ``s_k = max(move_scale·std_q X[a, :, k], min_std)`` (population std over the particles)."""
    n_agents, Q, dim = X.shape
    for a in prange(n_agents):
        for k in range(dim):
            m = 0.0
            for q in range(Q):
                m += X[a, q, k]
            m /= Q
            v = 0.0
            for q in range(Q):
                t = X[a, q, k] - m
                v += t * t
            s = max(np.sqrt(v / Q) * move_scale, min_std)
            for q in range(Q):
                out[a, q, k] = X[a, q, k] + s * z[a, q, k]


@by_threads
@njit(cache=True, parallel=True)
def mh_accept_kernel(X, lp, ll_old, ll_new, Xp, lpp, lop, lnp, lam, log_u):
    """Metropolis–Hastings acceptance, in place: particle ``(a, q)`` takes its proposal when
    ``log_u < prop − cur`` with ``cur = lp + λ_a·ll_new + (1 − λ_a)·ll_old`` and ``prop``
    likewise at the proposal; a proposal whose target is not finite is rejected. Returns the
    number of accepted moves."""
    n_agents, Q, dim = X.shape
    acc = np.zeros(n_agents, np.int64)
    for a in prange(n_agents):
        g = lam[a]
        for q in range(Q):
            prop = lpp[a, q] + g * lnp[a, q] + (1.0 - g) * lop[a, q]
            if not np.isfinite(prop):
                continue
            cur = lp[a, q] + g * ll_new[a, q] + (1.0 - g) * ll_old[a, q]
            if log_u[a, q] < prop - cur:
                for k in range(dim):
                    X[a, q, k] = Xp[a, q, k]
                lp[a, q] = lpp[a, q]
                ll_new[a, q] = lnp[a, q]
                ll_old[a, q] = lop[a, q]
                acc[a] += 1
    return acc.sum()
