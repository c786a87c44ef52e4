"""Truth-free coarse network solution and priors (phyloc.localization.initialization, .mds,
.priors and .gauge).

References: exact Euclidean distances (MDS must recover the configuration up to a rigid
transform), a loop-by-loop Guttman transform written here, the metrics of
phyloc.evaluation (framework distance RMSE, rigid alignment), and sample statistics of seeded
draws against their distributions.
"""

import numpy as np
import pytest
from scipy import stats

from phyloc.errors import ValidationError
from phyloc.evaluation.metrics import framework_distance_rmse, rigid_align
from phyloc.localization.gauge import gauge_log_prior, gauge_priors
from phyloc.localization.initialization import coarse_positions, range_matrix, relocate_nodes
from phyloc.localization.mds import classical_mds, raw_stress, shortest_path_completion, smacof
from phyloc.localization.priors import gaussian_log_prior, gaussian_priors, informed_centers
from phyloc.network import NetworkSpec, make_network


def _all_links(n):
    return np.array([[u, w] for u in range(n) for w in range(n) if u != w], dtype=np.int64)


def _dist(p, links):
    return np.linalg.norm(p[links[:, 0]] - p[links[:, 1]], axis=1)


def _full_d(p):
    return np.linalg.norm(p[:, None] - p[None], axis=-1)


def _naive_stress(X, D, W):
    s = 0.0
    for i in range(len(X)):
        for j in range(i + 1, len(X)):
            s += W[i, j] * (np.linalg.norm(X[i] - X[j]) - D[i, j]) ** 2
    return s


def _naive_guttman(X, D, W):
    """One Guttman transform by loops; V⁺ = (V + 11ᵀ/n)⁻¹ − 11ᵀ/n (connected graph)."""
    n = len(X)
    V = np.zeros((n, n))
    B = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            V[i, j] = -W[i, j]
            V[i, i] += W[i, j]
            dij = np.linalg.norm(X[i] - X[j])
            b = W[i, j] * D[i, j] / dij if dij > 0 else 0.0
            B[i, j] = -b
            B[i, i] += b
    one = np.ones((n, n)) / n
    return (np.linalg.inv(V + one) - one) @ B @ X


@pytest.fixture
def comm_range_network(rng):
    """30 agents + 4 corner anchors in 100 m × 100 m, 55 m range: about half of the pairs.

    Every node has >= 3 neighbours: a node with one or two ranges could swing or flip at zero
    stress (not rigidly determined), which no range-only method can resolve.
    """
    net = make_network(NetworkSpec(n_agents=30, comm_range_m=55.0, anchors=4), rng)
    assert net.adjacency().sum(axis=1).min() >= 3
    return net


# -- range matrix -------------------------------------------------------------------------------
def test_range_matrix_averages_and_marks_missing():
    links = [[0, 1], [1, 0], [1, 2], [2, 1], [0, 3], [2, 3]]
    ranges = [10.0, 12.0, 7.0, np.nan, 5.0, -0.5]
    valid = np.array([True, True, True, True, False, True])
    D, W = range_matrix(links, ranges, 4, valid)
    assert D[0, 1] == D[1, 0] == 11.0  # both directions averaged
    assert D[1, 2] == D[2, 1] == 7.0  # NaN direction ignored
    assert W[0, 3] == 0.0 and D[0, 3] == 0.0  # invalid -> missing
    assert W[2, 3] == 1.0 and D[2, 3] == 0.0  # negative estimate clipped
    np.testing.assert_array_equal(W, W.T)
    np.testing.assert_array_equal(np.diag(W), 0.0)
    assert W.sum() == 2 * 3
    # clipping happens after averaging: (−0.2 + 0.6)/2
    D2, _ = range_matrix([[0, 1], [1, 0]], [-0.2, 0.6], 2)
    assert D2[0, 1] == pytest.approx(0.2)


@pytest.mark.parametrize(
    "links, ranges, match",
    [
        ([[0, 0]], [1.0], "self-link"),
        ([[0, 5]], [1.0], "out of range"),
        ([[0, 1]], [np.inf], "finite"),
        ([[0, 1]], [1.0, 2.0], "ranges"),
        ([[0, 1, 2]], [1.0], "n_links, 2"),
    ],
)
def test_range_matrix_rejects_bad_input(links, ranges, match):
    with pytest.raises(ValidationError, match=match):
        range_matrix(links, ranges, 3)


# -- classical MDS ------------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [2, 3])
def test_mds_exact_distances_recover_configuration(dim, rng):
    p = rng.uniform(0, 100, size=(25, dim))
    X = classical_mds(_full_d(p), dim)
    assert framework_distance_rmse(X, p) < 1e-9
    _, _, aligned = rigid_align(X, p)
    np.testing.assert_allclose(aligned, p, atol=1e-8)
    np.testing.assert_allclose(X.mean(axis=0), 0.0, atol=1e-9)  # centred


