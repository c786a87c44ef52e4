"""Numba kernels of the polygon outer-approximation (POA, POA-NBP Algorithms 1–4).

A convex polygon is an array ``v`` of shape ``(m, 2)`` holding its vertices counter-clockwise
(CCW); ``m = 0`` is the empty set, ``m = 1`` a point and ``m = 2`` a segment (the closed
"2-gon" ``v0 → v1 → v0``). A halfspace set is ``(A, c)`` with unit outward normals ``A`` of
shape ``(k, 2)`` and offsets ``c`` of shape ``(k,)``: a point ``x`` is inside when
``A x <= c``. Every length tolerance ``tol`` is absolute, in metres; the public functions pass
``1e-12`` times the coordinate scale.

The kernels take arrays and scalars only, do not validate and draw no random numbers (the
uniforms of the samplers are drawn by the caller from its ``numpy.random.Generator``). Each
kernel has a plain-NumPy reference twin, written independently (vectorized per step, no
shared helpers); the twins are test code (``tests/naive_static.py``) and
``tests/test_polygons.py`` compares each kernel with its twin.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi


# ---------------------------------------------------------------------------------------------
# Clean-up: repeated vertices and vertices on a straight run
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def clean_kernel(v, m, tol):
    """Remove repeated and straight-through vertices of the closed polygon ``v[:m]`` in place.

    A vertex is dropped when it repeats its successor (both coordinates within ``tol``) or when
    the polygon runs straight (or dents inward) through it: turn cross product
    ``|e1 × e2| <= tol·max(|e1|, |e2|)`` with ``e1·e2 >= 0``. A reversal (``e1·e2 < 0``), the
    end of a flat polygon, is kept, so a flat input collapses to its two extreme points.
    Returns the new vertex count.
    """
    changed = True
    while changed and m > 1:
        changed = False
        k = 0
        while k < m and m > 1:
            kn = k + 1 if k + 1 < m else 0
            if abs(v[kn, 0] - v[k, 0]) <= tol and abs(v[kn, 1] - v[k, 1]) <= tol:
                for t in range(kn, m - 1):
                    v[t, 0] = v[t + 1, 0]
                    v[t, 1] = v[t + 1, 1]
                m -= 1
                changed = True
            else:
                k += 1
        k = 0
        while k < m and m >= 3:
            kp = k - 1 if k > 0 else m - 1
            kn = k + 1 if k + 1 < m else 0
            e1x = v[k, 0] - v[kp, 0]
            e1y = v[k, 1] - v[kp, 1]
            e2x = v[kn, 0] - v[k, 0]
            e2y = v[kn, 1] - v[k, 1]
            cr = e1x * e2y - e1y * e2x
            dt = e1x * e2x + e1y * e2y
            ln = max(math.hypot(e1x, e1y), math.hypot(e2x, e2y))
            if dt >= 0.0 and cr <= tol * ln:
                for t in range(k, m - 1):
                    v[t, 0] = v[t + 1, 0]
                    v[t, 1] = v[t + 1, 1]
                m -= 1
                changed = True
            else:
                k += 1
    return m


# ---------------------------------------------------------------------------------------------
# Sutherland–Hodgman clipping (POA-NBP Algorithm 3)
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _clip_one(src, n, a0, a1, c, tol, dst):
    """Clip ``src[:n]`` by ``a0·x + a1·y <= c`` into ``dst``; return the output count.

    Inside means ``d = a·x − c <= tol`` (points within ``tol`` outside are kept, so rounding
    never cuts the set). A crossing is inserted where an edge passes from ``d < 0`` to
    ``d > tol`` or back; ``dst`` must hold ``2n`` rows.
    """
    m = 0
    for k in range(n):
        kn = k + 1 if k + 1 < n else 0
        dk = a0 * src[k, 0] + a1 * src[k, 1] - c
        dn = a0 * src[kn, 0] + a1 * src[kn, 1] - c
        ink = dk <= tol
        inn = dn <= tol
        if ink:
            dst[m, 0] = src[k, 0]
            dst[m, 1] = src[k, 1]
            m += 1
            if not inn and dk < 0.0:
                t = dk / (dk - dn)
                dst[m, 0] = src[k, 0] + t * (src[kn, 0] - src[k, 0])
                dst[m, 1] = src[k, 1] + t * (src[kn, 1] - src[k, 1])
                m += 1
        elif inn and dn < 0.0:
            t = dk / (dk - dn)
            dst[m, 0] = src[k, 0] + t * (src[kn, 0] - src[k, 0])
            dst[m, 1] = src[k, 1] + t * (src[kn, 1] - src[k, 1])
            m += 1
    return m


@njit(cache=True)
def clip_groups_kernel(verts, A, c, group_off, tol, allow_drop):
    """Intersect the polygon ``verts`` with groups of halfspaces (POA-NBP Algorithm 3).

    Group ``g`` is the halfspace set ``A[group_off[g]:group_off[g+1]]`` (one clipping polygon,
    e.g. an anchor polygon or a scaled neighbour polygon). Groups are applied in order by
    Sutherland–Hodgman. With ``allow_drop``, a group whose intersection with the current polygon
    is empty is not applied (the polygon before it is kept) and ``dropped[g]`` is set; without
    it an empty intersection ends the loop. Returns ``(vertices (m, 2), dropped (n_groups,)
    bool)``; the result is cleaned with :func:`clean_kernel` after each group.
    """
    out, dropped, _ = clip_groups_count_kernel(verts, A, c, group_off, tol, allow_drop)
    return out, dropped


@njit(cache=True)
def clip_groups_count_kernel(verts, A, c, group_off, tol, allow_drop):
    """:func:`clip_groups_kernel` that also counts its vertex–halfspace tests.

    Returns ``(vertices, dropped, n_tests)``; ``n_tests`` is the number of vertices of the input
    list summed over every clipping halfspace applied (Sutherland–Hodgman's inner loop visits
    each vertex of the current list once per halfspace: the ``O(N_E²)`` per pair of polygons of
    POA-NBP §V-C2).
    """
    n_tests = 0
    n = verts.shape[0]
    n_groups = group_off.size - 1
    dropped = np.zeros(n_groups, dtype=np.bool_)
    cap = 2 * (n + A.shape[0]) + 8
    cur = np.empty((cap, 2))
    tmp = np.empty((cap, 2))
    keep = np.empty((cap, 2))
    for k in range(n):
        cur[k, 0] = verts[k, 0]
        cur[k, 1] = verts[k, 1]
    m = n
    for g in range(n_groups):
        if m == 0:
            break
        if keep.shape[0] < m:
            keep = np.empty((2 * m + 8, 2))
        for k in range(m):
            keep[k, 0] = cur[k, 0]
            keep[k, 1] = cur[k, 1]
        m_keep = m
        for h in range(group_off[g], group_off[g + 1]):
            if tmp.shape[0] < 2 * m + 2:
                tmp = np.empty((2 * m + 8, 2))
            n_tests += m
            m = _clip_one(cur, m, A[h, 0], A[h, 1], c[h], tol, tmp)
            cur, tmp = tmp, cur
            if m == 0:
                break
        if m == 0 and allow_drop:
            dropped[g] = True
            if cur.shape[0] < m_keep:
                cur = np.empty((m_keep + 8, 2))
            for k in range(m_keep):
                cur[k, 0] = keep[k, 0]
                cur[k, 1] = keep[k, 1]
            m = m_keep
        else:
            m = clean_kernel(cur, m, tol)
    return cur[:m].copy(), dropped, n_tests


# ---------------------------------------------------------------------------------------------
# Support halfspaces and polygon scaling (POA-NBP Algorithm 4, eqs. (18)–(20))
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def support_halfspaces_kernel(v, max_turn):
    """Support halfspaces ``(A, c, corner)`` of the convex polygon ``v`` in CCW normal order.

    Edge ``m`` (``v_m → v_{m+1}``) gives the halfspace of POA-NBP eq. (18),
    ``a_m ⊥ (v_{m+1} − v_m)`` outward and ``c_m = a_m·v_m``. Where the normal turns by more
    than ``max_turn`` between two edges, the corner is split into ``p = ceil(turn/max_turn)``
    equal turns by ``p − 1`` extra support lines through the vertex (bevels). A point
    (``m = 1``) gets ``max(3, ceil(2π/max_turn))`` equally spaced normals; a segment's two ends
    are corners of turn π. ``corner[k]`` is the vertex where line ``k`` meets line ``k + 1``
    (cyclic).
    """
    n = v.shape[0]
    if n == 0:
        return np.empty((0, 2)), np.empty(0), np.empty((0, 2))
    if n == 1:
        k_pts = max(3, math.ceil(TWO_PI / max_turn - 1e-12))
        A = np.empty((k_pts, 2))
        c = np.empty(k_pts)
        corner = np.empty((k_pts, 2))
        for s in range(k_pts):
            ang = TWO_PI * s / k_pts
            A[s, 0] = math.cos(ang)
            A[s, 1] = math.sin(ang)
            c[s] = A[s, 0] * v[0, 0] + A[s, 1] * v[0, 1]
            corner[s, 0] = v[0, 0]
            corner[s, 1] = v[0, 1]
        return A, c, corner
    nx = np.empty(n)
    ny = np.empty(n)
    for m in range(n):
        mn = m + 1 if m + 1 < n else 0
        dx = v[mn, 0] - v[m, 0]
        dy = v[mn, 1] - v[m, 1]
        ln = math.hypot(dx, dy)
        if ln > 0.0:
            nx[m] = dy / ln
            ny[m] = -dx / ln
        else:
            nx[m] = 1.0
            ny[m] = 0.0
    extra = np.zeros(n, dtype=np.int64)
    turns = np.empty(n)
    total = n
    for m in range(n):
        mn = m + 1 if m + 1 < n else 0
        cr = nx[m] * ny[mn] - ny[m] * nx[mn]
        dt = nx[m] * nx[mn] + ny[m] * ny[mn]
        th = math.atan2(cr, dt)
        if th < -0.5 * math.pi:
            th += TWO_PI
        if th < 0.0:
            th = 0.0
        turns[m] = th
        p = math.ceil(th / max_turn - 1e-12)
        if p > 1:
            extra[m] = p - 1
            total += p - 1
    A = np.empty((total, 2))
    c = np.empty(total)
    corner = np.empty((total, 2))
    k = 0
    for m in range(n):
        mn = m + 1 if m + 1 < n else 0
        A[k, 0] = nx[m]
        A[k, 1] = ny[m]
        c[k] = nx[m] * v[m, 0] + ny[m] * v[m, 1]
        corner[k, 0] = v[mn, 0]
        corner[k, 1] = v[mn, 1]
        k += 1
        p = extra[m] + 1
        base = math.atan2(ny[m], nx[m])
        for s in range(1, p):
            ang = base + turns[m] * s / p
            A[k, 0] = math.cos(ang)
            A[k, 1] = math.sin(ang)
            c[k] = A[k, 0] * v[mn, 0] + A[k, 1] * v[mn, 1]
            corner[k, 0] = v[mn, 0]
            corner[k, 1] = v[mn, 1]
            k += 1
    return A, c, corner


@njit(cache=True)
def scaled_vertices_kernel(A, corner, z, tol):
    """Vertices of ``{x : A x <= c + z}`` for support halfspaces from
    :func:`support_halfspaces_kernel` (POA-NBP Algorithm 4, step 6).

    Vertex ``m`` is where the shifted lines ``m − 1`` and ``m`` meet,
    ``corner_{m−1} + z·(a_{m−1} + a_m)/(1 + a_{m−1}·a_m)`` — the closed form of their
    intersection (POA-NBP eqs. (19)–(20)): it satisfies ``a·x = c + z`` for both lines and stays
    well conditioned when adjacent edges are almost parallel. Edge ``m`` (vertex ``m`` → ``m + 1``)
    therefore lies on line ``m``. The result is cleaned (``z = 0`` gives the input polygon).
    """
    k = A.shape[0]
    out = np.empty((k, 2))
    for m in range(k):
        mp = m - 1 if m > 0 else k - 1
        den = 1.0 + A[mp, 0] * A[m, 0] + A[mp, 1] * A[m, 1]
        out[m, 0] = corner[mp, 0] + z * (A[mp, 0] + A[m, 0]) / den
        out[m, 1] = corner[mp, 1] + z * (A[mp, 1] + A[m, 1]) / den
    m_out = clean_kernel(out, k, tol)
    return out[:m_out].copy()


# ---------------------------------------------------------------------------------------------
# Point tests and sampling (POA-NBP eqs. (21)–(22))
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def contains_kernel(A, c, points, tol):
    """``out[q] = all_k (A[k]·points[q] − c[k] <= tol)``."""
    n = points.shape[0]
    out = np.empty(n, dtype=np.bool_)
    for q in range(n):
        ok = True
        for k in range(A.shape[0]):
            if A[k, 0] * points[q, 0] + A[k, 1] * points[q, 1] - c[k] > tol:
                ok = False
                break
        out[q] = ok
    return out


@njit(cache=True)
def fan_sample_kernel(v, u):
    """Map uniforms ``u`` of shape ``(n, 3)`` to points uniform in the convex polygon ``v``.

    Triangle fan ``(v_0, v_k, v_{k+1})``: ``u[:, 0]`` picks a triangle with probability
    proportional to its area (inverse CDF), ``(u[:, 1], u[:, 2])`` is folded into the unit
    triangle by reflection (``s + t > 1 → (1 − s, 1 − t)``) and mapped affinely. A segment
    (``m = 2``) is sampled uniformly along its length, a point is repeated. Zero total area
    with ``m >= 3`` falls back to equal triangle weights (points stay on the flat set).
    """
    n = u.shape[0]
    m = v.shape[0]
    out = np.empty((n, 2))
    if m == 1:
        for q in range(n):
            out[q, 0] = v[0, 0]
            out[q, 1] = v[0, 1]
        return out
    if m == 2:
        for q in range(n):
            out[q, 0] = v[0, 0] + u[q, 1] * (v[1, 0] - v[0, 0])
            out[q, 1] = v[0, 1] + u[q, 1] * (v[1, 1] - v[0, 1])
        return out
    n_tri = m - 2
    cum = np.empty(n_tri)
    acc = 0.0
    for k in range(n_tri):
        e1x = v[k + 1, 0] - v[0, 0]
        e1y = v[k + 1, 1] - v[0, 1]
        e2x = v[k + 2, 0] - v[0, 0]
        e2y = v[k + 2, 1] - v[0, 1]
        acc += max(0.5 * (e1x * e2y - e1y * e2x), 0.0)
        cum[k] = acc
    if acc <= 0.0:
        for k in range(n_tri):
            cum[k] = k + 1.0
        acc = float(n_tri)
    for q in range(n):
        target = u[q, 0] * acc
        lo = 0
        hi = n_tri - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if cum[mid] <= target:
                lo = mid + 1
            else:
                hi = mid
        s = u[q, 1]
        t = u[q, 2]
        if s + t > 1.0:
            s = 1.0 - s
            t = 1.0 - t
        out[q, 0] = v[0, 0] + s * (v[lo + 1, 0] - v[0, 0]) + t * (v[lo + 2, 0] - v[0, 0])
        out[q, 1] = v[0, 1] + s * (v[lo + 1, 1] - v[0, 1]) + t * (v[lo + 2, 1] - v[0, 1])
    return out


# ---------------------------------------------------------------------------------------------
# Minimum-volume enclosing ellipse (Löwner–John), the ellipse baseline of POA-NBP Fig. 9
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _weighted_moments(u, X, Y):
    """Weighted mean ``(cx, cy)`` and second central moments ``(sxx, sxy, syy)`` of the
    points ``(X_i, Y_i)`` with weights ``u`` (summing to one)."""
    cx = 0.0
    cy = 0.0
    for i in range(X.size):
        cx += u[i] * X[i]
        cy += u[i] * Y[i]
    sxx = 0.0
    sxy = 0.0
    syy = 0.0
    for i in range(X.size):
        dx = X[i] - cx
        dy = Y[i] - cy
        sxx += u[i] * dx * dx
        sxy += u[i] * dx * dy
        syy += u[i] * dy * dy
    return cx, cy, sxx, sxy, syy


@njit(cache=True)
def mvee_kernel(P, eps, max_iter):
    """Minimum-area ellipse enclosing the points ``P`` (``(n, 2)``, not all collinear).

    Khachiyan's algorithm with Todd–Yıldırım away steps on the weights ``u`` (lifted points
    ``(p, 1)``, ``M_i = 1 + (p_i − c)ᵀ S⁻¹ (p_i − c)``, ``S = Σ u_i (p_i − c)(p_i − c)ᵀ``),
    stopped when ``max_i M_i <= 3(1 + eps)`` and ``min_{u_i>0} M_i >= 3(1 − eps)``. Returns
    ``(center (2,), Sigma (2, 2), n_iter)`` with ``E = {x : (x − c)ᵀ Σ⁻¹ (x − c) <= 1}``,
    ``Σ = 2S`` rescaled so that every point lies in ``E`` (the farthest on its boundary),
    whatever the stopping accuracy.
    """
    n = P.shape[0]
    ox = 0.0
    oy = 0.0
    for i in range(n):
        ox += P[i, 0]
        oy += P[i, 1]
    ox /= n
    oy /= n
    X = np.empty(n)
    Y = np.empty(n)
    for i in range(n):
        X[i] = P[i, 0] - ox
        Y[i] = P[i, 1] - oy
    u = np.full(n, 1.0 / n)
    M = np.empty(n)
    it = 0
    while it < max_iter:
        it += 1
        cx, cy, sxx, sxy, syy = _weighted_moments(u, X, Y)
        det = sxx * syy - sxy * sxy
        if det <= 0.0:
            break
        ixx = syy / det
        ixy = -sxy / det
        iyy = sxx / det
        jmax = 0
        jmin = -1
        for i in range(n):
            dx = X[i] - cx
            dy = Y[i] - cy
            M[i] = 1.0 + ixx * dx * dx + 2.0 * ixy * dx * dy + iyy * dy * dy
            if M[i] > M[jmax]:
                jmax = i
            if u[i] > 0.0 and (jmin < 0 or M[i] < M[jmin]):
                jmin = i
        e_plus = M[jmax] / 3.0 - 1.0
        e_minus = 1.0 - M[jmin] / 3.0
        if e_plus <= eps and e_minus <= eps:
            break
        if e_plus >= e_minus:
            beta = (M[jmax] - 3.0) / (3.0 * (M[jmax] - 1.0))
            for i in range(n):
                u[i] *= 1.0 - beta
            u[jmax] += beta
        else:
            den = 3.0 * (M[jmin] - 1.0)
            cap = u[jmin] / (1.0 - u[jmin]) if u[jmin] < 1.0 else 0.0
            beta = cap if den <= 0.0 else min((3.0 - M[jmin]) / den, cap)
            for i in range(n):
                u[i] *= 1.0 + beta
            u[jmin] -= beta
            if u[jmin] < 0.0:
                u[jmin] = 0.0
    cx, cy, sxx, sxy, syy = _weighted_moments(u, X, Y)
    sig = np.empty((2, 2))
    sig[0, 0] = 2.0 * sxx
    sig[0, 1] = 2.0 * sxy
    sig[1, 0] = 2.0 * sxy
    sig[1, 1] = 2.0 * syy
    det = sig[0, 0] * sig[1, 1] - sig[0, 1] * sig[0, 1]
    center = np.array([cx + ox, cy + oy])
    if det > 0.0:
        smax = 0.0
        for i in range(n):
            dx = X[i] - cx
            dy = Y[i] - cy
            q = (sig[1, 1] * dx * dx - 2.0 * sig[0, 1] * dx * dy + sig[0, 0] * dy * dy) / det
            smax = max(smax, q)
        for a in range(2):
            for b in range(2):
                sig[a, b] *= smax
    return center, sig, it
