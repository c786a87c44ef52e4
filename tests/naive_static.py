"""Plain-NumPy reference twins of the static family's Numba kernels (test code only).

Twins of :mod:`phyloc.localization.static._nbp_kernels` (the message KDE of POA-NBP eq. (7)
evaluated at the proposal samples, POA-NBP eq. (8), and the LSCV bandwidth score) and of
:mod:`phyloc.localization.static._polygon_kernels` (POA-NBP Algorithms 2–4: clean-up,
Sutherland–Hodgman clipping, support halfspaces and scaling, point-in-polygon, triangle-fan
sampling of POA-NBP eq. (21), and the minimum-volume enclosing ellipse of the ellipse
baseline). They are written independently of the kernels (vectorized per step, no shared
helpers); ``tests/test_nbp.py`` and ``tests/test_polygons.py`` compare each kernel with its
twin, and ``benchmarks/bench_nbp.py`` times them (via ``benchmarks._reference.naive``).

References
----------
.. [1] A. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
   indoor localization," IEEE Transactions on Signal and Information Processing over
   Networks, 2019 ("POA-NBP").
"""

import math

import numpy as np
from scipy.special import logsumexp

TWO_PI = 2.0 * math.pi


def kde_logpdf_numpy(points, centers, log_weights, bandwidths):
    """Plain-NumPy twin of :func:`kde_logpdf_kernel` (returns ``[M, P]``)."""
    h = np.asarray(bandwidths, dtype=np.float64)
    d2 = ((points[None, :, None, :] - centers[:, None, :, :]) ** 2).sum(axis=-1)  # [M, P, K]
    e = log_weights[:, None, :] - d2 / (2.0 * h * h)[:, None, None]
    return logsumexp(e, axis=2) - np.log(2.0 * np.pi * h * h)[:, None]


def lscv_grid_numpy(samples, weights, h0, n_grid):
    """Plain-NumPy twin of :func:`lscv_grid_kernel` (direct evaluation, returns ``[n_grid]``)."""
    n = samples.shape[0]
    iu, ju = np.triu_indices(n, 1)
    d2 = ((samples[iu] - samples[ju]) ** 2).sum(axis=1)
    w = weights
    loo = np.where(w < 1.0, 1.0 / np.where(w < 1.0, 1.0 - w, 1.0), 0.0)
    ww = w[iu] * w[ju]
    out = np.empty(n_grid)
    for t in range(n_grid):
        h2 = h0 * h0 * 0.5**t
        int_f2 = (np.sum(w * w) + 2.0 * np.sum(ww * np.exp(-d2 / (4.0 * h2)))) / (4 * np.pi * h2)
        cv = np.sum(ww * (loo[iu] + loo[ju]) * np.exp(-d2 / (2.0 * h2))) / (2 * np.pi * h2)
        out[t] = int_f2 - 2.0 * cv
    return out


def clean_numpy(v, tol):
    """Plain-NumPy twin of :func:`clean_kernel` (returns a new array)."""
    v = [np.array(p, dtype=np.float64) for p in np.asarray(v, dtype=np.float64)]
    changed = True
    while changed and len(v) > 1:
        changed = False
        k = 0
        while k < len(v) and len(v) > 1:
            kn = (k + 1) % len(v)
            if np.all(np.abs(v[kn] - v[k]) <= tol):
                del v[kn]
                changed = True
            else:
                k += 1
        k = 0
        while k < len(v) and len(v) >= 3:
            e1 = v[k] - v[k - 1]
            e2 = v[(k + 1) % len(v)] - v[k]
            cr = e1[0] * e2[1] - e1[1] * e2[0]
            ln = max(np.linalg.norm(e1), np.linalg.norm(e2))
            if e1 @ e2 >= 0.0 and cr <= tol * ln:
                del v[k]
                changed = True
            else:
                k += 1
    return np.array(v, dtype=np.float64).reshape(-1, 2)


