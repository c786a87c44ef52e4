"""NBP, Gaussian BP, WLS and the static range models (POA-NBP paper §II, §IV-B, §V)."""

import math

import numpy as np
import pytest
from naive_static import kde_logpdf_numpy, lscv_grid_numpy
from scipy import stats

from phyloc.errors import ValidationError
from phyloc.evaluation.static_scenarios import paper_static_scenario, simulate_ranges
from phyloc.localization.static import _nbp_kernels as NK
from phyloc.localization.static.gaussian_bp import (
    GaussianBPOptions,
    WLSOptions,
    heuristic_start,
    run_gaussian_bp,
    run_wls,
    wls_cost,
)
from phyloc.localization.static.kde import kde_logpdf, lscv_bandwidth, silverman_bandwidth
from phyloc.localization.static.messages import Message, message_product, range_message_samples
from phyloc.localization.static.nbp import NBPOptions, run_nbp
from phyloc.localization.static.static_ranges import (
    INFEASIBLE_LOG_PENALTY,
    ExponentialRangeError,
    GaussianRangeError,
    StaticMeasurements,
    StaticPrior,
    check_static_network,
    convergence_iteration,
    exponential_loglik,
    gaussian_loglik,
)


def _meas(Z, anc, anchor_pos, model=None):
    return StaticMeasurements(Z, anc, anchor_pos, model)


def _errors(res, pos, anc):
    """``[n_iter, n_agents]`` errors against the true agent positions (evaluation only)."""
    return np.linalg.norm(res.estimates - pos[~anc][None], axis=-1)


def _weights(res):
    return np.exp(res.log_weights)


class RectPolygon:
    """Axis-aligned rectangle with the duck-typed interface of ``polygons.ConvexPolygon``."""

    def __init__(self, xmin, ymin, xmax, ymax, leak=0.0):
        self.lo = np.array([xmin, ymin], float)
        self.hi = np.array([xmax, ymax], float)
        self.leak = leak  # > 0: sample_uniform also returns points outside (a faulty sampler)

    @property
    def vertices(self):
        (x0, y0), (x1, y1) = self.lo, self.hi
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    @property
    def area(self):
        return float(np.prod(self.hi - self.lo))

    def contains(self, points):
        p = np.asarray(points, float)
        return np.all((p >= self.lo) & (p <= self.hi), axis=1)

    def sample_uniform(self, n, rng):
        pad = self.leak * (self.hi - self.lo)
        return rng.uniform(self.lo - pad, self.hi + pad, size=(n, 2))


SQUARE = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
AGENT = np.array([7.0, 11.0])
REGION = (-5.0, -5.0, 25.0, 25.0)


def _four_anchor(rng, model, extra=()):
    """4 anchors (nodes 0–3) and one agent (node 4), plus optional extra agents."""
    pos = np.vstack([SQUARE, AGENT, *extra]) if extra else np.vstack([SQUARE, AGENT])
    anchors = np.zeros(pos.shape[0], bool)
    anchors[:4] = True
    return pos, anchors, simulate_ranges(pos, 100.0, model, rng)


def _gauss_messages(rng, h=0.05):
    m1, S1 = np.array([1.0, 2.0]), np.array([[1.0, 0.3], [0.3, 0.5]])
    m2, S2 = np.array([1.8, 1.2]), np.array([[0.4, -0.1], [-0.1, 0.9]])
    msgs = [  # different sample counts: the KDE batch pads with zero weights
        Message(rng.multivariate_normal(m, S, size=K), np.full(K, 1.0 / K), h)
        for m, S, K in ((m1, S1, 2000), (m2, S2, 1500))
    ]
    # the KDE of N(m, S) samples is N(m, S + h² I); the product of two Gaussians is Gaussian
    A1, A2 = np.linalg.inv(S1 + h * h * np.eye(2)), np.linalg.inv(S2 + h * h * np.eye(2))
    cov = np.linalg.inv(A1 + A2)
    return msgs, cov @ (A1 @ m1 + A2 @ m2), cov


