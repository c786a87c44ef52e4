"""Numba kernels of the direct family's link likelihoods and of its tempering step.

The likelihoods of DiPNet eqs. (25) (correlation table, ENV) and (18) (Gaussian ranges, ERV),
the marginal peak-mixture likelihood (its Laplace peaks, exact evaluation and tabulation) and
the adaptive tempering step of the safeguarded filter; the sample-based exchange has its own
kernels (:mod:`phyloc.localization.direct._sampled_kernels`).

Link likelihoods are summed per agent over its incoming links in CSR form: the links of agent
``a`` are ``j = offsets[a] … offsets[a+1]−1``, each with the neighbour node ``nb_node[j]``
whose published position is ``centers[nb_node[j]]``. Kernels run in parallel over agents and
write disjoint rows of ``out``. Each kernel is tested against a plain-NumPy twin in
``tests/naive_direct.py``.

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
from phyloc.localization._softplus import log1p_exp_neg_into
from phyloc.phy.correlation import lagrange_eval
from phyloc.ranging.numerics import correlate_derivs, newton_peak


@njit(cache=True, inline="always")
def _link_distances(particles, r, c, ways, xs):
    """``xs[q] = ways·‖particles[r, q] − c‖`` for every particle of row ``r``. The planar and
    spatial cases are written out so the loop over particles vectorizes (a loop over a
    run-time ``dim`` inside it does not)."""
    Q, dim = particles.shape[1], particles.shape[2]
    if dim == 2:
        c0, c1 = c[0], c[1]
        for q in range(Q):
            t0 = particles[r, q, 0] - c0
            t1 = particles[r, q, 1] - c1
            xs[q] = ways * np.sqrt(t0 * t0 + t1 * t1)
    elif dim == 3:
        c0, c1, c2 = c[0], c[1], c[2]
        for q in range(Q):
            t0 = particles[r, q, 0] - c0
            t1 = particles[r, q, 1] - c1
            t2 = particles[r, q, 2] - c2
            xs[q] = ways * np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    else:
        for q in range(Q):
            acc = 0.0
            for k in range(dim):
                t = particles[r, q, k] - c[k]
                acc += t * t
            xs[q] = ways * np.sqrt(acc)


@by_threads
@njit(cache=True, parallel=True)
def direct_loglik_kernel(
    particles, offsets, nb_node, nb_row, nb_scale, centers, values, inv_h, order, out
):
    """``out[a, q] = Σ_j nb_scale[j]·|f_{nb_row[j]}(‖x_{a,q} − c_{nb_node[j]}‖)|²``.

    The equivalent likelihood of DiPNet eq. (25) in log form, with
    ``nb_scale = γ/(σ̃²‖S‖²)`` (tempering γ, ENV σ̃² of DiPNet eq. (26)) and ``f`` interpolated from
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
                f = lagrange_eval(values, row, L, np.sqrt(acc) * inv_h, order)
                out[a, q] += s * (f.real * f.real + f.imag * f.imag)


