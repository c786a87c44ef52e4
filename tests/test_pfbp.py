"""PF-BP, EDH, SIR-BP and the range models (PF-BP paper), against closed forms and the PCRLB."""

import numpy as np
import pytest
from naive_flow import paired_range_loglik_numpy, range_flow_numpy
from range_fixtures import degenerate_scenario

from phyloc.analysis.pcrlb import pcrlb
from phyloc.errors import ValidationError
from phyloc.evaluation.range_scenarios import (
    RangeScenario,
    scenario_network_spec,
    simulate_scenario,
    state_errors,
)
from phyloc.localization.tracking import (
    GaussianPrior,
    PFBPOptions,
    RangeMeasurements,
    RangeModel,
    SIRBPOptions,
    _flow,
    paper_prior,
    run_edh,
    run_pfbp,
    run_sirbp,
    use_flow,
)
from phyloc.localization.tracking.measurements import agent_measurements, all_measurements
from phyloc.network import make_network


def _linear_problem(rng, n=6, L=3):
    A0 = rng.normal(size=(n, n))
    P = A0 @ A0.T + np.eye(n)
    H = rng.normal(size=(L, n))
    R = np.diag(rng.uniform(0.05, 0.2, L))
    m = rng.normal(size=n)
    z = H @ rng.multivariate_normal(m, P) + rng.multivariate_normal(np.zeros(L), R)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return P, H, R, m, z, m + K @ (z - H @ m), (np.eye(n) - K @ H) @ P


def _scenario(seed, n_agents=5, n_steps=5, motion="constant_acceleration", r_max=None, dim=3):
    rng = np.random.default_rng(seed)
    net = make_network(scenario_network_spec(n_agents, n_steps, motion=motion, dim=dim), rng)
    sc = simulate_scenario(net, RangeModel(motion, dim), rng, comm_range_m=r_max)
    return sc, rng


# ---- pseudo-time schedule and flow kernels --------------------------------------------------
def test_lambda_schedule_is_exponential_and_ends_at_one():
    lam, steps = _flow.lambda_schedule(20, 1.2)
    assert lam[-1] == 1.0 and np.isclose(steps.sum(), 1.0)
    np.testing.assert_allclose(steps[1:] / steps[:-1], 1.2)
    np.testing.assert_allclose(np.cumsum(steps), lam)


def test_edh_flow_matches_kalman_posterior_and_weights_are_uniform(rng):
    P, H, R, m, z, m_kf, P_kf = _linear_problem(rng)
    M = 20_000
    X = rng.multivariate_normal(m, P, size=M)
    lam, steps = _flow.lambda_schedule(400, 1.01)
    X1, mean1 = _flow.edh_flow(X, m, P, lambda x: (H, H @ x), z, R, lam, steps)
    sd = np.sqrt(np.diag(P_kf))
    assert np.all(np.abs(X1.mean(axis=0) - m_kf) < 5 * sd / np.sqrt(M) + 0.01 * sd)
    assert np.all(np.abs(mean1 - m_kf) < 0.02 * sd)  # deterministic mean flow
    np.testing.assert_allclose(np.cov(X1.T), P_kf, atol=0.03 * np.abs(P_kf).max())
    ll = -0.5 * np.sum((z - X1 @ H.T) ** 2 / np.diag(R), axis=1)
    lw = _flow.invertible_flow_log_weights(X, X1, m, P, ll)
    w = np.exp(lw - lw.max())
    w /= w.sum()
    assert 1.0 / np.sum(w * w) > 0.99 * M  # uniform weights


def test_invertible_weights_correct_a_coarse_flow(rng):
    """With 20 λ-steps the flowed cloud is off, the weighted one is the Kalman posterior."""
    P, H, R, m, z, m_kf, P_kf = _linear_problem(rng)
    M = 40_000
    X = rng.multivariate_normal(m, P, size=M)
    lam, steps = _flow.lambda_schedule(20, 1.2)
    X1, _ = _flow.edh_flow(X, m, P, lambda x: (H, H @ x), z, R, lam, steps)
    ll = -0.5 * np.sum((z - X1 @ H.T) ** 2 / np.diag(R), axis=1)
    lw = _flow.invertible_flow_log_weights(X, X1, m, P, ll)
    w = np.exp(lw - lw.max())
    w /= w.sum()
    sd = np.sqrt(np.diag(P_kf))
    ess = 1.0 / np.sum(w * w)
    assert np.all(np.abs(w @ X1 - m_kf) < 5 * sd / np.sqrt(ess))