# ---- (1) message product by importance sampling vs the analytic product -----------------------
@pytest.mark.parametrize(
    "proposal", ["min_entropy", "mixture", "parsimonious", "polygon", "auxiliary"]
)  # "auxiliary" without anchor messages: the mixture proposal
def test_message_product_of_two_gaussians_matches_analytic_product(proposal, rng):
    msgs, mean, cov = _gauss_messages(rng)
    sd = np.sqrt(np.diag(cov))
    extra = {}
    if proposal == "polygon":
        extra["polygon"] = RectPolygon(*(mean - 6 * sd), *(mean + 6 * sd))
    if proposal == "parsimonious":  # previous belief: a broad Gaussian cloud around the product
        prev = rng.multivariate_normal(mean, 4 * cov, size=2000)
        extra["previous"] = Message(prev, np.full(2000, 1 / 2000), 0.3)
    prod = message_product(
        msgs,
        rng,
        n_samples=6000,
        region=(-20, -20, 20, 20),
        proposal=proposal,
        uniform_fraction=0.05,
        **extra,
    )
    w = prod.weights
    assert prod.ok and np.isclose(w.sum(), 1.0)
    est_mean = w @ prod.samples
    dev = prod.samples - est_mean
    est_cov = (dev * w[:, None]).T @ dev
    mc = np.sqrt(np.diag(cov) / prod.ess)  # Monte Carlo standard error of the weighted mean
    assert prod.ess > 100
    assert np.all(np.abs(est_mean - mean) < 5 * mc + 0.01), (est_mean, mean, mc)
    np.testing.assert_allclose(np.diag(est_cov), np.diag(cov), rtol=0.15)
    assert abs(est_cov[0, 1] - cov[0, 1]) < 0.15 * math.sqrt(cov[0, 0] * cov[1, 1])


def test_wrong_proposal_density_would_be_detected(rng):
    """The test above has power: ignoring the proposal density (log q = 0) biases the mean."""
    msgs, mean, cov = _gauss_messages(rng)
    prod = message_product(
        msgs, rng, n_samples=6000, region=(-20, -20, 20, 20), proposal="min_entropy"
    )
    lw_target = sum(kde_logpdf(prod.samples, m.samples, m.weights, 0.05) for m in msgs)
    w = np.exp(lw_target - lw_target.max())
    w /= w.sum()
    mc = np.sqrt(np.diag(cov) / (1 / np.sum(w * w)))
    assert np.any(np.abs(w @ prod.samples - mean) > 5 * mc + 0.01)


def _grid_sample(anchors, z, model, n, rng, region, h=0.02):
    """Brute force: ``n`` draws from ``∝ Π_a p(z_a | ‖x − x_a‖)`` on ``region`` by inverse CDF
    on a grid of spacing ``h`` [m], jittered uniformly within the cell."""
    gx = np.arange(region[0] + h / 2, region[2], h)
    gy = np.arange(region[1] + h / 2, region[3], h)
    G = np.stack(np.meshgrid(gx, gy, indexing="ij"), -1).reshape(-1, 2)
    lp = np.zeros(G.shape[0])
    for a, za in zip(anchors, z, strict=True):
        lp += model.loglik(za, np.linalg.norm(G - a, axis=1))
    cdf = np.cumsum(np.exp(lp - lp.max()))
    idx = np.searchsorted(cdf / cdf[-1], rng.random(n))
    return G[idx] + rng.uniform(-h / 2, h / 2, (n, 2))