@by_threads
@njit(cache=True, parallel=True)
def gauss_loglik_kernel(
    particles,
    agents,
    offsets,
    nb_node,
    ranges,
    inv_var,
    centers,
    out,
    outlier_nats=np.inf,
    gamma=1.0,
    one_sided=False,
):
    """``out[r, q] = Σ_j ℓ_j(‖x_{r,q} − c_{nb_node[j]}‖)`` over the links ``j`` of agent
    ``a = agents[r]`` (row ``r`` of ``particles`` and ``out`` is that agent; a subset of the
    agents may be evaluated), with ``ℓ_j(d) = −½ inv_var[j]·(d − r_j)²``.

    The Gaussian ranging model with the equivalent ranging variance (ERV) of DiPNet eq. (18):
    ``1/inv_var = (var_r + σ²_{v→uv})/γ`` (γ the tempering exponent). With a finite
    ``outlier_nats`` f, each link is a mixture with an outlier component,
    ``ℓ_j = γ·log(e^{−½(d − r_j)²/var} + e^{−f})``, so one link moves a log-weight by at most
    ``γ f`` (``inv_var`` is then divided by ``gamma`` to get ``1/var``; ``gamma = 0`` gives 0).
    With ``one_sided`` the outlier component covers only ranges longer than the distance
    (``d < r_j``, a positive NLOS bias): for ``d > r_j`` it is ``e^{−f − ½(d − r_j)²/var}``, so
    ``ℓ_j = γ·(−½(d − r_j)²/var + log(1 + e^{−f}))`` keeps the Gaussian's pull there.
    """
    n_rows, Q, _ = particles.shape
    robust = outlier_nats < np.inf
    short = np.log1p(np.exp(-outlier_nats))  # the mixture's log(1 + e^{−f}) for d > r
    for r in prange(n_rows):
        a = agents[r]
        xs = np.empty(Q)
        us = np.empty(Q)
        xg = np.empty(Q)
        gs = np.empty(Q)
        work = np.empty(Q)
        for q in range(Q):
            out[r, q] = 0.0
        if robust and gamma == 0.0:
            continue
        for j in range(offsets[a], offsets[a + 1]):
            c = centers[nb_node[j]]
            rj = ranges[j]
            w = 0.5 * inv_var[j]
            _link_distances(particles, r, c, 1.0, xs)
            if robust:
                w = w / gamma
                for q in range(Q):
                    e = xs[q] - rj
                    us[q] = w * e * e  # −log of the Gaussian part
                    xg[q] = abs(us[q] - outlier_nats)
                log1p_exp_neg_into(xg, gs, work)  # log(1 + e^{−|u − f|}), vectorized
                if one_sided:
                    for q in range(Q):
                        if xs[q] > rj:
                            out[r, q] -= gamma * (us[q] - short)
                        else:
                            out[r, q] -= gamma * (min(us[q], outlier_nats) - gs[q])
                else:
                    for q in range(Q):
                        out[r, q] -= gamma * (min(us[q], outlier_nats) - gs[q])
            else:
                for q in range(Q):
                    e = xs[q] - rj
                    out[r, q] -= w * e * e


@njit(cache=True)
def _tempered_ess(lw, delta, step):
    """ESS of the weights ``exp(lw_q + step·delta_q)``; ``Q`` when none is finite (uniform)."""
    Q = lw.size
    m = -np.inf
    for q in range(Q):
        x = lw[q] + step * delta[q]
        if x == x and x > m:  # NaN counts as −inf
            m = x
    if not m > -np.inf:
        return float(Q)
    s1 = 0.0
    s2 = 0.0
    for q in range(Q):
        x = lw[q] + step * delta[q]
        if x == x and x > -np.inf:
            e = np.exp(x - m)
            s1 += e
            s2 += e * e
    return s1 * s1 / s2


@by_threads
@njit(cache=True, parallel=True)
def next_lambda_kernel(lw, delta, lam, ess_target, n_bisect, out):
    """Adaptive tempering: per agent, the largest ``λ' ∈ (λ, 1]`` whose incremental weights
    ``exp((λ' − λ)·delta)`` keep the ESS of ``lw + (λ' − λ)·delta`` at least ``ess_target``.

    The whole remaining step when it qualifies; otherwise ``n_bisect`` bisections on
    ``[0, 1 − λ]`` and at least ``1e-6·(1 − λ)``; 1 for agents already at 1.
    """
    n = lw.shape[0]
    for a in prange(n):
        if lam[a] >= 1.0:
            out[a] = 1.0
            continue
        room = 1.0 - lam[a]
        if _tempered_ess(lw[a], delta[a], room) >= ess_target:
            step = room
        else:
            lo = 0.0
            hi = room
            for _ in range(n_bisect):
                mid = 0.5 * (lo + hi)
                if _tempered_ess(lw[a], delta[a], mid) >= ess_target:
                    lo = mid
                else:
                    hi = mid
            step = max(lo, 1e-6 * room)
        out[a] = min(lam[a] + step, 1.0)


# ---------------------------------------------------------------------------------------------
# Marginal (peak-mixture) equivalent likelihood
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _mixture_link_setup(j, pk_off, pk_h, pk_c, s2, floor, base, half_prec, reach2, keep):
    """Per link ``j``: the smoothed components ``base_i − half_prec_i·t²`` that can matter.

    A component below ``floor_j − 37`` nats everywhere changes ``e^{floor} + Σ`` by less than
    half an ulp and is left out; the others are kept with the squared distance ``reach2``
    beyond which they drop below that level. Returns the number kept (in ``keep``).
    """
    p0 = pk_off[j]
    fl = floor[j]
    n = 0
    for i in range(pk_off[j + 1] - p0):
        ci = pk_c[p0 + i]
        b = pk_h[p0 + i] - 0.5 * np.log1p(ci * s2[j])
        if b < fl - _NEGLIGIBLE_NATS:
            continue
        hp = 0.5 / (1.0 / ci + s2[j])
        base[n] = b
        half_prec[n] = hp
        reach2[n] = (b - fl + _NEGLIGIBLE_NATS) / hp
        keep[n] = p0 + i
        n += 1
    return n


