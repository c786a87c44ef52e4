"""DiPNet Table I measured (``benchmarks/_table1.py``): the exact joint-grid posterior against
explicit enumeration and against the weighted least squares of a linearized problem, the
floats the schemes exchange, the exponent fit, and the figure names of the Table I section."""

import itertools
import math

import numpy as np
import pytest

from phyloc.commands import _import_benchmark
from phyloc.errors import ValidationError
from phyloc.localization.direct.sampled_exchange import NodeBeliefs

# the installed package (phyloc.benchmarks) or, when phyloc is the working tree, ./benchmarks
T = _import_benchmark("phyloc.benchmarks._table1")
bench_dipnet = _import_benchmark("phyloc.benchmarks.bench_dipnet")


# -- exact joint-grid posterior ---------------------------------------------------------------
def _enumerate(grids, anchors, links, ranges, variances):
    """The joint posterior by a loop over every joint configuration and every link."""
    M, Q, _ = grids.shape
    nodes_of = list(anchors)
    logp = {}
    for idx in itertools.product(range(Q), repeat=M):
        pos = [grids[a][idx[a]] for a in range(M)] + nodes_of
        s = 0.0
        for (u, v), r, var in zip(links, ranges, variances, strict=True):
            s += -((math.dist(pos[u], pos[v]) - r) ** 2) / (2 * var)
        logp[idx] = s
    top = max(logp.values())
    z = sum(math.exp(x - top) for x in logp.values())
    joint = np.empty((Q,) * M)
    marg = np.zeros((M, Q))
    for idx, x in logp.items():
        p = math.exp(x - top) / z
        joint[idx] = math.log(p)
        for a in range(M):
            marg[a, idx[a]] += p
    return joint, marg


