"""Polygon support outer-approximation (phyloc.localization.static.polygons, .poa_network,
.ellipses and their kernels).

References: convex hulls from scipy.spatial, a point-in-convex-polygon test by edge cross
products written here, brute-force membership on dense grids, closed forms (area of the regular
N_E-gon circumscribing a disk, POA-NBP eq. (16); the area A + Lz + z²Σtan(θ_k/2) of a polygon
grown by z with mitred corners; the Löwner–John ellipse of a rectangle), chi-square tests of the
samplers (scipy.stats), the plain-NumPy twins of the kernels (tests/naive_static.py) and the
truth of simulated networks with non-negative ranging errors (POA-NBP eq. (11)).
"""

import math

import naive_static as N
import numpy as np
import pytest
from scipy import stats
from scipy.spatial import ConvexHull

from phyloc.errors import ValidationError
from phyloc.localization.static import _polygon_kernels as K
from phyloc.localization.static.ellipses import ellipse_outer_approximation
from phyloc.localization.static.poa_network import poa
from phyloc.localization.static.polygons import (
    ConvexPolygon,
    anchor_polygon,
    intersect,
    scale_polygon,
)

TOL = 1e-12 * 100.0  # the geometry tolerance at the 100 m scale of the tests


# -- references written here --------------------------------------------------------------------
def _inside(verts, pts, tol=1e-9):
    """Point-in-convex-polygon (CCW vertices) by the sign of every edge cross product."""
    verts = np.asarray(verts)
    pts = np.atleast_2d(pts)
    if verts.shape[0] == 0:
        return np.zeros(len(pts), dtype=bool)
    if verts.shape[0] == 1:
        return np.linalg.norm(pts - verts[0], axis=1) <= tol
    ok = np.ones(len(pts), dtype=bool)
    n = verts.shape[0]
    for k in range(n):
        a, b = verts[k], verts[(k + 1) % n]
        e = b - a
        cr = e[0] * (pts[:, 1] - a[1]) - e[1] * (pts[:, 0] - a[0])
        ok &= cr >= -tol * np.linalg.norm(e)
    if n == 2:  # a segment: also within its ends
        d = (verts[1] - verts[0]) / np.linalg.norm(verts[1] - verts[0])
        t = (pts - verts[0]) @ d
        ok &= (t >= -tol) & (t <= np.linalg.norm(verts[1] - verts[0]) + tol)
    return ok


def _boundary_distance(verts, pts):
    """Distance of each point to the nearest edge line of a polygon (≥ distance to boundary)."""
    n = verts.shape[0]
    out = np.full(len(pts), np.inf)
    for k in range(n):
        a, b = verts[k], verts[(k + 1) % n]
        e = (b - a) / np.linalg.norm(b - a)
        out = np.minimum(out, np.abs(e[0] * (pts[:, 1] - a[1]) - e[1] * (pts[:, 0] - a[0])))
    return out


def _random_convex(rng, n_pts=9, center=(0.0, 0.0), scale=10.0):
    """Vertices (CCW) of the convex hull of random points, by scipy.spatial."""
    pts = np.asarray(center) + scale * rng.uniform(-1.0, 1.0, (n_pts, 2))
    return pts[ConvexHull(pts).vertices]


def _is_convex_ccw(verts, tol=1e-9):
    n = verts.shape[0]
    e1 = verts - np.roll(verts, 1, axis=0)
    e2 = np.roll(verts, -1, axis=0) - verts
    cr = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    return n < 3 or bool(np.all(cr > -tol))


def _exterior_angles(verts):
    e1 = verts - np.roll(verts, 1, axis=0)
    e2 = np.roll(verts, -1, axis=0) - verts
    return np.arctan2(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0], np.sum(e1 * e2, axis=1))