@njit(cache=True)
def _mixture_eval(x, fl, n, keep, pk_d, base, half_prec, reach2):
    """``log(e^{fl} + Σ_i exp(base_i − half_prec_i (x − d_i)²))`` over the kept components,
    in one pass (running maximum); components beyond their reach add nothing."""
    best = fl
    tot = 1.0
    for i in range(n):
        t = x - pk_d[keep[i]]
        t2 = t * t
        if t2 < reach2[i]:
            e = base[i] - half_prec[i] * t2
            if e > best:
                tot = tot * np.exp(best - e) + 1.0
                best = e
            else:
                tot += np.exp(e - best)
    if tot == 1.0:
        return best
    return best + np.log(tot)


_NEGLIGIBLE_NATS = 37.0  # e^-37 < 2^-53: below half an ulp of a sum >= 1


@by_threads
@njit(cache=True, parallel=True)
def mixture_loglik_kernel(
    particles, offsets, nb_node, pk_off, pk_d, pk_h, pk_c, s2, floor, ways, gamma, centers, out
):
    """``out[a, q] = γ Σ_j log(e^{floor_j} + Σ_i w_ij N(ways·‖x − c_j‖; d_ij, 1/c_ij + s²_j))``.

    The one-path likelihood ``exp(ℓ(d))`` of each link is represented by the Laplace
    approximations of its peaks (distance ``d_i``, log height ``h_i``, curvature ``c_i`` of
    ``ℓ``) plus a floor, and convolved with the neighbour's projected uncertainty
    ``N(0, s²)`` along the distance axis (exact for each Gaussian component):
    ``log(e^{floor} + Σ_i exp(h_i − ½log(1 + c_i s²) − (x − d_i)²/(2(1/c_i + s²))))``.
    ``floor_j = 0`` is the exact floor (``ℓ >= 0``); a higher floor bounds the evidence a
    single link can contribute (robustness to NLOS peaks). Components more than 37 nats
    below the floor at ``x`` are skipped (they cannot change the sum in double precision),
    so a particle pays one exponential per peak within reach, not per peak of the link.
    """
    n_agents, Q, _ = particles.shape
    max_p = 1
    for j in range(pk_off.size - 1):
        max_p = max(max_p, pk_off[j + 1] - pk_off[j])
    for a in prange(n_agents):
        base = np.empty(max_p)
        half_prec = np.empty(max_p)
        reach2 = np.empty(max_p)
        keep = np.empty(max_p, np.int64)
        xs = np.empty(Q)
        for q in range(Q):
            out[a, q] = 0.0
        for j in range(offsets[a], offsets[a + 1]):
            c = centers[nb_node[j]]
            n = _mixture_link_setup(j, pk_off, pk_h, pk_c, s2, floor, base, half_prec, reach2, keep)
            fl = floor[j]
            _link_distances(particles, a, c, ways, xs)
            for q in range(Q):
                out[a, q] += gamma * _mixture_eval(
                    xs[q], fl, n, keep, pk_d, base, half_prec, reach2
                )