def test_mds_ignores_unread_entries_and_fills_by_shortest_path():
    # path 0–1–2 on a line, pair (0, 2) missing: shortest path 3 + 4 = 7 = the true distance
    D = np.array([[0.0, 3.0, np.nan], [3.0, 0.0, 4.0], [np.nan, 4.0, 0.0]])
    W = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], dtype=float)
    full = shortest_path_completion(D, W)
    assert full[0, 2] == full[2, 0] == 7.0
    X = classical_mds(D, 2, W)
    np.testing.assert_allclose(_full_d(X), [[0, 3, 7], [3, 0, 4], [7, 4, 0]], atol=1e-9)


def test_mds_degenerate_configurations():
    # 2 nodes: ±d/2 on the first axis
    np.testing.assert_allclose(classical_mds([[0.0, 8.0], [8.0, 0.0]], 2), [[4, 0], [-4, 0]])
    # collinear nodes: exact distances, zero second coordinate
    p = np.array([[0.0, 0.0], [1.0, 1.0], [3.0, 3.0], [7.0, 7.0]])
    X = classical_mds(_full_d(p), 2)
    np.testing.assert_allclose(_full_d(X), _full_d(p), atol=1e-9)
    np.testing.assert_allclose(X[:, 1], 0.0, atol=1e-9)
    # coplanar nodes in 3-D
    q = np.c_[np.random.default_rng(0).uniform(0, 10, (6, 2)), np.zeros(6)]
    X3 = classical_mds(_full_d(q), 3)
    np.testing.assert_allclose(_full_d(X3), _full_d(q), atol=1e-8)
    np.testing.assert_allclose(X3[:, 2], 0.0, atol=1e-7)


def test_mds_is_deterministic(rng):
    p = rng.uniform(0, 100, size=(12, 2))
    np.testing.assert_array_equal(classical_mds(_full_d(p), 2), classical_mds(_full_d(p), 2))


def test_disconnected_graph_and_node_without_range_raise(rng):
    p = rng.uniform(0, 100, size=(5, 2))
    W = np.ones((5, 5)) - np.eye(5)
    W[4, :] = W[:, 4] = 0.0  # node 4 has no valid range
    with pytest.raises(ValidationError, match=r"without any valid range: \[4\]"):
        classical_mds(_full_d(p), 2, W)
    links = np.array([[0, 1], [1, 0], [2, 3], [3, 2]])  # two separate pairs
    with pytest.raises(ValidationError, match="2 connected components"):
        coarse_positions(links, np.ones(4), 4, 2)


def test_mds_validation():
    with pytest.raises(ValidationError, match="dim"):
        classical_mds(np.zeros((3, 3)), 4)
    with pytest.raises(ValidationError, match="symmetric"):
        classical_mds([[0.0, 1.0], [2.0, 0.0]], 2)
    with pytest.raises(ValidationError, match="square"):
        classical_mds(np.zeros((2, 3)), 2)
    with pytest.raises(ValidationError, match="finite and >= 0"):
        classical_mds([[0.0, -1.0], [-1.0, 0.0]], 2)


# -- SMACOF -------------------------------------------------------------------------------------
def test_stress_and_guttman_step_match_loops(rng):
    p = rng.uniform(0, 50, size=(8, 2))
    D = _full_d(p) + np.triu(rng.normal(0, 2, (8, 8)), 1)
    D = np.abs(np.triu(D, 1) + np.triu(D, 1).T)
    W = rng.uniform(0.5, 2.0, (8, 8))
    W = np.triu(W, 1) + np.triu(W, 1).T
    W[0, 1] = W[1, 0] = 0.0  # a missing pair, still connected
    X0 = rng.uniform(0, 50, size=(8, 2))
    assert raw_stress(X0, D, W) == pytest.approx(_naive_stress(X0, D, W), rel=1e-12)
    X1, s1 = smacof(D, W, X0, n_iter=1, tol=0)
    np.testing.assert_allclose(X1, _naive_guttman(X0, D, W), rtol=1e-9, atol=1e-9)
    assert s1 == pytest.approx(_naive_stress(X1, D, W), rel=1e-12)


def test_smacof_stress_never_increases_on_noisy_missing_data(comm_range_network, rng):
    net = comm_range_network
    p = net.positions[0]
    ranges = net.distances() + rng.normal(0, 1.0, net.links.shape[0])
    D, W = range_matrix(net.links, ranges, net.n_nodes)
    X0 = classical_mds(D, 2, W)
    X, s, hist = smacof(D, W, X0, n_iter=500, tol=0, return_history=True)
    assert hist.size > 100  # it really iterated
    assert np.all(np.diff(hist) <= 1e-12 * hist[:-1])
    assert hist[0] == pytest.approx(raw_stress(X0, D, W))
    assert s == hist[-1] == pytest.approx(raw_stress(X, D, W))
    # MDS on shortest paths is biased; SMACOF fits the measured pairs much better
    assert s < 0.5 * hist[0]
    assert framework_distance_rmse(X, p) < framework_distance_rmse(X0, p)