def test_auxiliary_proposal_samples_the_product_of_the_anchor_likelihoods():
    """POA-NBP ref. [27] ('NBP aux.'), our interpretation: for an agent with anchor neighbours
    the auxiliary proposal is ``q ∝ Π_a p(ẑ_a | x, x_a)`` on the region. Three anchors, fixed
    positive errors: the proposal samples (equally weighted: the anchor terms cancel) pass a
    two-sample KS test against a brute-force inverse-CDF sample of the normalized product on a
    2 cm grid, in x and in y; the product of only two of the anchors (a wrong target, with a
    second mode mirrored across the line of those two anchors) is rejected."""
    model = ExponentialRangeError(0.38)
    anchors = np.array([[0.0, 0.0], [14.0, 0.0], [0.0, 14.0]])
    z = np.linalg.norm(anchors - [5.0, 6.0], axis=1) + np.array([0.2, 0.5, 0.1])
    region = (-10.0, -10.0, 30.0, 30.0)
    rng = np.random.default_rng(7)
    msgs = []
    for a, za in zip(anchors, z, strict=True):
        y, w = range_message_samples(np.broadcast_to(a, (400, 2)), za, model, rng)
        msgs.append(Message(y, w, lscv_bandwidth(y, w, rng=rng), (a, za)))
    prod = message_product(
        msgs,
        rng,
        n_samples=500,
        region=region,
        proposal="auxiliary",
        error_model=model,
        oversampling=200,
    )
    assert prod.ok and np.allclose(prod.weights, 1 / 500)  # target / q = uniform prior
    assert prod.kernel_evaluations == 200 * 500 * 3 * 400  # 3 anchor KDEs at the candidates
    X = prod.samples
    right = _grid_sample(anchors, z, model, 4000, np.random.default_rng(1), region)
    wrong = _grid_sample(anchors[:2], z[:2], model, 4000, np.random.default_rng(1), region)
    for k in (0, 1):
        assert stats.ks_2samp(X[:, k], right[:, k]).pvalue > 0.01
    assert min(stats.ks_2samp(X[:, k], wrong[:, k]).pvalue for k in (0, 1)) < 1e-3


# ---- (2) kernels against their NumPy twins -----------------------------------------------------
def test_kde_kernel_matches_numpy_twin_including_zero_weights_and_far_points(rng):
    M, K, P = 3, 150, 80
    centers = rng.normal(size=(M, K, 2)) * [[[3.0, 1.0]]]
    weights = rng.uniform(size=(M, K))
    weights[0, :10] = 0.0  # zero weights (log −inf)
    points = np.vstack([rng.normal(size=(P - 2, 2)) * 4, [[1e3, -1e3], [0.0, 0.0]]])
    h = np.array([0.01, 0.5, 3.0])  # tiny bandwidth: far points are ~1e10 below the max
    a = kde_logpdf(points, centers, weights, h)
    lw = np.log(
        weights / weights.sum(axis=1, keepdims=True),
        where=weights > 0,
        out=np.full_like(weights, -np.inf),
    )
    b = kde_logpdf_numpy(points, centers, lw, h)
    assert np.all(np.isfinite(a))
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-9)
    # one centre: the exact Gaussian log-density
    one = kde_logpdf(points[:5], centers[1, :1], [1.0], 0.5)
    ref = stats.multivariate_normal(centers[1, 0], 0.25 * np.eye(2)).logpdf(points[:5])
    np.testing.assert_allclose(one, ref, rtol=1e-12)


def test_lscv_kernel_matches_numpy_twin_and_picks_a_sensible_bandwidth(rng):
    x = rng.normal(size=(300, 2))
    w = rng.uniform(0.5, 1.5, 300)
    w /= w.sum()
    out = np.empty(NK.LSCV_GRID)
    NK.lscv_grid_kernel(x, w, 0.8, out)
    np.testing.assert_allclose(out, lscv_grid_numpy(x, w, 0.8, NK.LSCV_GRID), rtol=1e-9, atol=1e-12)
    # Gaussian data: the normal-reference (Silverman) bandwidth is near-optimal, LSCV agrees
    h_s = silverman_bandwidth(x)
    h_cv = lscv_bandwidth(x, max_samples=300)
    # the twin's score picks the same grid point
    h0 = math.sqrt(2.0) * h_s
    ref = lscv_grid_numpy(x, np.full(300, 1 / 300), h0, NK.LSCV_GRID)
    assert h_cv == h0 * 0.5 ** (int(np.argmin(ref)) / 2.0)
    assert 0.35 * h_s < h_cv < 1.5 * h_s
    # a thin ring (a range message): LSCV is much narrower than Silverman's rule
    y, wy = range_message_samples(np.zeros((400, 2)), 10.0, GaussianRangeError(0.1), rng)
    assert lscv_bandwidth(y, wy, rng=rng) < 0.25 * silverman_bandwidth(y, wy)