@by_threads
@njit(cache=True, parallel=True)
def mixture_grid_kernel(
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
    lo,
    inv_h,
    count,
):
    """Grid of each link's smoothed log-likelihood (see ``mixture_loglik_kernel``) along the
    distance: ``lo[j]``, spacing ``1/inv_h[j]``, ``count[j]`` points (0: no table).

    The grid covers the distances ``ways·‖x_{a,q} − c_j‖`` of the agent's particles, widened by
    ``margin`` of their spread and two cells each side. Its spacing resolves the steepest
    transition of the log-sum: ``h = resolution / max_i √(hp_i·max(base_i − floor_j, 1))``
    (a component's slope where it crosses the floor is ``2√(hp·(base − floor))``). A link
    that needs more than ``max_points`` gets no table (``count = 0``).
    """
    n_agents, Q, _ = particles.shape
    max_p = 1
    for j in range(pk_off.size - 1):
        max_p = max(max_p, pk_off[j + 1] - pk_off[j])
    for a in prange(n_agents):
        base = np.empty(max_p)
        half_prec = np.empty(max_p)
        reach2 = np.empty(max_p)
        keep = np.empty(max_p, np.int64)
        xs = np.empty(Q)
        for j in range(offsets[a], offsets[a + 1]):
            c = centers[nb_node[j]]
            n = _mixture_link_setup(j, pk_off, pk_h, pk_c, s2, floor, base, half_prec, reach2, keep)
            steep = 0.0
            for i in range(n):
                steep = max(steep, np.sqrt(half_prec[i] * max(base[i] - floor[j], 1.0)))
            x_lo = np.inf
            x_hi = -np.inf
            _link_distances(particles, a, c, ways, xs)
            for q in range(Q):
                x_lo = min(x_lo, xs[q])
                x_hi = max(x_hi, xs[q])
            count[j] = 0
            lo[j] = 0.0
            inv_h[j] = 0.0
            if not (x_hi >= x_lo) or n == 0:
                continue  # no particles, or only the floor (no table needed: constant)
            h = resolution / steep
            wide = margin * (x_hi - x_lo) + 2.0 * h
            x_lo = max(x_lo - wide, 0.0)
            x_hi = x_hi + wide
            m = int(np.ceil((x_hi - x_lo) / h)) + 1
            if m < 4 or m > max_points:
                continue
            lo[j] = x_lo
            inv_h[j] = 1.0 / h
            count[j] = m


@by_threads
@njit(cache=True, parallel=True)
def mixture_table_kernel(
    offsets, pk_off, pk_d, pk_h, pk_c, s2, floor, lo, inv_h, count, t_off, out
):
    """Fill the grids of ``mixture_grid_kernel`` as cubic pieces: ``out[t_off[j] + i, 0]`` is
    the smoothed log-likelihood ``y_i`` of link ``j`` at distance ``lo[j] + i/inv_h[j]``
    (tempering not applied), and ``out[t_off[j] + i, 0:4]`` for ``1 <= i <= count[j] − 3``
    the power-basis coefficients ``c_0 + c_1 f + c_2 f² + c_3 f³`` of the 4-point Lagrange
    cubic through ``y_{i−1} … y_{i+2}`` on the cell ``[i, i + 1)`` (``_cubic_cell``); the
    other rows hold ``y_i`` and zeros."""
    n_agents = offsets.size - 1
    max_p = 1
    for j in range(pk_off.size - 1):
        max_p = max(max_p, pk_off[j + 1] - pk_off[j])
    for a in prange(n_agents):
        base = np.empty(max_p)
        half_prec = np.empty(max_p)
        reach2 = np.empty(max_p)
        keep = np.empty(max_p, np.int64)
        for j in range(offsets[a], offsets[a + 1]):
            m = count[j]
            if m == 0:
                continue
            n = _mixture_link_setup(j, pk_off, pk_h, pk_c, s2, floor, base, half_prec, reach2, keep)
            h = 1.0 / inv_h[j]
            t0 = t_off[j]
            for i in range(m):
                x = lo[j] + i * h
                out[t0 + i, 0] = _mixture_eval(x, floor[j], n, keep, pk_d, base, half_prec, reach2)
                for k in range(1, 4):
                    out[t0 + i, k] = 0.0
            for i in range(1, m - 2):
                _cubic_cell(
                    out[t0 + i - 1, 0], out[t0 + i, 0], out[t0 + i + 1, 0], out[t0 + i + 2, 0],
                    out[t0 + i],
                )  # fmt: skip


@njit(cache=True)
def _cubic_cell(ym, y0, y1, y2, c):
    """Power-basis coefficients of the cubic through ``(−1, ym), (0, y0), (1, y1), (2, y2)``:
    ``p(f) = c[0] + c[1] f + c[2] f² + c[3] f³`` (the 4-point Lagrange interpolant of the cell
    ``[0, 1)``, evaluated by Horner's rule in 3 multiply-adds instead of 4 weights)."""
    c[0] = y0
    c[1] = -ym / 3.0 - 0.5 * y0 + y1 - y2 / 6.0
    c[2] = 0.5 * (ym + y1) - y0
    c[3] = (y2 - ym) / 6.0 + 0.5 * (y0 - y1)


