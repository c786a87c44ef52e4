"""The truth-free start of range-limited networks, in the links' own cost.

:func:`~phyloc.localization.initialization.coarse_positions` builds ``n × n`` range and weight
matrices, completes them by shortest paths and runs SMACOF on them: right for the paper's
fully meshed networks of 3–30 agents, quadratic in memory and per iteration beyond. A network
of a thousand agents that each hear 20–30 neighbours has ~25 000 measured pairs, not 500 000:
everything here lives on the measured pairs (the *edges*), so the start costs what the links
cost.

1. :func:`pair_graph` — the measured pairs: one range per unordered pair (the mean, or the
   shortest of its directions: NLOS biases are positive), its weight, the anchors' pairs.
2. :func:`landmark_mds` — per connected component, classical MDS of a few *landmarks*
   (farthest-point sampled on shortest paths) and every other node placed from its shortest
   paths to them (landmark MDS, de Silva and Tenenbaum 2004): ``O(k · n_edges · log n)`` for
   ``k`` landmarks instead of the all-pairs completion.
3. :func:`sparse_smacof` — SMACOF with the Guttman transform solved on the weighted graph
   Laplacian of the edges (a sparse LU factorization per weight set, each iteration
   ``O(n_edges)`` plus two triangular solves); anchors held fixed.
4. :func:`sparse_coarse_positions` — the robust pipeline of the dense start on the edges:
   Cauchy-reweighted rounds per scale (one-sided if asked, then polished symmetrically),
   the lowest cost at the finest scale winning, and :func:`relocate_local` moving a node
   left in a wrong basin to the best point of its own cost — searched around its neighbours,
   not over the whole network.

Undetermined agents. A rule the reports follow (:func:`undetermined_nodes`): an agent is
*undetermined* when it is not in the largest connected component of the measured pairs
(components other than the largest, or without ``dim + 1`` anchors when there are anchors,
have no common frame with it), or when it has fewer than ``dim + 1`` measured neighbours (in
the plane, two ranges leave a reflection; one, a circle) and its component has other nodes
to be reflected against (a fully measured triangle is one shape). Their start is still a position —
their component's own solution, centred — but no method can be expected to place them.

References
----------
V. de Silva and J. B. Tenenbaum, "Sparse multidimensional scaling using landmark points,"
Technical report, Stanford University, 2004 (landmark MDS).
I. Borg and P. J. F. Groenen, *Modern Multidimensional Scaling: Theory and Applications*,
2nd ed., Springer, 2005 (SMACOF, the Guttman transform).
E. R. Gansner, Y. Koren and S. North, "Graph drawing by stress majorization," Graph Drawing
2004, LNCS 3383, pp. 239–250 (stress majorization over a graph's edges).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import splu

from phyloc.localization._start_kernels import (
    best_point_kernel,
    guttman_rhs_kernel,
    point_cost_kernel,
)


@dataclass(frozen=True)
class PairGraph:
    """Measured pairs of a network: edge ``e`` joins nodes ``i[e] < j[e]`` with range
    ``delta[e]`` [m] and weight ``w[e] > 0``."""

    n: int
    i: np.ndarray
    j: np.ndarray
    delta: np.ndarray
    w: np.ndarray

    @property
    def n_edges(self) -> int:
        """Number of measured pairs."""
        return int(self.i.size)

    def with_weights(self, w: np.ndarray) -> PairGraph:
        """The same pairs with other weights."""
        return PairGraph(self.n, self.i, self.j, self.delta, np.asarray(w, dtype=np.float64))

    def degree(self) -> np.ndarray:
        """Measured neighbours per node, ``[n]`` int64."""
        return np.bincount(self.i, minlength=self.n) + np.bincount(self.j, minlength=self.n)

    def components(self) -> np.ndarray:
        """Connected-component label of every node, ``[n]`` int (isolated nodes alone)."""
        adj = sparse.coo_matrix((np.ones(self.n_edges), (self.i, self.j)), shape=(self.n,) * 2)
        return csgraph.connected_components(adj, directed=False)[1]


def _combine(lo, hi, r, n, combine):
    """One range per unordered pair ``(lo, hi)``: the mean or the smallest of its ranges."""
    key = lo * n + hi
    uniq, inv = np.unique(key, return_inverse=True)
    if combine == "min":
        val = np.full(uniq.size, np.inf)
        np.minimum.at(val, inv, r)
    else:
        val = np.bincount(inv, weights=r, minlength=uniq.size) / np.bincount(
            inv, minlength=uniq.size
        )
    return uniq // n, uniq % n, np.maximum(val, 0.0)


def pair_graph(lk, r, ok, n, combine, invalid_weight=0.0, anchors=None) -> PairGraph:
    """The measured pairs of validated link ranges (see
    :func:`~phyloc.localization.initialization.range_matrix`, whose checks the caller ran).

    ``ok`` flags the valid ranges (weight 1); with ``invalid_weight > 0`` a pair known only
    from invalid but finite ranges joins at that weight; ``anchors = (index, positions)``
    adds every anchor–anchor pair at its known distance (weight 1)."""
    i, j, d = _combine(
        np.minimum(lk[ok, 0], lk[ok, 1]), np.maximum(lk[ok, 0], lk[ok, 1]), r[ok], n, combine
    )
    w = np.ones(i.size)
    if invalid_weight > 0:
        weak = ~ok & np.isfinite(r)
        a, b = lk[weak, 0], lk[weak, 1]
        wi, wj, wd = _combine(np.minimum(a, b), np.maximum(a, b), r[weak], n, combine)
        new = ~np.isin(wi * n + wj, i * n + j)
        i, j, d = np.r_[i, wi[new]], np.r_[j, wj[new]], np.r_[d, wd[new]]
        w = np.r_[w, np.full(int(new.sum()), float(invalid_weight))]
    if anchors is not None:
        idx, A = anchors
        ai, aj = np.triu_indices(idx.size, 1)
        key = np.minimum(idx[ai], idx[aj]) * n + np.maximum(idx[ai], idx[aj])
        old = np.isin(i * n + j, key)
        i, j, d, w = i[~old], j[~old], d[~old], w[~old]
        da = np.linalg.norm(A[ai] - A[aj], axis=-1)
        i = np.r_[i, np.minimum(idx[ai], idx[aj])]
        j = np.r_[j, np.maximum(idx[ai], idx[aj])]
        d, w = np.r_[d, da], np.r_[w, np.ones(da.size)]
    order = np.lexsort((j, i))
    return PairGraph(n, i[order].astype(np.int64), j[order].astype(np.int64), d[order], w[order])


# -- landmark MDS -------------------------------------------------------------------------------
def _classical(sq: np.ndarray, dim: int):
    """Top ``dim`` eigenpairs of the double-centred squared distances (positive part)."""
    B = -0.5 * (sq - sq.mean(axis=0)[None, :] - sq.mean(axis=1)[:, None] + sq.mean())
    lam, U = np.linalg.eigh(0.5 * (B + B.T))
    order = np.argsort(lam)[::-1][:dim]
    lam, U = lam[order], U[:, order]
    lam = np.where(lam > 1e-12 * max(float(lam[0]), 0.0), lam, 0.0)
    return lam, U


def landmark_mds(g: PairGraph, dim: int, n_landmarks: int = 20) -> np.ndarray:
    """A start configuration ``[n, dim]`` from shortest paths to a few landmarks.

    Per connected component of ``g`` (edges weighted by their ranges): ``k = min(size,
    n_landmarks)`` landmarks by farthest-point sampling of the shortest-path distance (first:
    the component's lowest node), classical MDS of the landmarks' ``k × k`` path distances,
    and every node placed by the landmark triangulation ``x = ½ L^# (μ − δ²)`` (``δ²`` its
    squared path distances to the landmarks, ``μ`` their column means, ``L^#`` the
    pseudo-inverse of the landmark embedding). Each component is centred at the origin; an
    isolated node sits there. Cost ``O(k · n_edges log n)``, memory ``O(k · n)``.
    """
    X = np.zeros((g.n, dim))
    graph = sparse.csr_matrix(
        (np.r_[g.delta, g.delta] + 1e-9, (np.r_[g.i, g.j], np.r_[g.j, g.i])), shape=(g.n,) * 2
    )
    labels = g.components()
    for c in np.unique(labels):
        nodes = np.flatnonzero(labels == c)
        if nodes.size < 2:
            continue
        sub = graph[nodes][:, nodes]
        k = min(nodes.size, int(n_landmarks))
        marks = [0]
        paths = [csgraph.dijkstra(sub, indices=0)]
        nearest = paths[0].copy()
        while len(marks) < k:
            nxt = int(np.argmax(np.where(np.isfinite(nearest), nearest, -1.0)))
            if nearest[nxt] <= 0:
                break
            marks.append(nxt)
            paths.append(csgraph.dijkstra(sub, indices=nxt))
            nearest = np.minimum(nearest, paths[-1])
        P2 = np.stack(paths) ** 2  # [k, size]
        lam, U = _classical(P2[:, marks], dim)
        keep = lam > 0
        Y = np.zeros((nodes.size, dim))
        if keep.any():
            pinv = U[:, keep] / np.sqrt(lam[keep])  # [k, r]
            mu = P2[:, marks].mean(axis=1)
            Y[:, keep] = 0.5 * ((mu[:, None] - P2).T @ pinv)
        X[nodes] = Y - Y.mean(axis=0)
    return X


# -- SMACOF over the edges ----------------------------------------------------------------------
def edge_lengths(g: PairGraph, X: np.ndarray) -> np.ndarray:
    """``‖x_i − x_j‖`` of every edge."""
    diff = X[g.i] - X[g.j]
    return np.sqrt(np.einsum("ek,ek->e", diff, diff))


def edge_stress(g: PairGraph, X: np.ndarray) -> float:
    """Raw stress ``Σ_e w_e (‖x_i − x_j‖ − δ_e)²`` [m²] (the dense ``raw_stress`` over the
    measured pairs)."""
    return float(np.sum(g.w * (edge_lengths(g, X) - g.delta) ** 2))


def _guttman_system(g: PairGraph, fixed: np.ndarray):
    """The Guttman system of the free nodes: ``A = V_ff + ε I`` (CSC) and ``V_fa`` (CSR; ``None``
    without fixed nodes), ``V`` the weighted Laplacian of the edges and ``ε`` ``1e-10`` of its
    mean degree (a ridge that centres a component without anchors and keeps a free node with
    no path to an anchor solvable).

    Built in the arrays' final order (``i < j`` unique and ``w > 0`` per :class:`PairGraph`):
    the same index and data arrays as assembling ``V`` with ``scipy.sparse`` and slicing it,
    so the LU factorization and its solves are the same bits, at a quarter to a half of the
    assembly's cost for the tens of nodes of the paper's networks (where the assembly took
    two thirds of each fit).
    """
    n = g.n
    diag = np.bincount(g.i, weights=g.w, minlength=n) + np.bincount(g.j, weights=g.w, minlength=n)
    ridge = 1.0e-10 * max(diag.mean(), 1e-30)
    free = ~fixed
    pos = np.cumsum(free) - 1  # a free node's row in the free system
    nf = int(free.sum())
    both = free[g.i] & free[g.j]
    fi, fj, fw = pos[g.i[both]], pos[g.j[both]], g.w[both]
    rows = np.r_[fi, fj, np.arange(nf)]
    cols = np.r_[fj, fi, np.arange(nf)]
    data = np.r_[-fw, -fw, diag[free] + ridge]
    order = np.lexsort((rows, cols))
    A = sparse.csc_matrix(
        (data[order], rows[order], np.searchsorted(cols[order], np.arange(nf + 1))),
        shape=(nf, nf),
    )
    if not fixed.any():
        return A, None
    held_pos = np.cumsum(fixed) - 1
    out, into = free[g.i] & fixed[g.j], fixed[g.i] & free[g.j]  # edges free–held, held–free
    cross_f = np.r_[g.i[out], g.j[into]]
    cross_h = np.r_[g.j[out], g.i[into]]
    cross_w = np.r_[g.w[out], g.w[into]]
    r, c = pos[cross_f], held_pos[cross_h]
    order = np.lexsort((c, r))
    Vfa = sparse.csr_matrix(
        (-cross_w[order], c[order], np.searchsorted(r[order], np.arange(nf + 1))),
        shape=(nf, int(fixed.sum())),
    )
    return A, Vfa


def sparse_smacof(g: PairGraph, X0, *, n_iter=300, tol=1e-9, fixed=None):
    """Weighted SMACOF on the edges of ``g`` from ``X0``; returns ``(X, stress)``.

    The Guttman transform ``V X⁺ = B(X) X`` with ``V`` the weighted Laplacian of the edges and
    ``B(X) X`` summed edge by edge (``c_e = w_e δ_e / d_e``, 0 for coincident nodes). Free
    nodes are solved for with the ``fixed`` ones (anchors) held; without fixed nodes ``V`` gets
    a ridge of ``1e-10`` of its mean degree, which centres every component and leaves the
    shape untouched to that order. One sparse LU factorization serves every iteration. Stops
    when an iteration lowers the stress by less than ``tol`` of it.
    """
    X = np.array(X0, dtype=np.float64, copy=True)
    n = X.shape[0]
    fixed = np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool)
    free = np.flatnonzero(~fixed)
    if g.n_edges == 0 or free.size == 0:
        return X, edge_stress(g, X)
    A, Vfa = _guttman_system(g, fixed)
    lu = splu(A)
    BX, s = guttman_rhs_kernel(X, g.i, g.j, g.w, g.delta)
    for _ in range(int(n_iter)):
        Xn = X.copy()
        if fixed.any():
            Xn[free] = lu.solve(BX[free] - Vfa @ X[fixed])
        else:
            Xn = lu.solve(BX)
        BX, sn = guttman_rhs_kernel(Xn, g.i, g.j, g.w, g.delta)
        done = s - sn < tol * s
        X, s = Xn, sn
        if done:
            break
    return X, s


# -- robust fit ---------------------------------------------------------------------------------
def _robust_terms(r, c, one_sided):
    """Cauchy cost and IRLS weight of residuals ``r`` at scale ``c`` (one-sided: the plain
    quadratic for ``r <= 0``) — the terms of the dense start."""
    z = (r / c) ** 2
    cost, weight = np.log1p(z), 1.0 / (1.0 + z)
    if one_sided:
        short = r <= 0
        cost, weight = np.where(short, z, cost), np.where(short, 1.0, weight)
    return cost, weight


def robust_cost(g: PairGraph, X, c, one_sided=False) -> float:
    """``Σ_e w_e ρ(δ_e − ‖x_i − x_j‖)`` at scale ``c``."""
    return float(np.sum(g.w * _robust_terms(g.delta - edge_lengths(g, X), c, one_sided)[0]))


def _robust_fit(g, X, c, rounds, n_iter, tol, fixed, one_sided=False):
    gw = g
    s = 0.0
    for _ in range(rounds):
        gw = g.with_weights(g.w * _robust_terms(g.delta - edge_lengths(g, X), c, one_sided)[1])
        X, s = sparse_smacof(gw, X, n_iter=n_iter, tol=tol, fixed=fixed)
    return X, gw, s, robust_cost(g, X, c, one_sided)


def relocate_local(g, X, c, *, fixed=None, n_grid=41, min_gain=2.0, n_passes=2, one_sided=False):
    """Move nodes a robust fit left in a wrong basin (the rule of the dense start's
    :func:`~phyloc.localization.initialization.relocate_nodes`), searching each node's own
    neighbourhood: the box of its measured neighbours widened by its longest range (every
    point within range of all of them lies in it), coarse grid then a fine grid of two cells
    around the best point. ``O(n · n_grid² · degree)``. Returns ``(X, moved)``."""
    X = np.array(X, dtype=np.float64, copy=True)
    n, dim = X.shape
    keep = np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool)
    per_axis = n_grid if dim == 2 else int(np.ceil(n_grid ** (2.0 / 3.0)))
    u = np.r_[g.i, g.j]
    nbr = np.r_[g.j, g.i]
    order = np.argsort(u, kind="stable")
    u, nbr = u[order], nbr[order]
    dl, wl = np.r_[g.delta, g.delta][order], np.r_[g.w, g.w][order]
    start = np.searchsorted(u, np.arange(n + 1))

    def grid_of(lo, hi):
        axes = [np.linspace(a, b, per_axis) for a, b in zip(lo, hi, strict=True)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)

    def args_of(a):
        sl = slice(start[a], start[a + 1])
        return X[nbr[sl]], dl[sl], wl[sl], float(c), bool(one_sided)

    def cost_at(a, points):
        return point_cost_kernel(points, *args_of(a))

    def best_of(a, points):  # argmin and min of cost_at, without summing hopeless points
        return best_point_kernel(points, *args_of(a))

    moved = []
    for _ in range(n_passes):
        terms = g.w * _robust_terms(g.delta - edge_lengths(g, X), c, one_sided)[0]
        node_cost = np.bincount(g.i, weights=terms, minlength=n) + np.bincount(
            g.j, weights=terms, minlength=n
        )
        changed = False
        for a in np.argsort(-node_cost, kind="stable"):
            sl = slice(start[a], start[a + 1])
            if keep[a] or sl.stop - sl.start < dim + 1:
                continue
            if cost_at(a, X[a][None])[0] <= min_gain:  # ρ >= 0: no point gains more
                continue
            P = X[nbr[sl]]
            reach = float(dl[sl].max()) + c
            lo, hi = P.min(axis=0) - reach, P.max(axis=0) + reach
            grid = grid_of(lo, hi)
            cell = (hi - lo) / (per_axis - 1)
            x0 = grid[best_of(a, grid)[0]]
            fine = grid_of(x0 - 2 * cell, x0 + 2 * cell)
            best, cost = best_of(a, fine)
            if cost < cost_at(a, X[a][None])[0] - min_gain:
                X[a] = fine[best]
                moved.append(int(a))
                changed = True
        if not changed:
            break
    return X, np.asarray(moved, dtype=np.int64)


#: Cost difference below which two robust fits are the same fit (as in the dense start).
_COST_TIE = 1e-6


def _lower(cost, best) -> bool:
    return cost < best - _COST_TIE * (1.0 + best)


def _robust_solution(g, starts, c, rounds, n_iter, tol, fixed, one_sided):
    best = None
    for Xs in starts:
        fit = _robust_fit(g, Xs, c, rounds, n_iter, tol, fixed, one_sided)
        if best is None or _lower(fit[3], best[3]):
            best = fit
    X, moved = relocate_local(g, best[0], c, fixed=fixed, one_sided=one_sided)
    if moved.size:
        fit = _robust_fit(g, X, c, rounds, n_iter, tol, fixed, one_sided)
        if _lower(fit[3], best[3]):
            return fit[:3]
    return best[:3]


def undetermined_nodes(g: PairGraph, dim: int, is_anchor=None) -> np.ndarray:
    """The documented rule (module docstring): ``[n]`` bool, True for a node outside the
    component that fixes the frame — the largest component, or with anchors the component
    holding the most anchors — or with fewer than ``dim + 1`` measured neighbours in a
    component of more than ``dim + 1`` nodes (a node of a triangle has two neighbours, and the
    triangle is one shape). Anchors are never undetermined."""
    anchor = np.zeros(g.n, bool) if is_anchor is None else np.asarray(is_anchor, bool)
    measured = g.with_weights(g.w)
    # anchor-anchor pairs carry no measurement: leave them out of the degree and components
    real = ~(anchor[g.i] & anchor[g.j])
    m = PairGraph(g.n, measured.i[real], measured.j[real], measured.delta[real], measured.w[real])
    labels = m.components()
    if anchor.any():
        votes = np.bincount(labels[anchor], minlength=labels.max() + 1)
        main = int(np.argmax(votes))
        # anchors join the frame's component through the known anchor distances
        frame = np.isin(labels, np.unique(labels[anchor])) if votes.max() else labels == main
    else:
        frame = labels == np.argmax(np.bincount(labels))
    # a node with fewer than dim + 1 neighbours can flip (reflect across its neighbours) —
    # unless its component has no other node to flip against (a triangle is one shape)
    size = np.bincount(labels)[labels]
    out = ~frame | (m.degree() < np.minimum(dim + 1, size - 1))
    out[anchor] = False
    return out


def sparse_coarse_positions(
    g: PairGraph,
    dim: int,
    *,
    fixed=None,
    anchor_positions=None,
    rng=None,
    n_restarts=0,
    n_iter=300,
    tol=1e-9,
    scales=None,
    rounds=10,
    one_sided=False,
    n_landmarks=20,
):
    """The robust coarse solution on the edges (steps 2–4 of the module docstring).

    ``scales`` (descending) are the Cauchy scales of the dense start's ``robust_scale_m``;
    ``fixed`` with ``anchor_positions`` fixes the anchors. Returns ``(X, final graph, stress)``.
    """
    n = g.n
    X0 = landmark_mds(g, dim, n_landmarks)
    anchor = np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool)
    held = anchor if anchor.any() else None
    if held is not None:
        from phyloc.network.geometry import kabsch

        R, t = kabsch(X0[anchor], anchor_positions)
        X0 = X0 @ R.T + t
        X0[anchor] = anchor_positions
    X, s = sparse_smacof(g, X0, n_iter=n_iter, tol=tol, fixed=held)
    starts = [X]
    if n_restarts:
        extent = float(g.delta.max(initial=1.0))
        for _ in range(int(n_restarts)):
            Xr0 = rng.uniform(-extent, extent, size=(n, dim))
            if held is not None:
                Xr0[anchor] = anchor_positions
            Xr, sr = sparse_smacof(g, Xr0, n_iter=n_iter, tol=tol, fixed=held)
            starts.append(Xr)
            if _lower(sr, s):
                X, s = Xr, sr
    gw = g
    if scales:
        chosen = None
        for c in scales:
            X_c, g_c, s_c = _robust_solution(g, starts, c, rounds, n_iter, tol, held, one_sided)
            cost = robust_cost(g, X_c, scales[-1], one_sided)
            if chosen is None or _lower(cost, chosen[3]):
                chosen = (X_c, g_c, s_c, cost)
        X, gw, s = chosen[:3]
        if one_sided:
            X, gw, s = _robust_fit(g, X, scales[-1], rounds, n_iter, tol, held)[:3]
    return X, gw, s