def clip_numpy(verts, A, c, tol):
    """Plain-NumPy twin of :func:`clip_groups_kernel` for one group (no dropping)."""
    v = np.asarray(verts, dtype=np.float64).reshape(-1, 2)
    for a, ch in zip(np.asarray(A), np.asarray(c), strict=True):
        if v.shape[0] == 0:
            break
        nxt = np.roll(v, -1, axis=0)
        d = v @ a - ch
        dn = np.roll(d, -1)
        inside = d <= tol
        inside_n = dn <= tol
        with np.errstate(divide="ignore", invalid="ignore"):
            t = d / (d - dn)
        cross = v + t[:, None] * (nxt - v)
        leave = inside & ~inside_n & (d < 0.0)
        enter = ~inside & inside_n & (dn < 0.0)
        rows = []
        for k in range(v.shape[0]):
            if inside[k]:
                rows.append(v[k])
            if leave[k] or enter[k]:
                rows.append(cross[k])
        v = np.array(rows, dtype=np.float64).reshape(-1, 2)
    return clean_numpy(v, tol)


def clip_groups_numpy(verts, A, c, group_off, tol, allow_drop):
    """Plain-NumPy twin of :func:`clip_groups_kernel`."""
    v = np.asarray(verts, dtype=np.float64).reshape(-1, 2)
    n_groups = len(group_off) - 1
    dropped = np.zeros(n_groups, dtype=bool)
    for g in range(n_groups):
        if v.shape[0] == 0:
            break
        sl = slice(group_off[g], group_off[g + 1])
        w = clip_numpy(v, A[sl], c[sl], tol)
        if w.shape[0] == 0 and allow_drop:
            dropped[g] = True
        else:
            v = w
    return v, dropped


def clip_groups_count_numpy(verts, A, c, group_off, tol, allow_drop):
    """Plain-NumPy twin of :func:`clip_groups_count_kernel`: ``(vertices, dropped, n_tests)``.

    ``n_tests`` counts, for every halfspace applied, the vertices of the list it is applied
    to (Sutherland–Hodgman visits each once); the list is cleaned after each group only.
    """
    v = np.asarray(verts, dtype=np.float64).reshape(-1, 2)
    n_groups = len(group_off) - 1
    dropped = np.zeros(n_groups, dtype=bool)
    n_tests = 0
    for g in range(n_groups):
        if v.shape[0] == 0:
            break
        w = v
        for h in range(group_off[g], group_off[g + 1]):
            n_tests += w.shape[0]
            d = w @ A[h] - c[h]
            dn = np.roll(d, -1)
            nxt = np.roll(w, -1, axis=0)
            rows = []
            for k in range(w.shape[0]):
                if d[k] <= tol:
                    rows.append(w[k])
                    if dn[k] > tol and d[k] < 0.0:
                        rows.append(w[k] + d[k] / (d[k] - dn[k]) * (nxt[k] - w[k]))
                elif dn[k] <= tol and dn[k] < 0.0:
                    rows.append(w[k] + d[k] / (d[k] - dn[k]) * (nxt[k] - w[k]))
            w = np.array(rows, dtype=np.float64).reshape(-1, 2)
            if w.shape[0] == 0:
                break
        if w.shape[0] == 0 and allow_drop:
            dropped[g] = True
        else:
            v = clean_numpy(w, tol)
    return v, dropped, n_tests


def support_halfspaces_numpy(v, max_turn):
    """Plain-NumPy twin of :func:`support_halfspaces_kernel`."""
    v = np.asarray(v, dtype=np.float64).reshape(-1, 2)
    n = v.shape[0]
    if n == 0:
        return np.empty((0, 2)), np.empty(0), np.empty((0, 2))
    if n == 1:
        k_pts = max(3, math.ceil(TWO_PI / max_turn - 1e-12))
        ang = TWO_PI * np.arange(k_pts) / k_pts
        A = np.column_stack([np.cos(ang), np.sin(ang)])
        return A, A @ v[0], np.repeat(v, k_pts, axis=0)
    d = np.roll(v, -1, axis=0) - v
    ln = np.hypot(d[:, 0], d[:, 1])
    safe = np.where(ln > 0.0, ln, 1.0)
    N = np.where((ln > 0.0)[:, None], np.column_stack([d[:, 1], -d[:, 0]]) / safe[:, None], 0.0)
    N[ln <= 0.0, 0] = 1.0
    Nn = np.roll(N, -1, axis=0)
    th = np.arctan2(N[:, 0] * Nn[:, 1] - N[:, 1] * Nn[:, 0], np.sum(N * Nn, axis=1))
    th = np.where(th < -0.5 * np.pi, th + TWO_PI, th)
    th = np.maximum(th, 0.0)
    rows_a, rows_c, rows_p = [], [], []
    for m in range(n):
        vn = v[(m + 1) % n]
        rows_a.append(N[m])
        rows_c.append(N[m] @ v[m])
        rows_p.append(vn)
        p = max(1, math.ceil(th[m] / max_turn - 1e-12))
        base = math.atan2(N[m, 1], N[m, 0])
        for s in range(1, p):
            a = np.array([math.cos(base + th[m] * s / p), math.sin(base + th[m] * s / p)])
            rows_a.append(a)
            rows_c.append(a @ vn)
            rows_p.append(vn)
    return np.array(rows_a), np.array(rows_c), np.array(rows_p)


