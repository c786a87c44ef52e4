"""The truth-free start on the measured pairs (phyloc.localization.sparse_start).

References: plain-NumPy twins of the two kernels written loop by loop here, the dense SMACOF
of phyloc.localization.mds (the same objective: both must reach the same stress from the same
start), exact Euclidean distances (the landmark start must recover the shape), and the
undetermined-agent rule checked on graphs built by hand.
"""

import numpy as np
import pytest

from phyloc.evaluation.metrics import framework_distance_errors, framework_distance_rmse
from phyloc.localization._start_kernels import (
    best_point_kernel,
    guttman_rhs_kernel,
    point_cost_kernel,
)
from phyloc.localization.initialization import coarse_positions, range_matrix
from phyloc.localization.mds import smacof
from phyloc.localization.sparse_start import (
    PairGraph,
    edge_stress,
    landmark_mds,
    pair_graph,
    relocate_local,
    sparse_smacof,
    undetermined_nodes,
)
from phyloc.network import NetworkSpec, make_network


def _graph_of(p, edges, noise=None):
    edges = np.asarray(edges, dtype=np.int64)
    pairs = np.unique(np.sort(edges, axis=1), axis=0)  # one edge per pair, i < j
    i, j = pairs[:, 0], pairs[:, 1]
    d = np.linalg.norm(p[i] - p[j], axis=1)
    if noise is not None:
        d = d + noise
    return PairGraph(p.shape[0], i, j, d, np.ones(i.size))


def _network(n, seed, comm=55.0):
    spec = NetworkSpec.from_dict(
        {"n_agents": n, "density_per_km2": 3000.0, "comm_range_m": comm, "on_isolated": "allow"}
    )
    return make_network(spec, np.random.default_rng(seed))


# -- kernels against loop-by-loop twins ------------------------------------------------------------
def _twin_point_cost(points, nbr, delta, w, c, one_sided):
    out = np.zeros(len(points))
    for p in range(len(points)):
        for j in range(len(nbr)):
            r = delta[j] - np.sqrt(np.sum((points[p] - nbr[j]) ** 2))
            z = (r / c) ** 2
            out[p] += w[j] * (z if (one_sided and r <= 0) else np.log1p(z))
    return out


def _twin_guttman(X, i, j, w, delta):
    BX = np.zeros_like(X)
    stress = 0.0
    for e in range(len(i)):
        diff = X[i[e]] - X[j[e]]
        d = np.sqrt(diff @ diff)
        stress += w[e] * (d - delta[e]) ** 2
        if d > 0:
            BX[i[e]] += w[e] * delta[e] / d * diff
            BX[j[e]] -= w[e] * delta[e] / d * diff
    return BX, stress


@pytest.mark.parametrize("one_sided", [False, True])
@pytest.mark.parametrize("dim", [2, 3])
def test_point_cost_kernel_matches_its_twin(one_sided, dim, rng):
    points = rng.normal(size=(17, dim)) * 20
    nbr = rng.normal(size=(9, dim)) * 20
    delta = rng.uniform(0, 40, 9)
    w = rng.uniform(0.1, 1, 9)
    got = point_cost_kernel(points, nbr, delta, w, 2.0, one_sided)
    np.testing.assert_allclose(got, _twin_point_cost(points, nbr, delta, w, 2.0, one_sided))


@pytest.mark.parametrize("one_sided", [False, True])
@pytest.mark.parametrize("dim", [2, 3])
def test_best_point_kernel_is_the_twins_first_argmin_and_min_bit_for_bit(one_sided, dim, rng):
    """The early-stopping search returns np.argmin / min of the full twin costs exactly,
    including a tie (the first of two equal best points wins) and a grid of 2000 points."""
    nbr = rng.normal(size=(25, dim)) * 20
    delta = np.linalg.norm(nbr - rng.normal(size=dim) * 5, axis=1) + rng.normal(0, 1, 25)
    w = rng.uniform(0.1, 1, 25)
    points = rng.normal(size=(2000, dim)) * 30
    full = point_cost_kernel(points, nbr, delta, w, 2.0, one_sided)
    k = int(np.argmin(full))
    points = np.insert(points, k + 7, points[k], axis=0)  # the same best point again, later
    twin = _twin_point_cost(points, nbr, delta, w, 2.0, one_sided)
    got_p, got_cost = best_point_kernel(points, nbr, delta, w, 2.0, one_sided)
    assert got_p == int(np.argmin(twin)) == k
    assert got_cost == point_cost_kernel(points, nbr, delta, w, 2.0, one_sided)[k]
    assert got_cost == pytest.approx(twin.min(), rel=1e-12)