def test_smacof_converges_to_exact_configuration_with_missing_pairs(comm_range_network):
    net = comm_range_network
    p = net.positions[0]
    D, W = range_matrix(net.links, net.distances(), net.n_nodes)
    assert W.sum() < 0.65 * net.n_nodes * (net.n_nodes - 1)  # really incomplete
    X0 = classical_mds(D, 2, W)
    assert framework_distance_rmse(X0, p) > 0.1  # shortest paths are not distances
    X, s = smacof(D, W, X0, n_iter=5000, tol=0)
    assert s < 1e-12
    assert framework_distance_rmse(X, p) < 1e-6


def test_smacof_fixed_rows_stay_and_stress_decreases(rng):
    p = rng.uniform(0, 50, size=(10, 2))
    D = _full_d(p)
    fixed = np.zeros(10, dtype=bool)
    fixed[:3] = True
    X0 = p + rng.normal(0, 5.0, p.shape)
    X0[fixed] = p[fixed]
    X, _, hist = smacof(D, None, X0, n_iter=3000, tol=0, fixed=fixed, return_history=True)
    np.testing.assert_array_equal(X[fixed], p[fixed])
    # exact data: σ reaches the rounding floor (~1e-25 m²), where it may jitter
    assert np.all(np.diff(hist) <= 1e-12 * hist[:-1] + 1e-20)
    assert hist[-1] < 1e-15
    np.testing.assert_allclose(X, p, atol=1e-5)  # fixed anchors pin the frame: absolute


def test_smacof_validation():
    D = np.zeros((3, 3))
    with pytest.raises(ValidationError, match="X0"):
        smacof(D, None, np.zeros((2, 2)))
    with pytest.raises(ValidationError, match="fixed"):
        smacof(D, None, np.zeros((3, 2)), fixed=[1, 0, 0])
    with pytest.raises(ValidationError, match="W"):
        smacof(D, -np.ones((3, 3)), np.zeros((3, 2)))


# -- coarse positions ---------------------------------------------------------------------------
def test_coarse_positions_with_anchors_is_in_the_anchor_frame(comm_range_network, rng):
    net = comm_range_network
    p = net.positions[0]
    sigma = 0.5
    ranges = net.distances() + rng.normal(0, sigma, net.links.shape[0])
    sol = coarse_positions(
        net.links, ranges, net.n_nodes, 2, is_anchor=net.is_anchor,
        anchor_positions=p[net.is_anchor],
    )  # fmt: skip
    assert sol.frame == "anchors"
    np.testing.assert_array_equal(sol.positions[net.is_anchor], p[net.is_anchor])
    # no alignment with the truth: the absolute error is of the order of the ranging noise
    err = np.linalg.norm(sol.positions - p, axis=1)[~net.is_anchor]
    assert np.sqrt(np.mean(err**2)) < 2 * sigma
    assert err.max() < 8 * sigma
    assert 0.3 * sigma < sol.residual_rms_m < 1.5 * sigma


@pytest.mark.parametrize("n_iter", [0, 300], ids=["alignment only", "with SMACOF"])
@pytest.mark.parametrize("mirror", [False, True])
def test_coarse_positions_resolves_reflection(mirror, n_iter, rng):
    # MDS sees the same distances for p and its mirror image, so its output has the wrong
    # handedness for one of the two: the anchor fit must reflect it back (3 anchors, no
    # symmetry between them). With n_iter = 0 (exact MDS, no SMACOF refinement) the rigid
    # fit alone must do it.
    p = rng.uniform(0, 100, size=(12, 2))
    p[-3:] = [[0, 0], [100, 10], [30, 100]]
    if mirror:
        p[:, 0] = 100.0 - p[:, 0]
    links = _all_links(12)
    anchor = np.zeros(12, dtype=bool)
    anchor[-3:] = True
    anchor_links = anchor[links[:, 0]] & anchor[links[:, 1]]
    sol = coarse_positions(
        links[~anchor_links], _dist(p, links[~anchor_links]), 12, 2, is_anchor=anchor,
        anchor_positions=p[anchor], n_iter=n_iter,
    )  # fmt: skip
    np.testing.assert_allclose(sol.positions, p, atol=1e-6)


def test_coarse_positions_3d_with_anchors(rng):
    p = rng.uniform(0, 20, size=(15, 3))
    anchor = np.zeros(15, dtype=bool)
    anchor[:5] = True
    links = _all_links(15)
    sol = coarse_positions(
        links, _dist(p, links), 15, 3, is_anchor=anchor, anchor_positions=p[anchor]
    )
    assert sol.frame == "anchors"
    np.testing.assert_allclose(sol.positions, p, atol=1e-6)


def test_coarse_positions_anchor_free_is_arbitrary_frame(comm_range_network, rng):
    net = comm_range_network
    p = net.positions[0]
    ranges = net.distances() + rng.normal(0, 0.5, net.links.shape[0])
    sol = coarse_positions(net.links, ranges, net.n_nodes, 2)
    assert sol.frame == "arbitrary"
    np.testing.assert_allclose(sol.positions.mean(axis=0), 0.0, atol=1e-6)
    assert framework_distance_rmse(sol.positions, p) < 2.0
    # a naive guess (everything at the region centre) is far worse
    assert framework_distance_rmse(np.full_like(p, 50.0), p) > 20.0