# ---- (3) one agent, four anchors: NBP / GBP within a few σ, WLS = brute-force minimum ----------
@pytest.mark.parametrize(
    "options",
    [
        {"proposal": "min_entropy"},
        {"proposal": "mixture"},
        {"proposal": "mixture", "link_mode": "both", "jacobian_weights": False},
        {"proposal": "parsimonious", "bandwidth": "silverman"},
    ],
)
def test_nbp_four_anchors_small_gaussian_noise(options, rng):
    sig = 0.2
    model = GaussianRangeError(sig)
    pos, anc, Z = _four_anchor(rng, model)
    res = run_nbp(
        _meas(Z, anc, pos[anc], model),
        StaticPrior(REGION),
        rng,
        NBPOptions(n_samples=1000, n_iterations=3, **options),
    )
    assert res.estimates.shape == (3, 1, 2) and res.covariances.shape == (3, 1, 2, 2)
    assert _errors(res, pos, anc)[-1, 0] < 4 * sig
    assert np.all(res.diagnostics["ess"][:, 0] >= 1.0)
    # the published covariance is the weighted sample covariance of the last update
    w = _weights(res)[0]
    dev = res.particles[0] - w @ res.particles[0]
    np.testing.assert_allclose(res.covariances[-1, 0], (dev * w[:, None]).T @ dev, rtol=1e-9)


def test_wls_matches_brute_force_grid_minimum_and_gbp_is_close(rng):
    sig = 0.2
    model = GaussianRangeError(sig)
    pos, anc, Z = _four_anchor(rng, model)
    Wm = np.where(np.isfinite(Z), rng.uniform(0.5, 2.0, Z.shape), 0.0)  # unequal weights
    meas = _meas(Z, anc, pos[anc], model)
    res = run_wls(meas, StaticPrior(REGION), None, WLSOptions(n_iterations=30), link_weights=Wm)
    est = res.estimates[-1, 0]
    net = check_static_network(Z, anc, pos[anc])
    rows, cols = np.nonzero(np.isfinite(net.ranges))
    z, w = Z[rows, cols], Wm[rows, cols]
    # brute force: 1 mm grid over ±0.6 m around the truth
    g = np.arange(-0.6, 0.6 + 1e-9, 1e-3)
    gx, gy = np.meshgrid(AGENT[0] + g, AGENT[1] + g, indexing="ij")
    cost = np.zeros_like(gx)
    for r, c, zz, ww in zip(rows, cols, z, w, strict=True):
        other = pos[c] if r == 4 else pos[r]
        d = np.hypot(gx - other[0], gy - other[1])
        cost += ww * (zz - d) ** 2
    k = np.unravel_index(np.argmin(cost), cost.shape)
    grid_min = np.array([gx[k], gy[k]])
    assert np.linalg.norm(est - grid_min) < 2e-3
    p = pos.copy()
    p[4] = est
    assert wls_cost(p, rows, cols, z, w, 0.0) <= cost[k] + 1e-9
    assert np.linalg.norm(est - AGENT) < 4 * sig
    # distributed WLS converges to the same point with one agent
    dist = run_wls(
        meas,
        StaticPrior(REGION),
        None,
        WLSOptions(mode="distributed", n_iterations=30),
        link_weights=Wm,
    )
    assert np.linalg.norm(dist.estimates[-1, 0] - est) < 1e-4
    gbp = run_gaussian_bp(meas, StaticPrior(REGION))
    assert np.linalg.norm(gbp.estimates[-1, 0] - AGENT) < 4 * sig
    assert gbp.diagnostics["converged_iteration"] is not None
    assert np.all(np.linalg.eigvalsh(gbp.covariances[-1, 0]) > 0)


# ---- (4) range error models against closed forms -----------------------------------------------
def test_exponential_sampler_and_loglik_against_closed_forms(rng):
    mean = 0.38
    e = ExponentialRangeError(mean).sample(200_000, rng)
    assert e.min() >= 0.0
    assert abs(e.mean() - mean) < 4 * mean / math.sqrt(e.size)
    assert stats.kstest(e, stats.expon(scale=mean).cdf).pvalue > 1e-3
    z, d = 12.0, np.array([12.0, 11.9, 10.0, 0.0])
    lam = 1 / mean
    np.testing.assert_allclose(exponential_loglik(z, d, mean), np.log(lam) - lam * (z - d))
    np.testing.assert_allclose(
        exponential_loglik(z, d, mean), stats.expon(scale=mean).logpdf(z - d)
    )
    # infeasible side (z < d): finite, far below the feasible side, decreasing in the violation
    bad = exponential_loglik(z, np.array([12.0 + 1e-9, 12.5, 20.0, 1e6]), mean)
    assert np.all(np.isfinite(bad))
    assert bad[0] < np.log(lam) - INFEASIBLE_LOG_PENALTY + 1e-6
    assert np.all(np.diff(bad) < 0)
    g = gaussian_loglik(z, d, 0.3)
    np.testing.assert_allclose(g, stats.norm(d, 0.3).logpdf(z))
    assert np.all(np.isfinite(gaussian_loglik(0.0, 1e3, 1e-200)))


