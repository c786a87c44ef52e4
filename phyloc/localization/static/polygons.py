"""Convex polygons and the three operations of the polygon support outer-approximation (POA).

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

:func:`~phyloc.localization.static.poa_network.poa` runs POA-NBP Algorithm 1 over a whole
network and :mod:`phyloc.localization.static.ellipses` holds the ellipse baseline of POA-NBP
Fig. 9. :class:`ConvexPolygon` carries the samplers of POA-NBP §IV-B: exact uniform sampling
(POA-NBP eq. (21)) and the paper's rejection sampling from the bounding box with acceptance
rate POA-NBP eq. (22).

Conventions: positions in metres, arrays ``float64``; a polygon's vertices are ``(m, 2)``
counter-clockwise (CCW); ``m = 0`` is the empty set, ``m = 1`` a point and ``m = 2`` a segment
(degenerate polygons arise from zero ranges and tangent disks and are handled without NaN).
Computations keep points within ``1e-12 ×`` the coordinate scale outside a halfspace, so
rounding never cuts off a feasible point. Numba kernels live in
:mod:`phyloc.localization.static._polygon_kernels`.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math
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
