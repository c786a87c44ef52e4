"""Initialization of the particle filters: the truth-free coarse solution of the network.

DiPNet Algorithm 1 draws each agent's Q particles once from its *a priori* pdf, which the
paper does not state. Run from uninformative priors the filter collapses (the ``gauge``
initialization of the localization recipes shows it), so phyloc offers three
initializations, each labelled as such wherever results are reported:

truth-free (default; this module)
    :func:`coarse_positions` solves the network coarsely from estimated ranges alone — the
    range matrix (:func:`range_matrix`), classical MDS with shortest-path completion and
    weighted SMACOF (:mod:`phyloc.localization.mds`), Cauchy-reweighted SMACOF against
    outlying ranges with :func:`relocate_nodes` — and fixes the frame with the anchors when
    there are any; :func:`~phyloc.localization.priors.gaussian_priors` then draws each agent's
    particles around its coarse position.
informed start (:mod:`phyloc.localization.priors`)
    :func:`~phyloc.localization.priors.informed_centers` perturbs given positions (typically
    the truth) by ``N(0, σ0²)``, σ0 = 10 m by default, and
    :func:`~phyloc.localization.priors.gaussian_priors` draws around them. **It uses the
    truth**: every output computed from it must say "informed start" (scenario tokens
    ``*_informed``).
uninformative gauge priors (:mod:`phyloc.localization.gauge`)
    :func:`~phyloc.localization.gauge.gauge_priors` /
    :func:`~phyloc.localization.gauge.gauge_log_prior`: the anchor-free gauge of the paper's
    setting (agent 0 at the origin, agent 1 on the positive x-axis, agent 2 in the upper
    half-plane, the rest uniform) — kept to show the collapse, not to be used for results.

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

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.mds import _dim, _pairwise, classical_mds, smacof
from phyloc.localization.sparse_start import (
    PairGraph,
    pair_graph,
    sparse_coarse_positions,
    undetermined_nodes,
)
from phyloc.network.geometry import kabsch

FRAMES = ("anchors", "partial", "arbitrary")
"""Values of :attr:`CoarseSolution.frame`."""
SOLVERS = ("dense", "sparse", "auto")
"""Values of :func:`coarse_positions`' ``solver``."""
SPARSE_ABOVE_NODES = 50
"""``solver="auto"`` solves networks of more nodes than this on their measured pairs only."""


# -- input checks -------------------------------------------------------------------------------
def _rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return rng


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
    lk, r, ok, w_bad = _link_ranges(links, ranges, n, valid, combine, invalid_weight)
    D, W = _pair_ranges(lk, r, ok, n, combine)
    if w_bad > 0:
        weak = ~ok & np.isfinite(r)
        Db, Wb = _pair_ranges(lk, r, weak, n, combine)
        fill = (W == 0) & (Wb > 0)
        D = np.where(fill, Db, D)
        W = np.where(fill, w_bad, W)
    return D, W


