"""Initialization of the particle filters: a truth-free coarse solution and the priors it seeds.

DiPNet Algorithm 1 draws each agent's Q particles once from its *a priori* pdf, which the
paper does not state. Run from uninformative priors the filter collapses (issue 5), so phyloc
offers three initializations, each labelled as such wherever results are reported:

truth-free (default)
    :func:`coarse_positions` solves the network coarsely from estimated ranges alone — the
    range matrix (:func:`range_matrix`), classical MDS with shortest-path completion
    (:func:`classical_mds`) and weighted SMACOF (:func:`smacof`) — and fixes the frame with the
    anchors when there are any; :func:`gaussian_priors` then draws each agent's particles
    around its coarse position.
informed start
    :func:`informed_centers` perturbs given positions (typically the truth) by ``N(0, σ0²)``,
    σ0 = 10 m by default, and :func:`gaussian_priors` draws around them. **It uses the truth**:
    every output computed from it must say "informed start" (scenario tokens ``*_informed``).
uninformative gauge priors
    :func:`gauge_priors` / :func:`gauge_log_prior`: the anchor-free gauge of the paper's setting
    (agent 0 at the origin, agent 1 on the positive x-axis, agent 2 in the upper half-plane,
    the rest uniform) — kept to show the collapse, not to be used for results.

Shapes follow the package conventions: positions ``[n_nodes, dim]``, particles
``[n_agents, Q, dim]``, links ``[n_links, 2]`` with ``(u, v)`` meaning "u receives from v".
Distances in metres. Every random draw takes a ``numpy.random.Generator``.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
I. Borg and P. J. F. Groenen, *Modern Multidimensional Scaling: Theory and Applications*,
2nd ed., Springer, 2005 (classical MDS, SMACOF).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csgraph

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization import _kernels
from phyloc.network.geometry import kabsch

INFORMED_START_STD_M = 10.0
"""Default σ0 [m] of the informed start (:func:`informed_centers`)."""

FRAMES = ("anchors", "partial", "arbitrary")
"""Values of :attr:`CoarseSolution.frame`."""


# -- input checks -------------------------------------------------------------------------------
def _rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return rng


def _dim(dim) -> int:
    d = v.integer("dim", dim, minimum=1)
    if d not in (2, 3):
        raise ValidationError("dim", dim, "must be 2 or 3")
    return d


def _square(name: str, a, n: int | None = None) -> np.ndarray:
    try:
        arr = np.array(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError(name, "<array>", "must convert to float64") from None
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or (n is not None and arr.shape[0] != n):
        want = f"({n}, {n})" if n is not None else "square [n, n]"
        raise ValidationError(name, f"array of shape {arr.shape}", f"must be {want}")
    return arr


def _weights(W, n: int) -> np.ndarray:
    """Validated symmetric non-negative weights with a zero diagonal (``None``: all pairs)."""
    if W is None:
        w = np.ones((n, n))
    else:
        w = _square("W", W, n)
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValidationError("W", "negative or non-finite entry", "weights must be >= 0")
        if not np.array_equal(w, w.T):
            raise ValidationError("W", "asymmetric matrix", "weights must be symmetric")
    np.fill_diagonal(w, 0.0)
    return w


def _dissimilarities(D, w: np.ndarray) -> np.ndarray:
    """``D`` with its used entries (w > 0) checked (finite, >= 0, symmetric), others set to 0."""
    n = w.shape[0]
    d = _square("D", D, n)
    used = w > 0
    bad = used & ~(np.isfinite(d) & (d >= 0))
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValidationError(
            "D", f"{d[i, j]} at ({i}, {j})", "distances with weight > 0 must be finite and >= 0"
        )
    d = np.where(used, d, 0.0)
    asym = np.abs(d - d.T) > 1e-9 * max(1.0, float(d.max(initial=0.0)))
    if asym.any():
        i, j = np.argwhere(asym)[0]
        raise ValidationError(
            "D", f"D[{i},{j}] = {d[i, j]} but D[{j},{i}] = {d[j, i]}", "must be symmetric"
        )
    return 0.5 * (d + d.T)


def _components_message(graph_w: np.ndarray) -> str:
    n_comp, label = csgraph.connected_components(graph_w > 0, directed=False)
    isolated = np.flatnonzero(~(graph_w > 0).any(axis=1))
    parts = [f"{n_comp} connected components (sizes {np.bincount(label).tolist()[:10]})"]
    if isolated.size:
        parts.append(f"nodes without any valid range: {isolated[:10].tolist()}")
    return "; ".join(parts)


# -- range matrix -------------------------------------------------------------------------------
PAIR_COMBINE = ("mean", "min")
"""How :func:`range_matrix` combines the ranges of one node pair."""


def range_matrix(
    links, ranges, n_nodes, valid=None, *, combine: str = "mean", invalid_weight: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric range matrix of a network from directed link range estimates.

    Every valid measurement of the unordered pair ``{u, v}`` — ``(u, v)``, ``(v, u)`` or
    repeats — is averaged (``combine="mean"``) or the smallest is kept (``combine="min"``:
    NLOS biases are positive, so the shortest of a pair's ranges is the least biased); a pair
    without a valid measurement gets weight 0.

    Parameters
    ----------
    links : [n_links, 2] int
        Directed links ``(u, v)``, "u receives from v", ``0 <= u, v < n_nodes``, ``u != v``.
    ranges : [n_links] float64
        Range estimates [m]. NaN marks a missing estimate (treated as invalid); a valid range
        must be finite. Noisy estimates of short distances may be negative: the pair mean is
        clipped to 0 (after averaging, so ``−0.2`` and ``0.6`` give ``0.2``).
    n_nodes : int
        Number of nodes (>= 1).
    valid : [n_links] bool, optional
        Which estimates to use (e.g. the NLOS-rejected links are False). Default: all non-NaN.
    combine : {"mean", "min"}
        How a pair's valid ranges are combined.
    invalid_weight : float
        Weight in ``[0, 1)`` of a pair that has no valid range but a finite invalid one (its
        invalid ranges combined the same way); 0 (default) leaves such pairs out. A small
        weight lets a weak guess (e.g. the strongest peak of a link below the detection
        threshold) place otherwise disconnected nodes without bending the rest.

    Returns
    -------
    D : [n_nodes, n_nodes] float64
        Mean (or smallest) range of each pair [m], symmetric, 0 on the diagonal and where
        missing.
    W : [n_nodes, n_nodes] float64
        1 where the pair has at least one valid range, else 0 (diagonal 0).

    Examples
    --------
    >>> D, W = range_matrix([[0, 1], [1, 0], [1, 2]], [10.0, 12.0, np.nan], 3)
    >>> D[0, 1], D[1, 0], W[1, 2]
    (np.float64(11.0), np.float64(11.0), np.float64(0.0))
    """
    n = v.integer("n_nodes", n_nodes, minimum=1)
    try:
        lk = np.asarray(links)
        if lk.size == 0:
            lk = lk.reshape(0, 2)
        if not (np.issubdtype(lk.dtype, np.integer) or lk.size == 0):
            raise TypeError
        lk = lk.astype(np.int64)
    except (TypeError, ValueError):
        raise ValidationError("links", "<array>", "must be an integer array [n_links, 2]") from None
    if lk.ndim != 2 or lk.shape[1] != 2:
        raise ValidationError("links", f"array of shape {lk.shape}", "must be [n_links, 2]")
    if np.any(lk < 0) or np.any(lk >= n):
        raise ValidationError("links", "node index out of range", f"indices must be in [0, {n})")
    if np.any(lk[:, 0] == lk[:, 1]):
        raise ValidationError("links", "a self-link (u, u)", "links must join distinct nodes")
    r = np.asarray(ranges, dtype=np.float64)
    if r.shape != (lk.shape[0],):
        raise ValidationError("ranges", f"array of shape {r.shape}", f"must be ({lk.shape[0]},)")
    ok = ~np.isnan(r)
    if valid is not None:
        m = np.asarray(valid)
        if m.dtype != np.bool_ or m.shape != r.shape:
            raise ValidationError(
                "valid", f"{m.dtype} array of shape {m.shape}", f"must be bool of shape {r.shape}"
            )
        ok &= m
    bad = ok & ~np.isfinite(r)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValidationError(
            "ranges", f"{r[k]} at link {k}", "a valid range must be finite (NaN: missing)"
        )
    if combine not in PAIR_COMBINE:
        raise ValidationError("combine", combine, f"one of {PAIR_COMBINE}")
    w_bad = v.positive("invalid_weight", invalid_weight, allow_zero=True)
    if w_bad >= 1.0:
        raise ValidationError("invalid_weight", invalid_weight, "in [0, 1)")
    D, W = _pair_ranges(lk, r, ok, n, combine)
    if w_bad > 0:
        weak = ~ok & np.isfinite(r)
        Db, Wb = _pair_ranges(lk, r, weak, n, combine)
        fill = (W == 0) & (Wb > 0)
        D = np.where(fill, Db, D)
        W = np.where(fill, w_bad, W)
    return D, W


