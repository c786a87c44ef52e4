"""Polygon support outer-approximation (POA) for 2-D static networks.

Mendrzik & Bauch, "Position-Constrained Stochastic Inference for Cooperative Indoor
Localization" ("POA-NBP"). With non-negative ranging errors, POA-NBP eq. (11)
``‖x_i − x_j‖ <= ẑ_{i→j}``, agent ``j`` lies in the disk of radius ``ẑ_{i→j}`` around an
anchor ``i`` (POA-NBP eq. (15)) and in the polygon of a neighbour agent ``i`` grown by
``ẑ_{i→j}``. POA (POA-NBP Algorithm 1) keeps one convex polygon per agent that contains the
agent with certainty, built from three operations:

* :func:`anchor_polygon` — the regular ``N_E``-gon circumscribing an anchor disk
  (POA-NBP Algorithm 2, eqs. (15)–(17));
* :func:`intersect` — Sutherland–Hodgman clipping (POA-NBP Algorithm 3, halfspaces of
  POA-NBP eq. (18));
* :func:`scale_polygon` — every supporting halfspace shifted outward by the range
  (POA-NBP Algorithm 4, eqs. (18)–(20)); the result contains the Minkowski sum of the
  polygon and the disk.

:func:`poa` runs POA-NBP Algorithm 1 over a whole network and
:func:`ellipse_outer_approximation` is the ellipse baseline of POA-NBP Fig. 9 (its ellipses
as proposal supports: :class:`EllipseRegion`). :class:`ConvexPolygon` carries the samplers of
POA-NBP §IV-B: exact uniform sampling (POA-NBP eq. (21)) and the paper's rejection sampling
from the bounding box with acceptance rate POA-NBP eq. (22).

Conventions: positions in metres, arrays ``float64``; a polygon's vertices are ``(m, 2)``
counter-clockwise (CCW); ``m = 0`` is the empty set, ``m = 1`` a point and ``m = 2`` a segment
(degenerate polygons arise from zero ranges and tangent disks and are handled without NaN).
Computations keep points within ``1e-12 ×`` the coordinate scale outside a halfspace, so
rounding never cuts off a feasible point. Numba kernels live in
:mod:`phyloc.localization.static._polygon_kernels`.

References
----------
R. Mendrzik and G. Bauch, "Position-Constrained Stochastic Inference for Cooperative
Indoor Localization." ("POA-NBP").
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.static import _polygon_kernels as K

_TOL_REL = 1e-12
"""Relative length tolerance of the geometry (times the coordinate scale, at least 1 m)."""

_PAPER_TURN = math.pi - 1e-3
"""Largest normal turn left unsplit by :func:`scale_polygon` in the paper's mode (``None``)."""


# -- input checks -------------------------------------------------------------------------------
def _rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return rng


def _polygon(name: str, P) -> ConvexPolygon:
    if not isinstance(P, ConvexPolygon):
        raise ValidationError(name, type(P).__name__, "must be a ConvexPolygon")
    return P


def _max_turn(max_turn_rad) -> float:
    if max_turn_rad is None:
        return _PAPER_TURN
    t = v.positive("max_turn_rad", max_turn_rad)
    if t > math.pi:
        raise ValidationError("max_turn_rad", max_turn_rad, "must be in (0, π] or None")
    return min(t, _PAPER_TURN)


def _tol(*arrays) -> float:
    scale = 1.0
    for a in arrays:
        if a.size:
            scale = max(scale, float(np.max(np.abs(a))))
    return _TOL_REL * scale


def _points(name: str, points) -> np.ndarray:
    p = v.finite_array(name, points)
    if p.ndim == 1 and p.size == 2:
        p = p.reshape(1, 2)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValidationError(name, f"array of shape {p.shape}", "must be (n, 2) or (2,)")
    return p


