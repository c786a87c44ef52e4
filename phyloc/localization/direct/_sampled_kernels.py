"""Numba kernels of the sample-based belief exchange (nonparametric messages, DiPNet §V-B).

The message of a neighbour is its particle set carried through the link likelihood,
``log Σ_i w_v^i p(r_uv | ‖x − x_v^i‖)``, with the interpolated table of DiPNet eq. (22), the
Gaussian ranging model or the peak mixture; ``O(Q_u·Q_v)`` per link (DiPNet Table I,
"Sampled SPAWN"). Messages are summed per agent over its incoming links in CSR form (the
links of agent ``a`` are ``j = offsets[a] … offsets[a+1]−1``, neighbour ``nb_node[j]``);
kernels run in parallel over agents and write disjoint rows of ``out``. Each kernel is tested
against a plain-NumPy twin in ``tests/naive_direct.py``.

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
from phyloc.phy.correlation import lagrange_eval


@njit(cache=True)
def _add_message(out_row, msg, gamma):
    """Add ``γ·msg`` to ``out_row``; a message that is −inf at every particle (a neighbour
    whose weights are all zero) carries no information and adds nothing."""
    top = -np.inf
    for q in range(msg.size):
        top = max(top, msg[q])
    if top == -np.inf:
        return
    for q in range(msg.size):
        out_row[q] += gamma * msg[q]


@njit(cache=True)
def _distance(particles, a, q, points, v, i):
    """``‖particles[a, q] − points[v, i]‖``."""
    acc = 0.0
    for k in range(particles.shape[2]):
        t = particles[a, q, k] - points[v, i, k]
        acc += t * t
    return np.sqrt(acc)


@njit(cache=True)
def _log_sum(terms, n):
    """``log Σ_{i<n} exp(terms[i])`` (−inf when every term is −inf)."""
    top = -np.inf
    for i in range(n):
        top = max(top, terms[i])
    if top == -np.inf:
        return -np.inf
    tot = 0.0
    for i in range(n):
        tot += np.exp(terms[i] - top)
    return top + np.log(tot)


@by_threads
@njit(cache=True, parallel=True)
def sampled_direct_kernel(
    particles,
    offsets,
    nb_node,
    nb_row,
    nb_scale,
    nb_points,
    nb_logw,
    nb_count,
    values,
    inv_h,
    order,
    gamma,
    out,
):
    """``out[a, q] = γ Σ_j log Σ_i exp(lw_{v,i} + nb_scale[j]·|f_j(‖x_{a,q} − y_{v,i}‖)|²)``.

    The sample-based message of neighbour ``v = nb_node[j]``: its belief particles ``y_{v,i}``
    (``i < nb_count[v]``, log weights ``nb_logw[v, i]``) carried through the one-path direct
    likelihood of DiPNet eq. (22), ``log p(r_uv | d) = |f(d)|²/(σ²‖S‖²)`` with
    ``nb_scale = 1/(σ²‖S‖²)`` (no ENV: the particles are the neighbour's uncertainty).
    Cost ``O(Q_u·Q_v)`` per link (DiPNet Table I, "Sampled SPAWN").
    """
    n_agents, Q = particles.shape[:2]
    L = values.shape[1]
    q_max = nb_points.shape[1]
    for a in prange(n_agents):
        terms = np.empty(q_max)
        msg = np.empty(Q)
        for q in range(Q):
            out[a, q] = 0.0
        for j in range(offsets[a], offsets[a + 1]):
            v = nb_node[j]
            n_v = nb_count[v]
            row = nb_row[j]
            s = nb_scale[j]
            for q in range(Q):
                for i in range(n_v):
                    d = _distance(particles, a, q, nb_points, v, i)
                    f = lagrange_eval(values, row, L, d * inv_h, order)
                    terms[i] = nb_logw[v, i] + s * (f.real * f.real + f.imag * f.imag)
                msg[q] = _log_sum(terms, n_v)
            _add_message(out[a], msg, gamma)


@by_threads
@njit(cache=True, parallel=True)
def sampled_gauss_kernel(
    particles,
    offsets,
    nb_node,
    ranges,
    inv_var,
    nb_points,
    nb_logw,
    nb_count,
    gamma,
    out,
    outlier_nats=np.inf,
    one_sided=False,
):
    """``out[a, q] = γ Σ_j log Σ_i exp(lw_{v,i} − ½ inv_var[j]·(‖x_{a,q} − y_{v,i}‖ − r_j)²)``.

    The sample-based message of the Gaussian ranging model (two-step, sample-based SAGE):
    range ``r_j`` with its model variance ``1/inv_var[j]``, the neighbour's belief particles in
    place of its mean and the ERV of DiPNet eq. (18). A finite ``outlier_nats`` f adds the
    outlier component ``e^{−f}`` inside each link's log (``lw`` normalized); with ``one_sided``
    per neighbour sample, only where the distance is shorter than the range (the component of
    :func:`~phyloc.localization.direct._kernels.gauss_loglik_kernel` with the same flag).
    """
    n_agents, Q = particles.shape[:2]
    q_max = nb_points.shape[1]
    per_sample = one_sided and outlier_nats < np.inf
    short = np.log1p(np.exp(-outlier_nats))
    for a in prange(n_agents):
        terms = np.empty(q_max)
        msg = np.empty(Q)
        for q in range(Q):
            out[a, q] = 0.0
        for j in range(offsets[a], offsets[a + 1]):
            v = nb_node[j]
            n_v = nb_count[v]
            r = ranges[j]
            w = 0.5 * inv_var[j]
            for q in range(Q):
                for i in range(n_v):
                    e = _distance(particles, a, q, nb_points, v, i) - r
                    u = w * e * e
                    if not per_sample:
                        terms[i] = nb_logw[v, i] - u
                    elif e > 0.0:
                        terms[i] = nb_logw[v, i] - u + short
                    else:
                        terms[i] = nb_logw[v, i] + np.logaddexp(-u, -outlier_nats)
                msg[q] = _log_sum(terms, n_v)
                if outlier_nats < np.inf and not per_sample:
                    msg[q] = np.logaddexp(msg[q], -outlier_nats)
            _add_message(out[a], msg, gamma)


@by_threads
@njit(cache=True, parallel=True)
def sampled_mixture_kernel(
    particles,
    offsets,
    nb_node,
    pk_off,
    pk_d,
    pk_h,
    pk_c,
    s2,
    floor,
    ways,
    nb_points,
    nb_logw,
    nb_count,
    gamma,
    out,
):
    """``out[a, q] = γ Σ_j log Σ_i exp(lw_{v,i} + ℓ̃_j(ways·‖x_{a,q} − y_{v,i}‖))``.

    The sample-based message with the peak-mixture form of the direct likelihood (DiPNet
    eq. (22), see :func:`~phyloc.localization.direct._kernels.mixture_loglik_kernel`), each
    neighbour particle a Gaussian kernel of variance ``s2[j]`` along the link:
    ``ℓ̃ = log(e^{floor_j} + Σ_p exp(h_p − ½log(1 + c_p s²) − (x − d_p)²/(2(1/c_p + s²))))``.
    """
    n_agents, Q = particles.shape[:2]
    q_max = nb_points.shape[1]
    max_p = 1
    for j in range(pk_off.size - 1):
        max_p = max(max_p, pk_off[j + 1] - pk_off[j])
    for a in prange(n_agents):
        terms = np.empty(q_max)
        msg = np.empty(Q)
        base = np.empty(max_p)
        half_prec = np.empty(max_p)
        for q in range(Q):
            out[a, q] = 0.0
        for j in range(offsets[a], offsets[a + 1]):
            v = nb_node[j]
            n_v = nb_count[v]
            p0 = pk_off[j]
            n_p = pk_off[j + 1] - p0
            for i in range(n_p):
                ci = pk_c[p0 + i]
                base[i] = pk_h[p0 + i] - 0.5 * np.log1p(ci * s2[j])
                half_prec[i] = 0.5 / (1.0 / ci + s2[j])
            fl = floor[j]
            for q in range(Q):
                for i in range(n_v):
                    x = ways * _distance(particles, a, q, nb_points, v, i)
                    best = fl
                    for p in range(n_p):
                        t = x - pk_d[p0 + p]
                        e = base[p] - half_prec[p] * t * t
                        if e > best:
                            best = e
                    tot = np.exp(fl - best)
                    for p in range(n_p):
                        t = x - pk_d[p0 + p]
                        tot += np.exp(base[p] - half_prec[p] * t * t - best)
                    terms[i] = nb_logw[v, i] + (best + np.log(tot))
                msg[q] = _log_sum(terms, n_v)
            _add_message(out[a], msg, gamma)