def test_simulated_ranges_follow_the_model(rng):
    sc = paper_static_scenario(rng, n_agents=60)
    Z, p = sc.ranges, sc.positions
    d = np.linalg.norm(p[:, None] - p[None], axis=-1)
    linked = np.isfinite(Z)
    assert not linked[np.diag_indices_from(Z)].any()
    assert not linked[np.ix_(sc.is_anchor, sc.is_anchor)].any()
    np.testing.assert_array_equal(
        linked,
        (d <= 20.0) & ~np.eye(len(p), dtype=bool) & ~(sc.is_anchor[:, None] & sc.is_anchor[None]),
    )
    err = (Z - d)[linked]
    assert err.min() >= 0 and abs(err.mean() - 0.38) < 0.05
    assert not np.allclose(Z[linked], Z.T[linked])  # z_ij ≠ z_ji
    Zs = simulate_ranges(p, 20.0, GaussianRangeError(0.1), rng, symmetric=True)
    np.testing.assert_array_equal(Zs, Zs.T)


def test_range_message_density_is_the_likelihood_with_jacobian_weights(rng):
    """Weighted message samples have radial density ∝ p(z|ρ)·ρ (2-D area element)."""
    model = GaussianRangeError(0.5)
    z = 1.0
    y, w = range_message_samples(np.zeros((400_000, 2)), z, model, rng)
    rho = np.linalg.norm(y, axis=1)
    hist, edges = np.histogram(rho, bins=20, range=(0.2, 2.0), weights=w)
    c = 0.5 * (edges[1:] + edges[:-1])
    target = (stats.norm(c, 0.5).pdf(z) + stats.norm(-c, 0.5).pdf(z)) * c  # includes r < 0
    target *= hist.sum() / target.sum()
    np.testing.assert_allclose(hist, target, rtol=0.06)


# ---- (5) no NaN / inf ------------------------------------------------------------------------
def test_isolated_agent_keeps_a_uniform_belief(rng):
    model = GaussianRangeError(0.2)
    pos, anc, Z = _four_anchor(rng, model, extra=[[40.0, 40.0]])
    region = (-5.0, -5.0, 45.0, 45.0)
    Z = simulate_ranges(pos, 25.0, model, rng)
    assert np.isnan(Z[5]).all() and np.isnan(Z[:, 5]).all()
    meas = _meas(Z, anc, pos[anc], model)
    res = run_nbp(meas, StaticPrior(region), rng, NBPOptions(n_samples=300, n_iterations=3))
    assert np.all(np.isfinite(res.estimates))
    np.testing.assert_allclose(res.estimates[-1, 1], [20.0, 20.0], atol=3.0)  # centre ± MC
    s = res.particles[1]
    assert s[:, 0].std() > 10 and res.diagnostics["ess"][:, 1].max() == 0.0  # never updated
    for r in (
        run_gaussian_bp(meas, StaticPrior(region)),
        run_wls(meas, StaticPrior(region)),
    ):
        assert np.all(np.isfinite(r.estimates))