def test_guttman_kernel_matches_its_twin_and_the_dense_stress(rng):
    X = rng.normal(size=(12, 2)) * 10
    X[3] = X[4]  # coincident nodes: no NaN, c = 0 on that edge
    edges = np.array([[a, b] for a in range(12) for b in range(a + 1, 12) if rng.random() < 0.5])
    edges = np.vstack([edges, [[3, 4]]])
    g = _graph_of(X + rng.normal(size=X.shape), edges)
    BX, s = guttman_rhs_kernel(X, g.i, g.j, g.w, g.delta)
    tBX, ts = _twin_guttman(X, g.i, g.j, g.w, g.delta)
    np.testing.assert_allclose(BX, tBX, atol=1e-12)
    assert np.all(np.isfinite(BX))
    assert s == pytest.approx(ts, rel=1e-12)
    assert edge_stress(g, X) == pytest.approx(ts, rel=1e-12)


# -- SMACOF on the edges = SMACOF on the matrices --------------------------------------------------
def test_sparse_smacof_reaches_the_dense_smacof_stress(rng):
    net = _network(40, 3)
    p = net.positions[0]
    lk = net.links
    r = np.linalg.norm(p[lk[:, 0]] - p[lk[:, 1]], axis=1) + rng.normal(0, 0.5, len(lk))
    D, W = range_matrix(lk, r, net.n_nodes)
    g = pair_graph(lk, r, np.ones(len(lk), bool), net.n_nodes, "mean")
    X0 = p + rng.normal(0, 3.0, p.shape)
    Xd, sd = smacof(D, W, X0, n_iter=2000, tol=0)
    Xs, ss = sparse_smacof(g, X0, n_iter=2000, tol=0)
    assert ss == pytest.approx(sd, rel=1e-6)
    assert framework_distance_rmse(Xs, Xd) < 1e-4


def test_sparse_smacof_stress_never_increases_and_fixed_rows_stay(rng):
    net = _network(60, 4)
    p = net.positions[0]
    g = _graph_of(p, net.links, None)
    g = PairGraph(g.n, g.i, g.j, g.delta + rng.normal(0, 1.0, g.n_edges), g.w)
    fixed = np.zeros(g.n, bool)
    fixed[:3] = True
    X = p + rng.normal(0, 5.0, p.shape)
    X[fixed] = p[fixed]
    last = edge_stress(g, X)
    for _ in range(20):
        X, s = sparse_smacof(g, X, n_iter=1, tol=0, fixed=fixed)
        assert s <= last * (1 + 1e-12)
        last = s
    np.testing.assert_array_equal(X[fixed], p[fixed])


def _assembled_system(g, fixed):
    """The Guttman system assembled with scipy.sparse and sliced, as the library did before it
    built the arrays in place: the reference the in-place build must equal bit for bit."""
    from scipy import sparse

    n = g.n
    diag = np.bincount(g.i, weights=g.w, minlength=n) + np.bincount(g.j, weights=g.w, minlength=n)
    rows = np.r_[g.i, g.j, np.arange(n)]
    cols = np.r_[g.j, g.i, np.arange(n)]
    V = sparse.csr_matrix((np.r_[-g.w, -g.w, diag], (rows, cols)), shape=(n, n))
    ridge = 1e-10 * max(V.diagonal().mean(), 1e-30)
    free = np.flatnonzero(~fixed)
    if not fixed.any():
        return (V + sparse.identity(n) * ridge).tocsc(), None
    A = V[free][:, free].tocsc() + sparse.identity(free.size, format="csc") * ridge
    return A, V[free][:, np.flatnonzero(fixed)]


