"""Localization metrics: framework distance RMSE, shape difference, error CDF, outage, RMSE.

Frameworks (DiPNet §II-A) are compared node by node: ``est`` and ``true`` are ``[n_nodes, dim]``
arrays in the same node order, ``is_anchor`` flags the anchors (``None``: every node is an
agent). Conventions shared by every function here:

- **Anchors are known.** An anchor row of ``est`` that is NaN is replaced by the true anchor
  position; a finite anchor row is used as given (so a rigidly moved copy of the whole framework
  is handled consistently).
- **Missing estimates.** An agent row of ``est`` with any NaN is *missing*. With
  ``missing="error"`` (default) a :class:`~phyloc.errors.ValidationError` names the rows; with
  ``missing="exclude"`` the missing agents are left out (of the pairs, the fit, the mean) and
  the functions that can say how many were used do so (``return_pairs``, ``return_counts``).
  ``±inf`` is always an error. A metric left with nothing to average raises, it never returns
  NaN.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

W. Kabsch, "A solution for the best rotation to relate two sets of vectors," Acta Cryst. A32,
1976.

S. Umeyama, "Least-squares estimation of transformation parameters between two point
patterns," IEEE Trans. PAMI 13(4), 1991.
"""

from __future__ import annotations

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.network.geometry import kabsch, orthogonal_fit

MISSING = ("error", "exclude")


def _missing_mode(missing) -> str:
    if missing not in MISSING:
        raise ValidationError("missing", missing, "must be 'error' or 'exclude'")
    return missing