@pytest.mark.parametrize("model", [ExponentialRangeError(1e-6), GaussianRangeError(1e-6)])
def test_coincident_nodes_and_extreme_small_noise_stay_finite(model, rng):
    # agent 4 on anchor 0; agents 5 and 6 at the same point
    extra = [[0.0, 0.0], [8.0, 8.0], [8.0, 8.0]]
    pos = np.vstack([SQUARE, *extra])
    anc = np.zeros(len(pos), bool)
    anc[:4] = True
    Z = simulate_ranges(pos, 100.0, model, rng)
    meas = _meas(Z, anc, pos[anc], model)
    for proposal in ("min_entropy", "mixture", "parsimonious"):
        res = run_nbp(
            meas,
            StaticPrior(REGION),
            rng,
            NBPOptions(n_samples=100, n_iterations=3, proposal=proposal),
        )
        assert np.all(np.isfinite(res.estimates)) and np.all(np.isfinite(_weights(res)))
        assert np.all(np.isfinite(res.particles)) and np.all(np.isfinite(res.covariances))
        assert _errors(res, pos, anc)[-1].max() < 5.0
    gbp = run_gaussian_bp(meas, StaticPrior(REGION))
    wls = run_wls(meas, StaticPrior(REGION))
    for r in (gbp, wls):
        assert np.all(np.isfinite(r.estimates))
    assert np.all(np.isfinite(gbp.covariances))
    assert _errors(wls, pos, anc)[-1].max() < 0.05


# ---- (6) reproducibility -----------------------------------------------------------------------
def test_nbp_is_reproducible_for_a_seed():
    sc = paper_static_scenario(np.random.default_rng(7), n_agents=15)
    meas, prior = sc.measurements(), sc.prior()
    opt = NBPOptions(n_samples=60, n_iterations=3)
    a = run_nbp(meas, prior, np.random.default_rng(11), opt)
    b = run_nbp(meas, prior, np.random.default_rng(11), opt)
    c = run_nbp(meas, prior, np.random.default_rng(12), opt)
    np.testing.assert_array_equal(a.estimates, b.estimates)
    np.testing.assert_array_equal(a.particles, b.particles)
    assert not np.array_equal(a.estimates, c.estimates)


# ---- (7) polygon proposal ----------------------------------------------------------------------
def test_polygon_proposal_never_yields_samples_outside_the_polygon(rng):
    model = ExponentialRangeError()
    pos, anc, Z = _four_anchor(rng, model, extra=[[12.0, 6.0]])
    polys = [RectPolygon(5.0, 9.0, 9.5, 13.0), RectPolygon(10.0, 4.0, 14.0, 8.0, leak=0.3)]
    meas = _meas(Z, anc, pos[anc], model)
    res = run_nbp(
        meas,
        StaticPrior(REGION, polygons=polys, polygon_time_per_node_s=0.5),
        rng,
        NBPOptions(n_samples=300, n_iterations=4, proposal="polygon"),
    )
    assert res.diagnostics["support"] == "prior"
    assert res.diagnostics["setup_time_per_node_s"] == 0.5
    for a, poly in enumerate(polys):
        inside = poly.contains(res.particles[a])
        w = _weights(res)[a]
        assert np.all(w[~inside] == 0.0)  # the leaky sampler's outliers: weight 0
        assert np.all(inside[w > 0])
        assert poly.contains(res.estimates[-1, a][None])[0]
    assert not polys[1].contains(res.particles[1]).all()  # the leak did happen
    assert _errors(res, pos, anc)[-1].max() < 1.0
    # also accepted per node and as a dict; missing polygons mean "uniform over the region"
    opt = NBPOptions(n_samples=50, n_iterations=1, proposal="polygon")
    per_node = [None] * 4 + polys
    r2 = run_nbp(meas, StaticPrior(REGION, polygons=per_node), np.random.default_rng(1), opt)
    r3 = run_nbp(
        meas,
        StaticPrior(REGION, polygons={4: polys[0], 5: polys[1]}),
        np.random.default_rng(1),
        opt,
    )
    np.testing.assert_array_equal(r2.estimates, r3.estimates)


# ---- the POA-NBP §V network: NBP converges and beats the uninformed start ---------------------
def test_nbp_cooperation_improves_a_sparse_anchor_network():
    """5 anchors, 30 agents in 60 m × 60 m, r_com = 20 m: most agents need their neighbours."""
    rng = np.random.default_rng(4)
    units = np.array([[1, 1], [5, 1], [1, 5], [5, 5], [3, 3]]) / 6.0
    sc = paper_static_scenario(rng, n_agents=30, side_m=60.0, anchor_units=units)
    res = run_nbp(
        sc.measurements(),
        sc.prior(),
        rng,
        NBPOptions(n_samples=150, n_iterations=6, proposal="min_entropy"),
    )
    err = _errors(res, sc.positions, sc.is_anchor)
    assert err[-1].mean() < 0.6 * err[0].mean() and np.median(err[-1]) < 3.0
    conv = res.diagnostics["converged_iteration"]
    assert conv is not None and 2 <= conv <= 6
    t = res.diagnostics["agent_time_s"]
    assert t.shape == (6, 30) and np.all(t > 0)
    np.testing.assert_allclose(res.timing.agent_s, t.mean(axis=1))
    assert res.timing.agent_iterations == 180 and res.timing.wall_s >= res.timing.step_s.sum()
    start = heuristic_start(sc.measurements(), sc.region)
    assert start.shape == (30, 2) and np.all(np.isfinite(start))