@pytest.mark.parametrize(
    "anchor_idx",
    [[0], [0, 1], [0, 1, 2]],
    ids=["one anchor", "two anchors", "three collinear anchors"],
)
def test_coarse_positions_with_too_few_or_degenerate_anchors(anchor_idx, rng):
    p = rng.uniform(0, 100, size=(10, 2))
    p[2] = p[0] + 0.3 * (p[1] - p[0])  # makes anchors 0, 1, 2 collinear
    anchor = np.zeros(10, dtype=bool)
    anchor[anchor_idx] = True
    links = _all_links(10)
    sol = coarse_positions(
        links, _dist(p, links), 10, 2, is_anchor=anchor, anchor_positions=p[anchor]
    )
    assert sol.frame == "partial"
    np.testing.assert_array_equal(sol.positions[anchor], p[anchor])  # anchors exact
    assert framework_distance_rmse(sol.positions, p) < 1e-6  # shape still right
    # the remaining freedom (rotation about / mirror across the anchors) is all that is left
    _, _, aligned = rigid_align(sol.positions, p, is_anchor=anchor)
    np.testing.assert_allclose(aligned, p, atol=1e-6)


def test_coarse_positions_two_nodes_and_validation():
    sol = coarse_positions([[0, 1], [1, 0]], [6.0, 6.2], 2, 2)
    assert np.linalg.norm(sol.positions[0] - sol.positions[1]) == pytest.approx(6.1)
    links = _all_links(4)
    with pytest.raises(ValidationError, match="anchor_positions"):
        coarse_positions(links, np.ones(12), 4, 2, is_anchor=np.array([1, 1, 1, 0], bool))
    with pytest.raises(ValidationError, match=r"anchor_positions"):
        coarse_positions(
            links, np.ones(12), 4, 2, is_anchor=np.array([1, 1, 1, 0], bool),
            anchor_positions=np.zeros((2, 2)),
        )  # fmt: skip
    with pytest.raises(ValidationError, match="n_nodes"):
        coarse_positions(np.zeros((0, 2), int), [], 1, 2)
    with pytest.raises(ValidationError, match="rng"):
        coarse_positions(links, np.ones(12), 4, 2, n_restarts=2)


def test_coarse_positions_reproducible_and_restarts_never_worse(comm_range_network):
    net = comm_range_network
    noise = np.random.default_rng(5).normal(0, 2.0, net.links.shape[0])
    ranges = net.distances() + noise
    base = coarse_positions(net.links, ranges, net.n_nodes, 2)
    a = coarse_positions(
        net.links, ranges, net.n_nodes, 2, n_restarts=3, rng=np.random.default_rng(9)
    )
    b = coarse_positions(
        net.links, ranges, net.n_nodes, 2, n_restarts=3, rng=np.random.default_rng(9)
    )
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.stress <= base.stress


# -- priors -------------------------------------------------------------------------------------
def test_gaussian_priors_moments(rng):
    centers = np.array([[0.0, 0.0], [10.0, -5.0], [100.0, 50.0]])
    std = np.array([1.0, 5.0, 10.0])
    Q = 20_000
    x = gaussian_priors(centers, std, Q, rng)
    assert x.shape == (3, Q, 2)
    # mean within 5 standard errors; sample std within 5·σ/√(2Q) ≈ 2.5 %
    assert np.all(np.abs(x.mean(axis=1) - centers) < 5 * std[:, None] / np.sqrt(Q))
    np.testing.assert_allclose(x.std(axis=1), np.repeat(std[:, None], 2, axis=1), rtol=0.025)
    # independent axes
    assert abs(np.corrcoef(x[1, :, 0], x[1, :, 1])[0, 1]) < 5 / np.sqrt(Q)
    # a scalar std is broadcast to every agent
    y = gaussian_priors(centers, 2.0, Q, rng)
    np.testing.assert_allclose(y.std(axis=1), 2.0, rtol=0.025)


def test_gaussian_log_prior_matches_scipy(rng):
    centers = rng.uniform(0, 100, size=(3, 3))
    std = np.array([0.5, 2.0, 7.0])
    x = gaussian_priors(centers, std, 50, rng)
    lp = gaussian_log_prior(x, centers, std)
    for u in range(3):
        ref = stats.multivariate_normal(centers[u], std[u] ** 2 * np.eye(3)).logpdf(x[u])
        np.testing.assert_allclose(lp[u], ref, rtol=1e-12)


def test_priors_reproducible_with_seed():
    c = np.zeros((4, 2))
    a = gaussian_priors(c, 3.0, 100, np.random.default_rng(1))
    b = gaussian_priors(c, 3.0, 100, np.random.default_rng(1))
    np.testing.assert_array_equal(a, b)
    g1 = gauge_priors(5, 3, 100, 50.0, np.random.default_rng(2))
    g2 = gauge_priors(5, 3, 100, 50.0, np.random.default_rng(2))
    np.testing.assert_array_equal(g1, g2)
    t = np.ones((3, 2))
    np.testing.assert_array_equal(
        informed_centers(t, rng=np.random.default_rng(3)),
        informed_centers(t, rng=np.random.default_rng(3)),
    )