def _pair_ranges(lk, r, sel, n, combine):
    """``range_matrix`` of the links ``sel`` (validated input)."""
    a, b = lk[sel, 0], lk[sel, 1]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    if combine == "min":
        D = np.full((n, n), np.inf)
        np.minimum.at(D, (lo, hi), r[sel])
        D = np.minimum(D, D.T)
        W = np.isfinite(D).astype(np.float64)
        np.fill_diagonal(W, 0.0)
        D = np.where(W > 0, D, 0.0)
        return np.maximum(D, 0.0), W
    total = np.zeros((n, n))
    count = np.zeros((n, n))
    np.add.at(total, (lo, hi), r[sel])
    np.add.at(count, (lo, hi), 1.0)
    total += total.T
    count += count.T
    W = (count > 0).astype(np.float64)
    D = np.divide(total, count, out=np.zeros((n, n)), where=count > 0)
    return np.maximum(D, 0.0), W


# -- classical MDS ------------------------------------------------------------------------------
def shortest_path_completion(D, W=None) -> np.ndarray:
    """Fill the missing entries (weight 0) of ``D`` with shortest-path distances.

    The graph has an edge ``i–j`` of length ``D[i, j]`` wherever ``W[i, j] > 0``; every entry of
    the result is the shortest-path length (Dijkstra, ``scipy.sparse.csgraph``), so measured
    entries are kept unless a shorter path exists (inconsistent, noisy triangles).

    Raises
    ------
    ValidationError
        When the graph is disconnected (the message names the components / nodes without a
        range): the relative placement of the parts is then unobservable.
    """
    w = _weights(W, _square("D", D).shape[0])
    d = _dissimilarities(D, w)
    graph = csgraph.csgraph_from_dense(np.where(w > 0, d, np.inf), null_value=np.inf)
    full = csgraph.shortest_path(graph, method="D", directed=False)
    if not np.all(np.isfinite(full)):
        raise ValidationError("W", "disconnected range graph", _components_message(w))
    return full