@by_threads
@njit(cache=True, parallel=True)
def mixture_tabulated_kernel(
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
    t_off,
    table,
    out,
):
    """``mixture_loglik_kernel`` with each link's smoothed log-likelihood read from its grid
    (the cubic pieces of ``mixture_table_kernel``: 4-point Lagrange, exact for the parabola of
    a lone component) where the distance lies inside the grid, and evaluated exactly
    elsewhere (and on links without a grid).

    Row ``r`` of ``particles`` and ``out`` belongs to agent ``agents[r]`` (a subset of the
    agents may be evaluated). Per link, one pass computes every particle's distance and cell
    (indices clamped into the grid, so the pass has no branch and vectorizes), a second reads
    the cubic of each cell, and only particles outside the grid are then evaluated exactly.
    """
    n_rows, Q, _ = particles.shape
    max_p = 1
    for j in range(pk_off.size - 1):
        max_p = max(max_p, pk_off[j + 1] - pk_off[j])
    for r in prange(n_rows):
        a = agents[r]
        base = np.empty(max_p)
        half_prec = np.empty(max_p)
        reach2 = np.empty(max_p)
        keep = np.empty(max_p, np.int64)
        xs = np.empty(Q)
        cell = np.empty(Q, np.int64)
        frac = np.empty(Q)
        val = np.empty(Q)
        for q in range(Q):
            out[r, q] = 0.0
        for j in range(offsets[a], offsets[a + 1]):
            c = centers[nb_node[j]]
            n = _mixture_link_setup(j, pk_off, pk_h, pk_c, s2, floor, base, half_prec, reach2, keep)
            fl = floor[j]
            if n == 0:  # only the floor
                for q in range(Q):
                    out[r, q] += gamma * fl
                continue
            m = count[j]
            _link_distances(particles, r, c, ways, xs)
            if m == 0:  # no grid: exact everywhere
                for q in range(Q):
                    out[r, q] += gamma * _mixture_eval(
                        xs[q], fl, n, keep, pk_d, base, half_prec, reach2
                    )
                continue
            x0 = lo[j]
            ih = inv_h[j]
            top = m - 2.0  # inside: 1 <= u < m − 2, cell i = int(u) in 1 … m − 3
            t0 = t_off[j]
            n_out = 0
            for q in range(Q):
                u = (xs[q] - x0) * ih
                n_out += (u < 1.0) | (u >= top)
                uc = min(max(u, 1.0), top)
                i = min(int(uc), m - 3)
                cell[q] = t0 + i
                frac[q] = uc - i
            for q in range(Q):
                f = frac[q]
                i = cell[q]
                val[q] = table[i, 0] + f * (table[i, 1] + f * (table[i, 2] + f * table[i, 3]))
            if n_out > 0:
                for q in range(Q):
                    u = (xs[q] - x0) * ih
                    if not (u >= 1.0 and u < top):
                        val[q] = _mixture_eval(xs[q], fl, n, keep, pk_d, base, half_prec, reach2)
            for q in range(Q):
                out[r, q] += gamma * val[q]


@by_threads
@njit(cache=True, parallel=True)
def peak_laplace_kernel(spectrum, rows, n0, w, d0, spacing, n_iter, inv_scale, out_d, out_h, out_c):
    """Refine each peak of ``ℓ(d) = |F(d)|²·inv_scale`` from its grid maximum and return its
    position, height ``ℓ`` and curvature ``−ℓ''`` (exact spectral derivatives)."""
    for i in prange(d0.size):
        x = spectrum[rows[i]]
        d = newton_peak(x, n0, w, d0[i], spacing, n_iter)
        T0, T1, T2 = correlate_derivs(x, n0, w, d)
        F1r = w * T1.imag  # F' = −jw T1
        F1i = -w * T1.real
        F2r = -(w * w) * T2.real
        F2i = -(w * w) * T2.imag
        g = T0.real * T0.real + T0.imag * T0.imag
        g2 = 2.0 * (F1r * F1r + F1i * F1i + T0.real * F2r + T0.imag * F2i)
        out_d[i] = d
        out_h[i] = g * inv_scale[i]
        out_c[i] = max(-g2 * inv_scale[i], 1e-12)
