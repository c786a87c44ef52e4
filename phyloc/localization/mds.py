"""Multidimensional scaling of a partial range matrix: classical MDS and weighted SMACOF.

The building blocks of the truth-free coarse solution
(:func:`phyloc.localization.initialization.coarse_positions`): missing pairs completed by
shortest paths (:func:`shortest_path_completion`), classical (Torgerson) MDS as the start
(:func:`classical_mds`) and weighted SMACOF (:func:`smacof`), the iterative majorization of
the raw stress (:func:`raw_stress`) over the measured pairs only. Range matrices ``D`` are
``[n, n]`` [m] with symmetric weights ``W`` (0: pair not measured).

References
----------
I. Borg and P. J. F. Groenen, *Modern Multidimensional Scaling: Theory and Applications*,
2nd ed., Springer, 2005 (classical MDS, SMACOF).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csgraph

from phyloc import _validate as v
from phyloc.errors import ValidationError


# -- input checks -------------------------------------------------------------------------------
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