def test_convergence_iteration_rules():
    est = np.zeros((5, 2, 2))
    est[:, 0, 0] = [0.0, 4.0, 6.0, 7.0, 7.5]  # changes 4, 2, 1, 0.5 (halving)
    est[:, 1, 0] = [0.0, 4.0, 6.0, 7.0, 7.5]
    assert convergence_iteration(est, 0.6) == 5
    assert convergence_iteration(est, 0.1) is None
    assert convergence_iteration(est, 0.1, rel=0.6) == 3  # 2 > (1 − 0.6)·4
    assert convergence_iteration(est[:1], 1.0) is None


# ---- input validation --------------------------------------------------------------------------
def test_invalid_inputs_name_the_field(rng):
    pos, anc, Z = _four_anchor(rng, GaussianRangeError(0.1))
    with pytest.raises(ValidationError, match="proposal"):
        NBPOptions(proposal="box")
    with pytest.raises(ValidationError, match="uniform_fraction"):
        NBPOptions(uniform_fraction=1.5)
    with pytest.raises(ValidationError, match="bandwidth"):
        NBPOptions(bandwidth=-1.0)
    meas = _meas(Z, anc, pos[anc])
    with pytest.raises(ValidationError, match="polygons"):
        run_nbp(meas, StaticPrior(REGION), rng, NBPOptions(proposal="polygon"))
    with pytest.raises(ValidationError, match="polygons"):
        run_nbp(meas, StaticPrior(REGION, polygons=[object()]), rng, NBPOptions(proposal="polygon"))
    with pytest.raises(ValidationError, match="support"):
        NBPOptions(support="box")
    with pytest.raises(ValidationError, match="region"):
        StaticPrior((0, 0, -1, 1))
    with pytest.raises(ValidationError, match="prior"):
        run_nbp(meas, None, rng)
    with pytest.raises(ValidationError, match="measurements"):
        run_nbp(Z, StaticPrior(REGION), rng)
    with pytest.raises(ValidationError, match="anchor_positions"):
        _meas(Z, anc, pos[:3])
    with pytest.raises(ValidationError, match="ranges"):
        _meas(Z[:, :4], anc, pos[anc])
    with pytest.raises(ValidationError, match="rng"):
        run_nbp(meas, StaticPrior(REGION), 3)
    with pytest.raises(ValidationError, match="initial"):
        run_wls(meas, StaticPrior(REGION, initial=np.zeros((3, 2))))
    with pytest.raises(ValidationError, match="mean_m"):
        ExponentialRangeError(0.0)
    with pytest.raises(ValidationError, match="mode"):
        WLSOptions(mode="central")
    with pytest.raises(ValidationError, match="n_inner"):
        GaussianBPOptions(n_inner=0)
    with pytest.raises(ValidationError, match=r"localization\.n_sample"):
        NBPOptions.from_dict({"n_sample": 10})


def test_logsumexp_matches_scipy():
    from scipy.special import logsumexp as ref

    from phyloc.localization.static.kde import logsumexp

    rng = np.random.default_rng(0)
    a = rng.normal(size=(3, 4, 50)) * 300.0
    a[0, 1, :] = -np.inf  # an all-zero-weight row
    a[1, 2, 5] = -np.inf
    for axis in (None, 0, 2, -1):
        for keep in (False, True):
            with np.errstate(divide="ignore"):
                np.testing.assert_allclose(
                    logsumexp(a, axis=axis, keepdims=keep),
                    ref(a, axis=axis, keepdims=keep),
                    rtol=1e-12,
                )