def classical_mds(D, dim, W=None) -> np.ndarray:
    """Classical (Torgerson) multidimensional scaling of a possibly incomplete range matrix.

    Missing entries (``W[i, j] == 0``) are first replaced by shortest-path distances
    (:func:`shortest_path_completion`); then, with ``J = I − 11ᵀ/n``,

    .. math:: B = -\\tfrac12 J D^{(2)} J = U Λ Uᵀ, \\qquad X = U_{:dim}\\, Λ_{:dim}^{1/2}

    using the ``dim`` largest eigenvalues (negative ones, from noise, and those below
    ``1e-12·λ_max``, from rounding, set to 0). Each
    eigenvector's sign is fixed so that its largest-magnitude entry is positive (deterministic
    output).

    Parameters
    ----------
    D : [n, n] float64
        Distances [m]; only the entries with ``W > 0`` are read (the rest may be anything).
    dim : int
        2 or 3.
    W : [n, n] float64, optional
        Symmetric weights, > 0 where ``D`` is measured. Default: every pair measured.

    Returns
    -------
    X : [n, dim] float64
        Centred configuration [m]. With exact complete Euclidean distances it equals the true
        configuration up to a rigid transform (rotation, reflection, translation). Degenerate
        inputs give a documented result: 2 nodes lie on the first axis at ``±d/2``; collinear
        (coplanar in 3-D) nodes have zero coordinates on the unused axes; one node sits at 0.

    Raises
    ------
    ValidationError
        Bad shapes or values; a disconnected range graph (e.g. a node with no valid range).

    Examples
    --------
    >>> X = classical_mds([[0.0, 5.0], [5.0, 0.0]], 2)
    >>> X.round(6).tolist()
    [[2.5, 0.0], [-2.5, 0.0]]
    """
    d = _dim(dim)
    full = shortest_path_completion(D, W)
    n = full.shape[0]
    sq = full**2
    B = -0.5 * (sq - sq.mean(axis=0)[None, :] - sq.mean(axis=1)[:, None] + sq.mean())
    lam, U = np.linalg.eigh(0.5 * (B + B.T))
    order = np.argsort(lam)[::-1][:d]
    lam, U = lam[order], U[:, order]
    lam = np.where(lam > 1e-12 * max(float(lam[0]), 0.0), lam, 0.0)  # noise, rounding -> 0
    flip = np.sign(U[np.argmax(np.abs(U), axis=0), np.arange(U.shape[1])])
    U = U * np.where(flip == 0, 1.0, flip)
    X = np.zeros((n, d))
    X[:, : U.shape[1]] = U * np.sqrt(lam)
    return X


# -- SMACOF -------------------------------------------------------------------------------------
def raw_stress(X, D, W) -> float:
    """Weighted raw stress ``σ(X) = Σ_{i<j} w_ij (‖x_i − x_j‖ − δ_ij)²`` [m²]."""
    w = _weights(W, _square("D", D).shape[0])
    return _stress(np.asarray(X, dtype=np.float64), _dissimilarities(D, w), w)


def _pairwise(X: np.ndarray) -> np.ndarray:
    diff = X[:, None, :] - X[None, :, :]
    return np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))


def _stress(X: np.ndarray, delta: np.ndarray, w: np.ndarray) -> float:
    return float(0.5 * np.sum(w * (_pairwise(X) - delta) ** 2))


def _guttman_b(X: np.ndarray, delta: np.ndarray, w: np.ndarray) -> np.ndarray:
    dist = _pairwise(X)
    ratio = np.divide(w * delta, dist, out=np.zeros_like(dist), where=dist > 0)
    B = -ratio
    B[np.diag_indices_from(B)] = ratio.sum(axis=1)
    return B


def smacof(D, W, X0, *, n_iter=200, tol=1e-9, fixed=None, return_history=False):
    """Weighted SMACOF: iterative majorization of the raw stress from a start ``X0``.

    Minimizes ``σ(X) = Σ_{i<j} w_ij (‖x_i − x_j‖ − δ_ij)²`` by the Guttman transform

    .. math:: X^{(k+1)} = V^{+} B(X^{(k)}) X^{(k)},\\qquad
              V = \\sum_{i<j} w_{ij}(e_i − e_j)(e_i − e_j)ᵀ,

    ``B(X)_ij = −w_ij δ_ij / d_ij(X)`` (0 where ``d_ij(X) = 0``), ``B_ii = −Σ_{j≠i} B_ij`` and
    ``V⁺`` the Moore–Penrose pseudo-inverse of the weighted ``V`` (de Leeuw's majorization; each
    step minimizes a majorizer that touches σ at ``X^{(k)}``, so σ never increases).

    With ``fixed`` the fixed rows keep their values (e.g. anchors at known positions) and the
    free rows solve the same majorizer restricted to them:
    ``V_ff X_f = (B X)_f − V_fa X_a`` (still monotone).

    Parameters
    ----------
    D : [n, n] float64
        Dissimilarities δ [m]; entries with weight 0 are not read.
    W : [n, n] float64 or None
        Symmetric non-negative weights (0: missing pair); ``None``: all pairs weight 1.
    X0 : [n, dim] float64
        Start configuration [m].
    n_iter : int
        Maximum number of Guttman transforms (>= 0). Default 200.
    tol : float
        Stop when an iteration lowers σ by less than ``tol·σ`` (relative, >= 0). Default 1e-9.
    fixed : [n] bool, optional
        Rows held at their ``X0`` values.
    return_history : bool
        Also return σ after every iteration (starting with σ(X0)).

    Returns
    -------
    X : [n, dim] float64
        [m]. Centred when nothing is fixed and the weight graph is connected.
    stress : float
        ``σ(X)`` [m²].
    history : [n_done + 1] float64
        Only with ``return_history``; non-increasing (up to rounding).

    Examples
    --------
    >>> D = np.array([[0, 3, 4], [3, 0, 5], [4, 5, 0]], dtype=float)
    >>> X, s = smacof(D, None, [[0, 0], [1, 0], [0, 1]], n_iter=500, tol=0)
    >>> bool(s < 1e-12)
    True
    """
    n_max = v.integer("n_iter", n_iter, minimum=0)
    rtol = v.positive("tol", tol, allow_zero=True)
    d0 = _square("D", D)
    n = d0.shape[0]
    w = _weights(W, n)
    delta = _dissimilarities(d0, w)
    X = v.finite_array("X0", X0, ndim=2).copy()
    if X.shape[0] != n or X.shape[1] < 1:
        raise ValidationError("X0", f"array of shape {X.shape}", f"must be [{n}, dim]")
    if fixed is None:
        fix = np.zeros(n, dtype=bool)
    else:
        fix = np.asarray(fixed)
        if fix.dtype != np.bool_ or fix.shape != (n,):
            raise ValidationError(
                "fixed", f"{fix.dtype} array of shape {fix.shape}", f"must be bool of shape ({n},)"
            )
    free = ~fix
    V = np.diag(w.sum(axis=1)) - w
    if fix.any():
        Vff_pinv = np.linalg.pinv(V[np.ix_(free, free)], hermitian=True)
        rhs_fixed = V[np.ix_(free, fix)] @ X[fix]
    else:
        V_pinv = np.linalg.pinv(V, hermitian=True)
    s = _stress(X, delta, w)
    history = [s]
    for _ in range(n_max if free.any() else 0):
        BX = _guttman_b(X, delta, w) @ X
        if fix.any():
            X_new = X.copy()
            X_new[free] = Vff_pinv @ (BX[free] - rhs_fixed)
        else:
            X_new = V_pinv @ BX
        s_new = _stress(X_new, delta, w)
        X, drop, s = X_new, s - s_new, s_new
        history.append(s)
        if drop <= rtol * s or s == 0.0:  # also stops on a rounding-level increase
            break
    if return_history:
        return X, s, np.asarray(history)
    return X, s


