"""POA-NBP Algorithm 1 over a whole static 2-D network: one support polygon per agent.

:func:`poa` intersects, per agent, the anchor polygons of its anchor neighbours (POA-NBP
Algorithm 2) and then, iteration by iteration, its neighbours' polygons grown by the ranges
(POA-NBP Algorithm 4), by Sutherland–Hodgman clipping (POA-NBP Algorithm 3); the operations are
those of :mod:`phyloc.localization.static.polygons`. With errors ``ε >= 0`` (POA-NBP eq. (11))
every polygon contains its agent; measurements that contradict the others are detected and
dropped (:func:`poa`, Notes). :class:`POAResult` records the polygons, their areas per
iteration (POA-NBP Fig. 9), the time, the operations and the floats exchanged (POA-NBP §V-C2).

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.static import _polygon_kernels as K
from phyloc.localization.static.polygons import (
    _PAPER_TURN,
    ConvexPolygon,
    _anchor_halfspaces,
    _anchor_vertices,
    _max_turn,
    _rng,
    _signed_area,
    _tol,
)


@dataclass(frozen=True, eq=False)
class POAResult:
    """Output of :func:`poa`.

    Attributes
    ----------
    agents : [n_agents], int
        Node index of each agent (the nodes that are not anchors), ascending.
    polygons : tuple of ConvexPolygon or None
        Final polygon ``V_j^{(N_FS)}`` per agent; ``None`` = unbounded (no anchor neighbour,
        no ``region`` and no bounded neighbour). Never empty.
    area_history : [n_iterations, n_agents], float
        Polygon area [m²] after iteration ``l = 1 … N_FS`` (row ``l − 1``); ``inf`` while
        unbounded. The curve of POA-NBP Fig. 9 is its mean over agents.
    time_s : [n_iterations, n_agents], float
        Wall time [s] spent on each agent in each iteration (its support halfspaces, scaling
        and clipping).
    dropped : [k, 2], int
        Dropped measurements as rows ``(i, j)``: agent ``j`` discarded its range to ``i``.
    dropped_iteration : [k], int
        Iteration (1-based) in which each measurement was dropped.
    n_edges : int
        ``N_E`` of the anchor polygons.
    operations : [n_iterations, n_agents], int
        Operations counted for each agent in each iteration, the ones of the complexity
        discussion of POA-NBP §V-C2: ``N_E`` per anchor polygon (Algorithm 2: one vertex, or
        its halfspace, per edge), one halfspace shift (POA-NBP eqs. (19), (20)) per edge of every
        neighbour polygon it scales (Algorithm 4; plus one vertex per edge where the scaled
        polygon's vertices are needed, i.e. as the first subject of an unbounded agent), and
        one vertex–halfspace test per vertex of the current list and clipping halfspace in
        Sutherland–Hodgman (Algorithm 3, ``O(|S_{→j}|·N_E²)``). Clipping by ``region`` is
        counted like any other clip. The support halfspaces each agent computes once from its
        own polygon before broadcasting are not counted (the receiver's shifts are).
    floats_per_link_iteration : float
        Floats one agent sends one agent neighbour per broadcast of Algorithm 1 (line 13):
        its polygon's vertices, 2 per vertex, averaged over the directed agent–agent links
        and the ``N_FS − 1`` broadcast iterations (NaN without any broadcast: ``N_FS = 1`` or
        no agent–agent link). Anchors send their position once (not counted).
    """

    agents: np.ndarray
    polygons: tuple
    area_history: np.ndarray
    time_s: np.ndarray
    dropped: np.ndarray
    dropped_iteration: np.ndarray
    n_edges: int
    operations: np.ndarray | None = None
    floats_per_link_iteration: float = math.nan

    @property
    def operations_per_node(self) -> float:
        """Mean over agents of :attr:`operations` summed over the iterations (0 without
        agents)."""
        if self.operations is None or self.operations.shape[1] == 0:
            return 0.0
        return float(self.operations.sum(axis=0).mean())

    def polygon_of(self, node) -> ConvexPolygon | None:
        """Final polygon of the agent with node index ``node`` (``None`` = unbounded)."""
        node = v.integer("node", node, minimum=0)
        hit = np.flatnonzero(self.agents == node)
        if hit.size == 0:
            raise ValidationError("node", node, "is not an agent of this result")
        return self.polygons[int(hit[0])]

    def mean_area(self) -> np.ndarray:
        """Mean area [m²] per iteration over the agents bounded from iteration 1 on
        (a fixed population, so the curve is comparable across iterations; POA-NBP Fig. 9).

        Returns ``inf`` per iteration when no agent is bounded from the start.
        """
        ok = np.all(np.isfinite(self.area_history), axis=0)
        if not ok.any():
            return np.full(self.area_history.shape[0], np.inf)
        return self.area_history[:, ok].mean(axis=1)


def _network_inputs(positions, ranges, anchors):
    """Validated ``(positions [N,2], z_used [N,N], is_anchor [N])``.

    ``z_used[j, i]`` is the range agent ``j`` uses for neighbour ``i``: ``ranges[j, i]`` when
    finite, else ``ranges[i, j]`` (so a one-sided matrix describes symmetric links); NaN = no
    link. The diagonal is ignored.
    """
    try:
        pos = np.array(positions, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError("positions", "<array>", "must convert to float64") from None
    if pos.ndim != 2 or pos.shape[1] != 2:
        raise ValidationError("positions", f"array of shape {pos.shape}", "must be (N, 2)")
    n = pos.shape[0]
    try:
        z = np.array(ranges, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError("ranges", "<array>", "must convert to float64") from None
    if z.shape != (n, n):
        raise ValidationError("ranges", f"array of shape {z.shape}", f"must be ({n}, {n})")
    if np.any(np.isinf(z)):
        raise ValidationError("ranges", "inf entry", "entries must be finite or NaN (no link)")
    a = np.asarray(anchors)
    if a.dtype == bool:
        if a.shape != (n,):
            raise ValidationError("anchors", f"mask of shape {a.shape}", f"must be ({n},)")
        is_anchor = a.copy()
    else:
        if a.ndim > 1 or (a.size and not np.issubdtype(a.dtype, np.integer)):
            raise ValidationError("anchors", a.dtype.name, "must be a bool mask or int indices")
        idx = a.astype(np.int64).ravel()
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise ValidationError("anchors", idx.tolist(), f"indices must be in [0, {n})")
        if np.unique(idx).size != idx.size:
            raise ValidationError("anchors", idx.tolist(), "indices must be unique")
        is_anchor = np.zeros(n, dtype=bool)
        is_anchor[idx] = True
    if not np.all(np.isfinite(pos[is_anchor])):
        raise ValidationError("positions", "non-finite anchor row", "anchor positions are known")
    used = np.where(np.isnan(z), z.T, z)
    np.fill_diagonal(used, np.nan)
    return pos, used, is_anchor


def _region(region) -> ConvexPolygon | None:
    if region is None:
        return None
    if isinstance(region, ConvexPolygon):
        R = region
    else:
        try:
            box = [float(x) for x in region]
        except (TypeError, ValueError):
            raise ValidationError(
                "region", type(region).__name__, "must be a ConvexPolygon, a box or None"
            ) from None
        if len(box) != 4:
            raise ValidationError("region", box, "a box is (xmin, ymin, xmax, ymax)")
        R = ConvexPolygon.from_box(*box)
    if R.area <= 0.0:
        raise ValidationError("region", "zero-area polygon", "must have a positive area")
    return R


def _clip(subject, groups_A, groups_c, tol):
    """Clip ``subject`` by the halfspace groups with dropping; returns (vertices, dropped,
    vertex–halfspace tests)."""
    off = np.zeros(len(groups_A) + 1, dtype=np.int64)
    off[1:] = np.cumsum([a.shape[0] for a in groups_A])
    A = np.concatenate(groups_A) if groups_A else np.empty((0, 2))
    c = np.concatenate(groups_c) if groups_c else np.empty(0)
    return K.clip_groups_count_kernel(subject, A, c, off, tol, True)


_WARM = False


def _warmup() -> None:
    """Compile / load the kernels once so that the first timed agent does not pay for it."""
    global _WARM
    if _WARM:
        return
    sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    A, c, corner = K.support_halfspaces_kernel(sq, _PAPER_TURN)
    K.scaled_vertices_kernel(A, corner, 1.0, 1e-12)
    K.clip_groups_kernel(sq, A, c, np.array([0, 4], dtype=np.int64), 1e-12, True)
    K.clip_groups_count_kernel(sq, A, c, np.array([0, 4], dtype=np.int64), 1e-12, True)
    K.mvee_kernel(sq, 1e-6, 10)
    _WARM = True


def poa(
    positions,
    ranges,
    anchors,
    *,
    rng,
    n_edges: int = 16,
    n_iterations: int = 2,
    region=None,
    max_turn_rad=None,
) -> POAResult:
    """Polygon support outer-approximation of a whole static 2-D network (POA-NBP Algorithm 1).

    Iteration ``l = 1`` (POA-NBP Algorithm 1, lines 4–11): agent ``j`` starts from ``region``
    (the prior support, if given) and intersects it with the anchor polygons (POA-NBP
    Algorithm 2) of its anchor neighbours, each with its own angular offset
    ``α_0 ~ U[0, 2π/N_E)`` drawn from ``rng``. Iterations ``l = 2 … N_FS`` (lines 12–20), Jacobi
    schedule: every agent intersects its current polygon with the polygons of its agent
    neighbours from iteration ``l − 1`` scaled by the range (POA-NBP Algorithm 4), by
    Sutherland–Hodgman (POA-NBP Algorithm 3). Keeping the agent's own polygon in the
    intersection keeps its anchor constraints and makes the area non-increasing. With errors
    ``ε >= 0`` (POA-NBP eq. (11)) every polygon contains its agent.

    Parameters
    ----------
    positions : [N, 2], float
        Node positions [m]; only the anchors' rows are read (agents' rows may be NaN).
    ranges : [N, N], float
        ``ranges[j, i]`` = range [m] measured between ``j`` and ``i``, NaN = no link. Agent
        ``j`` uses ``ranges[j, i]`` and, where that is NaN, ``ranges[i, j]`` (so an upper
        triangle alone describes symmetric links). Links between anchors are ignored.
    anchors : [N] bool or [n_anchors] int
        Anchor mask or indices: nodes with known positions.
    rng : numpy.random.Generator
        Draws the anchor-polygon offsets, one per anchor link, in the order (agent, anchor).
    n_edges : int
        ``N_E >= 3`` edges of the anchor polygons (paper: 16).
    n_iterations : int
        ``N_FS >= 1``; iteration 1 is the anchor step (paper: ``N_FS = 2``).
    region : ConvexPolygon or (xmin, ymin, xmax, ymax) or None
        Deployment area, the support of the uniform prior (e.g. the 100 m × 100 m square of
        POA-NBP §V-A); every agent's polygon starts as ``region``. ``None``: agents without anchor
        neighbours are unbounded (``None`` polygon, area ``inf``) until a bounded neighbour
        constrains them; unbounded neighbours are skipped.
    max_turn_rad : float or None
        Corner splitting of :func:`~phyloc.localization.static.polygons.scale_polygon`
        (``None`` = POA-NBP Algorithm 4).

    Returns
    -------
    POAResult

    Notes
    -----
    **Negative ranging errors.** Without the truth, a negative error is detectable only as an
    inconsistency, and POA detects exactly two kinds:

    * a negative range estimate ``ẑ < 0`` (no disk has negative radius), and
    * a constraint whose polygon does not meet the agent's current polygon: the intersection
      would be empty, so the measurements used so far cannot all satisfy POA-NBP eq. (11).

    Such a measurement is dropped (the polygon before it is kept, never an empty one), for
    this and all later iterations, and recorded in :attr:`POAResult.dropped`. Constraints are
    applied in the order: ``region``, anchors, then agent neighbours by node index. A
    constraint that does not meet the polygon of the constraints before it is the one
    dropped; when several *new* measurements contradict only each other, the later one is
    dropped even if the earlier one carried the negative error — inconsistency shows that
    some measurement is wrong, not which. A negative error that shrinks the polygon without
    emptying it is undetectable; the polygon may then miss the agent (and the error
    propagates to neighbours). Measurements contradicting the agent's polygon from the
    previous iteration are always the ones dropped, whatever their order.

    Examples
    --------
    >>> import numpy as np
    >>> pos = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [3.0, 4.0]])
    >>> d = np.linalg.norm(pos[:, None] - pos[None], axis=-1) + 0.1
    >>> res = poa(pos, d, [0, 1, 2], rng=np.random.default_rng(0))
    >>> bool(res.polygons[0].contains(pos[3])[0])
    True
    """
    pos, z, is_anchor = _network_inputs(positions, ranges, anchors)
    rng = _rng(rng)
    n_edges = v.integer("n_edges", n_edges, minimum=3)
    n_iter = v.integer("n_iterations", n_iterations, minimum=1)
    R = _region(region)
    turn = _max_turn(max_turn_rad)
    _warmup()

    agents = np.flatnonzero(~is_anchor)
    anchor_idx = np.flatnonzero(is_anchor)
    slot = np.full(pos.shape[0], -1, dtype=np.int64)
    slot[agents] = np.arange(agents.size)
    finite_z = z[np.isfinite(z)]
    tol = _tol(pos[is_anchor], finite_z, R.vertices if R is not None else np.empty(0))
    alpha = 2.0 * math.pi / n_edges

    link = np.isfinite(z)
    anchor_links = [anchor_idx[link[j, anchor_idx]] for j in agents]
    offsets = rng.uniform(0.0, alpha, size=sum(a.size for a in anchor_links))

    polys: list[np.ndarray | None] = [None] * agents.size
    areas = np.empty((n_iter, agents.size))
    times = np.zeros((n_iter, agents.size))
    ops = np.zeros((n_iter, agents.size), dtype=np.int64)
    sent_floats, sent_links = 0, 0
    dropped: list[tuple[int, int, int]] = []
    bad = set()

    # l = 1: region ∩ anchor polygons (POA-NBP Algorithm 1 lines 4–11, Algorithm 2)
    k = 0
    for a, j in enumerate(agents):
        t0 = time.perf_counter()
        gA, gc, nb = [], [], []
        for i in anchor_links[a]:
            zz, off = float(z[j, i]), float(offsets[k])
            k += 1
            if zz < 0.0:
                dropped.append((int(i), int(j), 1))
                bad.add((int(i), int(j)))
                continue
            A, c = _anchor_halfspaces(pos[i], zz, n_edges, off)
            ops[0, a] += n_edges  # Algorithm 2: one vertex (halfspace) per edge
            gA.append(A)
            gc.append(c)
            nb.append((int(i), zz, off))
        if R is not None:
            subject = R.vertices
        elif nb:
            i0, z0, o0 = nb[0]
            subject = _anchor_vertices(pos[i0], z0, n_edges, o0)
            gA, gc, nb = gA[1:], gc[1:], nb[1:]
        else:
            subject = None
        if subject is not None:
            out, drop, n_tests = _clip(subject, gA, gc, tol)
            ops[0, a] += n_tests
            for g in np.flatnonzero(drop):
                dropped.append((nb[g][0], int(j), 1))
                bad.add((nb[g][0], int(j)))
            polys[a] = out
        times[0, a] += time.perf_counter() - t0
        areas[0, a] = _area(polys[a])

    # l = 2 … N_FS: scaled neighbour polygons (POA-NBP Algorithm 1 lines 12–20, Algorithm 4)
    for it in range(1, n_iter):
        support = [None] * agents.size
        for a in range(agents.size):
            if polys[a] is not None:
                t0 = time.perf_counter()
                support[a] = K.support_halfspaces_kernel(polys[a], turn)
                times[it, a] += time.perf_counter() - t0
        new = list(polys)
        for a, j in enumerate(agents):
            t0 = time.perf_counter()
            gA, gc, nb = [], [], []
            for i in np.flatnonzero(link[j] & ~is_anchor):
                s = support[slot[i]]
                if s is not None:  # Algorithm 1 line 13: i broadcasts its vertices
                    sent_floats += 2 * polys[slot[i]].shape[0]
                    sent_links += 1
                if s is None or (int(i), int(j)) in bad:
                    continue
                zz = float(z[j, i])
                if zz < 0.0:
                    dropped.append((int(i), int(j), it + 1))
                    bad.add((int(i), int(j)))
                    continue
                gA.append(s[0])
                gc.append(s[1] + zz)  # one shift per halfspace, POA-NBP eqs. (19)-(20)
                ops[it, a] += s[0].shape[0]
                nb.append((int(i), zz))
            if gA:
                subject = polys[a]
                if subject is None:
                    s = support[slot[nb[0][0]]]
                    subject = K.scaled_vertices_kernel(s[0], s[2], nb[0][1], tol)
                    ops[it, a] += s[0].shape[0]  # Algorithm 4 line 6: the scaled vertices
                    gA, gc, nb = gA[1:], gc[1:], nb[1:]
                out, drop, n_tests = _clip(subject, gA, gc, tol)
                ops[it, a] += n_tests
                for g in np.flatnonzero(drop):
                    dropped.append((nb[g][0], int(j), it + 1))
                    bad.add((nb[g][0], int(j)))
                new[a] = out
            times[it, a] += time.perf_counter() - t0
        polys = new
        for a in range(agents.size):
            areas[it, a] = _area(polys[a])
    return POAResult(
        agents=agents,
        polygons=tuple(None if w is None else ConvexPolygon._trusted(w) for w in polys),
        area_history=areas,
        time_s=times,
        dropped=np.array([(i, j) for i, j, _ in dropped], dtype=np.int64).reshape(-1, 2),
        dropped_iteration=np.array([it for _, _, it in dropped], dtype=np.int64),
        n_edges=n_edges,
        operations=ops,
        floats_per_link_iteration=sent_floats / sent_links if sent_links else math.nan,
    )


def _area(w: np.ndarray | None) -> float:
    if w is None:
        return math.inf
    return max(_signed_area(w), 0.0) if w.shape[0] >= 3 else 0.0