@pytest.mark.parametrize("n_agents, Q", [(2, 9), (3, 5)])
def test_exact_posterior_equals_explicit_enumeration(rng, n_agents, Q):
    grids = rng.uniform(0, 20, (n_agents, Q, 2))
    anchors = rng.uniform(0, 20, (3, 2))
    M = n_agents
    links = [[1, 0], [0, M], [M + 1, 0], [1, M + 2], [M, M + 1]]  # reversed, anchor first,
    if M == 3:  # anchor–anchor (a constant)
        links += [[2, 1], [0, 2], [2, M + 1]]
    links = np.array(links)
    ranges = rng.uniform(2, 15, len(links))
    variances = rng.uniform(0.5, 4, len(links))
    post = T.exact_joint_posterior(grids, anchors, links, ranges, variances)
    joint, marg = _enumerate(grids, anchors, links, ranges, variances)
    np.testing.assert_allclose(post.log_joint, joint, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(post.marginals, marg, rtol=1e-10, atol=1e-14)
    means = np.einsum("aq,aqd->ad", marg, grids)
    np.testing.assert_allclose(post.means, means, rtol=1e-10)
    dev = grids - means[:, None]
    np.testing.assert_allclose(
        post.covs, np.einsum("aq,aqd,aqe->ade", marg, dev, dev), rtol=1e-9, atol=1e-12
    )
    assert post.log_joint.size == Q**n_agents  # the Q^|M| joint table of DiPNet Table I


def _wls(truth, anchors, links, ranges, var, n_iter=30):
    """Gauss–Newton weighted least squares of all agents jointly; returns (θ̂, J⁻¹)."""
    M = truth.shape[0]
    th = truth.astype(float).copy()
    for _ in range(n_iter):
        nodes = np.vstack([th, anchors])
        H = np.zeros((len(links), 2 * M))
        res = np.zeros(len(links))
        for i, (u, v) in enumerate(links):
            diff = nodes[u] - nodes[v]
            d = np.linalg.norm(diff)
            res[i] = ranges[i] - d
            e = diff / d
            if u < M:
                H[i, 2 * u : 2 * u + 2] = e
            if v < M:
                H[i, 2 * v : 2 * v + 2] = -e
        W = np.diag(1.0 / var)
        J = H.T @ W @ H
        th = th + np.linalg.solve(J, H.T @ W @ res).reshape(M, 2)
    return th, np.linalg.inv(J)


def test_exact_posterior_is_the_wls_gaussian_when_linearized(rng):
    """Far anchors make every anchor range linear in position; the posterior is then the
    Gaussian of the weighted least squares: mean θ̂, covariance the blocks of J⁻¹."""
    truth = np.array([[20.0, 30.0], [170.0, 70.0]])  # far apart: the link bends little
    ang = np.deg2rad([0.0, 90.0, 200.0, 45.0, 300.0])
    anchors = 1.0e4 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    links = np.array([[0, 1], [0, 2], [0, 3], [0, 4], [1, 5], [1, 6]])
    nodes = np.vstack([truth, anchors])
    d = np.linalg.norm(nodes[links[:, 0]] - nodes[links[:, 1]], axis=1)
    std = 0.3
    ranges = d + std * rng.standard_normal(d.size)
    ranges[0] += 0.6  # the agent–agent range disagrees with the anchors: it must pull both
    var = np.full(d.size, std**2)
    G, half = 41, 2.5
    ax = np.linspace(-half, half, G)
    cell = np.stack(np.meshgrid(ax, ax, indexing="ij"), axis=-1).reshape(-1, 2)
    post = T.exact_joint_posterior(truth[:, None] + cell, anchors, links, ranges, var)
    th, cov = _wls(truth, anchors, links, ranges, var)
    np.testing.assert_allclose(post.means, th, atol=2e-3)
    for a in range(2):
        block = cov[2 * a : 2 * a + 2, 2 * a : 2 * a + 2]
        assert np.linalg.norm(post.covs[a] - block) < 0.01 * np.linalg.norm(block)
    # the check discriminates: without the agent–agent link the solution is elsewhere
    th_alone, _ = _wls(truth, anchors, links[1:], ranges[1:], var[1:])
    assert np.max(np.abs(th_alone - th)) > 0.1


def test_exact_posterior_rejects_bad_input(rng):
    grids = rng.uniform(0, 1, (2, 4, 2))
    with pytest.raises(ValidationError):
        T.exact_joint_posterior(grids, np.zeros((1, 2)), [[0, 0]], [1.0], [1.0])
    with pytest.raises(ValidationError):
        T.exact_joint_posterior(grids, np.zeros((1, 2)), [[0, 3]], [1.0], [1.0])
    with pytest.raises(ValidationError):
        T.exact_joint_posterior(grids, np.zeros((1, 2)), [[0, 1]], [1.0], [0.0])
    with pytest.raises(ValidationError):
        T.exact_joint_posterior(grids[0], np.zeros((1, 2)), [[0, 1]], [1.0], [1.0])


# -- floats exchanged, exponents --------------------------------------------------------------
def test_floats_per_link_read_off_the_exchanged_arrays(rng):
    net = T.circulant_network(5, 2, rng)
    f7 = T.sampled_seconds(net, 2, 7, rng, 1, n_rx=2)[1]
    f11 = T.sampled_seconds(net, 2, 11, rng, 1, n_rx=2)[1]
    # Q points of dim 2 and Q log weights (and at most one per-node scalar, a kernel width)
    assert f11 - f7 == 4 * (2 + 1) and f7 - 7 * 3 in (0, 1)
    anchors_only = NodeBeliefs.single(np.zeros((3, 2)))
    assert T.belief_floats(anchors_only, 1) - 1 * 3 in (0, 1)
    _t, floats = T.el_seconds(net, 2, 7, rng, 1)
    assert floats == 2 + 3  # mean + the distinct entries of a symmetric 2×2 covariance
    C = np.array([[1.0, 0.2], [0.3, 1.0]])
    assert T._moment_floats(np.zeros(2), C) == 6
    t, size = T.exact_seconds(3, 2, rng, 1)
    assert size == 9**2 and t > 0


def test_slope_recovers_a_power_law():
    x = np.array([100, 200, 400, 800])
    assert T.slope(x, 3e-9 * x**2.0) == pytest.approx(2.0)
    assert T.slope(x, 5e-6 * x) == pytest.approx(1.0)


def test_circulant_network_degrees(rng):
    net = T.circulant_network(6, 3, rng)
    for k in (1, 2, 3):
        links, table = net.degree(k)
        assert table.n_links == len(links) == 6 * k
        np.testing.assert_array_equal(np.bincount(links[:, 0], minlength=6), k)  # |V_u| = k
    with pytest.raises(ValidationError):
        T.circulant_network(4, 4, rng)


# -- the bench section: figure names and the printed table ------------------------------------
TINY = {
    "q": {"exact": [9, 16], "sampled": [10, 20], "el": [10, 20], "dipnet_published": [10, 20],
          "dipnet": [10, 20]},
    "links": [1, 2],
    "links_fixed": 2,
    "q_fixed": {"exact": 9, "sampled": 10, "el": 10, "dipnet_published": 10, "dipnet": 10},
    "exact_agents_g": 3,
    "n_agents": 5,
    "passes": 1,
}  # fmt: skip


def test_table1_section_figures_and_summary(monkeypatch):
    monkeypatch.setattr(T, "sweeps", lambda quick=False: TINY)
    monkeypatch.setattr(T, "MIN_TIME_S", 0.0)
    fig = T.report()
    for s in T.SCHEMES:
        for q in TINY["q"][s]:
            assert fig[f"table1.{s}.agent_iteration_s.q_{q}"] > 0
            fl = fig[f"table1.{s}.floats_per_link_iteration.q_{q}"]
            assert fig[f"table1.{s}.bytes_per_link_iteration.q_{q}"] == 8 * fl
        for k in TINY["links"]:
            assert fig[f"table1.{s}.agent_iteration_s.links_{k}"] > 0
        names = ("exponent_q", "exponent_q_largest", "exponent_links", "per_link_s", "fixed_s")
        for name in (*names, "links_sweep_q"):
            assert np.isfinite(fig[f"table1.{s}.{name}"])
    assert fig["table1.exact.floats_per_link_iteration.q_16"] == 16**2
    f10, f20 = (fig[f"table1.sampled.floats_per_link_iteration.q_{q}"] for q in (10, 20))
    assert f20 - f10 == 10 * 3 and f10 - 10 * 3 in (0, 1)
    for s in ("el", "dipnet_published", "dipnet"):
        assert fig[f"table1.{s}.floats_per_link_iteration.q_20"] == 5
    text = T.summarize(fig)
    for s in T.SCHEMES:
        assert T.LABELS[s] in text
    assert "exponent in Q" in text and "Table I" in text
    # bench_dipnet prints the section after its own tables when the figures are there
    own = {
        f"dipnet.{k}": 1.0
        for k in (
            "env.evals_per_s_per_core",
            "marginal.evals_per_s_per_core",
            "marginal_tabulated.evals_per_s_per_core",
            "marginal_tabulated.speedup",
            "c2.agent_iteration_s",
            "gauss.evals_per_s_per_core",
            "gauss_bounded.evals_per_s_per_core",
            "gauss_bounded.cost_vs_gauss",
            "env.numpy_evals_per_s",
            "env.speedup_vs_numpy",
            "agent_iteration_s",
            "scaling_exponent_q",
            "scaling_exponent_links",
        )
    }
    own["dipnet_published.agent_iteration_s"] = 1.0
    assert "DiPNet Table I, measured" not in bench_dipnet.summarize(own)
    printed = bench_dipnet.summarize({**own, **fig})
    assert printed.startswith(bench_dipnet.summarize(own)) and printed.endswith(text)