def _robust_terms(r, c, one_sided):
    """Cost ``ρ(r)`` and IRLS weight of range residuals ``r = δ − ‖x_i − x_j‖`` at scale ``c``.

    Cauchy, ``ρ = log(1 + (r/c)²)`` with weight ``1 / (1 + (r/c)²)`` — on both sides, or with
    ``one_sided`` only for ``r > 0`` (a range *longer* than the fitted distance, as an NLOS
    excess delay makes it) and the plain quadratic ``ρ = (r/c)²``, weight 1, for ``r <= 0``:
    a positive bias never makes a range shorter than the distance, so a short range is noise
    and keeps its full pull. The two sides agree to second order at ``r = 0``.
    """
    z = (r / c) ** 2
    cost, weight = np.log1p(z), 1.0 / (1.0 + z)
    if one_sided:
        short = r <= 0
        cost, weight = np.where(short, z, cost), np.where(short, 1.0, weight)
    return cost, weight


def _cauchy_weights(D, W, X, c, one_sided=False):
    """``W / (1 + (r/c)²)``, ``r = D − ‖x_i − x_j‖`` (robust MDS reweighting; ``one_sided``:
    see :func:`_robust_terms`)."""
    return W * _robust_terms(D - _pairwise(X), c, one_sided)[1]


def _cauchy_cost(D_row, w_row, X_other, points, c, one_sided=False):
    """``Σ_j w_j ρ(δ_j − ‖x − x_j‖)`` at each of ``points [m, dim]`` (:func:`_robust_terms`)."""
    r = D_row[None, :] - np.linalg.norm(points[:, None, :] - X_other[None, :, :], axis=-1)
    return _robust_terms(r, c, one_sided)[0] @ w_row


def _robust_fit(D, measured, X, c, rounds, n_iter, tol, one_sided=False):
    """``rounds`` of Cauchy-reweighted SMACOF from ``X``. Returns ``(X, W, stress, cost)``,
    ``cost`` the total robust cost ``Σ_{i<j} w_ij ρ(r_ij)`` over the measured pairs (the
    objective the reweighting descends, :func:`_robust_terms`)."""
    W, s = measured, 0.0
    for _ in range(rounds):
        W = _cauchy_weights(D, measured, X, c, one_sided)
        X, s = smacof(D, W, X, n_iter=n_iter, tol=tol)
    return X, W, s, _total_cauchy_cost(D, measured, X, c, one_sided)


#: Cost difference below which two robust fits are the same fit (a 1 mm residual at 1 m).
_COST_TIE = 1e-6


def _lower(cost, best) -> bool:
    """``cost`` beats ``best`` by more than :data:`_COST_TIE` (relative to ``1 + best``): exact
    fits of a flexible network tie at ~1e-25, and rounding (complex64 storage of the samples)
    must not decide between them; the earlier candidate keeps a tie."""
    return cost < best - _COST_TIE * (1.0 + best)


def _total_cauchy_cost(D, measured, X, c, one_sided=False) -> float:
    """``Σ_{i<j} w_ij ρ(r_ij)`` over the measured pairs at configuration ``X``."""
    cost = _robust_terms(D - _pairwise(X), c, one_sided)[0]
    return float(np.sum(np.triu(measured * cost, 1)))


def _robust_solution(D, measured, starts, c, rounds, n_iter, tol, fixed, one_sided=False):
    """The robust fit at scale ``c`` of :func:`coarse_positions`: every start through
    :func:`_robust_fit` (the lowest cost wins), then :func:`relocate_nodes` and, when a node
    moved, a refit kept if its cost is lower. Returns ``(X, W, stress)``."""
    best = None
    for Xs in starts:
        fit = _robust_fit(D, measured, Xs, c, rounds, n_iter, tol, one_sided)
        if best is None or _lower(fit[3], best[3]):
            best = fit
    X, moved = relocate_nodes(D, measured, best[0], c, fixed=fixed, one_sided=one_sided)
    if moved.size:  # refine the repaired configuration the same way
        fit = _robust_fit(D, measured, X, c, rounds, n_iter, tol, one_sided)
        if _lower(fit[3], best[3]):
            return fit[:3]
    return best[:3]