def _link_ranges(links, ranges, n, valid, combine, invalid_weight):
    """Checked ``(links [n_links, 2] int64, ranges, valid flags, invalid_weight)`` of
    :func:`range_matrix`'s arguments."""
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
    return lk, r, ok, w_bad


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
        prior standard deviation of :func:`~phyloc.localization.priors.gaussian_priors`.
    frame : {"anchors", "partial", "arbitrary"}
        ``"anchors"``: the anchors (>= dim + 1, affinely independent) fix the frame, positions
        are absolute. ``"partial"``: fewer or degenerate (collinear/coplanar) anchors fix it only
        up to the rotations/reflections that leave them in place. ``"arbitrary"``: anchor-free,
        the frame is a gauge (centred configuration) and only the shape is meaningful.
    undetermined : [n_nodes] bool
        Nodes the measured pairs do not place, by the rule of
        :func:`~phyloc.localization.sparse_start.undetermined_nodes` (outside the component
        that fixes the frame, or fewer than ``dim + 1`` measured neighbours).
    """

    positions: np.ndarray
    stress: float
    residual_rms_m: float
    frame: str
    undetermined: np.ndarray | None = None


#: Consistency factor of the median absolute deviation for Gaussian data (MAD·1.4826 = σ).
MAD_TO_STD = 1.482602218505602


def start_scale(
    positions, links, ranges, *, valid=None, combine="min", floor_m=0.0, position=False
):
    """Each node's truth-free accuracy scale of a coarse solution: the robust scale of its own
    measured ranges' residuals against the solution.

    For node ``u`` and its measured pairs ``(u, v)`` (the two directions combined as in
    :func:`coarse_positions`): ``r_uv = δ_uv − ‖x_u − x_v‖`` and
    ``σ_u = max(1.4826 · median_v |r_uv|, floor_m)`` — the median absolute residual, a
    standard deviation for Gaussian residuals, which NLOS-biased outliers barely move. It is
    not divided by the number of links: range errors of neighbouring links share their
    multipath and the start's own bias, so σ_u is the scale of the ranges that placed ``u``,
    not a CRB. A node without a measured pair gets ``inf``.

    Parameters
    ----------
    positions : [n_nodes, dim] float64
        The coarse solution [m] (:attr:`CoarseSolution.positions`).
    links, ranges, valid, combine
        As :func:`coarse_positions` (``valid=None``: every finite range).
    floor_m : float
        Smallest scale returned [m], >= 0.
    position : bool
        A position std instead: ``σ · sqrt(tr(J_u⁻¹)/dim)`` with ``J_u = Σ_v e_uv e_uvᵀ`` (unit
        vectors to the measured neighbours at the solution), the position CRB of ranges of std
        ``σ`` (``inf`` where ``J_u`` is singular). Here ``σ`` is the *network's* robust residual
        scale (1.4826 · the median absolute residual over every measured pair): a node with
        only ``dim`` measured pairs fits them exactly, and its own residual scale would be 0.

    Returns
    -------
    [n_nodes] float64
        σ_u [m].

    Examples
    --------
    >>> x = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])
    >>> lk = np.array([[0, 1], [1, 0], [0, 2], [1, 2]])
    >>> start_scale(x, lk, np.array([3.2, 3.1, 4.0, 5.0])).round(4).tolist()
    [0.0741, 0.0741, 0.0]
    """
    X = np.asarray(positions, dtype=np.float64)
    n = X.shape[0]
    lk, r, ok, _ = _link_ranges(links, ranges, n, valid, combine, 0.0)
    floor = v.positive("floor_m", floor_m, allow_zero=True)
    g = pair_graph(lk, r, ok, n, combine)
    res = np.abs(g.delta - np.linalg.norm(X[g.i] - X[g.j], axis=1))
    node = np.concatenate([g.i, g.j])
    res2 = np.concatenate([res, res])
    order = np.lexsort((res2, node))
    node, res2 = node[order], res2[order]
    out = np.full(n, np.inf)
    starts = np.searchsorted(node, np.arange(n + 1))
    for u in range(n):
        a, b = starts[u], starts[u + 1]
        if b > a:
            out[u] = MAD_TO_STD * float(np.median(res2[a:b]))
    if position:
        out = np.where(
            np.isfinite(out), MAD_TO_STD * float(np.median(res)) if res.size else 0.0, np.inf
        )
        dim = X.shape[1]
        e = X[g.j] - X[g.i]
        e /= np.maximum(np.linalg.norm(e, axis=1), 1e-12)[:, None]
        outer = e[:, :, None] * e[:, None, :]
        J = np.zeros((n, dim, dim))
        np.add.at(J, g.i, outer)
        np.add.at(J, g.j, outer)
        with np.errstate(invalid="ignore", divide="ignore"):
            det_ok = np.linalg.matrix_rank(J) == dim
            tr = np.full(n, np.inf)
            tr[det_ok] = np.trace(np.linalg.inv(J[det_ok]), axis1=1, axis2=2)
        ok = np.isfinite(tr) & np.isfinite(out)
        out = np.where(ok, np.where(ok, out, 0.0) * np.sqrt(np.where(ok, tr, 0.0) / dim), np.inf)
    return np.where(np.isfinite(out), np.maximum(out, floor), out)


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
    solver="dense",
) -> CoarseSolution:
    """Truth-free coarse network solution from range estimates: MDS → SMACOF → anchor frame.

    1. :func:`range_matrix` of the valid link ranges; with anchors, the anchor–anchor
       distances (known exactly) are added to it.
    2. :func:`~phyloc.localization.mds.classical_mds` (missing pairs by shortest paths) as the
       start of weighted :func:`~phyloc.localization.mds.smacof` on the measured pairs only.
       With ``n_restarts > 0``, as many extra SMACOF runs start from uniform random
       configurations (drawn with ``rng``) in a box the size of the largest range; the lowest
       stress wins (with ``robust_scale_m``: every start goes through the robust rounds below
       and the lowest robust cost wins — folds of a sparse urban network that the MDS start
       falls into are left this way).
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
        SMACOF iteration limit and relative tolerance, see
        :func:`~phyloc.localization.mds.smacof`.
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
    solver : {"dense", "sparse", "auto"}
        ``"dense"`` (default): the ``n × n`` matrices above. ``"sparse"``: the same steps on
        the measured pairs only (:mod:`phyloc.localization.sparse_start`: landmark MDS instead
        of the all-pairs completion, SMACOF on the pairs' Laplacian, relocation around each
        node's neighbours) — for range-limited networks, whose cost it keeps linear in the
        links; a disconnected range graph is no error there (each component is solved on its
        own, centred; its nodes are flagged ``undetermined``). ``"auto"``: sparse above
        :data:`SPARSE_ABOVE_NODES` nodes.

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
    v.choice("solver", solver, SOLVERS)
    if solver == "auto":
        solver = "sparse" if n > SPARSE_ABOVE_NODES else "dense"
    restarts = v.integer("n_restarts", n_restarts, minimum=0)
    if restarts:
        _rng(rng)
    if solver == "sparse":
        lk, r, ok, w_bad = _link_ranges(links, ranges, n, valid, combine, invalid_weight)
    else:
        D, W = range_matrix(links, ranges, n, valid, combine=combine, invalid_weight=invalid_weight)
    if robust_scale_m is not None:
        scales = np.atleast_1d(np.asarray(robust_scale_m, dtype=object))
        if scales.ndim != 1 or scales.size == 0:
            raise ValidationError("robust_scale_m", robust_scale_m, "a scale > 0 [m] or a list")
        scales = sorted({v.positive("robust_scale_m", c) for c in scales}, reverse=True)
        rounds = v.integer("robust_rounds", robust_rounds, minimum=1)

    robust = robust_scale_m is not None
    sparse_kw = {
        "rng": rng,
        "n_restarts": restarts,
        "n_iter": n_iter,
        "tol": tol,
        "scales": scales if robust else None,
        "rounds": rounds if robust else 1,
        "one_sided": one_sided,
    }
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
        if solver == "sparse":
            return _sparse_solution(lk, r, ok, w_bad, n, d, combine, anchor, A, **sparse_kw)
        dA = np.linalg.norm(A[:, None, :] - A[None, :, :], axis=-1)
        D[np.ix_(idx, idx)] = dA
        W[np.ix_(idx, idx)] = 1.0
        np.fill_diagonal(W, 0.0)
        np.fill_diagonal(D, 0.0)

    elif solver == "sparse":
        return _sparse_solution(lk, r, ok, w_bad, n, d, combine, anchor, None, **sparse_kw)
    measured = W
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
    i, j = np.nonzero(np.triu(measured, 1))
    g = PairGraph(n, i.astype(np.int64), j.astype(np.int64), D[i, j], measured[i, j])
    return CoarseSolution(
        positions=X,
        stress=float(s),
        residual_rms_m=rms,
        frame=frame,
        undetermined=undetermined_nodes(g, d, anchor),
    )


def _sparse_solution(lk, r, ok, w_bad, n, d, combine, anchor, A, **kw) -> CoarseSolution:
    """:func:`coarse_positions` with ``solver="sparse"`` (checked inputs; ``kw`` the options
    of :func:`~phyloc.localization.sparse_start.sparse_coarse_positions`)."""
    n_anchor = int(anchor.sum())
    idx = np.flatnonzero(anchor)
    g = pair_graph(lk, r, ok, n, combine, w_bad, anchors=(idx, A) if n_anchor else None)
    X, gw, s = sparse_coarse_positions(
        g, d, fixed=anchor if n_anchor else None, anchor_positions=A, **kw
    )
    if n_anchor:
        frame = "anchors" if _affine_rank(A) == d else "partial"
    else:
        frame = "arbitrary"
    n_pairs = int(np.count_nonzero(gw.w > 0))
    rms = float(np.sqrt(s / n_pairs)) if n_pairs else 0.0
    return CoarseSolution(
        positions=X,
        stress=float(s),
        residual_rms_m=rms,
        frame=frame,
        undetermined=undetermined_nodes(g, d, anchor),
    )