def _network(seed, n_agents=30, n_anchors=13, r_com=20.0, error=("exp", 0.38), side=100.0):
    """Agents and anchors uniform in [0, side]², symmetric ranges within r_com, NaN else."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0.0, side, (n_agents + n_anchors, 2))
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    kind, scale = error
    eps = rng.exponential(scale, d.shape) if kind == "exp" else rng.normal(0.0, scale, d.shape)
    z = np.triu(d + eps, 1)
    z = z + z.T
    z[d > r_com] = np.nan
    np.fill_diagonal(z, np.nan)
    return pos, z, np.arange(n_agents, n_agents + n_anchors)


# -- kernels against their NumPy twins ----------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
def test_clean_kernel_matches_twin_and_hull(seed):
    rng = np.random.default_rng(seed)
    hull = _random_convex(rng)
    rows = []
    for k in range(hull.shape[0]):  # repeat vertices and add points on the edges
        a, b = hull[k], hull[(k + 1) % hull.shape[0]]
        rows += [a, a, a + 0.3 * (b - a), a + 0.7 * (b - a)]
    noisy = np.array(rows)
    want = N.clean_numpy(noisy, TOL)
    w = noisy.copy()
    m = K.clean_kernel(w, w.shape[0], TOL)
    np.testing.assert_allclose(w[:m], want, atol=1e-12)
    np.testing.assert_allclose(np.roll(want, -int(np.argmin(np.hypot(*(want - hull[0]).T)))), hull)
    # a flat polygon collapses to its two extreme points
    flat = np.array([[0.0, 0.0], [1.0, 1.0], [3.0, 3.0], [2.0, 2.0]])
    w = flat.copy()
    m = K.clean_kernel(w, 4, TOL)
    assert {tuple(p) for p in w[:m]} == {(0.0, 0.0), (3.0, 3.0)}


@pytest.mark.parametrize("seed", range(5))
def test_intersection_matches_dense_grid(seed):
    rng = np.random.default_rng(100 + seed)
    P = ConvexPolygon(_random_convex(rng, center=(0.0, 0.0)))
    Q = ConvexPolygon(_random_convex(rng, center=rng.uniform(-8.0, 8.0, 2)))
    R = intersect(P, Q)
    assert _is_convex_ccw(R.vertices)
    assert R.n_vertices <= P.n_vertices + Q.n_vertices
    g = np.linspace(-20.0, 20.0, 241) + 1e-3 * math.pi
    pts = np.column_stack([a.ravel() for a in np.meshgrid(g, g)])
    want = _inside(P.vertices, pts, 0.0) & _inside(Q.vertices, pts, 0.0)
    got = _inside(R.vertices, pts, 0.0) if not R.is_empty else np.zeros(len(pts), bool)
    near = np.minimum(_boundary_distance(P.vertices, pts), _boundary_distance(Q.vertices, pts))
    assert np.all((got == want) | (near < 1e-7))
    assert want.sum() > 0 or R.is_empty
    # kernel == NumPy twin, and the intersection is symmetric as a set
    A, c = Q.halfspaces()
    off = np.array([0, A.shape[0]], dtype=np.int64)
    kern, _ = K.clip_groups_kernel(P.vertices, A, c, off, TOL, False)
    twin, _ = N.clip_groups_numpy(P.vertices, A, c, off, TOL, False)
    np.testing.assert_allclose(kern, twin, atol=1e-12)
    assert intersect(Q, P).area == pytest.approx(R.area, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_clip_groups_drops_exactly_the_groups_that_empty_it(seed):
    rng = np.random.default_rng(seed)
    P = ConvexPolygon(_random_convex(rng, center=(0.0, 0.0), scale=5.0))
    far = ConvexPolygon(_random_convex(rng, center=(50.0, 0.0), scale=5.0))
    near = ConvexPolygon(_random_convex(rng, center=(2.0, 2.0), scale=5.0))
    groups = [near.halfspaces(), far.halfspaces(), P.halfspaces()]
    A = np.concatenate([g[0] for g in groups])
    c = np.concatenate([g[1] for g in groups])
    off = np.cumsum([0] + [g[0].shape[0] for g in groups]).astype(np.int64)
    out, dropped = K.clip_groups_kernel(P.vertices, A, c, off, TOL, True)
    twin, dropped_twin = N.clip_groups_numpy(P.vertices, A, c, off, TOL, True)
    assert dropped.tolist() == [False, True, False] == dropped_twin.tolist()
    np.testing.assert_allclose(out, twin, atol=1e-12)
    assert ConvexPolygon(out).area == pytest.approx(intersect(P, near).area, rel=1e-9)


def test_intersection_disjoint_touching_and_empty():
    sq = ConvexPolygon.from_box(0.0, 0.0, 1.0, 1.0)
    assert intersect(sq, ConvexPolygon.from_box(2.0, 0.0, 3.0, 1.0)).is_empty
    edge = intersect(sq, ConvexPolygon.from_box(1.0, 0.0, 2.0, 1.0))  # shared edge
    assert edge.n_vertices == 2 and edge.area == 0.0
    np.testing.assert_allclose(sorted(edge.vertices.tolist()), [[1.0, 0.0], [1.0, 1.0]])
    corner = intersect(sq, ConvexPolygon.from_box(1.0, 1.0, 2.0, 2.0))
    np.testing.assert_allclose(corner.vertices, [[1.0, 1.0]])
    assert intersect(sq, ConvexPolygon.empty()).is_empty
    pt = ConvexPolygon([[0.5, 0.5]])
    np.testing.assert_allclose(intersect(sq, pt).vertices, [[0.5, 0.5]])
    np.testing.assert_allclose(intersect(pt, sq).vertices, [[0.5, 0.5]])


# -- anchor polygon (POA-NBP Algorithm 2) ----------------------------------------------------------
@pytest.mark.parametrize("n_edges", [3, 4, 7, 16, 64])
def test_anchor_polygon_circumscribes_the_disk(n_edges):
    rng = np.random.default_rng(n_edges)
    x, z, a0 = rng.uniform(-50, 50, 2), rng.uniform(0.5, 30.0), rng.uniform(0.0, 2 * np.pi)
    P = anchor_polygon(x, z, n_edges, a0)
    assert P.n_vertices == n_edges and _is_convex_ccw(P.vertices)
    ang = np.linspace(0.0, 2 * np.pi, 2000, endpoint=False)
    circle = x + z * np.column_stack([np.cos(ang), np.sin(ang)])
    assert np.all(_inside(P.vertices, circle, 1e-9))
    assert P.area == pytest.approx(n_edges * z**2 * math.tan(math.pi / n_edges), rel=1e-12)
    # tight: every edge is tangent (edge midpoints at distance z), vertices at z / cos(α/2)
    mid = 0.5 * (P.vertices + np.roll(P.vertices, -1, axis=0))
    np.testing.assert_allclose(np.linalg.norm(mid - x, axis=1), z, rtol=1e-12)
    r = np.linalg.norm(P.vertices - x, axis=1)
    np.testing.assert_allclose(r, z / math.cos(math.pi / n_edges), rtol=1e-12)
    first = math.atan2(*(P.vertices[0] - x)[::-1]) % (2 * np.pi)
    assert first == pytest.approx(a0 % (2 * np.pi), abs=1e-9)
    A, c = P.halfspaces()
    np.testing.assert_allclose(c - A @ x, z, rtol=1e-12)


# -- polygon scaling (POA-NBP Algorithm 4) ---------------------------------------------------------
@pytest.mark.parametrize("seed", range(5))
def test_scaled_polygon_contains_minkowski_sum(seed):
    rng = np.random.default_rng(200 + seed)
    P = ConvexPolygon(_random_convex(rng, n_pts=12))
    z = rng.uniform(0.1, 8.0)
    S = scale_polygon(P, z)
    Sb = scale_polygon(P, z, max_turn_rad=2 * np.pi / 16)
    # p + z·u with p on P's boundary / vertices / inside and |u| <= 1
    k = rng.integers(0, P.n_vertices, 3000)
    t = rng.uniform(0, 1, 3000)[:, None]
    p = P.vertices[k] + t * (np.roll(P.vertices, -1, axis=0)[k] - P.vertices[k])
    p = np.concatenate([p, P.vertices.repeat(200, axis=0), P.sample_uniform(1000, rng)])
    phi = rng.uniform(0, 2 * np.pi, len(p))
    rad = np.where(rng.uniform(size=len(p)) < 0.5, 1.0, np.sqrt(rng.uniform(size=len(p))))
    q = p + z * rad[:, None] * np.column_stack([np.cos(phi), np.sin(phi)])
    assert np.all(_inside(S.vertices, q, 1e-9))
    assert np.all(_inside(Sb.vertices, q, 1e-9))
    # paper mode: same normals, offsets c + z; area of the mitred parallel polygon
    A, c = P.halfspaces()
    As, cs = S.halfspaces()
    np.testing.assert_allclose(As, A, atol=1e-12)
    np.testing.assert_allclose(cs, c + z, atol=1e-9)
    perim = np.sum(np.linalg.norm(np.roll(P.vertices, -1, axis=0) - P.vertices, axis=1))
    theta = _exterior_angles(P.vertices)
    want = P.area + perim * z + z**2 * np.sum(np.tan(theta / 2))
    assert S.area == pytest.approx(want, rel=1e-10)
    # bevels: between the Minkowski sum (Steiner formula) and the mitred polygon
    assert P.area + perim * z + math.pi * z**2 <= Sb.area <= S.area + 1e-9
    np.testing.assert_allclose(scale_polygon(P, 0.0).vertices, P.vertices, atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_support_and_scaling_kernels_match_twins(seed):
    rng = np.random.default_rng(300 + seed)
    w = _random_convex(rng, n_pts=10)
    for turn in (np.pi - 1e-3, np.pi / 2, 2 * np.pi / 16):
        A, c, corner = K.support_halfspaces_kernel(w, turn)
        A2, c2, corner2 = N.support_halfspaces_numpy(w, turn)
        np.testing.assert_allclose(A, A2, atol=1e-14)
        np.testing.assert_allclose(c, c2, atol=1e-12)
        np.testing.assert_allclose(corner, corner2)
        ang = np.arctan2(A[:, 1], A[:, 0])
        assert np.all(np.mod(np.diff(np.append(ang, ang[0])), 2 * np.pi) <= turn + 1e-12)
        np.testing.assert_allclose(np.einsum("ij,ij->i", A, corner), c, atol=1e-9)
        z = rng.uniform(0.5, 5.0)
        vk = K.scaled_vertices_kernel(A, corner, z, TOL)
        vt = N.scaled_vertices_numpy(A, c, z, TOL)
        np.testing.assert_allclose(vk, vt, atol=1e-9)


def test_scaling_degenerate_polygons():
    z = 2.0
    ang = np.linspace(0, 2 * np.pi, 500, endpoint=False)
    u = np.column_stack([np.cos(ang), np.sin(ang)])
    pt = ConvexPolygon([[3.0, 4.0]])
    S = scale_polygon(pt, z, max_turn_rad=2 * np.pi / 16)
    assert S.n_vertices == 16
    assert S.area == pytest.approx(16 * z**2 * math.tan(math.pi / 16), rel=1e-12)
    assert np.all(_inside(S.vertices, pt.vertices + z * u))
    assert np.all(_inside(scale_polygon(pt, z).vertices, pt.vertices + z * u))
    seg = ConvexPolygon([[0.0, 0.0], [5.0, 1.0]])
    for turn in (None, np.pi / 4):
        S = scale_polygon(seg, z, max_turn_rad=turn)
        t = np.linspace(0, 1, 50)[:, None]
        on = seg.vertices[0] + t * (seg.vertices[1] - seg.vertices[0])
        q = (on[:, None, :] + z * u[None]).reshape(-1, 2)
        assert np.all(_inside(S.vertices, q)) and np.all(np.isfinite(S.vertices))
    assert scale_polygon(ConvexPolygon.empty(), z).is_empty
    np.testing.assert_allclose(scale_polygon(pt, 0.0).vertices, pt.vertices)
    # a very sharp corner: paper mode stays finite, bevels stay tight
    sliver = ConvexPolygon([[0.0, 0.0], [100.0, 0.0], [0.0, 1e-4]])
    Sp, Sb = scale_polygon(sliver, 1.0), scale_polygon(sliver, 1.0, max_turn_rad=np.pi / 8)
    assert np.all(np.isfinite(Sp.vertices)) and Sb.area <= Sp.area
    assert np.all(_inside(Sb.vertices, (sliver.vertices[:, None] + u[None]).reshape(-1, 2)))


# -- sampling (POA-NBP eqs. (21)–(22)) -------------------------------------------------------------
def test_fan_sampling_kernel_matches_twin():
    rng = np.random.default_rng(5)
    for w in (_random_convex(rng), np.array([[0.0, 0.0], [2.0, 1.0]]), np.array([[1.0, 1.0]])):
        u = rng.random((500, 3))
        np.testing.assert_allclose(K.fan_sample_kernel(w, u), N.fan_sample_numpy(w, u))


def test_contains_kernel_matches_twin_and_brute_force():
    rng = np.random.default_rng(9)
    P = ConvexPolygon(_random_convex(rng))
    A, c = P.halfspaces()
    pts = rng.uniform(-3.0, 3.0, size=(2000, 2)) * np.abs(P.vertices).max()
    np.testing.assert_array_equal(
        K.contains_kernel(A, c, pts, 0.0), N.contains_numpy(A, c, pts, 0.0)
    )
    pts = np.vstack([pts, P.vertices])  # the vertices: inside within tol (not by rounding)
    for tol in (1e-9, 0.5):
        got = K.contains_kernel(A, c, pts, tol)
        np.testing.assert_array_equal(got, N.contains_numpy(A, c, pts, tol))
    got = K.contains_kernel(A, c, pts, 1e-9)
    np.testing.assert_array_equal(got, _inside(P.vertices, pts, 1e-9))
    assert got.any() and not got.all()


def test_uniform_sampling_triangle_fractions():
    rng = np.random.default_rng(11)
    P = ConvexPolygon(_random_convex(rng, n_pts=14))
    n = 40_000
    x = P.sample_uniform(n, rng)
    assert np.all(_inside(P.vertices, x, 1e-9))
    w = P.vertices
    tri = [np.array([w[0], w[k], w[k + 1]]) for k in range(1, w.shape[0] - 1)]
    counts = np.array([_inside(t, x, 0.0).sum() for t in tri])
    areas = np.array([0.5 * abs(np.linalg.det(np.array([t[1] - t[0], t[2] - t[0]]))) for t in tri])
    assert counts.sum() == pytest.approx(n, abs=20)  # shared fan diagonals count twice
    assert stats.chisquare(counts, counts.sum() * areas / areas.sum()).pvalue > 1e-3


def test_uniform_sampling_grid_cells():
    rng = np.random.default_rng(12)
    sq = ConvexPolygon([[0.0, 0.0], [5.0, 0.0], [5.0, 5.0], [0.0, 5.0]])
    x = sq.sample_uniform(25_000, rng)
    cells = np.floor(x).astype(int)
    counts = np.bincount(cells[:, 0] * 5 + cells[:, 1], minlength=25)
    assert stats.chisquare(counts).pvalue > 1e-3
    # regular hexagon: the six triangles around the centre (not the sampler's fan) hold 1/6 each
    hexagon = anchor_polygon([0.0, 0.0], 1.0, n_edges=6, offset_rad=0.1)
    x = hexagon.sample_uniform(30_000, rng)
    sector = np.floor(((np.arctan2(x[:, 1], x[:, 0]) - 0.1) % (2 * np.pi)) / (np.pi / 3))
    counts = np.bincount(sector.astype(int), minlength=6)
    assert stats.chisquare(counts).pvalue > 1e-3
    # and the radius has the density 2r/R² of a uniform disk-like fill within the incircle
    r = np.linalg.norm(x, axis=1)
    inner = r[r <= math.cos(math.pi / 6)] / math.cos(math.pi / 6)
    assert stats.kstest(inner, lambda s: np.clip(s, 0, 1) ** 2).pvalue > 1e-3


def test_rejection_sampling_acceptance_rate():
    rng = np.random.default_rng(13)
    P = ConvexPolygon(_random_convex(rng, n_pts=8))
    x0, y0, x1, y1 = P.bounding_box
    want = P.area / ((x1 - x0) * (y1 - y0))
    n = 30_000
    x, rate = P.sample_rejection(n, rng)
    assert x.shape == (n, 2) and np.all(_inside(P.vertices, x, 1e-9))
    drawn = n / rate
    assert abs(rate - want) < 5 * math.sqrt(want * (1 - want) / drawn)
    # degenerate: no hang, exact sampler used
    seg = ConvexPolygon([[0.0, 0.0], [1.0, 1.0]])
    y, r0 = seg.sample_rejection(10, rng)
    assert r0 == 0.0 and np.all(np.abs(y[:, 0] - y[:, 1]) < 1e-12)


def test_polygon_properties_known_answers():
    P = ConvexPolygon([[0.0, 0.0], [0.0, 3.0], [4.0, 0.0]])  # clockwise input is reversed
    assert P.area == 6.0
    np.testing.assert_allclose(P.centroid, [4 / 3, 1.0])
    assert P.bounding_box == (0.0, 0.0, 4.0, 3.0)
    A, c = P.halfspaces()
    np.testing.assert_allclose(np.linalg.norm(A, axis=1), 1.0)
    np.testing.assert_allclose(A @ P.centroid - c < 0, True)
    assert P.contains([[1.0, 1.0], [3.0, 3.0], [4.0, 0.0]]).tolist() == [True, False, True]
    with pytest.raises(ValidationError, match="vertices"):
        ConvexPolygon([[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]])  # not convex
    with pytest.raises(ValidationError, match="vertices"):
        ConvexPolygon([[0, 0], [1, 0], [0, 1], [1, 1]])  # self-intersecting
    hull = ConvexPolygon.from_points(np.random.default_rng(1).normal(size=(200, 2)))
    assert hull.n_vertices >= 3 and _is_convex_ccw(hull.vertices)


# -- POA on networks (POA-NBP Algorithm 1) ---------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("region", [None, (0.0, 0.0, 100.0, 100.0)])
def test_poa_polygons_contain_truth_and_shrink(seed, region):
    pos, z, anchors = _network(seed)
    res = poa(pos, z, anchors, rng=np.random.default_rng(seed), n_iterations=4, region=region)
    n_ag = pos.shape[0] - anchors.size
    assert res.area_history.shape == (4, n_ag) == res.time_s.shape
    assert np.all(res.time_s >= 0.0) and res.dropped.shape == (0, 2)
    for P, j in zip(res.polygons, res.agents, strict=True):
        if P is None:
            assert region is None
            continue
        assert not P.is_empty and np.all(np.isfinite(P.vertices))
        assert _inside(P.vertices, pos[j], 1e-9)[0]
    H = res.area_history
    assert not np.any(np.isnan(H))
    assert np.all(H[1:] <= H[:-1] * (1 + 1e-12) + 1e-9)  # inf = still unbounded
    if region is not None:
        assert np.all(np.isfinite(H)) and np.all(H <= 100.0 * 100.0 + 1e-6)
        assert np.mean(H[-1]) < 0.5 * np.mean(H[0])  # cooperation tightens the polygons


@pytest.mark.parametrize("seed", range(3))
def test_poa_first_iteration_outer_approximates_anchor_disks(seed):
    pos, z, anchors = _network(seed, n_agents=20)
    res = poa(pos, z, anchors, rng=np.random.default_rng(1), n_edges=8, n_iterations=1)
    rng = np.random.default_rng(seed)
    for P, j in zip(res.polygons, res.agents, strict=True):
        nb = [i for i in anchors if np.isfinite(z[j, i])]
        if not nb:
            assert P is None
            continue
        q = pos[j] + rng.uniform(-25.0, 25.0, (4000, 2))
        feasible = np.all([np.linalg.norm(q - pos[i], axis=1) <= z[j, i] for i in nb], axis=0)
        assert np.all(_inside(P.vertices, q[feasible], 1e-9))
        for i in nb:  # and inside each anchor's circumscribed N_E-gon
            r = z[j, i] / math.cos(math.pi / 8)
            assert np.all(np.linalg.norm(P.vertices - pos[i], axis=1) <= r + 1e-9)


def _two_agent_scene():
    """Anchors 0–4, agents 5 (true (10, 5)) and 6 (true (30, 5)), ranges with +0.1 m error."""
    pos = np.array(
        [[0.0, 0.0], [20.0, 0.0], [10.0, 20.0], [40.0, 0.0], [30.0, 20.0], [10.0, 5.0], [30, 5]]
    )
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    z = np.full_like(d, np.nan)
    for a, b in [(5, 0), (5, 1), (5, 2), (6, 1), (6, 3), (6, 4), (5, 6)]:
        z[a, b] = z[b, a] = d[a, b] + 0.1
    return pos, z


def test_poa_drops_inconsistent_agent_measurement():
    pos, z = _two_agent_scene()
    z[5, 6] = z[6, 5] = 12.0  # true distance 20: a negative error of −8 m
    res = poa(pos, z, [0, 1, 2, 3, 4], rng=np.random.default_rng(3), n_iterations=3)
    assert sorted(map(tuple, res.dropped.tolist())) == [(5, 6), (6, 5)]
    assert res.dropped_iteration.tolist() == [2, 2]
    for P, j in zip(res.polygons, res.agents, strict=True):
        assert not P.is_empty and _inside(P.vertices, pos[j])[0]
    # the same scene with the consistent range uses the link (and shrinks the polygons)
    ok = poa(*_two_agent_scene(), [0, 1, 2, 3, 4], rng=np.random.default_rng(3), n_iterations=3)
    assert ok.dropped.shape == (0, 2)
    assert np.all(ok.area_history[-1] <= res.area_history[-1] + 1e-9)


def test_poa_drops_inconsistent_anchor_measurement_and_negative_range():
    pos = np.array([[40.0, 50.0], [60.0, 50.0], [50.0, 60.0], [50.0, 40.0], [50.0, 50.0]])
    d = np.linalg.norm(pos - pos[4], axis=1)
    z = np.full((5, 5), np.nan)
    z[4, :4] = d[:4] + 0.1
    z[4, 2] = d[2] - 3.0  # anchor 2: negative error, its disk misses the lens of anchors 0, 1
    z[4, 3] = -1.0  # a negative range estimate: inconsistent on its own
    for region in (None, (0, 0, 100, 100)):
        res = poa(pos, z, [0, 1, 2, 3], rng=np.random.default_rng(0), region=region)
        assert sorted(map(tuple, res.dropped.tolist())) == [(2, 4), (3, 4)]
        P = res.polygons[0]
        assert not P.is_empty and _inside(P.vertices, pos[4])[0]


def test_poa_with_negative_errors_never_empty_and_reproducible():
    pos, z, anchors = _network(7, n_agents=40, error=("normal", 1.0))
    runs = [
        poa(pos, z, anchors, rng=np.random.default_rng(42), n_iterations=3, region=(0, 0, 100, 100))
        for _ in range(2)
    ]
    a, b = runs
    assert a.dropped.shape[0] > 0  # Gaussian errors of 1 m produce inconsistencies
    np.testing.assert_array_equal(a.dropped, b.dropped)
    np.testing.assert_array_equal(a.area_history, b.area_history)
    for P, Q in zip(a.polygons, b.polygons, strict=True):
        assert not P.is_empty and np.all(np.isfinite(P.vertices))
        np.testing.assert_array_equal(P.vertices, Q.vertices)
    assert np.all(np.isfinite(a.area_history))
    assert np.all(np.diff(a.area_history, axis=0) <= 1e-9)
    for i, j in a.dropped:  # every dropped row is a measured link
        assert np.isfinite(z[j, i]) or np.isfinite(z[i, j])
    c = poa(pos, z, anchors, rng=np.random.default_rng(43), n_iterations=3, region=(0, 0, 100, 100))
    assert not np.array_equal(c.area_history, a.area_history)  # offsets come from rng


def test_no_nan_under_degenerate_inputs():
    # coincident anchors, a zero range (agent on an anchor), exact (tangent) ranges
    pos = np.array([[0.0, 0.0], [0.0, 0.0], [10.0, 0.0], [0.0, 0.0], [5.0, 0.0], [20.0, 0.0]])
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    z = d.copy()  # zero errors: every disk is tangent to the truth
    res = poa(pos, z, [0, 1, 2], rng=np.random.default_rng(0), n_iterations=3, n_edges=4)
    for P, j in zip(res.polygons, res.agents, strict=True):
        assert not P.is_empty and np.all(np.isfinite(P.vertices))
        assert np.all(np.isfinite(P.centroid)) and np.isfinite(P.area)
        assert _inside(P.vertices, pos[j], 1e-6)[0]
    assert np.all(np.isfinite(res.area_history))
    pt = res.polygon_of(3)
    assert pt.n_vertices == 1 and np.allclose(pt.vertices, 0.0)
    assert np.all(np.isfinite(pt.sample_uniform(5, np.random.default_rng(0))))
    # empty polygon: defined values, no NaN
    E = ConvexPolygon.empty()
    assert E.area == 0.0 and E.is_empty and not E.contains([0.0, 0.0]).any()
    A, c = E.halfspaces()
    assert np.all(np.isfinite(A)) and not np.all(A @ np.zeros(2) <= c)
    assert E.sample_uniform(0, np.random.default_rng(0)).shape == (0, 2)
    with pytest.raises(ValidationError, match="polygon"):
        _ = E.centroid
    # parallel edges and duplicate vertices
    P = ConvexPolygon([[0, 0], [1, 0], [1, 0], [2, 0], [2, 1], [0, 1], [0, 0.5]])
    assert P.n_vertices == 4 and P.area == pytest.approx(2.0)
    S = scale_polygon(P, 1.0)
    assert np.all(np.isfinite(S.vertices)) and S.area == pytest.approx(2 + 6 + 4)
    # ellipse baseline on the same degenerate network
    e = ellipse_outer_approximation(pos, z, [0, 1, 2], n_iterations=2)
    assert np.all(np.isfinite(e.centers)) and np.all(np.isfinite(e.shapes))
    assert np.all(np.isfinite(e.area_history))


# -- ellipse baseline (POA-NBP Fig. 9) -------------------------------------------------------------
def test_mvee_known_answers_and_twin():
    rect = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 2.0], [0.0, 2.0]])
    c, S, _ = K.mvee_kernel(rect, 1e-9, 10_000)
    np.testing.assert_allclose(c, [2.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(S, np.diag([8.0, 2.0]), atol=1e-6)  # semi-axes √2·(2, 1)
    hexagon = anchor_polygon([3.0, -1.0], 2.0, n_edges=6).vertices
    c, S, _ = K.mvee_kernel(hexagon, 1e-9, 10_000)
    r = 2.0 / math.cos(math.pi / 6)
    np.testing.assert_allclose(c, [3.0, -1.0], atol=1e-7)
    np.testing.assert_allclose(S, r**2 * np.eye(2), atol=1e-6 * r**2)
    pts = np.random.default_rng(0).normal(size=(60, 2)) * [3.0, 1.0]
    ck, Sk, _ = K.mvee_kernel(pts, 1e-7, 100_000)
    cn, Sn, _ = N.mvee_numpy(pts, 1e-7, 100_000)
    np.testing.assert_allclose(ck, cn, atol=1e-9)
    np.testing.assert_allclose(Sk, Sn, rtol=1e-9)
    q = np.einsum("ij,jk,ik->i", pts - ck, np.linalg.inv(Sk), pts - ck)
    assert np.all(q <= 1.0 + 1e-12) and q.max() == pytest.approx(1.0)


@pytest.mark.parametrize("seed", range(2))
def test_ellipse_baseline_contains_truth_and_shrinks(seed):
    pos, z, anchors = _network(seed)
    box = (0.0, 0.0, 100.0, 100.0)
    e = ellipse_outer_approximation(pos, z, anchors, n_iterations=3, region=box)
    p = poa(pos, z, anchors, rng=np.random.default_rng(0), n_iterations=3, region=box)
    assert e.area_history.shape == p.area_history.shape
    for a, j in enumerate(e.agents):
        assert e.bounded[a] and e.contains(a, pos[j])[0]
    H = e.area_history
    assert np.all(np.isfinite(H)) and np.all(np.diff(H, axis=0) <= 1e-9)
    # iteration 1: each ellipse contains the whole feasible set region ∩ anchor disks
    e1 = ellipse_outer_approximation(pos, z, anchors, n_iterations=1, region=box)
    rng = np.random.default_rng(seed)
    q = rng.uniform(0.0, 100.0, (20_000, 2))
    for a, j in enumerate(e1.agents):
        feasible = np.ones(len(q), dtype=bool)
        for i in anchors[np.isfinite(z[j, anchors])]:
            feasible &= np.linalg.norm(q - pos[i], axis=1) <= z[j, i]
        assert np.all(e1.contains(a, q[feasible]))
        k = feasible.sum()  # Monte Carlo area of the feasible set, minus 4 sigma
        assert e1.area_history[0, a] >= (k - 4 * math.sqrt(k) - 1) / len(q) * 100.0**2


# -- input validation ---------------------------------------------------------------------------
def test_validation_errors_name_the_parameter():
    pos, z, anchors = _network(0, n_agents=5)
    rng = np.random.default_rng(0)
    with pytest.raises(ValidationError, match="n_edges"):
        poa(pos, z, anchors, rng=rng, n_edges=2)
    with pytest.raises(ValidationError, match="n_iterations"):
        poa(pos, z, anchors, rng=rng, n_iterations=0)
    with pytest.raises(ValidationError, match="rng"):
        poa(pos, z, anchors, rng=np.random.RandomState(0))
    with pytest.raises(ValidationError, match="ranges"):
        poa(pos, z[:-1], anchors, rng=rng)
    with pytest.raises(ValidationError, match="anchors"):
        poa(pos, z, [0, 0], rng=rng)
    with pytest.raises(ValidationError, match="region"):
        poa(pos, z, anchors, rng=rng, region=(0, 0, 0, 100))
    with pytest.raises(ValidationError, match="max_turn_rad"):
        scale_polygon(ConvexPolygon.from_box(0, 0, 1, 1), 1.0, max_turn_rad=4.0)
    with pytest.raises(ValidationError, match="range_m"):
        anchor_polygon([0.0, 0.0], -1.0)
    with pytest.raises(ValidationError, match="center"):
        anchor_polygon([0.0, np.nan], 1.0)
    with pytest.raises(ValidationError, match="Q"):
        intersect(ConvexPolygon.from_box(0, 0, 1, 1), np.zeros((3, 2)))
    bad = pos.copy()
    bad[anchors[0]] = np.nan
    with pytest.raises(ValidationError, match="positions"):
        poa(bad, z, anchors, rng=rng)