def relocate_nodes(D, W, X, c, *, fixed=None, n_grid=41, min_gain=2.0, n_passes=2, one_sided=False):
    """Move nodes that a robust SMACOF left in a wrong basin to their best position.

    A node whose correct ranges are outvoted early (e.g. two ranges biased by 200 m pull it
    out of the network before the reweighting starts) ends in a local minimum where its
    *correct* ranges look like the outliers. Per node, in order of decreasing robust cost, the
    Cauchy cost ``Σ_j w_ij log(1 + ((δ_ij − ‖x − x_j‖)/c)²)`` (the objective whose
    reweighting :func:`coarse_positions` iterates) is evaluated on a ``n_grid``-per-axis grid
    over the other nodes' bounding box widened by a quarter of its size per side, then on a
    grid of the same size spanning two cells around the best point; the node moves to the
    best point when that lowers its cost by more than ``min_gain``. Nodes with fewer than
    ``dim + 1`` measured pairs (not determined) and ``fixed`` nodes stay.

    Parameters
    ----------
    D, W : [n, n] float64
        Pair ranges and (measured, not reweighted) weights of :func:`range_matrix`.
    X : [n, dim] float64
        Configuration from robust SMACOF.
    c : float
        Cauchy scale [m].
    fixed : [n] bool, optional
        Nodes never moved (anchors).
    one_sided : bool
        Down-weight only ranges longer than the distance (positive NLOS bias), the cost of
        :func:`coarse_positions` with the same flag.

    Returns
    -------
    X : [n, dim] float64
        The configuration with the moved nodes (a copy).
    moved : int array
        The nodes moved, in the order they moved.
    """
    X = np.array(X, dtype=np.float64, copy=True)
    n, dim = X.shape
    keep = np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool)
    per_axis = n_grid if dim == 2 else int(np.ceil(n_grid ** (2.0 / 3.0)))

    def grid_of(lo, hi):
        axes = [np.linspace(a, b, per_axis) for a, b in zip(lo, hi, strict=True)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)

    moved = []
    for _ in range(n_passes):
        cost = np.array(
            [
                _cauchy_cost(D[i], W[i], X, X[i][None], c, one_sided)[0] if W[i].any() else 0.0
                for i in range(n)
            ]
        )
        changed = False
        for i in np.argsort(-cost):
            nb = np.flatnonzero(W[i] > 0)
            if keep[i] or nb.size < dim + 1:
                continue
            others = np.delete(np.arange(n), i)
            lo, hi = X[others].min(axis=0), X[others].max(axis=0)
            pad = 0.25 * np.maximum(hi - lo, c)
            grid = grid_of(lo - pad, hi + pad)
            cell = (hi - lo + 2 * pad) / (per_axis - 1)
            g = _cauchy_cost(D[i, nb], W[i, nb], X[nb], grid, c, one_sided)
            x0 = grid[int(np.argmin(g))]
            fine = grid_of(x0 - 2 * cell, x0 + 2 * cell)
            g = _cauchy_cost(D[i, nb], W[i, nb], X[nb], fine, c, one_sided)
            best = int(np.argmin(g))
            now = _cauchy_cost(D[i, nb], W[i, nb], X[nb], X[i][None], c, one_sided)[0]
            if g[best] < now - min_gain:
                X[i] = fine[best]
                moved.append(int(i))
                changed = True
        if not changed:
            break
    return X, np.asarray(moved, dtype=np.int64)


# -- coarse network solution --------------------------------------------------------------------
@dataclass(frozen=True)
class CoarseSolution:
    """A coarse, truth-free solution of the network from ranges (:func:`coarse_positions`).

    Attributes
    ----------
    positions : [n_nodes, dim] float64
        Coarse positions [m]; anchor rows equal the known anchor positions exactly.
    stress : float
        Final weighted raw stress ``Σ_{i<j} w_ij (‖x_i − x_j‖ − δ_ij)²`` [m²] over the measured
        pairs (and anchor–anchor pairs, when anchors are given); after robust reweighting
        ``w_ij`` are the final Cauchy weights, so outlying ranges barely count.
    residual_rms_m : float
        ``sqrt(stress / n_pairs)`` [m], the RMS range residual — a truth-free scale for the
        prior standard deviation of :func:`gaussian_priors`.
    frame : {"anchors", "partial", "arbitrary"}
        ``"anchors"``: the anchors (>= dim + 1, affinely independent) fix the frame, positions
        are absolute. ``"partial"``: fewer or degenerate (collinear/coplanar) anchors fix it only
        up to the rotations/reflections that leave them in place. ``"arbitrary"``: anchor-free,
        the frame is a gauge (centred configuration) and only the shape is meaningful.
    """

    positions: np.ndarray
    stress: float
    residual_rms_m: float
    frame: str


def _affine_rank(P: np.ndarray) -> int:
    if P.shape[0] < 2:
        return 0
    s = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    scale = max(1.0, float(np.abs(P).max()))
    return int(np.sum(s > 1e-9 * scale))