@pytest.mark.parametrize("n_fixed", [0, 1, 3])
@pytest.mark.parametrize("seed", [5, 6])
def test_guttman_system_equals_the_scipy_assembly_bit_for_bit(n_fixed, seed):
    """Same index and data arrays as the scipy assembly (so splu and its solves give the same
    bits), on a range-limited network with an isolated node and anchors among the nodes."""
    from phyloc.localization.sparse_start import _guttman_system

    rng = np.random.default_rng(seed)
    net = _network(45, seed)
    p, lk = net.positions[0], net.links
    r = np.linalg.norm(p[lk[:, 0]] - p[lk[:, 1]], axis=1)
    g = pair_graph(lk, r, np.ones(len(lk), bool), net.n_nodes, "mean")  # unique pairs i < j
    g = g.with_weights(rng.uniform(0.01, 2.0, g.n_edges))
    keep = (g.i != 7) & (g.j != 7)  # node 7 isolated: its row is the ridge alone
    g = PairGraph(g.n, g.i[keep], g.j[keep], g.delta[keep], g.w[keep])
    fixed = np.zeros(g.n, bool)
    fixed[rng.choice(g.n, n_fixed, replace=False)] = True
    A, Vfa = _guttman_system(g, fixed)
    A_ref, Vfa_ref = _assembled_system(g, fixed)
    A_ref.sort_indices()
    for got, ref in ((A, A_ref), (Vfa, Vfa_ref)):
        if ref is None:
            assert got is None
            continue
        assert got.format == ref.format and got.shape == ref.shape
        np.testing.assert_array_equal(got.indptr, ref.indptr)
        np.testing.assert_array_equal(got.indices, ref.indices)
        np.testing.assert_array_equal(got.data, ref.data)


# -- landmark start --------------------------------------------------------------------------------
def test_landmark_mds_recovers_the_shape_from_exact_complete_distances(rng):
    p = rng.uniform(0, 100, (50, 2))
    edges = np.array([[a, b] for a in range(50) for b in range(a + 1, 50)])
    X = landmark_mds(_graph_of(p, edges), 2, n_landmarks=10)
    assert framework_distance_rmse(X, p) < 1e-8


def test_landmark_mds_centres_each_component_and_leaves_isolated_nodes_at_zero(rng):
    p = rng.uniform(0, 10, (9, 2))
    edges = [[0, 1], [1, 2], [0, 2], [2, 3], [5, 6], [6, 7], [5, 7]]
    X = landmark_mds(_graph_of(p, edges), 2)
    np.testing.assert_allclose(X[[0, 1, 2, 3]].mean(axis=0), 0, atol=1e-9)
    np.testing.assert_allclose(X[[5, 6, 7]].mean(axis=0), 0, atol=1e-9)
    np.testing.assert_array_equal(X[[4, 8]], 0.0)


# -- the undetermined-agent rule -------------------------------------------------------------------
def test_undetermined_rule_on_hand_built_graphs():
    p = np.zeros((10, 2))
    # nodes 0-4 fully linked (main component), node 5 with two links into it, 6-8 a triangle
    # apart, node 9 isolated
    edges = [[a, b] for a in range(5) for b in range(a + 1, 5)] + [[5, 0], [5, 1]]
    edges += [[6, 7], [7, 8], [6, 8]]
    und = undetermined_nodes(_graph_of(p, edges), 2)
    assert und.tolist() == [False] * 5 + [True] * 5
    # a lone measured triangle (or pair) is one shape: its nodes are determined
    tri = _graph_of(np.zeros((3, 2)), [[0, 1], [1, 2], [0, 2]])
    assert not undetermined_nodes(tri, 2).any()
    assert not undetermined_nodes(_graph_of(np.zeros((2, 2)), [[0, 1]]), 2).any()
    # in 3-D a node needs four neighbours: the fully linked five have four each
    assert undetermined_nodes(_graph_of(np.zeros((10, 3)), edges), 3)[:5].tolist() == [False] * 5
    # with anchors the frame is the anchors' component, and anchors are never undetermined
    anchor = np.zeros(10, bool)
    anchor[[6, 7, 8]] = True
    und = undetermined_nodes(_graph_of(p, edges), 2, anchor)
    assert und[[6, 7, 8]].tolist() == [False] * 3
    assert und[:6].all() and und[9]