def test_prior_validation(rng):
    with pytest.raises(ValidationError, match="std_m"):
        gaussian_priors(np.zeros((2, 2)), 0.0, 10, rng)
    with pytest.raises(ValidationError, match="std_m"):
        gaussian_priors(np.zeros((2, 2)), [1.0, 2.0, 3.0], 10, rng)
    with pytest.raises(ValidationError, match="rng"):
        gaussian_priors(np.zeros((2, 2)), 1.0, 10, 42)
    with pytest.raises(ValidationError, match="Q"):
        gaussian_priors(np.zeros((2, 2)), 1.0, 0, rng)
    with pytest.raises(ValidationError, match="particles"):
        gaussian_log_prior(np.zeros((2, 5, 3)), np.zeros((2, 2)), 1.0)
    with pytest.raises(ValidationError, match="extent_m"):
        gauge_priors(3, 2, 10, 0.0, rng)
    with pytest.raises(ValidationError, match="dim"):
        gauge_priors(3, 4, 10, 1.0, rng)


def test_informed_centers_statistics(rng):
    truth = rng.uniform(0, 100, size=(20_000, 2))
    c = informed_centers(truth, rng=rng)  # σ0 = 10 m by default
    err = c - truth
    assert abs(err.mean()) < 5 * 10.0 / np.sqrt(err.size)
    assert err.std() == pytest.approx(10.0, rel=0.02)
    np.testing.assert_array_equal(informed_centers(truth, 0.0, rng=rng), truth)
    assert informed_centers(truth, 3.0, rng=rng).shape == truth.shape


@pytest.mark.parametrize("dim", [2, 3])
def test_gauge_priors_constraints(dim, rng):
    e = 150.0
    x = gauge_priors(7, dim, 5000, e, rng)
    assert x.shape == (7, 5000, dim)
    assert np.all(x[0] == 0.0)  # origin
    assert np.all(x[1, :, 0] >= 0) and np.all(x[1, :, 1:] == 0.0)  # positive x-axis
    assert np.all(x[2, :, 1] >= 0)  # upper half-plane
    if dim == 3:
        assert np.all(x[2, :, 2] == 0.0) and np.all(x[3, :, 2] >= 0)
    assert np.all(np.abs(x) <= e)
    # uniform on their supports: means and spreads of U(0, e) and U(−e, e)
    tol = 5 * e / np.sqrt(12 * 5000)
    assert abs(x[1, :, 0].mean() - e / 2) < tol
    assert abs(x[2, :, 1].mean() - e / 2) < tol
    assert abs(x[-1, :, 0].mean()) < 2 * tol
    assert x[-1, :, 0].std() == pytest.approx(2 * e / np.sqrt(12), rel=0.05)
    assert stats.kstest(x[-1, :, 1], stats.uniform(-e, 2 * e).cdf).pvalue > 1e-3
    # every drawn particle is inside the support of the log prior
    assert np.all(gauge_log_prior(x, e) == 0.0)


def test_gauge_log_prior_outside_support():
    e = 10.0
    x = np.zeros((5, 1, 3))
    x[3, 0, 2] = 1.0
    assert np.all(gauge_log_prior(x, e) == 0.0)
    cases = [
        (0, (0, 0, 0.1)),  # agent 0 off the origin
        (1, (0, 0, -1.0)),  # agent 1 on the negative x-axis
        (1, (0, 1, 0.5)),  # agent 1 off the axis
        (2, (0, 1, -1.0)),  # agent 2 below the x-axis
        (2, (0, 2, 1.0)),  # agent 2 out of the xy-plane (3-D)
        (3, (0, 2, -1.0)),  # agent 3 below the xy-plane (3-D)
        (4, (0, 0, 10.5)),  # beyond the extent
    ]
    for agent, (q, axis, value) in cases:
        y = x.copy()
        y[agent, q, axis] = value
        lp = gauge_log_prior(y, e)
        assert lp[agent, 0] == -np.inf, (agent, axis, value)
        assert np.sum(np.isinf(lp)) == 1
    # in 2-D agent 3 is unconstrained (besides the extent)
    x2 = np.array([[[0, 0]], [[1, 0]], [[0, 1]], [[-3, -4]]], dtype=float)
    assert gauge_log_prior(x2, e)[3, 0] == 0.0


# -- robust truth-free start (NLOS-biased ranges) ----------------------------------------------
def test_range_matrix_min_keeps_the_shortest_valid_range():
    links = [[0, 1], [1, 0], [1, 2], [2, 1], [0, 2]]
    r = [10.0, 95.0, 7.0, np.nan, 30.0]
    valid = np.array([True, True, True, True, False])
    D, W = range_matrix(links, r, 3, valid, combine="min")
    assert D[0, 1] == D[1, 0] == 10.0  # the NLOS-biased 95 m direction is not averaged in
    assert D[1, 2] == 7.0 and W[0, 2] == 0.0 and D[0, 2] == 0.0
    with pytest.raises(ValidationError, match="combine"):
        range_matrix(links, r, 3, combine="median")