def coarse_positions(
    links,
    ranges,
    n_nodes,
    dim,
    *,
    valid=None,
    is_anchor=None,
    anchor_positions=None,
    rng=None,
    n_restarts=0,
    n_iter=300,
    tol=1e-9,
    combine="mean",
    robust_scale_m=None,
    robust_rounds=10,
    invalid_weight=0.0,
    one_sided=False,
) -> CoarseSolution:
    """Truth-free coarse network solution from range estimates: MDS → SMACOF → anchor frame.

    1. :func:`range_matrix` of the valid link ranges; with anchors, the anchor–anchor
       distances (known exactly) are added to it.
    2. :func:`classical_mds` (missing pairs by shortest paths) as the start of weighted
       :func:`smacof` on the measured pairs only. With ``n_restarts > 0``, as many extra
       SMACOF runs start from uniform random configurations (drawn with ``rng``) in a box the
       size of the largest range; the lowest stress wins (with ``robust_scale_m``: every start
       goes through the robust rounds below and the lowest robust cost wins — folds of a
       sparse urban network that the MDS start falls into are left this way).
    3. With anchors: the solution is rigidly fitted (rotation, translation and reflection —
       Kabsch) onto the known anchor positions, the anchor rows are set exactly, and SMACOF
       refines the agents with the anchors held fixed. With ``>= dim + 1`` affinely independent
       anchors the result is in the anchors' frame (``frame="anchors"``). With fewer or
       degenerate anchors (1 anchor; 2 or collinear anchors; coplanar anchors in 3-D) the same
       steps run, but the rotations/reflections fixing the anchors are not observable and the
       result is one of the equivalent solutions (``frame="partial"``).
       Without anchors the configuration is centred at the origin in an arbitrary orientation
       (``frame="arbitrary"``): compare it only gauge-invariantly (framework distance RMSE).

    With ``robust_scale_m = c``, step 2 is followed by ``robust_rounds`` rounds of iteratively
    reweighted SMACOF: each pair's weight becomes ``1 / (1 + (r/c)²)`` of its residual
    ``r = δ_ij − ‖x_i − x_j‖`` (Cauchy weights, the M-estimator of robust MDS), so a range that
    disagrees with the rest of the network by many ``c`` — an NLOS-biased range, or a false
    peak — stops pulling the configuration. In dense urban networks this is what keeps the
    start within a metre (:doc:`DiPNet Fig. 5 </guide/experiments>`); with exact or LOS ranges
    it changes nothing (every residual is ~0). A node the reweighting left in a wrong basin is
    then moved to the best point of its own robust cost (:func:`relocate_nodes`) and the
    rounds are repeated (kept when the total robust cost drops).

    No true position is used. A node that is connected but not rigidly determined (e.g. two
    ranges in 2-D) gets one of its ambiguous positions.

    Parameters
    ----------
    links : [n_links, 2] int
        Directed links ``(u, v)``.
    ranges : [n_links] float64
        Range estimates [m] (NaN: missing), e.g. correlation-peak ranges.
    n_nodes : int
        Number of nodes (>= 2).
    dim : int
        2 or 3.
    valid : [n_links] bool, optional
        Estimates to use; see :func:`range_matrix`.
    is_anchor : [n_nodes] bool, optional
        Anchor flags; ``None`` or no True entry: anchor-free.
    anchor_positions : [n_anchors, dim] float64, optional
        Known anchor positions [m], in the order of ``np.flatnonzero(is_anchor)``; required
        when there are anchors.
    rng : numpy.random.Generator, optional
        Needed only for ``n_restarts > 0``.
    n_restarts : int
        Extra random SMACOF starts (>= 0). Default 0 (deterministic).
    n_iter, tol
        SMACOF iteration limit and relative tolerance, see :func:`smacof`.
    combine : {"mean", "min"}
        How the ranges of one pair are combined, see :func:`range_matrix`.
    robust_scale_m : float or sequence of float, optional
        Cauchy scale ``c`` [m] of the reweighting rounds (> 0); ``None``: plain SMACOF.
        Several scales: the robust fit runs at each, and the configuration with the lowest
        Cauchy cost at the *smallest* scale wins (one objective; the larger scales are other
        ways into its basin — with many NLOS ranges a single scale can fold the network).
    robust_rounds : int
        Reweighting rounds (>= 1) when ``robust_scale_m`` is given.
    invalid_weight : float
        Weight of pairs known only from invalid ranges, see :func:`range_matrix`.
    one_sided : bool
        Ranges are biased only upwards (an NLOS excess delay makes a range longer, never
        shorter): the Cauchy reweighting then applies only to ranges longer than the fitted
        distance, and a shorter range keeps its full least-squares weight (cost ``(r/c)²``).
        With many NLOS ranges (a small network where every link is detected) this keeps the
        biased ranges from folding the network around them. The chosen configuration is then
        polished by symmetric rounds at the finest scale (both sides agree within the noise).
        Default False (symmetric).

    Returns
    -------
    CoarseSolution

    Raises
    ------
    ValidationError
        Bad input, or a disconnected range graph (the message names the components and the
        nodes without any valid range).

    Examples
    --------
    >>> p = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [4.0, 3.0]])
    >>> links = np.array([[i, j] for i in range(4) for j in range(4) if i != j])
    >>> r = np.linalg.norm(p[links[:, 0]] - p[links[:, 1]], axis=1)
    >>> sol = coarse_positions(links, r, 4, 2, is_anchor=np.array([1, 1, 1, 0], bool),
    ...                        anchor_positions=p[:3])
    >>> sol.frame, bool(np.allclose(sol.positions, p, atol=1e-6))
    ('anchors', True)
    """
    n = v.integer("n_nodes", n_nodes, minimum=2)
    d = _dim(dim)
    restarts = v.integer("n_restarts", n_restarts, minimum=0)
    if restarts:
        _rng(rng)
    D, W = range_matrix(links, ranges, n, valid, combine=combine, invalid_weight=invalid_weight)
    if robust_scale_m is not None:
        scales = np.atleast_1d(np.asarray(robust_scale_m, dtype=object))
        if scales.ndim != 1 or scales.size == 0:
            raise ValidationError("robust_scale_m", robust_scale_m, "a scale > 0 [m] or a list")
        scales = sorted({v.positive("robust_scale_m", c) for c in scales}, reverse=True)
        rounds = v.integer("robust_rounds", robust_rounds, minimum=1)

    anchor = np.zeros(n, dtype=bool)
    if is_anchor is not None:
        anchor = np.asarray(is_anchor)
        if anchor.dtype != np.bool_ or anchor.shape != (n,):
            raise ValidationError(
                "is_anchor",
                f"{anchor.dtype} array of shape {anchor.shape}",
                f"must be a bool array of shape ({n},) or None",
            )
    n_anchor = int(anchor.sum())
    if n_anchor:
        if anchor_positions is None:
            raise ValidationError(
                "anchor_positions", None, "required when is_anchor flags any anchor"
            )
        A = v.finite_array("anchor_positions", anchor_positions, ndim=2)
        if A.shape != (n_anchor, d):
            raise ValidationError(
                "anchor_positions", f"array of shape {A.shape}", f"must be ({n_anchor}, {d})"
            )
        idx = np.flatnonzero(anchor)
        dA = np.linalg.norm(A[:, None, :] - A[None, :, :], axis=-1)
        D[np.ix_(idx, idx)] = dA
        W[np.ix_(idx, idx)] = 1.0
        np.fill_diagonal(W, 0.0)
        np.fill_diagonal(D, 0.0)

    X0 = classical_mds(D, d, W)
    X, s = smacof(D, W, X0, n_iter=n_iter, tol=tol)
    starts = [X]
    if restarts:
        extent = float(D[W > 0].max(initial=1.0))
        for _ in range(restarts):
            Xr, sr = smacof(D, W, rng.uniform(-extent, extent, size=(n, d)), n_iter=n_iter, tol=tol)
            starts.append(Xr)
            if _lower(sr, s):
                X, s = Xr, sr
    if robust_scale_m is not None:  # per scale, every start robustly (lowest cost wins)
        measured, chosen = W, None
        for c in scales:
            X_c, W_c, s_c = _robust_solution(
                D, measured, starts, c, rounds, n_iter, tol, anchor if n_anchor else None, one_sided
            )
            # all at the finest scale
            cost = _total_cauchy_cost(D, measured, X_c, scales[-1], one_sided)
            # a smaller scale wins only by more than a 1 mm residual at the finest scale: fits
            # that tie (a flexible network fits exactly in many ways) keep the larger scale's,
            # so rounding (e.g. complex64 storage) cannot flip the choice
            if chosen is None or _lower(cost, chosen[3]):
                chosen = (X_c, W_c, s_c, cost)
        X, W, s = chosen[:3]
        if one_sided:  # polish symmetrically in the basin found: the sides agree within noise
            X, W, s = _robust_fit(D, measured, X, scales[-1], rounds, n_iter, tol)[:3]

    if n_anchor:
        R, t = kabsch(X[anchor], A)
        X = X @ R.T + t
        X[anchor] = A
        if n_anchor < n:
            X, s = smacof(D, W, X, n_iter=n_iter, tol=tol, fixed=anchor)
        frame = "anchors" if _affine_rank(A) == d else "partial"
    else:
        frame = "arbitrary"
    n_pairs = int(np.count_nonzero(np.triu(W, 1)))
    rms = float(np.sqrt(s / n_pairs)) if n_pairs else 0.0
    return CoarseSolution(positions=X, stress=float(s), residual_rms_m=rms, frame=frame)