# -- the whole start, and the metric over the links ------------------------------------------------
@pytest.mark.parametrize("one_sided", [False, True])
def test_sparse_start_rejects_nlos_biased_ranges_like_the_dense_one(one_sided, rng):
    net = _network(80, 7)
    p, lk = net.positions[0], net.links
    d = np.linalg.norm(p[lk[:, 0]] - p[lk[:, 1]], axis=1)
    biased = rng.random(d.size) < 0.15
    r = d + rng.normal(0, 0.2, d.size) + biased * rng.uniform(10, 60, d.size)
    kw = {
        "combine": "min",
        "robust_scale_m": [5.0, 2.0, 1.0],
        "one_sided": one_sided,
        "rng": rng,
    }
    sparse = coarse_positions(lk, r, net.n_nodes, 2, solver="sparse", **kw)
    dense = coarse_positions(lk, r, net.n_nodes, 2, solver="dense", **kw)
    e_s = framework_distance_errors(sparse.positions, p, pairs=lk)
    e_d = framework_distance_errors(dense.positions, p, pairs=lk)
    rmse_s, rmse_d = np.sqrt(np.mean(e_s**2)), np.sqrt(np.mean(e_d**2))
    assert rmse_s < 0.5  # NLOS-biased pairs (15 %, +10..60 m) no longer pull
    assert rmse_s < 1.5 * rmse_d + 0.05
    assert not sparse.undetermined.any()


def test_sparse_start_with_anchors_is_in_their_frame(rng):
    spec = NetworkSpec.from_dict(
        {"n_agents": 60, "anchors": 4, "region_m": [100, 100], "comm_range_m": 45.0}
    )
    net = make_network(spec, np.random.default_rng(2))
    p, lk = net.positions[0], net.links
    r = np.linalg.norm(p[lk[:, 0]] - p[lk[:, 1]], axis=1)
    sol = coarse_positions(
        lk,
        r,
        net.n_nodes,
        2,
        is_anchor=net.is_anchor,
        anchor_positions=p[net.is_anchor],
        solver="sparse",
    )
    assert sol.frame == "anchors"
    np.testing.assert_array_equal(sol.positions[net.is_anchor], p[net.is_anchor])
    assert np.max(np.abs(sol.positions - p)) < 1e-3


def test_sparse_start_on_a_disconnected_network_flags_the_small_part(rng):
    p = np.r_[rng.uniform(0, 40, (30, 2)), rng.uniform(500, 520, (4, 2))]
    lk = np.array([[a, b] for a in range(34) for b in range(34) if a != b])
    d = np.linalg.norm(p[lk[:, 0]] - p[lk[:, 1]], axis=1)
    near = d < 30.0
    sol = coarse_positions(lk[near], d[near], 34, 2, solver="sparse")
    assert np.all(np.isfinite(sol.positions))
    assert sol.undetermined[30:].all()
    assert framework_distance_rmse(sol.positions[:30], p[:30]) < 1e-3


def test_relocate_local_moves_only_a_misplaced_node(rng):
    net = _network(50, 9)
    p = net.positions[0]
    g = _graph_of(p, net.links)
    X = p.copy()
    X[7] = X[7] + np.array([60.0, -40.0])
    moved_X, moved = relocate_local(g, X, 1.0)
    assert moved.tolist() == [7]
    assert np.linalg.norm(moved_X[7] - p[7]) < 1.0
    np.testing.assert_array_equal(np.delete(moved_X, 7, 0), np.delete(p, 7, 0))


def test_framework_errors_over_links_are_eq4_restricted_to_the_edges(rng):
    p = rng.uniform(0, 50, (6, 2))
    q = p + rng.normal(0, 1, p.shape)
    anchor = np.array([0, 0, 0, 0, 1, 1], bool)
    links = np.array([[0, 1], [1, 0], [0, 4], [4, 0], [2, 5], [4, 5]])
    got = framework_distance_errors(q, p, anchor, pairs=links)
    want = [
        abs(np.linalg.norm(q[u] - q[v]) - np.linalg.norm(p[u] - p[v]))
        for u, v in links
        if not anchor[u]
    ]
    np.testing.assert_allclose(got, want)
    # every ordered pair given: the published eq. (4)
    every = np.array([[u, v] for u in range(6) for v in range(6) if u != v])
    np.testing.assert_allclose(
        framework_distance_errors(q, p, anchor, pairs=every),
        framework_distance_errors(q, p, anchor),
    )