def test_flow_parameters_closed_form(rng):
    P, H, R, m, z, *_ = _linear_problem(rng)
    e = rng.normal(size=z.size)
    lam = 0.3
    A, b = _flow.flow_parameters(P, H, R, z, e, m, lam)
    A_ref = -0.5 * P @ H.T @ np.linalg.inv(lam * H @ P @ H.T + R) @ H
    eye = np.eye(m.size)
    b_ref = (eye + 2 * lam * A_ref) @ (
        (eye + lam * A_ref) @ P @ H.T @ np.linalg.inv(R) @ (z - e) + A_ref @ m
    )
    np.testing.assert_allclose(A, A_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(b, b_ref, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("many", [False, True])
@pytest.mark.parametrize("dense", [False, True])
@pytest.mark.parametrize("n_flow", [9, 27])
def test_range_flow_kernel_equals_numpy_twin(rng, n_flow, dense, many):
    """Both particle-update paths of the kernel: few measurements (``A_f x = T H x``) and,
    with ``many``, the formed ``A_f`` (each link measured 12 times)."""
    dim, n = 3, 27
    P = np.diag(rng.uniform(1, 4, n))
    if dense:  # correlated agents, as in the stacked state of PF-BP after a few steps
        G = rng.normal(size=(n, n))
        P = P + 0.1 * G @ G.T
    mean = rng.normal(size=n) * 5
    X = mean + rng.normal(size=(64, n)) * 2
    off_a = np.array([0, 0, 9, 0, 18], np.int64)
    off_b = np.array([-1, 9, 18, -1, -1], np.int64)
    anchors = rng.normal(size=(5, dim)) * 10
    if not dense:
        # zero distance at the mean: a degenerate Jacobian row. (With a dense P and n_flow = n
        # the mean then moves to a tiny distance from this anchor, whose direction amplifies
        # rounding differences between any two implementations to ~1e-7.)
        anchors[4] = mean[18:21]
    z = rng.uniform(3, 9, 5)
    r_var = np.full(5, 0.01)
    if many:  # L = 60 > n_flow·n / (2·dim + n_flow) for both n_flow
        off_a, off_b, anchors = np.tile(off_a, 12), np.tile(off_b, 12), np.tile(anchors, (12, 1))
        z = np.tile(z, 12) + rng.normal(0, 0.05, 60)
        r_var = np.full(60, 0.01)
    # One λ-step checks the algebra (sparse kernel vs dense twin) to rounding. Over 20 steps
    # the linearization point is the flowing mean, so rounding differences feed back; with a
    # dense P or repeated links (ill-conditioned S) they grow to ~1e-9 absolute, hence the
    # looser 20-step tolerance in those cases.
    for n_lambda, tol in ((1, 1e-10), (20, 1e-6 if dense or many else 1e-9)):
        lam, steps = _flow.lambda_schedule(n_lambda)
        Xa, ma = range_flow_numpy(
            X, mean, P, off_a, off_b, anchors, z, r_var, dim, n_flow, lam, steps
        )
        Xb, mb = X.copy(), mean.copy()
        _flow.range_flow_kernel(Xb, mb, P, off_a, off_b, anchors, z, r_var, dim, n_flow, lam, steps)
        assert np.all(np.isfinite(Xb))
        np.testing.assert_allclose(Xb, Xa, rtol=tol, atol=tol)
        np.testing.assert_allclose(mb, ma, rtol=tol, atol=tol)
        np.testing.assert_array_equal(Xb[:, n_flow:], X[:, n_flow:])  # neighbours stay (21)


def test_range_linearization_matches_finite_differences(rng):
    x = rng.normal(size=18) * 4
    off_a, off_b = np.array([0, 0], np.int64), np.array([-1, 9], np.int64)
    anchors = rng.normal(size=(2, 3)) * 10
    H, h = _flow.range_linearization(x, off_a, off_b, anchors, 3)
    eps = 1e-6
    for c in range(18):
        dx = np.zeros(18)
        dx[c] = eps
        fd = (_flow.range_linearization(x + dx, off_a, off_b, anchors, 3)[1] - h) / eps
        np.testing.assert_allclose(H[:, c], fd, atol=1e-5)


@pytest.mark.parametrize("my", [1, 50])
def test_paired_loglik_kernel_equals_numpy_twin(rng, my):
    x, y = rng.normal(size=(50, 3)), rng.normal(size=(my, 3))
    out = np.full(50, 1.5)
    _flow.paired_range_loglik_kernel(x, y, 1.2, 100.0, out)
    np.testing.assert_allclose(out, 1.5 + paired_range_loglik_numpy(x, y, 1.2, 100.0))


def test_ukf_update_matches_kalman_in_the_linear_regime(rng):
    """A far anchor makes the range nearly linear: the UKF covariance is the Kalman one."""
    P = np.diag([0.04, 0.09, 0.01, 1.0, 1.0, 1.0])
    mean = np.array([1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
    anchors = np.array([[1e4, 2.0, 3.0], [1.0, -1e4, 3.0]])
    off_a, off_b = np.zeros(2, np.int64), np.full(2, -1, np.int64)
    r_var = np.array([0.01, 0.02])
    out = _flow.ukf_covariance_update(mean, P, off_a, off_b, anchors, r_var, 3, 6)
    H, _ = _flow.range_linearization(mean, off_a, off_b, anchors, 3)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + np.diag(r_var))
    np.testing.assert_allclose(out, P - K @ H @ P, atol=1e-6)


# ---- models ---------------------------------------------------------------------------------
def test_simulated_ranges_follow_the_model():
    sc, _ = _scenario(3, n_agents=6, n_steps=30, r_max=18.0)
    d = np.linalg.norm(
        sc.positions()[:, :, None]
        - np.concatenate(
            [sc.positions(), np.broadcast_to(sc.anchors, (30, *sc.anchors.shape))], axis=1
        )[:, None],
        axis=-1,
    )
    assert sc.z.shape == (30, 6, 15)
    finite = np.isfinite(sc.z)
    np.testing.assert_array_equal(finite, (d <= 18.0) & (d > 0))
    resid = (sc.z - d)[finite]
    assert abs(resid.std() - 0.1) < 0.01 and abs(resid.mean()) < 0.01
    za = sc.z[:, :, :6]
    both = np.isfinite(za) & np.isfinite(za.transpose(0, 2, 1))
    assert both.any() and np.all(za[both] != za.transpose(0, 2, 1)[both])  # z_ij ≠ z_ji


def test_distributed_and_centralized_factors():
    z = np.full((3, 5), np.nan)
    z[0, 1], z[1, 0], z[2, 0], z[0, 3] = 1.0, 1.1, 2.0, 3.0
    rx, tx, zz, partners = agent_measurements(z, 0, "distributed")
    assert list(zip(rx, tx, zz, strict=True)) == [(0, 1, 1.0), (0, 3, 3.0)]
    assert list(partners) == [1]
    rx, tx, zz, partners = agent_measurements(z, 0, "centralized")
    got = sorted(zip(rx, tx, zz, strict=True))
    assert got == [(0, 1, 1.0), (0, 3, 3.0), (1, 0, 1.1), (2, 0, 2.0)]
    assert list(partners) == [1, 2]
    assert all_measurements(z)[2].size == 4


@pytest.mark.parametrize(
    "motion,nd", [("static", 2), ("constant_velocity", 4), ("constant_acceleration", 6)]
)
def test_state_models_2d(motion, nd):
    m = RangeModel(motion, 2)
    F, Q = m.matrices()
    assert m.state_dim == nd and F.shape == Q.shape == (nd, nd)
    assert np.allclose(np.diag(m.regularization_cov())[:2], 0.0)


def test_validation_errors():
    with pytest.raises(ValidationError, match="motion"):
        RangeModel("jerk")
    with pytest.raises(ValidationError, match="lambda_ratio"):
        PFBPOptions(lambda_ratio=0.5)
    with pytest.raises(ValidationError, match="factors"):
        SIRBPOptions(factors="both")
    sc, rng = _scenario(0, n_steps=1)
    meas = sc.measurements()
    with pytest.raises(ValidationError, match=r"prior\.mean"):
        run_pfbp(meas, GaussianPrior(np.zeros((5, 6)), np.zeros((5, 6, 6))), rng)
    with pytest.raises(ValidationError, match=r"prior\.cov"):
        GaussianPrior(np.zeros((5, 9)), np.zeros((5, 6, 6)))
    with pytest.raises(ValidationError, match="measurements"):
        run_pfbp(sc, paper_prior(meas, rng), rng)  # the scenario (with truth) is not accepted
    with pytest.raises(ValidationError, match="z"):
        RangeMeasurements(RangeModel(), sc.anchors, sc.z[:, :, :-1])
    with pytest.raises(ValidationError, match="anchors"):
        RangeMeasurements(RangeModel(), sc.anchors[:, :2], sc.z)


# ---- trackers -------------------------------------------------------------------------------
def test_pfbp_tracks_at_pcrlb_level():
    """Scenario I-like (5 agents, 9 anchors, σ = 0.1 m, CA, r_max = ∞, 200 particles, 20 λ)."""
    K, runs = 10, 3
    err_pf, err_edh, scs, P0 = [], [], [], None
    for seed in range(runs):
        sc, rng = _scenario(100 + seed, n_steps=K)
        meas = sc.measurements()
        prior = paper_prior(meas, rng)
        P0 = prior.cov
        err_pf.append(state_errors(run_pfbp(meas, prior, rng), sc)["p"] ** 2)
        err_edh.append(state_errors(run_edh(meas, prior, rng), sc)["p"] ** 2)
        scs.append(sc)
    bound = pcrlb(scs, P0).bounds["p"]
    rmse_pf = np.sqrt(np.mean(err_pf, axis=0))
    rmse_edh = np.sqrt(np.mean(err_edh, axis=0))
    assert np.all(rmse_pf[-3:] < 2.0 * bound[-3:]), (rmse_pf, bound)
    assert np.all(rmse_edh[-3:] < 2.0 * bound[-3:]), (rmse_edh, bound)
    assert np.all(rmse_pf[-3:] > 0.8 * bound[-3:])  # a bound is a bound


def test_sirbp_with_many_particles_reaches_the_bound_static_2d():
    """Static 2-D network, informative prior: SIR-BP ≈ PF-BP ≈ PCRLB at the first step."""
    runs = 4
    e_sir, e_pf, scs = [], [], []
    for seed in range(runs):
        sc, rng = _scenario(200 + seed, n_agents=4, n_steps=1, motion="static", dim=2)
        P0 = np.repeat(np.eye(2)[None] * 0.25, 4, axis=0)
        prior = GaussianPrior(sc.initial_states + rng.normal(size=(4, 2)) * 0.5, P0)
        meas = sc.measurements()
        opt = SIRBPOptions(n_particles=50_000, uniform_positions=False)
        e_sir.append(state_errors(run_sirbp(meas, prior, rng, opt), sc)["p"] ** 2)
        e_pf.append(state_errors(run_pfbp(meas, prior, rng), sc)["p"] ** 2)
        scs.append(sc)
    bound = pcrlb(scs, P0).bounds["p"][0]
    assert np.sqrt(np.mean(e_sir)) < 2.0 * bound
    assert np.sqrt(np.mean(e_pf)) < 2.0 * bound


def test_reproducible_for_a_seed():
    out = []
    for _ in range(2):
        sc, rng = _scenario(7, n_steps=2)
        meas = sc.measurements()
        prior = paper_prior(meas, rng)
        out.append(run_pfbp(meas, prior, rng, PFBPOptions(n_particles=50)).estimates)
        out.append(run_sirbp(meas, prior, rng, SIRBPOptions(n_particles=500)).estimates)
        out.append(run_edh(meas, prior, rng, PFBPOptions(n_particles=50)).estimates)
    for a, b in zip(out[:3], out[3:], strict=True):
        np.testing.assert_array_equal(a, b)


def test_numpy_flow_gives_the_same_track():
    """PF-BP and EDH with the NumPy twin swapped in by ``use_flow``: the same tracks."""
    sc, rng = _scenario(8, n_steps=2)
    meas = sc.measurements()
    prior = paper_prior(meas, rng)
    opt = PFBPOptions(n_particles=40)
    calls = []

    def twin(*args):
        calls.append(1)
        return range_flow_numpy(*args)

    for run in (run_pfbp, run_edh):
        calls.clear()
        a = run(meas, prior, np.random.default_rng(1), opt)
        with use_flow(twin):
            b = run(meas, prior, np.random.default_rng(1), opt)
        assert calls  # the twin really ran
        np.testing.assert_allclose(a.estimates, b.estimates, rtol=1e-7, atol=1e-7)
    calls.clear()
    run_pfbp(meas, prior, np.random.default_rng(1), opt)
    assert not calls  # outside the block, the numba kernel is back
    with pytest.raises(ValidationError, match="flow"):
        with use_flow("numpy"):
            pass


def test_degenerate_geometry_stays_finite():
    """Coplanar anchors and an agent without any measurement: no NaN/inf anywhere."""
    rng, _, _, _, _, sc, m, P, F = degenerate_scenario(3)
    K = 3
    assert np.all(np.isnan(sc.z[:, 2]))
    expected = np.stack([(np.linalg.matrix_power(F, k + 1) @ m[2])[:3] for k in range(K)])
    sir = SIRBPOptions(n_particles=2000, regularize=True, uniform_positions=False)
    meas, prior = sc.measurements(), GaussianPrior(m, P)
    for r, tol in (
        (run_pfbp(meas, prior, rng, PFBPOptions(n_particles=200, regularize=True)), 0.6),
        (run_edh(meas, prior, rng, PFBPOptions(n_particles=200)), 2.0),  # joint resampling
        (run_sirbp(meas, prior, rng, sir), 0.6),
    ):
        assert np.all(np.isfinite(r.estimates)) and np.all(np.isfinite(r.covariances))
        # the isolated agent is only predicted (its mean follows F; 5 MC std)
        np.testing.assert_allclose(r.estimates[:, 2, :3], expected, atol=tol)
        assert np.all(np.abs(r.estimates[:, 0, :3] - 5.0) < 0.5)  # the other one is localized


def test_scenario_validation():
    sc, rng = _scenario(1, n_steps=2)
    net = make_network(scenario_network_spec(2, 2), rng)
    with pytest.raises(ValidationError, match="n_steps"):
        simulate_scenario(net, RangeModel(), rng, n_steps=5)
    with pytest.raises(ValidationError, match="dim"):
        simulate_scenario(net, RangeModel(dim=2), rng)
    assert isinstance(sc, RangeScenario)


def _two_agent_step(exchange, reflect):
    """One PF-BP step (one message-passing iteration) of agent 0 with neighbour 1, whose
    particles are reflected about their mean when ``reflect`` (same mean, other particles)."""
    from phyloc.localization.tracking.pfbp import PFBPTracker

    model = RangeModel("constant_velocity", 2, dt_s=0.1, accel_std=0.1, sigma_r=0.1)
    anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0]])
    truth = np.array([[5.0, 6.0], [12.0, 9.0]])
    z = np.full((2, 5), np.nan)
    for i in range(2):
        z[i, 2:] = np.linalg.norm(anchors - truth[i], axis=1)
        z[i, 1 - i] = np.linalg.norm(truth[0] - truth[1])
    z[1, 2:] = np.nan  # agent 1 sees only agent 0: its belief stays wide
    prior = GaussianPrior(
        np.hstack([truth + 1.0, np.zeros((2, 2))]),
        np.tile(np.diag([4.0, 4.0, 0.1, 0.1]), (2, 1, 1)),
    )
    opts = PFBPOptions(n_particles=300, n_lambda=10, n_iterations=1, exchange=exchange)
    t = PFBPTracker(model, prior, np.random.default_rng(2), opts)
    if reflect:
        p = t.particles[1]
        t.particles[1] = 2.0 * p.mean(axis=0) - p
    t.rng = np.random.default_rng(9)
    t.step(z, anchors)
    return t.particles[0], t.cov[0]


