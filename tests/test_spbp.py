"""SP-BP (Meyer et al. 2014) against an independent UKF, degenerate geometry, PF-BP, the PCRLB."""

import numpy as np
import pytest
from naive_spbp import ca_matrices, ukf_track
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
    RangeModel,
    SPBPOptions,
    _flow,
    paper_prior,
    run_pfbp,
    run_spbp,
)
from phyloc.localization.tracking.spbp import unscented_range_update
from phyloc.network import make_network


def _scenario(seed, n_agents=5, n_steps=5, r_max=None):
    rng = np.random.default_rng(seed)
    net = make_network(scenario_network_spec(n_agents, n_steps), rng)
    return simulate_scenario(net, RangeModel(), rng, comm_range_m=r_max), rng


def test_naive_ca_model_is_the_package_model():
    F, Q = ca_matrices(3, 0.1, 0.15)
    F2, Q2 = RangeModel().matrices()
    np.testing.assert_allclose(F, F2, atol=1e-15)
    np.testing.assert_allclose(Q, Q2, atol=1e-15)


@pytest.mark.parametrize("r_max,n_iterations", [(None, 1), (None, 2), (18.0, 2)])
def test_one_agent_with_anchors_is_an_unscented_kalman_filter(r_max, n_iterations):
    """One agent has no neighbours: every MP iteration is the same UKF update (r_max = 18 m
    also drops anchors, so some steps have fewer than four ranges)."""
    sc, rng = _scenario(31, n_agents=1, n_steps=15, r_max=r_max)
    P0 = np.diag(np.r_[np.full(3, 4.0), np.full(3, 0.25), np.full(3, 0.05)])
    m0 = sc.initial_states[0] + rng.multivariate_normal(np.zeros(9), P0)
    prior = GaussianPrior(m0[None], P0[None])
    got = run_spbp(sc.measurements(), prior, options=SPBPOptions(n_iterations=n_iterations))
    mean, cov = ukf_track(m0, P0, sc.z[:, 0, 1:], sc.anchors, 3, 0.1, 0.15, 0.1)
    np.testing.assert_allclose(got.estimates[:, 0], mean, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got.covariances[:, 0], cov, rtol=1e-7, atol=1e-12)
    assert state_errors(got, sc)["p"][-1] < 0.5  # and it localizes


def test_unscented_update_covariance_is_the_pfbp_ukf_step(rng):
    """Same sigma points as PF-BP eq. (30): the covariance equals ukf_covariance_update."""
    n, dim = 27, 3
    A0 = rng.normal(size=(n, n))
    P = A0 @ A0.T / n + np.eye(n)
    mean = rng.normal(size=n) * 5
    off_a = np.zeros(4, np.int64)
    off_b = np.array([9, 18, -1, -1], np.int64)
    anchors = rng.normal(size=(4, dim)) * 10
    z = rng.uniform(3, 9, 4)
    r_var = np.full(4, 0.01)
    m1, P1 = unscented_range_update(mean, P, off_a, off_b, anchors, z, r_var, dim, 9)
    ref = _flow.ukf_covariance_update(mean, P, off_a, off_b, anchors, r_var, dim, 9)
    np.testing.assert_allclose(P1, ref, rtol=1e-10, atol=1e-12)
    assert m1.shape == (9,) and np.all(np.linalg.eigvalsh(P1) > 0)


def test_degenerate_geometry_stays_finite():
    """Coplanar anchors and an agent without any measurement: no NaN/inf; the isolated agent
    is exactly predicted (mean Fᵏ m, covariance Fᵏ P Fᵏᵀ + …)."""
    _, model, anchors, states, z, sc, m, P, F = degenerate_scenario(4)
    K = 4
    assert np.all(np.isnan(sc.z[:, 2]))
    prior = GaussianPrior(m, P)
    for opt in (SPBPOptions(), SPBPOptions(regularize=True), SPBPOptions(factors="centralized")):
        r = run_spbp(sc.measurements(), prior, options=opt)
        assert np.all(np.isfinite(r.estimates)) and np.all(np.isfinite(r.covariances))
        assert np.all(np.linalg.eigvalsh(r.covariances) > -1e-9)
        expected = np.stack([np.linalg.matrix_power(F, k + 1) @ m[2] for k in range(K)])
        np.testing.assert_allclose(r.estimates[:, 2], expected, rtol=1e-12, atol=1e-12)
        assert np.all(np.abs(r.estimates[-1, 0, :3] - 5.0) < 0.5)  # the other one is localized
    # an agent exactly on an anchor (zero range): still finite
    states2 = states.copy()
    states2[:, 0, :3] = anchors[1]
    z2 = z.copy()
    z2[0, 4] = 0.0
    sc2 = RangeScenario(model, anchors, states2[0], states2, np.repeat(z2[None], K, axis=0), 30.0)
    r = run_spbp(sc2.measurements(), prior)
    assert np.all(np.isfinite(r.estimates)) and np.all(np.isfinite(r.covariances))