# -- priors -------------------------------------------------------------------------------------
def _std_per_agent(std_m, n_agents: int) -> np.ndarray:
    s = np.asarray(std_m, dtype=np.float64)
    if s.ndim == 0:
        s = np.full(n_agents, float(s))
    if s.shape != (n_agents,):
        raise ValidationError("std_m", f"array of shape {s.shape}", f"scalar or ({n_agents},)")
    if not np.all(np.isfinite(s) & (s > 0)):
        raise ValidationError("std_m", std_m, "standard deviations must be finite and > 0 [m]")
    return s


def _centers(centers) -> np.ndarray:
    c = v.finite_array("centers", centers, ndim=2)
    if c.shape[1] not in (2, 3):
        raise ValidationError("centers", f"array of shape {c.shape}", "must be [n_agents, 2|3]")
    return c


def gaussian_priors(centers, std_m, Q, rng) -> np.ndarray:
    """Particles from isotropic Gaussian priors ``p_u ~ N(c_u, σ_u² I)``.

    Parameters
    ----------
    centers : [n_agents, dim] float64
        Prior means [m]: coarse positions (:func:`coarse_positions`, truth-free) or
        :func:`informed_centers` (informed start).
    std_m : float or [n_agents] float64
        Prior standard deviation σ_u per axis [m], > 0.
    Q : int
        Particles per agent (>= 1).
    rng : numpy.random.Generator

    Returns
    -------
    particles : [n_agents, Q, dim] float64
        [m]. Their log prior density is :func:`gaussian_log_prior`.

    Examples
    --------
    >>> x = gaussian_priors(np.zeros((2, 2)), 5.0, 1000, np.random.default_rng(0))
    >>> x.shape
    (2, 1000, 2)
    """
    c = _centers(centers)
    s = _std_per_agent(std_m, c.shape[0])
    q = v.integer("Q", Q, minimum=1)
    noise = _rng(rng).standard_normal((c.shape[0], q, c.shape[1]))
    return c[:, None, :] + s[:, None, None] * noise


def gaussian_log_prior(particles, centers, std_m) -> np.ndarray:
    """Log density of the priors of :func:`gaussian_priors` at the particles.

    .. math:: \\ln N(x; c_u, σ_u^2 I) = −\\frac{\\|x − c_u\\|^2}{2σ_u^2}
              − \\frac{\\dim}{2}\\ln(2πσ_u^2)

    Parameters
    ----------
    particles : [n_agents, Q, dim] float64
        [m].
    centers : [n_agents, dim] float64
        [m].
    std_m : float or [n_agents] float64
        [m], > 0.

    Returns
    -------
    log_prior : [n_agents, Q] float64
        Normalized log density [log 1/m^dim] (finite everywhere).
    """
    c = _centers(centers)
    x = v.finite_array("particles", particles, ndim=3)
    if x.shape[0] != c.shape[0] or x.shape[2] != c.shape[1]:
        raise ValidationError(
            "particles", f"array of shape {x.shape}", f"must be [{c.shape[0]}, Q, {c.shape[1]}]"
        )
    s = _std_per_agent(std_m, c.shape[0])
    out = np.empty(x.shape[:2])
    _kernels.gaussian_log_prior_kernel(
        np.ascontiguousarray(x, dtype=np.float64),
        np.ascontiguousarray(c, dtype=np.float64),
        np.ascontiguousarray(s, dtype=np.float64),
        out,
    )
    return out


