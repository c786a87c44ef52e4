"""Numba kernels of the sparse truth-free start (:mod:`phyloc.localization.sparse_start`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _point_cost(points, p, nbr, delta, w, c, one_sided, bound):
    """``Σ_j w_j ρ(δ_j − ‖x_p − x_j‖)`` summed in neighbour order, stopped as soon as the
    partial sum reaches ``bound`` (every term is >= 0, so the total can only be larger)."""
    dim = points.shape[1]
    total = 0.0
    for j in range(nbr.shape[0]):
        s = 0.0
        for k in range(dim):
            t = points[p, k] - nbr[j, k]
            s += t * t
        r = delta[j] - math.sqrt(s)
        z = (r / c) ** 2
        if one_sided and r <= 0:
            total += w[j] * z
        else:
            total += w[j] * math.log1p(z)
        if total >= bound:
            break
    return total


@njit(cache=True)
def point_cost_kernel(points, nbr, delta, w, c, one_sided):
    """``Σ_j w_j ρ(δ_j − ‖x − x_j‖)`` at every point ``x`` of ``points [m, dim]`` for the
    neighbours ``nbr [k, dim]``; ``ρ`` the Cauchy cost at scale ``c`` (one-sided: ``(r/c)²``
    for ``r <= 0``)."""
    m = points.shape[0]
    out = np.zeros(m)
    for p in range(m):
        out[p] = _point_cost(points, p, nbr, delta, w, c, one_sided, np.inf)
    return out


@njit(cache=True)
def best_point_kernel(points, nbr, delta, w, c, one_sided):
    """``(p, cost)`` of the first point of lowest cost (:func:`point_cost_kernel`'s
    ``argmin`` and ``min``, the same bits, for finite costs): a point's sum stops once it
    reaches the best cost so far, since its non-negative terms cannot bring it back below
    (weights ``w > 0``)."""
    best, best_cost = 0, np.inf
    for p in range(points.shape[0]):
        total = _point_cost(points, p, nbr, delta, w, c, one_sided, best_cost)
        if total < best_cost:
            best, best_cost = p, total
    return best, best_cost


@njit(cache=True)
def guttman_rhs_kernel(X, i, j, w, delta):
    """The Guttman transform's right-hand side ``B(X) X`` over the edges ``(i, j)`` and the raw
    stress ``Σ_e w_e (‖x_i − x_j‖ − δ_e)²`` at ``X``: per edge ``c = w δ / d`` (0 when the
    nodes coincide), ``(BX)_i += c (x_i − x_j)``, ``(BX)_j −= c (x_i − x_j)``."""
    n, dim = X.shape
    BX = np.zeros((n, dim))
    stress = 0.0
    for e in range(i.size):
        a, b = i[e], j[e]
        s = 0.0
        for k in range(dim):
            t = X[a, k] - X[b, k]
            s += t * t
        d = math.sqrt(s)
        stress += w[e] * (d - delta[e]) ** 2
        if d > 0:
            c = w[e] * delta[e] / d
            for k in range(dim):
                t = c * (X[a, k] - X[b, k])
                BX[a, k] += t
                BX[b, k] -= t
    return BX, stress