def test_reproducible_and_independent_of_rng():
    out = []
    for rng_arg in (None, np.random.default_rng(5), np.random.default_rng(6)):
        sc, rng = _scenario(7, n_steps=3)
        meas = sc.measurements()
        out.append(run_spbp(meas, paper_prior(meas, rng), rng_arg))
    for r in out[1:]:
        np.testing.assert_array_equal(r.estimates, out[0].estimates)
        np.testing.assert_array_equal(r.covariances, out[0].covariances)
    assert out[0].label == "spbp" and out[0].timing.step_s.shape == (3,)
    assert out[0].timing.agent_iterations == 3 * 2 * 5  # K · U · n_agents


def test_validation_errors():
    sc, rng = _scenario(0, n_steps=1)
    meas = sc.measurements()
    prior = paper_prior(meas, rng)
    with pytest.raises(ValidationError, match="factors"):
        SPBPOptions(factors="both")
    with pytest.raises(ValidationError, match="n_iterations"):
        SPBPOptions(n_iterations=0)
    with pytest.raises(ValidationError, match="options"):
        run_spbp(meas, prior, rng, options={"n_iterations": 2})
    with pytest.raises(ValidationError, match="rng"):
        run_spbp(meas, prior, 3)
    with pytest.raises(ValidationError, match=r"prior\.mean"):
        run_spbp(meas, GaussianPrior(np.zeros((5, 6)), prior.cov[:, :6, :6]))
    with pytest.raises(ValidationError, match="prior"):
        run_spbp(meas, (prior.mean, prior.cov))
    with pytest.raises(ValidationError):
        SPBPOptions.from_dict({"n_iteration": 2})


def test_spbp_tracks_and_pfbp_is_more_accurate_at_k10():
    """Scenario I-like (5 agents, 9 anchors, CA, r_max = ∞, prior σ_p = 20 m), K = 10, 3 runs.

    SP-BP converges slowly from the wide prior (PF-BP §VI): measured RMSE_p(k = 10) ≈ 2.7 m
    for SP-BP, ≈ 0.08 m for PF-BP, PCRLB ≈ 0.058 m.
    """
    K, runs = 10, 3
    e_sp, e_pf, scs, P0 = [], [], [], None
    for seed in range(runs):
        sc, rng = _scenario(100 + seed, n_steps=K)
        meas = sc.measurements()
        prior = paper_prior(meas, rng)
        P0 = prior.cov
        e_sp.append(state_errors(run_spbp(meas, prior), sc)["p"] ** 2)
        e_pf.append(state_errors(run_pfbp(meas, prior, rng), sc)["p"] ** 2)
        scs.append(sc)
    bound = pcrlb(scs, P0).bounds["p"]
    rmse_sp = np.sqrt(np.mean(e_sp, axis=0))
    rmse_pf = np.sqrt(np.mean(e_pf, axis=0))
    assert np.all(np.isfinite(rmse_sp))
    assert np.all(rmse_sp > 0.8 * bound)  # a bound is a bound
    assert np.all(rmse_sp[4:] < 100.0 * bound[4:]), (rmse_sp, bound)  # it does track
    assert rmse_sp[-1] < 0.2 * rmse_sp[0]
    assert rmse_pf[-1] < 0.5 * rmse_sp[-1], (rmse_pf, rmse_sp)  # PF-BP more accurate at k = 10