def informed_centers(true_positions, std_m=INFORMED_START_STD_M, *, rng) -> np.ndarray:
    """Prior centres of the **informed start**: ``p + N(0, σ0² I)``.

    This initialization uses the true positions: it is a diagnostic (how good is the filter
    once near the truth?), not a localization method. Every result computed from it must be
    labelled "informed start" (scenario tokens ``*_informed``); the truth-free default is
    :func:`coarse_positions`.

    Parameters
    ----------
    true_positions : [..., dim] float64
        Positions to perturb [m] (usually the agents' true positions).
    std_m : float
        σ0 [m], >= 0. Default 10 m (:data:`INFORMED_START_STD_M`).
    rng : numpy.random.Generator
        Keyword-only.

    Returns
    -------
    centers : like ``true_positions``, float64 [m]
    """
    p = v.finite_array("true_positions", true_positions)
    if p.ndim < 1:
        raise ValidationError("true_positions", "a scalar", "must be an array [..., dim]")
    s = v.positive("std_m", std_m, allow_zero=True)
    return p + s * _rng(rng).standard_normal(p.shape)


def gauge_priors(n_agents, dim, Q, extent_m, rng) -> np.ndarray:
    """Uninformative anchor-free gauge priors (issue 5: kept to show DiPNet's collapse).

    An anchor-free network is determined only up to a rigid transform; these priors remove the
    gauge freedom by convention, with support (``e = extent_m``):

    - agent 0: the origin (a Dirac: all particles exactly at 0) — fixes translation;
    - agent 1: the positive x-axis, ``x ~ U(0, e)``, other coordinates 0 — fixes rotation in
      2-D (and two rotation angles in 3-D);
    - agent 2: the upper half-plane ``y ~ U(0, e)``, ``x ~ U(−e, e)`` (in 3-D: ``z = 0``, i.e.
      the half-plane ``{y >= 0, z = 0}``) — fixes the reflection in 2-D (and the last rotation
      angle in 3-D);
    - 3-D only, agent 3: ``z ~ U(0, e)`` (upper half-space), ``x, y ~ U(−e, e)`` — fixes the
      reflection in 3-D;
    - every other agent: uniform on ``[−e, e]^dim``.

    Choose ``e`` at least the network diameter (e.g. ``√dim ×`` the region side), otherwise the
    true relative configuration lies outside the support. The density is uniform on the
    support; :func:`gauge_log_prior` evaluates it.

    Parameters
    ----------
    n_agents : int
        >= 1 (agents 3, … in 2-D and 4, … in 3-D are uniform on the cube).
    dim : int
        2 or 3.
    Q : int
        Particles per agent (>= 1).
    extent_m : float
        e [m], > 0.
    rng : numpy.random.Generator

    Returns
    -------
    particles : [n_agents, Q, dim] float64
        [m].
    """
    n = v.integer("n_agents", n_agents, minimum=1)
    d = _dim(dim)
    q = v.integer("Q", Q, minimum=1)
    e = v.positive("extent_m", extent_m)
    g = _rng(rng)
    x = g.uniform(-e, e, size=(n, q, d))
    x[0] = 0.0
    if n > 1:
        x[1] = 0.0
        x[1, :, 0] = g.uniform(0.0, e, size=q)
    if n > 2:
        x[2, :, 1] = g.uniform(0.0, e, size=q)
        if d == 3:
            x[2, :, 2] = 0.0
    if n > 3 and d == 3:
        x[3, :, 2] = g.uniform(0.0, e, size=q)
    return x


def gauge_log_prior(particles, extent_m, *, atol_m=None) -> np.ndarray:
    """Unnormalized log density of :func:`gauge_priors`: 0 on the support, ``-inf`` outside.

    Equality constraints (agent 0 at the origin, agent 1's off-axis coordinates, agent 2's z in
    3-D) hold within ``atol_m`` (default ``1e-9·extent_m``). Callers must treat ``-inf`` with
    care: a particle outside the support has zero prior weight, and an agent whose particles all
    lie outside has no valid belief (do not normalize ``-inf − (-inf)``).

    Parameters
    ----------
    particles : [n_agents, Q, dim] float64
        [m], dim 2 or 3.
    extent_m : float
        e [m], > 0, as given to :func:`gauge_priors`.
    atol_m : float, optional
        Tolerance of the equality constraints [m], >= 0.

    Returns
    -------
    log_prior : [n_agents, Q] float64
        0.0 or ``-inf``.
    """
    x = v.finite_array("particles", particles, ndim=3)
    d = _dim(x.shape[2])
    e = v.positive("extent_m", extent_m)
    tol = 1e-9 * e if atol_m is None else v.positive("atol_m", atol_m, allow_zero=True)
    n = x.shape[0]
    inside = np.all(np.abs(x) <= e + tol, axis=2)
    if n > 0:
        inside[0] &= np.all(np.abs(x[0]) <= tol, axis=1)
    if n > 1:
        inside[1] &= (x[1, :, 0] >= -tol) & np.all(np.abs(x[1, :, 1:]) <= tol, axis=1)
    if n > 2:
        inside[2] &= x[2, :, 1] >= -tol
        if d == 3:
            inside[2] &= np.abs(x[2, :, 2]) <= tol
    if n > 3 and d == 3:
        inside[3] &= x[3, :, 2] >= -tol
    return np.where(inside, 0.0, -np.inf)
