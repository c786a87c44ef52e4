"""Numba kernels of the resampling step of the shared particle machinery.

:func:`~phyloc.localization.particles.resample_agents` resamples every agent of a
``[n_agents, Q, dim]`` particle set systematically and gathers the particles (and any per-particle
values carried with them) with the same indices. NumPy computes the shifted weights
``exp(lw − max)`` and their sums (its ``exp`` and pairwise sum, so the weights are those of a
per-agent :func:`~phyloc.localization.particles.systematic_resample`); the kernels here do the
rest in one pass per agent: normalization, the cumulative-weight search and the gather, without
the per-agent Python loop and the index arrays of ``numpy.take_along_axis``. Each kernel is
tested against a plain-NumPy twin in ``tests/test_particle_kernels.py``.

References
----------
A. Doucet, N. de Freitas, N. Gordon (eds.), *Sequential Monte Carlo Methods in Practice*,
Springer, 2001 (systematic resampling).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def systematic_gather_kernel(w, total, u0, X, idx, out):
    """Systematic resampling of every agent, and the gather of its particles.

    Per agent ``a`` the weights are ``w[a] / total[a]`` (``w`` the shifted linear weights,
    ``total`` their sum), ``idx[a, i]`` is the particle whose cumulative weight covers
    ``(i + u0[a]) / Q`` (the search of
    :func:`~phyloc.localization._kernels.systematic_resample_kernel`, operation for operation)
    and ``out[a, i] = X[a, idx[a, i]]``. ``w`` is overwritten with the normalized weights.
    """
    n_agents, Q, dim = X.shape
    m = w.shape[1]
    for a in range(n_agents):
        s = total[a]
        for q in range(m):
            w[a, q] = w[a, q] / s
        c = w[a, 0]
        j = 0
        for i in range(Q):
            u = (i + u0[a]) / Q
            while u > c and j < m - 1:
                j += 1
                c += w[a, j]
            idx[a, i] = j
            for k in range(dim):
                out[a, i, k] = X[a, j, k]


@njit(cache=True)
def gather_rows_kernel(values, idx, out):
    """``out[a, i] = values[a, idx[a, i]]``: per-particle values gathered with the indices of
    :func:`systematic_gather_kernel` (``numpy.take_along_axis`` along axis 1)."""
    n, Q = idx.shape
    for a in range(n):
        for i in range(Q):
            out[a, i] = values[a, idx[a, i]]


@njit(cache=True)
def mh_propose_draw_kernel(rng, X, move_scale, min_std, out):
    """Random-walk proposals with their normals drawn here: ``out = X + s·z`` per agent,
    ``s_k = max(move_scale·std_q X[a, :, k], min_std)`` (population std over the particles) and
    ``z`` standard normals of ``rng`` in the order of ``rng.standard_normal(X.shape)``.

    :func:`~phyloc.localization._kernels.mh_propose_kernel` given
    ``z = rng.standard_normal(X.shape)``, bit for bit and with the generator left in the same
    state: Numba's ``Generator.standard_normal`` is NumPy's ziggurat on the same bit generator,
    and the std is computed with the same operations in the same order. Serial (one stream).
    """
    n_agents, Q, dim = X.shape
    s = np.empty(dim)
    for a in range(n_agents):
        for k in range(dim):
            m = 0.0
            for q in range(Q):
                m += X[a, q, k]
            m /= Q
            v = 0.0
            for q in range(Q):
                t = X[a, q, k] - m
                v += t * t
            s[k] = max(np.sqrt(v / Q) * move_scale, min_std)
        for q in range(Q):
            for k in range(dim):
                out[a, q, k] = X[a, q, k] + s[k] * rng.standard_normal()