# -- the polygon --------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ConvexPolygon:
    """A closed convex polygon in the plane, vertices counter-clockwise.

    Parameters
    ----------
    vertices : [m, 2], float
        Vertices in order (CCW or clockwise; clockwise input is reversed) [m]. Repeated
        vertices and vertices on a straight run are removed; ``m = 0`` is the empty polygon,
        ``m = 1`` a point, ``m = 2`` a segment, and collinear input collapses to its two
        extreme points. Non-convex input raises :class:`~phyloc.errors.ValidationError`.

    Examples
    --------
    >>> import numpy as np
    >>> P = ConvexPolygon([[0, 0], [2, 0], [2, 1], [0, 1]])
    >>> P.area, P.centroid.tolist()
    (2.0, [1.0, 0.5])
    >>> P.contains([[1.0, 0.5], [3.0, 0.0]]).tolist()
    [True, False]
    >>> P.sample_uniform(4, np.random.default_rng(1)).shape
    (4, 2)
    """

    vertices: np.ndarray

    def __post_init__(self):
        arr = v.finite_array("vertices", self.vertices)
        if arr.size == 0:
            arr = np.empty((0, 2))
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise ValidationError("vertices", f"array of shape {arr.shape}", "must be (m, 2)")
        arr = arr.copy()
        tol = _tol(arr)
        if arr.shape[0] >= 3:
            arr = _dedupe(arr, tol)
        if arr.shape[0] >= 3:
            signed = _signed_area(arr)
            if signed < 0.0:
                arr = arr[::-1].copy()
            if not _collinear(arr, tol):
                _check_convex(arr, tol)
        m = K.clean_kernel(arr, arr.shape[0], tol)
        object.__setattr__(self, "vertices", _freeze(arr[:m].copy()))

    # construction helpers
    @classmethod
    def _trusted(cls, vertices: np.ndarray) -> ConvexPolygon:
        """Wrap kernel output (already CCW, convex and cleaned) without re-validation."""
        obj = object.__new__(cls)
        object.__setattr__(obj, "vertices", _freeze(np.ascontiguousarray(vertices, np.float64)))
        return obj

    @classmethod
    def empty(cls) -> ConvexPolygon:
        """The empty polygon (no vertices)."""
        return cls._trusted(np.empty((0, 2)))

    @classmethod
    def from_box(cls, xmin, ymin, xmax, ymax) -> ConvexPolygon:
        """The axis-aligned rectangle ``[xmin, xmax] × [ymin, ymax]`` [m]."""
        x0, y0 = v.finite("xmin", xmin), v.finite("ymin", ymin)
        x1, y1 = v.finite("xmax", xmax), v.finite("ymax", ymax)
        if x1 < x0:
            raise ValidationError("xmax", xmax, f"must be >= xmin = {x0}")
        if y1 < y0:
            raise ValidationError("ymax", ymax, f"must be >= ymin = {y0}")
        return cls([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    @classmethod
    def from_points(cls, points) -> ConvexPolygon:
        """Convex hull of ``points`` ``[n, 2]`` (Andrew's monotone chain), CCW."""
        p = v.finite_array("points", points)
        if p.size == 0:
            return cls.empty()
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValidationError("points", f"array of shape {p.shape}", "must be (n, 2)")
        p = np.unique(p, axis=0)  # sorted by x, then y
        if p.shape[0] <= 2:
            return cls(p)

        def chain(pts):
            out: list[np.ndarray] = []
            for q in pts:
                while len(out) >= 2 and _cross(out[-2], out[-1], q) <= 0.0:
                    out.pop()
                out.append(q)
            return out

        lower, upper = chain(p), chain(p[::-1])
        return cls(np.array(lower[:-1] + upper[:-1]))

    # properties
    @property
    def n_vertices(self) -> int:
        """Number of vertices ``m``."""
        return int(self.vertices.shape[0])

    @property
    def is_empty(self) -> bool:
        """True for the empty set (no vertices)."""
        return self.vertices.shape[0] == 0

    @property
    def area(self) -> float:
        """Area [m²] by the shoelace formula (0 for empty, point and segment); ``A_p`` of
        POA-NBP eq. (21)."""
        if self.vertices.shape[0] < 3:
            return 0.0
        return max(_signed_area(self.vertices), 0.0)

    @property
    def centroid(self) -> np.ndarray:
        """Area centroid ``[2]`` [m]; the vertex mean for a point or a segment.

        Raises :class:`~phyloc.errors.ValidationError` for the empty polygon (no centroid).
        """
        w = self.vertices
        if w.shape[0] == 0:
            raise ValidationError("polygon", "empty", "the empty polygon has no centroid")
        if w.shape[0] < 3:
            return w.mean(axis=0)
        d = w - w[0]
        e1, e2 = d[1:-1], d[2:]
        a = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        tot = a.sum()
        if tot <= 0.0:
            return w.mean(axis=0)
        return w[0] + (a[:, None] * (e1 + e2)).sum(axis=0) / (3.0 * tot)

    @property
    def bounding_box(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` [m], the rectangle of the rejection sampler (POA-NBP §IV-B).

        Raises :class:`~phyloc.errors.ValidationError` for the empty polygon.
        """
        w = self.vertices
        if w.shape[0] == 0:
            raise ValidationError("polygon", "empty", "the empty polygon has no bounding box")
        lo, hi = w.min(axis=0), w.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    def halfspaces(self) -> tuple[np.ndarray, np.ndarray]:
        """Halfspace form ``(A [k, 2], c [k])``: ``x`` is inside ⇔ ``A x <= c`` (POA-NBP eq. (18)).

        Row ``m`` belongs to edge ``v_m → v_{m+1}``: unit outward normal
        ``a_m ⊥ (v_{m+1} − v_m)`` and ``c_m = a_m·v_m``. A segment gives its two sides and
        two end caps (``k = 4``), a point the four axis halfspaces through it, and the empty
        polygon the contradictory pair ``x <= −1, −x <= −1``.
        """
        w = self.vertices
        m = w.shape[0]
        if m == 0:
            return np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([-1.0, -1.0])
        if m == 1:
            A = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
            return A, A @ w[0]
        if m == 2:
            d = (w[1] - w[0]) / np.linalg.norm(w[1] - w[0])
            nrm = np.array([d[1], -d[0]])
            A = np.array([nrm, d, -nrm, -d])
            return A, np.array([nrm @ w[0], d @ w[1], -nrm @ w[0], -d @ w[0]])
        d = np.roll(w, -1, axis=0) - w
        A = np.column_stack([d[:, 1], -d[:, 0]]) / np.hypot(d[:, 0], d[:, 1])[:, None]
        return A, np.einsum("ij,ij->i", A, w)

    def contains(self, points, tol: float = 1e-9) -> np.ndarray:
        """Whether each point lies in the polygon (within ``tol`` metres of it).

        Parameters
        ----------
        points : [n, 2] or [2], float
            Query points [m].
        tol : float
            Slack [m] added to every halfspace offset (``A x <= c + tol``).

        Returns
        -------
        inside : [n], bool
            All False for the empty polygon.
        """
        p = _points("points", points)
        t = v.positive("tol", tol, allow_zero=True)
        if self.is_empty:
            return np.zeros(p.shape[0], dtype=bool)
        A, c = self.halfspaces()
        return K.contains_kernel(A, c, p, t)

    def sample_uniform(self, n, rng) -> np.ndarray:
        """``n`` points uniform in the polygon — the proposal ``q`` of POA-NBP eq. (21), exactly.

        Triangle fan from vertex 0: a triangle is chosen with probability proportional to its
        area, then a point uniform in it (two uniforms folded by reflection). A segment is
        sampled uniformly along it, a point is repeated. Draws ``rng.random((n, 3))``.

        Raises :class:`~phyloc.errors.ValidationError` for ``n > 0`` on the empty polygon.
        """
        n = v.integer("n", n, minimum=0)
        rng = _rng(rng)
        if n == 0:
            return np.empty((0, 2))
        if self.is_empty:
            raise ValidationError("polygon", "empty", "cannot sample from the empty polygon")
        return K.fan_sample_kernel(self.vertices, rng.random((n, 3)))

    def sample_rejection(self, n, rng, *, max_draws: int = 100_000_000):
        """``n`` points uniform in the polygon by rejection from its bounding box (POA-NBP §IV-B).

        Candidates are drawn uniformly in :attr:`bounding_box` (x and y independently) and
        accepted when inside; the expected acceptance rate is ``R_a = A_p/A_r`` (POA-NBP eq. (22)).

        Returns
        -------
        points : [n, 2], float
        acceptance_rate : float
            Accepted / drawn candidates. For a polygon of zero area (point, segment), where
            rejection cannot accept, the exact :meth:`sample_uniform` draws are returned with
            rate 0.0.

        Raises :class:`~phyloc.errors.ValidationError` when ``max_draws`` candidates do not
        yield ``n`` points, or for ``n > 0`` on the empty polygon.
        """
        n = v.integer("n", n, minimum=0)
        rng = _rng(rng)
        max_draws = v.integer("max_draws", max_draws, minimum=1)
        if n == 0:
            return np.empty((0, 2)), 1.0
        if self.is_empty:
            raise ValidationError("polygon", "empty", "cannot sample from the empty polygon")
        if self.area <= 0.0:
            return self.sample_uniform(n, rng), 0.0
        x0, y0, x1, y1 = self.bounding_box
        A, c = self.halfspaces()
        rate_guess = self.area / ((x1 - x0) * (y1 - y0))
        out, got, drawn = [], 0, 0
        while got < n:
            if drawn >= max_draws:
                raise ValidationError(
                    "max_draws", max_draws, f"too few to accept {n} points (got {got})"
                )
            batch = min(max(64, int(1.2 * (n - got) / rate_guess) + 16), max_draws - drawn)
            cand = np.column_stack([rng.uniform(x0, x1, batch), rng.uniform(y0, y1, batch)])
            ok = K.contains_kernel(A, c, cand, 0.0)
            out.append(cand[ok])
            got += int(ok.sum())
            drawn += batch
        pts = np.concatenate(out)[:n]
        return pts, got / drawn


def _freeze(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _signed_area(w: np.ndarray) -> float:
    d = w - w[0]
    return float(0.5 * np.sum(d[1:-1, 0] * d[2:, 1] - d[1:-1, 1] * d[2:, 0]))


def _cross(o, a, b) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _dedupe(w: np.ndarray, tol: float) -> np.ndarray:
    keep = np.any(np.abs(w - np.roll(w, -1, axis=0)) > tol, axis=1)
    if not keep.any():
        return w[:1].copy()
    return w[keep].copy()


def _collinear(w: np.ndarray, tol: float) -> bool:
    """True when every vertex lies within ``tol`` of one line (a flat polygon)."""
    d = w - w.mean(axis=0)
    return bool(np.linalg.svd(d, compute_uv=False)[-1] <= tol * math.sqrt(w.shape[0]))


def _check_convex(w: np.ndarray, tol: float) -> None:
    """Raise unless the CCW vertex list ``w`` turns left everywhere and winds once."""
    e1 = w - np.roll(w, 1, axis=0)
    e2 = np.roll(w, -1, axis=0) - w
    cr = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ln = np.maximum(np.hypot(e1[:, 0], e1[:, 1]), np.hypot(e2[:, 0], e2[:, 1]))
    turn = np.arctan2(cr, np.einsum("ij,ij->i", e1, e2))
    if np.any(cr < -tol * ln) or abs(turn.sum() - 2.0 * math.pi) > 1e-6:
        bad = int(np.argmin(cr))
        raise ValidationError(
            "vertices", f"turn at vertex {bad}", "must be a convex polygon listed in order"
        )


# -- the three operations -----------------------------------------------------------------------
def anchor_polygon(center, range_m, n_edges: int = 16, offset_rad: float = 0.0) -> ConvexPolygon:
    """Regular ``N_E``-gon circumscribing the disk of radius ``z`` around an anchor.

    POA-NBP Algorithm 2, eqs. (15)–(17): vertices at angles ``α_0 + mα``, ``α = 2π/N_E``,
    ``m = 0 … N_E − 1``, radius ``r = z / cos(α/2)`` (POA-NBP eq. (16)), shifted by the anchor
    position (POA-NBP eq. (17)). Every edge touches the circle, so the polygon contains the feasible
    disk ``B = {x : ‖x − x*‖ <= z}`` of POA-NBP eq. (15); its area is ``N_E z² tan(π/N_E)``.

    Parameters
    ----------
    center : [2], float
        Anchor position ``x*`` [m].
    range_m : float
        Range estimate ``ẑ_{i→j} >= 0`` [m]; 0 gives the point polygon.
    n_edges : int
        ``N_E >= 3`` (POA-NBP uses 16, §V-B).
    offset_rad : float
        Angular offset ``α_0`` [rad] (the paper draws it at random).

    Examples
    --------
    >>> P = anchor_polygon([0.0, 0.0], 1.0, n_edges=4)
    >>> round(P.area, 12)
    4.0
    """
    x = v.finite_array("center", center)
    if x.shape != (2,):
        raise ValidationError("center", f"array of shape {x.shape}", "must be (2,)")
    z = v.positive("range_m", range_m, allow_zero=True)
    ne = v.integer("n_edges", n_edges, minimum=3)
    a0 = v.finite("offset_rad", offset_rad)
    return ConvexPolygon._trusted(_anchor_vertices(x, z, ne, a0))


def _anchor_vertices(x: np.ndarray, z: float, n_edges: int, offset: float) -> np.ndarray:
    if z == 0.0:
        return x.reshape(1, 2).copy()
    alpha = 2.0 * math.pi / n_edges
    ang = offset + alpha * np.arange(n_edges)
    r = z / math.cos(0.5 * alpha)
    return x + r * np.column_stack([np.cos(ang), np.sin(ang)])


def _anchor_halfspaces(x: np.ndarray, z: float, n_edges: int, offset: float):
    """Halfspaces of :func:`anchor_polygon`: normals at ``α_0 + (m + ½)α``, offsets
    ``a·x* + z`` (edge ``m`` is tangent to the circle)."""
    ang = offset + (2.0 * math.pi / n_edges) * (np.arange(n_edges) + 0.5)
    A = np.column_stack([np.cos(ang), np.sin(ang)])
    return A, A @ x + z


def intersect(P: ConvexPolygon, Q: ConvexPolygon) -> ConvexPolygon:
    """Intersection of two convex polygons by Sutherland–Hodgman (POA-NBP Algorithm 3).

    The subject ``P`` is clipped successively by each halfspace of ``Q`` (POA-NBP eq. (18)); the
    result is convex and CCW, has at most ``m_P + m_Q`` vertices, and is empty when the
    polygons are disjoint. Points within ``1e-12 ×`` the coordinate scale of a halfspace are
    kept, so touching polygons give a point or a segment rather than the empty set.

    Parameters
    ----------
    P, Q : ConvexPolygon

    Returns
    -------
    ConvexPolygon
        ``P ∩ Q`` (possibly empty or degenerate).

    Examples
    --------
    >>> P = ConvexPolygon.from_box(0, 0, 2, 2)
    >>> intersect(P, ConvexPolygon.from_box(1, 1, 3, 3)).area
    1.0
    """
    P = _polygon("P", P)
    Q = _polygon("Q", Q)
    if P.is_empty or Q.is_empty:
        return ConvexPolygon.empty()
    A, c = Q.halfspaces()
    tol = _tol(P.vertices, Q.vertices)
    out, _ = K.clip_groups_kernel(
        P.vertices, A, c, np.array([0, A.shape[0]], dtype=np.int64), tol, False
    )
    return ConvexPolygon._trusted(out)


def scale_polygon(P: ConvexPolygon, range_m, *, max_turn_rad=None) -> ConvexPolygon:
    """Grow a polygon by a range: every supporting halfspace shifted outward by ``z``.

    POA-NBP Algorithm 4, eqs. (18)–(20): halfspace ``a_m·x <= c_m`` becomes
    ``a_m·x <= c_m + z`` (POA-NBP eqs. (20), (19): ``v̄ = z a_m + v``), and vertex ``m`` is the
    intersection of the shifted lines ``m − 1`` and ``m``, evaluated in the closed form
    ``v_m + z (a_{m−1} + a_m)/(1 + a_{m−1}·a_m)`` (exact, and well conditioned for nearly
    parallel edges). Since ``h_{P⊕zB}(a) = h_P(a) + z``, the result contains the Minkowski sum
    of ``P`` and the disk of radius ``z``: every point within ``z`` of ``P``.

    Parameters
    ----------
    P : ConvexPolygon
        Polygon ``V_i^{(l)}`` of the neighbour.
    range_m : float
        Range estimate ``ẑ_{i→j} >= 0`` [m].
    max_turn_rad : float or None
        Largest angle between adjacent outward normals left unsplit. ``None`` (default) is
        POA-NBP Algorithm 4: only the polygon's own edges are shifted, except that a corner
        whose normals turn by more than ``π − 10⁻³`` (a miter longer than ~2000 z, or none at
        all for the ends of a segment) gets extra support lines (bevels) through the vertex. A
        value ``θ`` splits every corner turning by more than ``θ`` into equal turns
        ``<= θ`` with bevels through the vertex, which also contain the Minkowski sum and
        tighten sharp corners (``2π/N_E`` rounds corners like an anchor polygon). A point is
        grown into a regular polygon with ``max(3, ceil(2π/θ))`` edges.

    Returns
    -------
    ConvexPolygon
        ``V_ij^{(l)}``; without bevels its halfspaces are exactly ``(A, c + z)`` of ``P``.

    Examples
    --------
    >>> S = scale_polygon(ConvexPolygon.from_box(0, 0, 1, 1), 1.0)
    >>> S.bounding_box
    (-1.0, -1.0, 2.0, 2.0)
    """
    P = _polygon("P", P)
    z = v.positive("range_m", range_m, allow_zero=True)
    turn = _max_turn(max_turn_rad)
    if P.is_empty:
        return ConvexPolygon.empty()
    A, _, corner = K.support_halfspaces_kernel(P.vertices, turn)
    tol = _tol(P.vertices) + _TOL_REL * z
    return ConvexPolygon._trusted(K.scaled_vertices_kernel(A, corner, z, tol))


# -- the network algorithm ----------------------------------------------------------------------
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
        Corner splitting of :func:`scale_polygon` (``None`` = POA-NBP Algorithm 4).

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


# -- the ellipse baseline (POA-NBP Fig. 9) ------------------------------------------------------
class EllipseRegion:
    """An ellipse ``{x : (x − c)ᵀ Σ⁻¹ (x − c) <= 1}`` as a support region of the polygon
    proposal (``area``, ``contains``, ``sample_uniform``; the NBP of POA-NBP eq. (21) with an
    ellipse in place of the polygon: the 'NBP ell.' baseline).

    Parameters
    ----------
    center : [2] float64
        ``c`` [m].
    shape : [2, 2] float64
        ``Σ`` [m²], symmetric positive semi-definite; a singular ``Σ`` has area 0 (no density).

    Examples
    --------
    >>> E = EllipseRegion([0.0, 0.0], [[4.0, 0.0], [0.0, 1.0]])
    >>> round(E.area, 6), E.contains([[1.9, 0.0], [0.0, 1.1]]).tolist()
    (6.283185, [True, False])
    >>> bool(E.contains(E.sample_uniform(100, np.random.default_rng(0))).all())
    True
    """

    def __init__(self, center, shape):
        self.center = np.asarray(center, dtype=np.float64)
        self.shape = np.asarray(shape, dtype=np.float64)
        det = float(np.linalg.det(self.shape))
        self.area = math.pi * math.sqrt(det) if det > 0 else 0.0
        if self.area > 0:
            self._L = np.linalg.cholesky(self.shape)
            self._inv = np.linalg.inv(self.shape)

    def contains(self, points, tol=1e-9) -> np.ndarray:
        """Whether each of ``points [n, 2]`` lies in the ellipse (``≤ 1 + tol``)."""
        d = np.asarray(points, dtype=np.float64).reshape(-1, 2) - self.center
        if self.area == 0:
            return np.zeros(d.shape[0], bool)
        return np.einsum("ni,ij,nj->n", d, self._inv, d) <= 1.0 + tol

    def sample_uniform(self, n, rng) -> np.ndarray:
        """``n`` points uniform in the ellipse: ``c + L u``, ``u`` uniform in the unit disk
        (``√U`` radius, uniform angle; draws ``rng.uniform(size=n)`` twice), ``Σ = L Lᵀ``."""
        r = np.sqrt(rng.uniform(size=n))
        t = rng.uniform(0.0, 2.0 * np.pi, size=n)
        u = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
        return self.center + u @ self._L.T


@dataclass(frozen=True, eq=False)
class EllipseResult:
    """Output of :func:`ellipse_outer_approximation`.

    Ellipse ``j`` is ``E_j = {x : (x − c_j)ᵀ Σ_j⁻¹ (x − c_j) <= 1}``, area ``π √det Σ_j``
    (``Σ_j`` may be singular for a flat feasible set).

    Attributes
    ----------
    agents : [n_agents], int
        Node index of each agent, ascending.
    centers : [n_agents, 2], float
        Centers ``c_j`` [m] (zeros where unbounded).
    shapes : [n_agents, 2, 2], float
        Shape matrices ``Σ_j`` [m²] (zeros where unbounded).
    bounded : [n_agents], bool
        False where the agent has no ellipse (unbounded).
    area_history : [n_iterations, n_agents], float
        Ellipse area [m²] after each iteration (``inf`` while unbounded); comparable with
        :attr:`POAResult.area_history`.
    dropped : [k, 2], int
        Dropped measurements ``(i, j)`` (same rule as :func:`poa`).
    dropped_iteration : [k], int
        Iteration (1-based) of each drop.
    n_directions : int
        Number of tangent directions of the polygonal intermediate sets.
    """

    agents: np.ndarray
    centers: np.ndarray
    shapes: np.ndarray
    bounded: np.ndarray
    area_history: np.ndarray
    dropped: np.ndarray
    dropped_iteration: np.ndarray
    n_directions: int

    def contains(self, slot, points, tol: float = 1e-9) -> np.ndarray:
        """Whether ``points`` ``[n, 2]`` lie in the ellipse of agent ``slot`` (position in
        :attr:`agents`), tested against ``Σ + tol² I``; all True when unbounded."""
        a = v.integer("slot", slot, minimum=0)
        if a >= self.agents.size:
            raise ValidationError("slot", slot, f"must be < {self.agents.size}")
        p = _points("points", points)
        t = v.positive("tol", tol, allow_zero=True)
        if not self.bounded[a]:
            return np.ones(p.shape[0], dtype=bool)
        d = p - self.centers[a]
        S = self.shapes[a] + max(t * t, 1e-300) * np.eye(2)
        return np.einsum("ij,jk,ik->i", d, np.linalg.inv(S), d) <= 1.0

    def regions(self) -> list:
        """One :class:`EllipseRegion` per agent (``None`` where unbounded): the supports of
        the 'NBP ell.' proposal."""
        return [
            EllipseRegion(c, sh) if b else None
            for c, sh, b in zip(self.centers, self.shapes, self.bounded, strict=True)
        ]

    def mean_area(self) -> np.ndarray:
        """Mean area per iteration over the agents bounded from iteration 1 on (see
        :meth:`POAResult.mean_area`)."""
        ok = np.all(np.isfinite(self.area_history), axis=0)
        if not ok.any():
            return np.full(self.area_history.shape[0], np.inf)
        return self.area_history[:, ok].mean(axis=1)


def _ellipse_area(sig: np.ndarray) -> float:
    return math.pi * math.sqrt(max(float(np.linalg.det(sig)), 0.0))


def _outer_ellipse(w: np.ndarray, tol: float):
    """Minimum-area ellipse containing the convex polygon ``w`` (its vertices).

    Löwner–John ellipse by :func:`~phyloc.localization.static._polygon_kernels.mvee_kernel`; a flat
    polygon (point, segment, area below ``tol²``) gets the ellipse through the corners of its
    principal-axis bounding rectangle (``Σ = 2 Σ_k h_k² e_k e_kᵀ``, half-extents ``h_k``).
    """
    if w.shape[0] >= 3 and _signed_area(w) > tol * tol:
        c, sig, _ = K.mvee_kernel(w, 1e-7, 20_000)
        if np.linalg.det(sig) > 0.0 and np.all(np.isfinite(sig)):
            return c, sig
    if w.shape[0] == 1:
        return w[0].copy(), np.zeros((2, 2))
    d = w - w.mean(axis=0)
    _, vecs = np.linalg.eigh(d.T @ d)
    proj = w @ vecs
    lo, hi = proj.min(axis=0), proj.max(axis=0)
    h = 0.5 * (hi - lo)
    c = vecs @ (0.5 * (hi + lo))
    return c, 2.0 * (vecs * h**2) @ vecs.T


def _halfspace_vertices(A: np.ndarray, c: np.ndarray, tol: float) -> np.ndarray:
    """Vertices of ``{A x <= c}`` for normals sorted CCW with turns < π and support-function
    offsets: adjacent lines ``m − 1`` and ``m`` meet at vertex ``m`` (Cramer's rule)."""
    Ap, cp = np.roll(A, 1, axis=0), np.roll(c, 1)
    det = Ap[:, 0] * A[:, 1] - Ap[:, 1] * A[:, 0]
    x = (cp * A[:, 1] - c * Ap[:, 1]) / det
    y = (Ap[:, 0] * c - A[:, 0] * cp) / det
    w = np.column_stack([x, y])
    m = K.clean_kernel(w, w.shape[0], tol)
    return w[:m].copy()


def ellipse_outer_approximation(
    positions,
    ranges,
    anchors,
    *,
    n_iterations: int = 2,
    region=None,
    n_directions: int = 64,
) -> EllipseResult:
    """Ellipse outer-approximation of the feasible sets: the baseline of POA-NBP Fig. 9.

    The paper compares POA with the ellipses of "distributed bounding of feasible sets"
    (its refs. [8], [10], [42]), which agents exchange instead of polygons. This function keeps
    that information flow but computes each ellipse as tightly as possible, so the baseline is
    conservative (no looser than the original convex relaxation):

    * iteration 1: ``S_j = region ∩ ⋂_{anchors i} B(x_i, ẑ_{i→j})``;
    * iteration ``l >= 2`` (Jacobi): ``S_j = T(E_j) ∩ region ∩ ⋂_{anchors} B(x_i, ẑ_{i→j}) ∩
      ⋂_{agents i} T(E_i ⊕ ẑ_{i→j} B)`` with the neighbours' ellipses of iteration ``l − 1``;
    * ``E_j`` = the minimum-area (Löwner–John) ellipse of ``S_j``'s vertices, kept only if its
      area is below that of the previous ``E_j`` (both contain the feasible set).

    ``T(K)`` is the polygon of the ``n_directions`` supporting halfspaces of ``K`` at the
    normals ``2πk/n_directions``; for an ellipse grown by ``z`` their offsets are
    ``a·c + √(aᵀΣa) + z`` (exact support function). Each ``S_j`` is therefore an outer
    polygon of the true intersection, and each ellipse contains it: with errors ``ε >= 0``
    every ellipse contains its agent. Measurements are dropped exactly as in :func:`poa`.

    Parameters
    ----------
    positions, ranges, anchors, region
        As in :func:`poa`.
    n_iterations : int
        ``N_FS >= 1``.
    n_directions : int
        Number of tangent directions, ``>= 8`` (64 keeps ``T`` within 0.5 % of the disks).

    Returns
    -------
    EllipseResult
    """
    pos, z, is_anchor = _network_inputs(positions, ranges, anchors)
    n_iter = v.integer("n_iterations", n_iterations, minimum=1)
    nd = v.integer("n_directions", n_directions, minimum=8)
    R = _region(region)
    _warmup()
    agents = np.flatnonzero(~is_anchor)
    slot = np.full(pos.shape[0], -1, dtype=np.int64)
    slot[agents] = np.arange(agents.size)
    tol = _tol(pos[is_anchor], z[np.isfinite(z)], R.vertices if R is not None else np.empty(0))
    link = np.isfinite(z)
    half = -math.pi / nd  # anchor-polygon offset that puts the normals at 2πk/nd
    ang = 2.0 * math.pi * np.arange(nd) / nd
    D = np.column_stack([np.cos(ang), np.sin(ang)])

    ell: list[tuple[np.ndarray, np.ndarray] | None] = [None] * agents.size
    areas = np.empty((n_iter, agents.size))
    dropped: list[tuple[int, int, int]] = []
    bad = set()

    def ellipse_halfspaces(e, zz):
        c, sig = e
        return D, D @ c + np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", D, sig, D), 0.0)) + zz

    for it in range(n_iter):
        new = list(ell)
        for a, j in enumerate(agents):
            gA, gc, nb = [], [], []  # nb: (node, kind) with kind "prior" for non-measurements
            if R is not None:
                A, c = R.halfspaces()
                gA.append(A)
                gc.append(c)
                nb.append((-1, 0.0))
            if ell[a] is not None:
                A, c = ellipse_halfspaces(ell[a], 0.0)
                gA.insert(0, A)
                gc.insert(0, c)
                nb.insert(0, (-1, 0.0))
            for i in np.flatnonzero(link[j]):
                key = (int(i), int(j))
                if key in bad:
                    continue
                zz = float(z[j, i])
                if is_anchor[i]:
                    A, c = _anchor_halfspaces(pos[i], max(zz, 0.0), nd, half)
                elif it > 0 and ell[slot[i]] is not None:
                    A, c = ellipse_halfspaces(ell[slot[i]], zz)
                else:
                    continue
                if zz < 0.0:
                    dropped.append((*key, it + 1))
                    bad.add(key)
                    continue
                gA.append(A)
                gc.append(c)
                nb.append((int(i), zz))
            if not gA:
                areas[it, a] = math.inf
                continue
            subject = _halfspace_vertices(gA[0], gc[0], tol)
            out, drop, _ = _clip(subject, gA[1:], gc[1:], tol)
            for g in np.flatnonzero(drop):
                i = nb[g + 1][0]
                if i >= 0:
                    dropped.append((i, int(j), it + 1))
                    bad.add((i, int(j)))
            cand = _outer_ellipse(out, tol)
            if ell[a] is None or _ellipse_area(cand[1]) < _ellipse_area(ell[a][1]):
                new[a] = cand
            areas[it, a] = _ellipse_area(new[a][1])
        ell = new

    centers = np.zeros((agents.size, 2))
    shapes = np.zeros((agents.size, 2, 2))
    bounded = np.array([e is not None for e in ell], dtype=bool)
    for a, e in enumerate(ell):
        if e is not None:
            centers[a], shapes[a] = e
    return EllipseResult(
        agents=agents,
        centers=centers,
        shapes=shapes,
        bounded=bounded,
        area_history=areas,
        dropped=np.array([(i, j) for i, j, _ in dropped], dtype=np.int64).reshape(-1, 2),
        dropped_iteration=np.array([it for _, _, it in dropped], dtype=np.int64),
        n_directions=nd,
    )