def test_gaussian_exchange_reads_only_the_neighbours_mean_and_covariance():
    """``exchange = "gaussian"`` (PF-BP §VI: a belief is sent as mean and covariance): another
    particle set of the neighbour with the same mean and covariance leaves the agent's update
    unchanged; with ``"particles"`` (the default) the particles themselves enter."""
    a, ca = _two_agent_step("gaussian", reflect=False)
    b, cb = _two_agent_step("gaussian", reflect=True)
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(cb, ca, rtol=1e-9, atol=1e-12)
    c, _ = _two_agent_step("particles", reflect=False)
    d, _ = _two_agent_step("particles", reflect=True)
    assert np.abs(c - d).max() > 1e-3
    with pytest.raises(ValidationError, match="exchange"):
        PFBPOptions(exchange="beliefs")


def test_gaussian_exchange_with_anchor_links_only():
    """An agent that ranges only to anchors has no neighbour to sample: the same update as
    with particles exchanged (no agent-agent link, nothing read from a neighbour)."""
    from phyloc.localization import METHODS

    model = RangeModel("constant_velocity", 2, dt_s=0.1, accel_std=0.1, sigma_r=0.1)
    anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0]])
    truth = np.array([[5.0, 6.0], [12.0, 9.0]])
    z = np.full((3, 2, 5), np.nan)
    z[:, :, 2:] = np.linalg.norm(truth[:, None] - anchors[None], axis=2)
    meas = RangeMeasurements(model, anchors, z)
    prior = GaussianPrior(
        np.hstack([truth + 1.0, np.zeros((2, 2))]),
        np.tile(np.diag([4.0, 4.0, 0.1, 0.1]), (2, 1, 1)),
    )
    m = METHODS["pfbp"]
    out = [
        m.run(meas, prior, np.random.default_rng(4), m.make_options({"exchange": e}))
        for e in ("particles", "gaussian")
    ]
    np.testing.assert_array_equal(out[0].estimates, out[1].estimates)
    assert np.all(np.isfinite(out[1].covariances))