def test_robust_smacof_rejects_biased_ranges_and_leaves_exact_ones_alone():
    """Positive biases of 40–120 m on 8 % of the links (NLOS): plain SMACOF is pulled metres
    off, the Cauchy-reweighted fit recovers the network; on exact ranges both agree."""
    rng = np.random.default_rng(5)
    n = 15
    P = rng.uniform(0, 100, (n, 2))
    links = np.array([[i, j] for i in range(n) for j in range(n) if i != j])
    exact = np.linalg.norm(P[links[:, 0]] - P[links[:, 1]], axis=1)
    biased = exact + rng.normal(0, 0.1, exact.size)
    hit = rng.random(exact.size) < 0.08
    biased[hit] += rng.uniform(40, 120, hit.sum())
    err = {}
    for combine in ("mean", "min"):
        plain = coarse_positions(links, biased, n, 2, combine=combine)
        robust = coarse_positions(links, biased, n, 2, combine=combine, robust_scale_m=5.0)
        err[combine] = framework_distance_rmse(robust.positions, P)
        assert framework_distance_rmse(plain.positions, P) > 2.0
        assert err[combine] < 0.05 * framework_distance_rmse(plain.positions, P)
    # the shortest direction leaves fewer biased pairs, and Cauchy weights a residual pull of
    # ~c²/r per outlier: with "min" the fit is within twice the 0.1 m range noise
    assert err["min"] < 0.15 and err["min"] < err["mean"]
    a = coarse_positions(links, exact, n, 2)
    b = coarse_positions(links, exact, n, 2, robust_scale_m=5.0, combine="min")
    assert framework_distance_rmse(b.positions, P) < 1e-4
    assert framework_distance_rmse(a.positions, b.positions) < 1e-4
    with pytest.raises(ValidationError, match="robust_scale_m"):
        coarse_positions(links, exact, n, 2, robust_scale_m=-1.0)
    with pytest.raises(ValidationError, match="robust_rounds"):
        coarse_positions(links, exact, n, 2, robust_scale_m=5.0, robust_rounds=0)


def test_weakly_weighted_invalid_ranges_place_a_silent_node_without_bending_the_rest():
    """A node whose links all fail detection: its noise ranges at weight 1e-3 place it (a
    guess), while the detected part of the network keeps its exact shape; at full weight
    the same noise bends it."""
    rng = np.random.default_rng(4)
    n = 8
    P = rng.uniform(0, 100, (n, 2))
    links = np.array([[i, j] for i in range(n) for j in range(n) if i != j])
    r = np.linalg.norm(P[links[:, 0]] - P[links[:, 1]], axis=1)
    silent = (links[:, 0] == 7) | (links[:, 1] == 7)
    r[silent] = rng.uniform(0, 300, silent.sum())  # noise peaks
    valid = ~silent
    with pytest.raises(ValidationError):
        coarse_positions(links, r, n, 2, valid=valid)
    weak = coarse_positions(links, r, n, 2, valid=valid, invalid_weight=1e-3)
    full = coarse_positions(links, r, n, 2)
    assert framework_distance_rmse(weak.positions[:7], P[:7]) < 0.05
    assert framework_distance_rmse(full.positions[:7], P[:7]) > 1.0
    D, W = range_matrix(links, r, n, valid, invalid_weight=1e-3)
    assert np.all(W[7, :7] == 1e-3) and np.all(W[:7, :7][~np.eye(7, dtype=bool)] == 1.0)
    r_pair = {(a, b): x for (a, b), x in zip(links.tolist(), r, strict=True)}
    for j in range(7):  # the weak pairs carry the mean of their two invalid ranges
        assert D[7, j] == pytest.approx(0.5 * (r_pair[(7, j)] + r_pair[(j, 7)]))
    with pytest.raises(ValidationError, match="invalid_weight"):
        range_matrix(links, r, n, valid, invalid_weight=1.0)


def test_relocate_moves_a_node_stuck_in_a_wrong_basin_and_nothing_else():
    """A node 100 m out of a network whose ranges to it are exact except two biased by
    +200 m (the configuration robust SMACOF can be trapped in): its Cauchy cost is lowest at
    its true position, so it moves there (to the grid's resolution); a correct configuration
    and anchors stay where they are."""
    rng = np.random.default_rng(9)
    n, c = 12, 5.0
    P = rng.uniform(0, 100, (n, 2))
    D = np.linalg.norm(P[:, None] - P[None], axis=-1)
    D[0, [3, 7]] += 200.0
    D[[3, 7], 0] += 200.0
    W = 1.0 - np.eye(n)
    X = P.copy()
    X[0] = P[0] + np.array([100.0, 40.0])
    out, moved = relocate_nodes(D, W, X, c)
    assert moved.tolist() == [0]
    cell = 1.5 * 100 / 40 * 4 / 40  # fine grid: 4 coarse cells (box < 150 m, 41 points)
    assert np.linalg.norm(out[0] - P[0]) < cell
    np.testing.assert_array_equal(out[1:], X[1:])
    same, none = relocate_nodes(D, W, P, c)
    assert none.size == 0 and np.array_equal(same, P)
    fixed = np.zeros(n, bool)
    fixed[0] = True
    kept, none = relocate_nodes(D, W, X, c, fixed=fixed)
    assert none.size == 0 and np.array_equal(kept, X)