def _frames(est, true, is_anchor, missing):
    """Validated ``(q, p, anchor, present)``: est with anchors filled, truth, masks."""
    mode = _missing_mode(missing)
    p = v.finite_array("true", true, ndim=2)
    n, dim = p.shape
    if n < 1 or dim < 1:
        raise ValidationError("true", f"array of shape {p.shape}", "must be [n_nodes >= 1, dim]")
    try:
        q = np.array(est, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError("est", "<array>", "must convert to float64") from None
    if q.shape != p.shape:
        raise ValidationError("est", f"array of shape {q.shape}", f"must match true {p.shape}")
    if np.isinf(q).any():
        raise ValidationError("est", "inf", "entries must be finite or NaN (missing)")
    if is_anchor is None:
        anchor = np.zeros(n, dtype=bool)
    else:
        anchor = np.asarray(is_anchor)
        if anchor.dtype != np.bool_ or anchor.shape != (n,):
            raise ValidationError(
                "is_anchor",
                f"{anchor.dtype} array of shape {anchor.shape}",
                f"must be a bool array of shape ({n},) or None",
            )
    if anchor.all():
        raise ValidationError("is_anchor", "all True", "at least one node must be an agent")
    nan_row = np.isnan(q).any(axis=1)
    q[nan_row & anchor] = p[nan_row & anchor]
    missing_agents = np.flatnonzero(nan_row & ~anchor)
    if missing_agents.size and mode == "error":
        raise ValidationError(
            "est",
            f"NaN in agent rows {missing_agents[:10].tolist()}"
            + (" ..." if missing_agents.size > 10 else ""),
            f"{missing_agents.size} of {int((~anchor).sum())} agents have no estimate; "
            "pass missing='exclude' to leave them out",
        )
    present = ~(nan_row & ~anchor)
    if not (present & ~anchor).any():
        raise ValidationError("est", "NaN in every agent row", "no agent has an estimate")
    return q, p, anchor, present


def framework_distance_errors(
    est, true, is_anchor=None, *, missing: str = "error", return_pairs: bool = False, pairs=None
):
    """Absolute framework distance errors ``ε_uv = |d̂_uv − d_uv|`` (DiPNet eq. (4) summands).

    Following the double sum of DiPNet eq. (4) exactly, ``u`` runs over the agents and ``v``
    over every other node: an agent–agent pair appears twice, as ``(u, v)`` and ``(v, u)``, an
    agent–anchor pair once, an anchor–anchor pair never. All pairs count, linked or not.

    With ``pairs`` (ordered ``(u, v)``, e.g. the directed links of a range-limited network)
    the sum runs over those pairs whose ``u`` is an agent: DiPNet eq. (4) over the edges of the
    framework's graph, which for a fully meshed network are all its pairs. A network of a
    thousand agents has ~10⁶ pairs but ~2.5·10⁴ links: over the links the metric costs what
    the links cost, and scores the distances the network measures.

    Parameters
    ----------
    est : [n_nodes, dim] float64
        Estimated positions ``q`` [m]; NaN rows: see the module docstring.
    true : [n_nodes, dim] float64
        True positions ``p`` [m].
    is_anchor : [n_nodes] bool, optional
        Anchor flags; ``None``: all nodes are agents (anchor-free).
    missing : {"error", "exclude"}
        Missing agent estimates raise, or every pair involving one is dropped.
    return_pairs : bool
        Also return the ordered pairs.

    Returns
    -------
    errors : [n_pairs] float64
        ``|‖q_u − q_v‖ − ‖p_u − p_v‖|`` [m], ``n_pairs = |M|(|V|−1)`` when nothing is
        missing; pairs sorted by ``(u, v)``.
    pairs : [n_pairs, 2] int64
        ``(u, v)``, only with ``return_pairs``.
    """
    q, p, anchor, present = _frames(est, true, is_anchor, missing)
    n = p.shape[0]
    if pairs is None:
        keep = (~anchor & present)[:, None] & present[None, :] & ~np.eye(n, dtype=bool)
        pairs = np.argwhere(keep).astype(np.int64)
    else:
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        if pairs.size and (pairs.min() < 0 or pairs.max() >= n):
            raise ValidationError("pairs", "node index out of range", f"indices in [0, {n})")
        u, w = pairs[:, 0], pairs[:, 1]
        pairs = pairs[~anchor[u] & present[u] & present[w] & (u != w)]
    u, w = pairs[:, 0], pairs[:, 1]
    errors = np.abs(np.linalg.norm(q[u] - q[w], axis=1) - np.linalg.norm(p[u] - p[w], axis=1))
    return (errors, pairs) if return_pairs else errors


def framework_distance_rmse(est, true, is_anchor=None, *, missing: str = "error") -> float:
    """Framework distance RMSE ``ε_d`` (DiPNet eq. (4)).

    .. math::

        \\varepsilon_d = \\sqrt{\\frac{
            \\sum_{u \\in \\mathcal{M}} \\sum_{v \\in \\mathcal{V} \\setminus u}
            \\varepsilon_{uv}^2}{|\\mathcal{M}|(|\\mathcal{V}|-1)}}

    invariant to any rigid transform (rotation, translation, reflection) of the whole estimated
    framework. With ``missing="exclude"`` the mean runs over the remaining pairs.

    Parameters
    ----------
    est, true, is_anchor, missing
        See :func:`framework_distance_errors`.

    Returns
    -------
    float
        [m].

    Raises
    ------
    ValidationError
        When there is no pair (a single node, or every partner missing).

    Examples
    --------
    Moving node 1 of a 3-4-5 triangle by 1 m changes d_01 by 1 m and d_12 by √32 − 5 m;
    each error is counted twice among the 6 ordered pairs:

    >>> true = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])
    >>> est = true + [[0, 0], [1, 0], [0, 0]]
    >>> bool(np.isclose(framework_distance_rmse(est, true),
    ...                 np.sqrt((2 * 1.0**2 + 2 * (np.sqrt(32) - 5) ** 2) / 6)))
    True
    """
    errors = framework_distance_errors(est, true, is_anchor, missing=missing)
    if errors.size == 0:
        raise ValidationError(
            "est", "no node pair", "the framework distance needs at least 2 nodes with estimates"
        )
    return float(np.sqrt(np.mean(errors**2)))


def rigid_align(est, true, *, is_anchor=None, reflection: bool = True, missing: str = "error"):
    """Optimal rigid transform ``T(x) = R x + t`` of the estimates onto the truth.

    Without anchors, ``(R, t)`` minimises ``Σ_{u∈M} ‖R q_u + t − p_u‖²`` over rotations (and
    reflections, if ``reflection``) and translations — Kabsch/Umeyama without scaling: with
    ``H = Σ (q_u − q̄)(p_u − p̄)ᵀ = U S Vᵀ``, ``R = V D Uᵀ``, ``D = I`` or
    ``diag(1, …, 1, det(V Uᵀ))``, ``t = p̄ − R q̄``.

    With anchors, ``T`` keeps the anchors at their true positions (DiPNet eq. (3)) and uses the
    remaining freedom for the agents:

    1. ``T₀``: the rigid least-squares fit of the anchor estimates onto the true anchors.
    2. If the transformed anchors span the space (>= dim + 1 affinely independent anchors),
       ``T = T₀`` (a rigid map fixing dim + 1 independent points is the identity, so the agents
       leave no freedom).
    3. Otherwise they span an affine subspace ``c + span(B)`` of dimension ``k < dim`` (1 anchor:
       a point; 2 anchors, or collinear ones: a line; coplanar anchors in 3-D: a plane). The
       transforms fixing it pointwise are ``x ↦ c + BBᵀ(x − c) + C W Cᵀ(x − c)``, ``C`` the
       orthonormal complement of ``B``, ``W`` orthogonal on the complement (``det W = +1``
       unless ``reflection``); ``W`` is fitted to the agents by the same SVD without centring.
       E.g. 1 anchor: a rotation about it; 2 anchors in 2-D: the identity or, with
       ``reflection``, the mirror across their line.

    If the anchor estimates equal the true anchors, the anchors stay exactly in place; if they
    are not congruent to them, step 1 is a least-squares compromise.

    Degenerate frameworks (a single agent, 2 nodes, collinear nodes) have several optimal
    transforms; one of them is returned (the residual, hence :func:`shape_difference`, is
    unique). No output is NaN unless its ``est`` row was a missing agent.

    Parameters
    ----------
    est : [n_nodes, dim] float64
        Estimated positions ``q`` [m] (see the module docstring for NaN rows).
    true : [n_nodes, dim] float64
        True positions ``p`` [m].
    is_anchor : [n_nodes] bool, optional
        ``None``: anchor-free.
    reflection : bool
        Allow improper transforms (``det R = −1``, "flipping" in DiPNet §II-A). Default True.
    missing : {"error", "exclude"}
        Missing agents raise, or are left out of the fit (their aligned rows stay NaN).

    Returns
    -------
    R : [dim, dim] float64
        Orthogonal; ``det R = +1`` unless ``reflection``.
    t : [dim] float64
        [m].
    aligned : [n_nodes, dim] float64
        ``est @ R.T + t`` (anchor rows that were NaN: their transformed true positions).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> p = rng.uniform(0, 10, size=(5, 2))
    >>> R0 = np.array([[0.0, -1.0], [1.0, 0.0]])
    >>> R, t, aligned = rigid_align(p @ R0.T + 3.0, p)
    >>> bool(np.allclose(aligned, p))
    True
    """
    q, p, anchor, present = _frames(est, true, is_anchor, missing)
    dim = p.shape[1]
    agents = ~anchor & present
    if not anchor.any():
        r, t = kabsch(q[agents], p[agents], reflection)
    else:
        r0, t0 = kabsch(q[anchor], p[anchor], reflection)
        ya = q[anchor] @ r0.T + t0
        c = ya.mean(axis=0)
        _, s, vt = np.linalg.svd(ya - c, full_matrices=True)
        scale = max(1.0, float(np.abs(ya).max()))
        k = int(np.sum(s > 1e-9 * scale))
        if k == dim:
            r, t = r0, t0
        else:
            b, cc = vt[:k].T, vt[k:].T
            y = q[agents] @ r0.T + t0
            w = orthogonal_fit((y - c) @ cc, (p[agents] - c) @ cc, reflection)
            s_map = b @ b.T + cc @ w @ cc.T
            r = s_map @ r0
            t = c + s_map @ (t0 - c)
    aligned = q @ r.T + t
    return r, t, aligned


def shape_difference(
    est, true, is_anchor=None, *, reflection: bool = True, missing: str = "error"
) -> float:
    """Average shape difference ``ε_{q,p}`` (DiPNet eq. (1)).

    .. math::

        \\varepsilon_{q,p} = \\sqrt{\\frac{1}{|\\mathcal{M}|}
        \\sum_{u \\in \\mathcal{M}} \\| \\mathcal{T}_{opt}(q_u) - p_u \\|^2}

    with ``T_opt`` from :func:`rigid_align` (anchors kept at their true positions, DiPNet
    eq. (3)). The sum runs over the agents (the anchors' residual is zero when their estimates
    are exact).
    With ``missing="exclude"`` the mean runs over the agents with an estimate.

    Parameters
    ----------
    est, true, is_anchor, reflection, missing
        See :func:`rigid_align`.

    Returns
    -------
    float
        [m]. Invariant to rotating, translating (and, with ``reflection``, mirroring) the whole
        estimated framework.

    Examples
    --------
    >>> true = np.array([[0.0, 0.0], [2.0, 0.0]])
    >>> shape_difference(np.array([[5.0, 5.0], [5.0, 8.0]]), true)  # |3 − 2| / 2
    0.5
    """
    q, p, anchor, present = _frames(est, true, is_anchor, missing)
    _, _, aligned = rigid_align(q, p, is_anchor=anchor, reflection=reflection, missing="exclude")
    agents = ~anchor & present
    return float(np.sqrt(np.mean(np.sum((aligned[agents] - p[agents]) ** 2, axis=1))))


def _errors_1d(errors) -> np.ndarray:
    e = np.asarray(errors, dtype=np.float64).ravel()
    if e.size == 0:
        raise ValidationError("errors", "empty", "at least one error value is needed")
    if not np.all(np.isfinite(e)):
        bad = int(np.flatnonzero(~np.isfinite(e))[0])
        raise ValidationError(
            "errors", f"{e[bad]} at index {bad}", "must be finite (drop missing estimates first)"
        )
    return e


def error_cdf(errors, grid=None) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF ``F(x) = #{e_i <= x} / n`` of absolute errors.

    Parameters
    ----------
    errors : array_like float64
        Errors [m], any shape (flattened), finite, at least one.
    grid : [n_grid] float64, optional
        Where to evaluate ``F``. Default: the distinct error values, ascending (the jumps of the
        step function).

    Returns
    -------
    x : [n_x] float64
    F : [n_x] float64
        Non-decreasing, in [0, 1].

    Examples
    --------
    >>> error_cdf([0.5, 0.1, 0.5, 2.0])
    (array([0.1, 0.5, 2. ]), array([0.25, 0.75, 1.  ]))
    """
    e = np.sort(_errors_1d(errors))
    x = np.unique(e) if grid is None else v.finite_array("grid", grid, ndim=1)
    return x, np.searchsorted(e, x, side="right") / e.size


def outage_probability(errors, thresholds) -> np.ndarray:
    """Outage probability ``P(e > threshold)`` (PF-BP §VI: errors above the threshold).

    Parameters
    ----------
    errors : array_like float64
        Errors [m], any shape (flattened), finite, at least one.
    thresholds : array_like float64
        Thresholds [m], finite, any shape.

    Returns
    -------
    P : float64 array shaped like ``thresholds``
        ``1 − F(threshold)`` with ``F`` from :func:`error_cdf`.
    """
    e = np.sort(_errors_1d(errors))
    thr = v.finite_array("thresholds", thresholds)
    return (e.size - np.searchsorted(e, thr, side="right")) / e.size


def rmse_per_snapshot(est, true, mask=None, *, missing: str = "error", return_counts: bool = False):
    """RMSE per snapshot ``sqrt(mean_u ‖x̂_u^{(k)} − x_u^{(k)}‖²)`` (PF-BP §VI RMSE_p).

    Works for positions, velocities or accelerations alike.

    Parameters
    ----------
    est : [T, n, dim] float64
        Estimates; a row with any NaN is missing.
    true : [T, n, dim] float64
        Truth, finite.
    mask : [n] or [T, n] bool, optional
        Nodes included (e.g. ``~is_anchor``); default all.
    missing : {"error", "exclude"}
        Missing included rows raise, or are left out of their snapshot's mean.
    return_counts : bool
        Also return how many nodes entered each snapshot's mean.

    Returns
    -------
    rmse : [T] float64
        [unit of the input].
    counts : [T] int64
        Only with ``return_counts``.

    Raises
    ------
    ValidationError
        A missing row with ``missing="error"``; a snapshot with no node left to average.
    """
    mode = _missing_mode(missing)
    x = v.finite_array("true", true, ndim=3)
    try:
        xh = np.asarray(est, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError("est", "<array>", "must convert to float64") from None
    if xh.shape != x.shape:
        raise ValidationError("est", f"array of shape {xh.shape}", f"must match true {x.shape}")
    if np.isinf(xh).any():
        raise ValidationError("est", "inf", "entries must be finite or NaN (missing)")
    T, n, _ = x.shape
    if mask is None:
        sel = np.ones((T, n), dtype=bool)
    else:
        m = np.asarray(mask)
        if m.dtype != np.bool_ or m.shape not in ((n,), (T, n)):
            raise ValidationError(
                "mask",
                f"{m.dtype} array of shape {m.shape}",
                f"must be bool of shape ({n},) or ({T}, {n})",
            )
        sel = np.broadcast_to(m, (T, n))
    nan_row = np.isnan(xh).any(axis=2) & sel
    if nan_row.any() and mode == "error":
        k, u = np.argwhere(nan_row)[0]
        raise ValidationError(
            "est",
            f"NaN at snapshot {k}, node {u}",
            f"{int(nan_row.sum())} included rows have no estimate; pass missing='exclude' "
            "to leave them out",
        )
    use = sel & ~nan_row
    counts = use.sum(axis=1)
    if np.any(counts == 0):
        empty = np.flatnonzero(counts == 0)
        raise ValidationError(
            "est", f"snapshots {empty[:10].tolist()}", "no included node has an estimate there"
        )
    sq = np.where(use, np.sum((np.where(use[..., None], xh, 0.0) - x) ** 2, axis=2), 0.0)
    rmse = np.sqrt(sq.sum(axis=1) / counts)
    return (rmse, counts.astype(np.int64)) if return_counts else rmse
