"""Plain-NumPy twins of the localization kernels (``phyloc.localization.direct._kernels``,
``phyloc.localization.direct._sampled_kernels`` and the shared ``phyloc.localization._kernels``).

Test code only: tests import them (``from naive_direct import ...``) and
``benchmarks/bench_dipnet.py`` loads this file through ``benchmarks._reference.naive`` for its
speed-up figures. The table interpolation comes from ``tests/naive_phy.py``, loaded by path so
that both ways of loading this file find it.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np


def _naive_phy():
    """The module ``tests/naive_phy.py`` beside this file."""
    mod = sys.modules.get("naive_phy")
    if mod is None:
        path = Path(__file__).with_name("naive_phy.py")
        spec = importlib.util.spec_from_file_location("naive_phy", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    return mod


def direct_loglik_numpy(
    particles, offsets, nb_node, nb_row, nb_scale, centers, values, inv_h, order
):
    """Twin of ``direct_loglik_kernel``: DiPNet eq. (25), one link at a time."""
    interp_numpy = _naive_phy().interp_numpy

    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            d = np.linalg.norm(particles[a] - centers[nb_node[j]], axis=1)
            f = interp_numpy(values, np.full(Q, nb_row[j]), d * inv_h, order)
            out[a] += nb_scale[j] * np.abs(f) ** 2
    return out


def gauss_loglik_numpy(
    particles,
    offsets,
    nb_node,
    ranges,
    inv_var,
    centers,
    outlier_nats=np.inf,
    gamma=1.0,
    one_sided=False,
):
    """Twin of ``gauss_loglik_kernel``: Gaussian ranges with the ERV of DiPNet eq. (18), with
    the outlier mixture ``γ·logaddexp(−½e²/var, −f)`` when ``outlier_nats`` f is finite; with
    ``one_sided`` the outlier density is ``e^{−f}`` for ``d <= r`` and ``e^{−f}·e^{−½e²/var}``
    for ``d > r``."""
    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            d = np.linalg.norm(particles[a] - centers[nb_node[j]], axis=1)
            if np.isfinite(outlier_nats):
                if gamma == 0:
                    continue
                g = -0.5 * inv_var[j] / gamma * (d - ranges[j]) ** 2
                outlier = -outlier_nats + (np.where(d > ranges[j], g, 0.0) if one_sided else 0.0)
                out[a] += gamma * np.logaddexp(g, outlier)
            else:
                out[a] -= 0.5 * inv_var[j] * (d - ranges[j]) ** 2
    return out


def systematic_resample_numpy(weights, u0, n):
    """Twin of ``systematic_resample_kernel``: the textbook searchsorted resampler."""
    edges = np.cumsum(weights)
    edges[-1] = max(edges[-1], 1.0)
    u = (np.arange(n) + u0) / n
    return np.minimum(np.searchsorted(edges, u, side="left"), weights.size - 1)


def mixture_loglik_numpy(
    particles, offsets, nb_node, pk_off, pk_d, pk_h, pk_c, s2, floor, ways, gamma, centers
):
    """Twin of ``mixture_loglik_kernel``: the marginal peak-mixture likelihood, vectorized."""
    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            x = ways * np.linalg.norm(particles[a] - centers[nb_node[j]], axis=1)
            sl = slice(pk_off[j], pk_off[j + 1])
            v = 1.0 / pk_c[sl] + s2[j]
            terms = (pk_h[sl] - 0.5 * np.log1p(pk_c[sl] * s2[j]))[None, :] - 0.5 * (
                x[:, None] - pk_d[sl][None, :]
            ) ** 2 / v[None, :]
            terms = np.concatenate([np.full((Q, 1), floor[j]), terms], axis=1)
            m = terms.max(axis=1)
            out[a] += gamma * (m + np.log(np.exp(terms - m[:, None]).sum(axis=1)))
    return out


def _sampled_message_numpy(ell, nb_logw_v):
    """``log Σ_i exp(lw_i + ℓ[q, i])`` per particle q (scipy's logsumexp), −inf when empty."""
    from scipy.special import logsumexp

    terms = nb_logw_v[None, :] + ell
    with np.errstate(divide="ignore"):
        return logsumexp(terms, axis=1) if terms.shape[1] else np.full(terms.shape[0], -np.inf)


def _add_numpy(out_row, msg, gamma):
    if np.any(np.isfinite(msg)) or np.any(msg > -np.inf):
        out_row += gamma * msg


def sampled_direct_numpy(
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
):
    """Twin of ``sampled_direct_kernel``: each link's message as a [Q_u, Q_v] matrix."""
    interp_numpy = _naive_phy().interp_numpy

    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            v = nb_node[j]
            pts = nb_points[v, : nb_count[v]]
            d = np.linalg.norm(particles[a][:, None, :] - pts[None], axis=2)
            f = interp_numpy(values, np.full(d.size, nb_row[j]), d.ravel() * inv_h, order)
            ell = nb_scale[j] * (np.abs(f) ** 2).reshape(d.shape)
            _add_numpy(out[a], _sampled_message_numpy(ell, nb_logw[v, : nb_count[v]]), gamma)
    return out


def sampled_gauss_numpy(
    particles,
    offsets,
    nb_node,
    ranges,
    inv_var,
    nb_points,
    nb_logw,
    nb_count,
    gamma,
    outlier_nats=np.inf,
    one_sided=False,
):
    """Twin of ``sampled_gauss_kernel``: each link's message as a [Q_u, Q_v] matrix (with
    ``one_sided``, the one-sided outlier mixture of ``gauss_loglik_numpy`` per sample pair)."""
    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            v = nb_node[j]
            pts = nb_points[v, : nb_count[v]]
            d = np.linalg.norm(particles[a][:, None, :] - pts[None], axis=2)
            ell = -0.5 * inv_var[j] * (d - ranges[j]) ** 2
            if one_sided and np.isfinite(outlier_nats):
                ell = np.logaddexp(ell, -outlier_nats + np.where(d > ranges[j], ell, 0.0))
                msg = _sampled_message_numpy(ell, nb_logw[v, : nb_count[v]])
            else:
                msg = _sampled_message_numpy(ell, nb_logw[v, : nb_count[v]])
                msg = np.logaddexp(msg, -outlier_nats)
            _add_numpy(out[a], msg, gamma)
    return out


def sampled_mixture_numpy(
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
):
    """Twin of ``sampled_mixture_kernel``: each link's message as a [Q_u, Q_v] matrix."""
    from scipy.special import logsumexp

    n_agents, Q, _ = particles.shape
    out = np.zeros((n_agents, Q))
    for a in range(n_agents):
        for j in range(offsets[a], offsets[a + 1]):
            v = nb_node[j]
            pts = nb_points[v, : nb_count[v]]
            x = ways * np.linalg.norm(particles[a][:, None, :] - pts[None], axis=2)
            sl = slice(pk_off[j], pk_off[j + 1])
            var = 1.0 / pk_c[sl] + s2[j]
            comp = (
                pk_h[sl]
                - 0.5 * np.log1p(pk_c[sl] * s2[j])
                - (x[..., None] - pk_d[sl]) ** 2 / (2 * var)
            )
            allc = np.concatenate([np.full((*x.shape, 1), floor[j]), comp], axis=-1)
            ell = logsumexp(allc, axis=-1)
            _add_numpy(out[a], _sampled_message_numpy(ell, nb_logw[v, : nb_count[v]]), gamma)
    return out


def next_lambda_numpy(lw, delta, lam, ess_target, n_bisect=30):
    """Twin of ``next_lambda_kernel``: the adaptive tempering step by bisection on the ESS
    (normalized weights by logsumexp, all agents at once)."""
    from scipy.special import logsumexp

    def ess(step):
        x = lw + step[:, None] * delta
        x = np.where(np.isnan(x), -np.inf, x)
        lse = logsumexp(x, axis=1, keepdims=True)
        bad = ~np.isfinite(lse[:, 0])
        with np.errstate(invalid="ignore"):
            w = np.exp(x - lse)
        w[bad] = 1.0 / x.shape[1]
        return 1.0 / np.sum(w * w, axis=1)

    room = 1.0 - lam
    full = ess(room) >= ess_target
    lo = np.zeros_like(lam)
    hi = room.copy()
    for _ in range(n_bisect):
        mid = 0.5 * (lo + hi)
        ok = ess(mid) >= ess_target
        lo = np.where(ok, mid, lo)
        hi = np.where(ok, hi, mid)
    step = np.where(full, room, np.maximum(lo, 1e-6 * room))
    return np.where(lam >= 1.0, 1.0, np.minimum(lam + step, 1.0))


def _link_mixture_numpy(x, j, pk_off, pk_d, pk_h, pk_c, s2, floor):
    """The smoothed log-likelihood of link ``j`` at distances ``x`` (no tempering), by
    logsumexp over the floor and every component."""
    from scipy.special import logsumexp

    x = np.asarray(x, dtype=np.float64)
    sl = slice(pk_off[j], pk_off[j + 1])
    v = 1.0 / pk_c[sl] + s2[j]
    terms = (pk_h[sl] - 0.5 * np.log1p(pk_c[sl] * s2[j])) - 0.5 * (x[..., None] - pk_d[sl]) ** 2 / v
    allc = np.concatenate([np.full((*x.shape, 1), floor[j]), terms], axis=-1)
    return logsumexp(allc, axis=-1)


def mixture_grid_numpy(
    particles,
    offsets,
    nb_node,
    pk_off,
    pk_h,
    pk_c,
    s2,
    floor,
    ways,
    centers,
    resolution,
    max_points,
    margin,
):
    """Twin of ``mixture_grid_kernel``: per link ``(lo, inv_h, count)``, ``count = 0`` for no
    table."""
    n_links = pk_off.size - 1
    lo, inv_h = np.zeros(n_links), np.zeros(n_links)
    count = np.zeros(n_links, np.int64)
    for a in range(offsets.size - 1):
        for j in range(offsets[a], offsets[a + 1]):
            sl = slice(pk_off[j], pk_off[j + 1])
            base = pk_h[sl] - 0.5 * np.log1p(pk_c[sl] * s2[j])
            hp = 0.5 / (1.0 / pk_c[sl] + s2[j])
            kept = base >= floor[j] - 37.0
            if not kept.any():
                continue
            steep = np.max(np.sqrt(hp[kept] * np.maximum(base[kept] - floor[j], 1.0)))
            x = ways * np.linalg.norm(particles[a] - centers[nb_node[j]], axis=1)
            if x.size == 0:
                continue
            h = resolution / steep
            wide = margin * (x.max() - x.min()) + 2.0 * h
            x_lo = max(x.min() - wide, 0.0)
            m = int(np.ceil((x.max() + wide - x_lo) / h)) + 1
            if 4 <= m <= max_points:
                lo[j], inv_h[j], count[j] = x_lo, 1.0 / h, m
    return lo, inv_h, count


def mixture_table_numpy(pk_off, pk_d, pk_h, pk_c, s2, floor, lo, inv_h, count):
    """Twin of ``mixture_table_kernel``: the grids, concatenated in link order."""
    parts = [
        _link_mixture_numpy(
            lo[j] + np.arange(count[j]) / inv_h[j], j, pk_off, pk_d, pk_h, pk_c, s2, floor
        )
        for j in range(count.size)
        if count[j] > 0
    ]
    return np.concatenate(parts) if parts else np.zeros(0)


def mixture_tabulated_numpy(
    particles,
    agents,
    offsets,
    nb_node,
    pk_off,
    pk_d,
    pk_h,
    pk_c,
    s2,
    floor,
    ways,
    gamma,
    centers,
    lo,
    inv_h,
    count,
    table,
):
    """Twin of ``mixture_tabulated_kernel``: 4-point Lagrange interpolation inside each
    link's grid, the exact mixture outside."""
    t_off = np.concatenate([[0], np.cumsum(count)[:-1]])
    out = np.zeros(particles.shape[:2])
    for r, a in enumerate(agents):
        for j in range(offsets[a], offsets[a + 1]):
            x = ways * np.linalg.norm(particles[r] - centers[nb_node[j]], axis=1)
            val = _link_mixture_numpy(x, j, pk_off, pk_d, pk_h, pk_c, s2, floor)
            m = count[j]
            if m > 0:
                u = (x - lo[j]) * inv_h[j]
                inside = (u >= 1.0) & (u < m - 2.0)
                i = u[inside].astype(np.int64)
                f = u[inside] - i
                y = table[t_off[j] : t_off[j] + m]
                # Lagrange weights of the nodes i−1, i, i+1, i+2 at i + f
                w = np.stack(
                    [
                        -f * (f - 1) * (f - 2) / 6,
                        (f + 1) * (f - 1) * (f - 2) / 2,
                        -(f + 1) * f * (f - 2) / 2,
                        (f + 1) * f * (f - 1) / 6,
                    ]
                )
                nodes = np.stack([y[i - 1], y[i], y[i + 1], y[i + 2]])
                val[inside] = np.sum(w * nodes, axis=0)
            out[r] += gamma * val
    return out


def mh_propose_numpy(X, z, move_scale, min_std):
    """Twin of ``mh_propose_kernel``: ``X + max(move_scale·std_q X, min_std)·z`` per agent."""
    return X + np.maximum(X.std(axis=1, keepdims=True) * move_scale, min_std) * z


def mh_accept_numpy(X, lp, ll_old, ll_new, Xp, lpp, lop, lnp, lam, log_u):
    """Twin of ``mh_accept_kernel`` (returns new arrays and the number of accepted moves)."""
    g = lam[:, None]
    cur = lp + g * ll_new + (1.0 - g) * ll_old
    prop = lpp + g * lnp + (1.0 - g) * lop
    with np.errstate(invalid="ignore"):
        log_ratio = np.where(np.isfinite(prop), prop - cur, -np.inf)
    acc = log_u < log_ratio
    out = (
        np.where(acc[:, :, None], Xp, X),
        np.where(acc, lpp, lp),
        np.where(acc, lop, ll_old),
        np.where(acc, lnp, ll_new),
    )
    return out, int(acc.sum())