def test_robust_restarts_never_raise_the_robust_cost():
    """``n_restarts`` with ``robust_scale_m``: every start goes through the robust fit and the
    lowest total Cauchy cost wins, so the cost with restarts is at most the cost of the MDS
    start alone, on sparse networks with NLOS-biased ranges (8 seeds); restarts are drawn
    from the passed generator (reproducible)."""
    worse = 0
    better = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        n = 10
        P = rng.uniform(0, 100, (n, 2))
        links = np.array([[i, j] for i in range(n) for j in range(n) if i != j])
        r = np.linalg.norm(P[links[:, 0]] - P[links[:, 1]], axis=1) + rng.normal(0, 0.1, 90)
        hit = rng.random(r.size) < 0.15
        r[hit] += rng.uniform(40, 200, hit.sum())
        valid = rng.random(r.size) < 0.45
        kw = dict(valid=valid, combine="min", robust_scale_m=5.0, invalid_weight=1e-3)

        D, Wm = range_matrix(links, r, n, valid, combine="min", invalid_weight=1e-3)

        def cost(X, D=D, Wm=Wm):
            res = D - np.linalg.norm(X[:, None] - X[None], axis=-1)
            return float(np.sum(np.triu(Wm * np.log1p((res / 5.0) ** 2), 1)))

        one = coarse_positions(links, r, n, 2, **kw)
        many = coarse_positions(links, r, n, 2, n_restarts=4, rng=np.random.default_rng(1), **kw)
        again = coarse_positions(links, r, n, 2, n_restarts=4, rng=np.random.default_rng(1), **kw)
        assert np.array_equal(many.positions, again.positions)
        worse += cost(many.positions) > cost(one.positions) + 1e-6
        better += cost(many.positions) < cost(one.positions) - 1.0
    assert worse == 0 and better >= 1


def _nlos_network(seed, n, fraction):
    """``n`` nodes in 100 m × 100 m, all directed links; a ``fraction`` of the pairs NLOS with
    both directions late by U(30, 120) m (WINNER II C2's NLOS excess delay is ~90 m)."""
    rng = np.random.default_rng(seed)
    P = rng.uniform(0, 100, (n, 2))
    links = np.array([[i, j] for i in range(n) for j in range(n) if i != j])
    nlos = np.zeros((n, n), bool)
    iu = np.triu_indices(n, 1)
    nlos[iu] = rng.random(iu[0].size) < fraction
    nlos |= nlos.T
    bias = np.where(nlos[links[:, 0], links[:, 1]], rng.uniform(30, 120, len(links)), 0.0)
    r = np.linalg.norm(P[links[:, 0]] - P[links[:, 1]], axis=1) + bias
    return P, links, r + 0.1 * rng.standard_normal(len(links))


def test_several_robust_scales_keep_the_fit_with_the_lowest_cost_at_the_smallest():
    """``robust_scale_m = [5, 2, 1]`` is the brute-force choice among the single-scale fits:
    the one whose Cauchy cost at 1 m is lowest (the same starts for every scale)."""
    n = 9
    for seed in range(3):
        _, links, r = _nlos_network(seed, n, 0.25)
        D, Wm = range_matrix(links, r, n, combine="min")
        kw = dict(combine="min", n_restarts=2)

        def cost_at_1m(X, D=D, Wm=Wm):
            res = D - np.linalg.norm(X[:, None] - X[None], axis=-1)
            return float(np.sum(np.triu(Wm * np.log1p(res**2), 1)))

        single = [
            coarse_positions(links, r, n, 2, robust_scale_m=c, rng=np.random.default_rng(4), **kw)
            for c in (5.0, 2.0, 1.0)
        ]
        multi = coarse_positions(
            links, r, n, 2, robust_scale_m=[1.0, 5.0, 2.0], rng=np.random.default_rng(4), **kw
        )
        best = min(single, key=lambda s: cost_at_1m(s.positions))
        np.testing.assert_array_equal(multi.positions, best.positions)
    with pytest.raises(ValidationError, match="robust_scale_m"):
        coarse_positions(links, r, n, 2, robust_scale_m=[5.0, 0.0])
    with pytest.raises(ValidationError, match="robust_scale_m"):
        coarse_positions(links, r, n, 2, robust_scale_m=[])


@pytest.mark.slow
def test_several_robust_scales_hold_where_one_folds_the_network():
    """A quarter of the pairs NLOS (biased by 30–120 m, as many as WINNER II C2 shows once
    the SNR is high enough to detect them): over 12 seeded 12-node networks the 5 m scale
    alone folds several into a wrong configuration; the scales [5, 2, 1] m recover at least
    10 of 12 within 1 m (framework distance RMSE)."""
    ok = {5.0: 0, "multi": 0}
    for seed in range(12):
        P, links, r = _nlos_network(seed, 12, 0.25)
        for key, scale in ((5.0, 5.0), ("multi", (5.0, 2.0, 1.0))):
            sol = coarse_positions(
                links,
                r,
                12,
                2,
                combine="min",
                robust_scale_m=scale,
                n_restarts=10,
                rng=np.random.default_rng(0),
            )
            ok[key] += framework_distance_rmse(sol.positions, P) < 1.0
    assert ok["multi"] >= 10 and ok["multi"] > ok[5.0]


