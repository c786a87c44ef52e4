"""Numba kernels of the particle localizers, each beside its plain-NumPy twin (``*_numpy``).

Link likelihoods are summed per agent over its incoming links in CSR form: the links of agent
``a`` are ``j = offsets[a] … offsets[a+1]−1``, each with the neighbour node ``nb_node[j]``
whose published position is ``centers[nb_node[j]]``. Kernels run in parallel over agents and
write disjoint rows of ``out``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from phyloc.phy._kernels import _lagrange_eval


@njit(cache=True, parallel=True)
def direct_loglik_kernel(
    particles, offsets, nb_node, nb_row, nb_scale, centers, values, inv_h, order, out
):
    """``out[a, q] = Σ_j nb_scale[j]·|f_{nb_row[j]}(‖x_{a,q} − c_{nb_node[j]}‖)|²``.

    The equivalent likelihood of DiPNet eq. (25) in log form, with
    ``nb_scale = γ/(σ̃²‖S‖²)`` (tempering γ, ENV σ̃² of eq. (26)) and ``f`` interpolated from
    the correlation table ``values`` (grid spacing ``1/inv_h``, Lagrange ``order``).
    """
    n_agents, Q, dim = particles.shape
    L = values.shape[1]
    for a in prange(n_agents):
        for q in range(Q):
            out[a, q] = 0.0
        for j in range(offsets[a], offsets[a + 1]):
            c = centers[nb_node[j]]
            row = nb_row[j]
            s = nb_scale[j]
            for q in range(Q):
                acc = 0.0
                for k in range(dim):
                    t = particles[a, q, k] - c[k]
                    acc += t * t
                f = _lagrange_eval(values, row, L, np.sqrt(acc) * inv_h, order)
                out[a, q] += s * (f.real * f.real + f.imag * f.imag)


def direct_loglik_numpy(
    particles, offsets, nb_node, nb_row, nb_scale, centers, values, inv_h, order
):
    """Plain-NumPy twin of :func:`direct_loglik_kernel`."""
    from phyloc.phy._kernels import interp_numpy

    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            d = np.linalg.norm(particles[a] - centers[nb_node[j]], axis=1)
            f = interp_numpy(values, np.full(Q, nb_row[j]), d * inv_h, order)
            out[a] += nb_scale[j] * np.abs(f) ** 2
    return out


@njit(cache=True, parallel=True)
def gauss_loglik_kernel(particles, offsets, nb_node, ranges, inv_var, centers, out):
    """``out[a, q] = −½ Σ_j inv_var[j]·(‖x_{a,q} − c_{nb_node[j]}‖ − r_j)²``.

    The Gaussian ranging model with the equivalent ranging variance (ERV) of DiPNet eq. (18):
    ``1/inv_var = var_r + σ²_{v→uv}`` (times 1/γ when tempered).
    """
    n_agents, Q, dim = particles.shape
    for a in prange(n_agents):
        for q in range(Q):
            out[a, q] = 0.0
        for j in range(offsets[a], offsets[a + 1]):
            c = centers[nb_node[j]]
            r = ranges[j]
            w = 0.5 * inv_var[j]
            for q in range(Q):
                acc = 0.0
                for k in range(dim):
                    t = particles[a, q, k] - c[k]
                    acc += t * t
                e = np.sqrt(acc) - r
                out[a, q] -= w * e * e


def gauss_loglik_numpy(particles, offsets, nb_node, ranges, inv_var, centers):
    """Plain-NumPy twin of :func:`gauss_loglik_kernel`."""
    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            d = np.linalg.norm(particles[a] - centers[nb_node[j]], axis=1)
            out[a] -= 0.5 * inv_var[j] * (d - ranges[j]) ** 2
    return out


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


def systematic_resample_numpy(weights, u0, n):
    """Plain-NumPy twin of :func:`systematic_resample_kernel`."""
    edges = np.cumsum(weights)
    edges[-1] = max(edges[-1], 1.0)
    u = (np.arange(n) + u0) / n
    return np.minimum(np.searchsorted(edges, u, side="left"), weights.size - 1)