@pytest.mark.parametrize("M", [50, 120])
def test_floats_per_link_iteration_count_what_each_method_sends(M):
    """Counted by hand for the 9-D CA state (PF-BP §VI): a Gaussian belief is 9 + 45 floats
    (mean, symmetric covariance) whatever M; PF-BP with particles sends M·9 + 45; SIR-BP's
    neighbours read M 3-D positions; the centralized EDH exchanges no beliefs."""
    from phyloc.localization import METHODS

    model = RangeModel("constant_acceleration", 3)
    z = np.full((1, 2, 3), np.nan)
    meas = RangeMeasurements(model, np.zeros((1, 3)), z)
    prior = GaussianPrior(np.zeros((2, 9)), np.tile(np.eye(9), (2, 1, 1)))
    expected = {
        ("pfbp", "particles"): M * 9 + 45,
        ("pfbp", "gaussian"): 54,
        ("sirbp", None): M * 3,
        ("spbp", None): 54,
    }
    for (name, exchange), want in expected.items():
        m = METHODS[name]
        raw = {} if name == "spbp" else {"n_particles": M}
        if exchange:
            raw["exchange"] = exchange
        res = m.run(meas, prior, np.random.default_rng(0), m.make_options(raw))
        assert res.diagnostics["floats_per_link_iteration"] == want, (name, exchange)
    edh = METHODS["edh"]
    res = edh.run(meas, prior, np.random.default_rng(0), edh.make_options({"n_particles": M}))
    assert np.isnan(res.diagnostics["floats_per_link_iteration"])