def test_start_scale_is_the_robust_residual_scale_per_node(rng):
    """Gaussian residuals of std s on every pair: the per-node scale estimates s (MAD·1.4826);
    a few large NLOS-like biases on a node's links barely move it; a node without a pair is
    inf; the floor holds."""
    from phyloc.localization.initialization import start_scale

    n, s = 40, 0.3
    X = rng.uniform(0, 100, (n, 2))
    i, j = np.triu_indices(n, 1)
    d = np.linalg.norm(X[i] - X[j], axis=1) + s * rng.standard_normal(i.size)
    biased = rng.random(i.size) < 0.1
    d[biased] += rng.exponential(20.0, biased.sum())
    lk = np.column_stack([i, j])
    scale = start_scale(X, lk, d)
    assert np.all(np.abs(np.median(scale) / s - 1) < 0.15)
    # brute force of node 0: its pairs' absolute residuals
    mine = (i == 0) | (j == 0)
    expect = 1.482602218505602 * np.median(
        np.abs(d[mine] - np.linalg.norm(X[i[mine]] - X[j[mine]], axis=1))
    )
    assert scale[0] == pytest.approx(expect)
    # "min" combines the two directions: a longer reverse range changes nothing
    both = start_scale(X, np.vstack([lk, lk[:, ::-1]]), np.concatenate([d, d + 5.0]))
    np.testing.assert_allclose(both, scale)
    X2 = np.vstack([X, [[500.0, 500.0]]])
    lone = start_scale(X2, lk, d, floor_m=0.5)
    assert np.isinf(lone[-1]) and np.all(lone[:-1] >= 0.5)
    exact = start_scale(X, lk, np.linalg.norm(X[i] - X[j], axis=1), floor_m=0.05)
    np.testing.assert_allclose(exact, 0.05)


def test_start_scale_as_a_position_std_is_the_crb_form():
    """A node with k neighbours evenly around it in 2-D: J = (k/2)·I, so the position std is
    the range scale times sqrt(tr(J⁻¹)/2) = sqrt(2/k); with collinear neighbours J is singular
    (inf)."""
    from phyloc.localization.initialization import start_scale

    k = 8
    ang = 2 * np.pi * np.arange(k) / k
    X = np.vstack([[0.0, 0.0], 10 * np.column_stack([np.cos(ang), np.sin(ang)])])
    lk = np.column_stack([np.zeros(k, int), np.arange(1, k + 1)])
    r = 10.0 + np.array([0.1, -0.1, 0.2, -0.2, 0.1, -0.1, 0.2, -0.2])
    rng_scale = start_scale(X, lk, r)[0]
    assert rng_scale == pytest.approx(1.482602218505602 * 0.15)
    pos = start_scale(X, lk, r, position=True)
    assert pos[0] == pytest.approx(rng_scale * np.sqrt(2.0 / k))
    assert np.all(np.isinf(pos[1:]))  # one neighbour each: a direction is undetermined
    line = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    assert np.isinf(
        start_scale(line, np.array([[0, 1], [0, 2]]), np.array([5.1, 10.0]), position=True)[0]
    )


def test_start_prior_width_is_capped_where_the_directions_leave_a_node_undetermined():
    """An agent measured only by two neighbours nearly in line with it: its CRB-form scale is
    far above 10 m, and the "start" prior width caps it at START_PRIOR_FALLBACK_M; a node
    without a measured pair gets the same; the others keep their narrow widths."""
    from phyloc.evaluation.front_end import (
        START_PRIOR_FALLBACK_M,
        START_PRIOR_FLOOR_M,
        start_prior_std,
    )
    from phyloc.localization.initialization import start_scale

    P = np.array([[0, 0], [40, 0], [20, 30], [0, 50], [45, 45], [80.0, 0.05], [500.0, 500.0]])
    pairs = [(i, j) for i in range(5) for j in range(5) if i != j]
    pairs += [(5, 0), (0, 5), (5, 1), (1, 5)]
    lk = np.array(pairs)
    r = np.linalg.norm(P[lk[:, 0]] - P[lk[:, 1]], axis=1)
    r += 0.2 * np.random.default_rng(1).standard_normal(len(lk))
    scale = start_scale(P, lk, r, position=True, floor_m=START_PRIOR_FLOOR_M)
    assert scale[5] > 10 * START_PRIOR_FALLBACK_M and np.isinf(scale[6])
    std = start_prior_std(P, lk, r, np.ones(len(lk), bool), "min")
    assert std[5] == std[6] == START_PRIOR_FALLBACK_M
    np.testing.assert_array_equal(std[:5], scale[:5])
    assert np.all((std[:5] >= START_PRIOR_FLOOR_M) & (std[:5] < 1.0))