def _stacked_problem(rng, n=27, dim=3, scale=1.0):
    A0 = rng.normal(size=(n, n))
    P = (A0 @ A0.T / n + np.eye(n)) * scale**2
    mean = rng.normal(size=n) * 5
    off_a = np.zeros(4, np.int64)
    off_b = np.array([9, 18, -1, -1], np.int64)
    anchors = rng.normal(size=(4, dim)) * 10
    return mean, P, off_a, off_b, anchors


def test_scaled_transform_with_alpha_one_is_the_cubature_rule(rng):
    """(α, β, κ) = (1, 0, 0): λ = 0, the centre point weighs nothing and the others sit at
    ``±√n L_j`` with weights ``1/(2n)``: the cubature rule, mean and covariance."""
    mean, P, off_a, off_b, anchors = _stacked_problem(rng)
    z, r_var = rng.uniform(3, 9, 4), np.full(4, 0.01)
    ref = unscented_range_update(mean, P, off_a, off_b, anchors, z, r_var, 3, 9)
    got = unscented_range_update(mean, P, off_a, off_b, anchors, z, r_var, 3, 9, (1.0, 0.0, 0.0))
    np.testing.assert_allclose(got[0], ref[0], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(got[1], ref[1], rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("scaled", [None, (1e-3, 2.0, 0.0), (0.5, 2.0, 1.0)])
def test_both_rules_are_the_kalman_update_of_a_linear_range(rng, scaled):
    """An anchor 100 km away: its range is linear in the state over the sigma points (the
    curvature and the rounding of 10⁵ m ranges under weights up to 3·10⁴ stay below 10⁻⁵), so
    every rule gives the Kalman filter's update with ``H`` the unit vector from the anchor
    (closed form). Weights not summing to one would shift the predicted range by ~10⁵ m."""
    n, dim = 18, 3
    mean, P, _, _, _ = _stacked_problem(rng, n=n, scale=0.3)
    u = rng.normal(size=dim)
    u /= np.linalg.norm(u)
    anchor = mean[:dim] - 1e5 * u
    off_a, off_b = np.zeros(1, np.int64), np.full(1, -1, np.int64)
    z, r_var = np.array([1e5 + 0.7]), np.array([0.04])
    m1, P1 = unscented_range_update(mean, P, off_a, off_b, anchor[None], z, r_var, dim, n, scaled)
    H = np.zeros(n)
    H[:dim] = u
    S = H @ P @ H + r_var[0]
    K = P @ H / S
    np.testing.assert_allclose(m1, mean + K * 0.7, atol=2e-5)
    np.testing.assert_allclose(P1, P - np.outer(K, K) * S, atol=2e-5)


def test_scaled_points_stay_finite_under_the_paper_prior(rng):
    """A 45-D stacked state (five agents) with the 20 m position prior of PF-BP eq. (31): the
    centre weight is about −10⁶, yet mean and covariance are finite, symmetric and PSD."""
    n, dim = 45, 3
    diag = np.tile(np.r_[np.full(3, 400.0), np.full(3, 0.0225), np.full(3, 2.25)], 5)
    P = np.diag(diag)
    mean = np.zeros(n)
    mean[0:45:9] = rng.uniform(0, 20, 5)
    off_a = np.zeros(13, np.int64)
    off_b = np.r_[np.array([9, 18, 27, 36]), np.full(9, -1)].astype(np.int64)
    anchors = rng.uniform(0, 20, (13, dim))
    z = rng.uniform(1, 30, 13)
    m1, P1 = unscented_range_update(
        mean, P, off_a, off_b, anchors, z, np.full(13, 0.01), dim, 9, (1e-3, 2.0, 0.0)
    )
    assert np.all(np.isfinite(m1)) and np.all(np.isfinite(P1))
    np.testing.assert_array_equal(P1, P1.T)
    assert np.linalg.eigvalsh(P1).min() > -1e-9 * np.abs(P1).max()


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"sigma_points": "unscented"}, "sigma_points"), ({"ut_alpha": 0.0}, "ut_alpha"),
     ({"ut_kappa": -1.0}, "ut_kappa")],
)  # fmt: skip
def test_bad_sigma_point_options_name_their_key(kwargs, field):
    with pytest.raises(ValidationError) as err:
        SPBPOptions(**kwargs)
    assert err.value.field == field