def scaled_vertices_numpy(A, c, z, tol):
    """Plain-NumPy twin of :func:`scaled_vertices_kernel`, by solving the 2×2 line systems.

    Takes the offsets ``c`` instead of the corners: vertex ``m`` solves
    ``[a_{m−1}; a_m] x = [c_{m−1} + z; c_m + z]`` (ill conditioned for nearly parallel
    neighbours, which the kernel's closed form avoids).
    """
    A = np.asarray(A, dtype=np.float64)
    cz = np.asarray(c, dtype=np.float64) + z
    Ap = np.roll(A, 1, axis=0)
    cp = np.roll(cz, 1)
    M = np.stack([Ap, A], axis=1)
    out = np.linalg.solve(M, np.column_stack([cp, cz])[..., None])[..., 0]
    return clean_numpy(out, tol)


def contains_numpy(A, c, points, tol):
    """Plain-NumPy twin of :func:`contains_kernel`."""
    return np.all(np.asarray(points) @ np.asarray(A).T - np.asarray(c) <= tol, axis=1)


def fan_sample_numpy(v, u):
    """Plain-NumPy twin of :func:`fan_sample_kernel`."""
    v = np.asarray(v, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    m = v.shape[0]
    if m == 1:
        return np.repeat(v, u.shape[0], axis=0)
    if m == 2:
        return v[0] + u[:, 1:2] * (v[1] - v[0])
    e1 = v[1:-1] - v[0]
    e2 = v[2:] - v[0]
    areas = np.maximum(0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]), 0.0)
    if areas.sum() <= 0.0:
        areas = np.ones_like(areas)
    cum = np.cumsum(areas)
    tri = np.minimum(np.searchsorted(cum, u[:, 0] * cum[-1], side="right"), m - 3)
    s, t = u[:, 1].copy(), u[:, 2].copy()
    flip = s + t > 1.0
    s[flip], t[flip] = 1.0 - s[flip], 1.0 - t[flip]
    return v[0] + s[:, None] * e1[tri] + t[:, None] * e2[tri]


def mvee_numpy(P, eps, max_iter):
    """Plain-NumPy twin of :func:`mvee_kernel` (same iteration, vectorized)."""
    P = np.asarray(P, dtype=np.float64)
    off = P.mean(axis=0)
    Q = P - off
    n = Q.shape[0]
    u = np.full(n, 1.0 / n)
    it = 0
    while it < max_iter:
        it += 1
        c = u @ Q
        D = Q - c
        S = (u[:, None] * D).T @ D
        if np.linalg.det(S) <= 0.0:
            break
        M = 1.0 + np.einsum("ij,jk,ik->i", D, np.linalg.inv(S), D)
        jmax = int(np.argmax(M))
        sup = np.flatnonzero(u > 0.0)
        jmin = int(sup[np.argmin(M[sup])])
        e_plus, e_minus = M[jmax] / 3.0 - 1.0, 1.0 - M[jmin] / 3.0
        if e_plus <= eps and e_minus <= eps:
            break
        if e_plus >= e_minus:
            beta = (M[jmax] - 3.0) / (3.0 * (M[jmax] - 1.0))
            u *= 1.0 - beta
            u[jmax] += beta
        else:
            den = 3.0 * (M[jmin] - 1.0)
            cap = u[jmin] / (1.0 - u[jmin]) if u[jmin] < 1.0 else 0.0
            beta = cap if den <= 0.0 else min((3.0 - M[jmin]) / den, cap)
            u *= 1.0 + beta
            u[jmin] = max(u[jmin] - beta, 0.0)
    c = u @ Q
    D = Q - c
    sig = 2.0 * (u[:, None] * D).T @ D
    if np.linalg.det(sig) > 0.0:
        sig = sig * np.max(np.einsum("ij,jk,ik->i", D, np.linalg.inv(sig), D))
    return c + off, sig, it
