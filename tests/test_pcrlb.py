"""PCRLB (Tichavský recursion) against the Kalman filter and brute-force Fisher information."""

import numpy as np
import pytest

from phyloc.analysis.pcrlb import one_range_per_pair, pcrlb, pcrlb_recursion, range_information
from phyloc.errors import ValidationError
from phyloc.evaluation.range_scenarios import RangeScenario
from phyloc.localization.tracking import RangeModel, _flow
from phyloc.network.motion import transition_matrices


def test_recursion_equals_kalman_covariance(rng):
    """Linear-Gaussian CA model (singular Q), time-varying linear measurements."""
    F, Q = transition_matrices("constant_acceleration", 2, 0.1, 0.5)
    n, K = F.shape[0], 12
    A0 = rng.normal(size=(n, n))
    P = A0 @ A0.T + np.eye(n)
    J0 = np.linalg.inv(P)
    Hs = [rng.normal(size=(3, n)) * (k % 3 != 1) for k in range(K)]  # some steps without info
    R = np.diag([0.1, 0.2, 0.3])
    Jz = np.stack([H.T @ np.linalg.inv(R) @ H for H in Hs])
    got = pcrlb_recursion(J0, F, Q, Jz)
    for k, H in enumerate(Hs):  # Kalman filter in gain (Joseph) form
        P = F @ P @ F.T + Q
        S = H @ P @ H.T + R
        G = P @ H.T @ np.linalg.inv(S)
        IKH = np.eye(n) - G @ H
        P = IKH @ P @ IKH.T + G @ R @ G.T
        np.testing.assert_allclose(got[k], P, rtol=1e-7, atol=1e-10)


def test_range_information_equals_jacobian_outer_product(rng):
    """J_z = Hᵀ H / σ² with H the brute-force Jacobian of every measured range."""
    n_ag, dim, nd, sigma = 3, 3, 6, 0.2
    p = rng.uniform(0, 10, size=(n_ag, dim))
    anchors = rng.uniform(0, 10, size=(2, dim))
    measured = np.zeros((n_ag, n_ag + 2), bool)
    measured[0, 1] = measured[1, 0] = measured[0, 3] = measured[2, 4] = measured[2, 0] = True
    J = range_information(p, anchors, measured, sigma, nd)
    x = np.zeros(n_ag * nd)
    for i in range(n_ag):
        x[i * nd : i * nd + dim] = p[i]
    rows = []
    for i, j in zip(*np.nonzero(measured), strict=True):
        off_b = -1 if j >= n_ag else j * nd
        apos = anchors[j - n_ag][None] if j >= n_ag else np.zeros((1, dim))
        H, _ = _flow.range_linearization(x, np.array([i * nd]), np.array([off_b]), apos, dim)
        rows.append(H[0])
    H = np.array(rows)
    np.testing.assert_allclose(J, H.T @ H / sigma**2, atol=1e-9)


def test_pcrlb_static_single_step_closed_form():
    """One agent, static model, one step: C = (P0⁻¹ + Σ u uᵀ/σ²)⁻¹; bound = sqrt(tr C)."""
    model = RangeModel("static", 2, sigma_r=0.1)
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    x = np.array([[3.0, 4.0]])
    z = np.full((1, 1, 4), np.nan)
    z[0, 0, 1:] = 1.0  # measured to the three anchors (values do not enter the bound)
    sc = RangeScenario(model, anchors, x, x[None], z)
    P0 = np.eye(2)[None] * 4.0
    res = pcrlb([sc, sc], P0)
    u = (x[0] - anchors) / np.linalg.norm(x[0] - anchors, axis=1, keepdims=True)
    C = np.linalg.inv(np.eye(2) / 4.0 + u.T @ u / 0.01)
    np.testing.assert_allclose(res.cov[0], C)
    np.testing.assert_allclose(res.bounds["p"], [np.sqrt(np.trace(C))])
    assert set(res.bounds) == {"p"}


def test_pcrlb_information_vs_bound_average_closed_form():
    """Two scenarios with different connectivity: the Bayesian PCRLB inverts the mean
    information, the conditional bound averages the per-scenario inverses (Jensen: larger)."""
    model = RangeModel("static", 2, sigma_r=0.1)
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    x = np.array([[3.0, 4.0]])
    scs = []
    for linked in ([1, 2, 3], [1]):  # all anchors / only the first one
        z = np.full((1, 1, 4), np.nan)
        z[0, 0, linked] = 1.0
        scs.append(RangeScenario(model, anchors, x, x[None], z))
    P0 = np.eye(2)[None] * 4.0
    u = (x[0] - anchors) / np.linalg.norm(x[0] - anchors, axis=1, keepdims=True)
    J_all = np.eye(2) / 4.0 + u.T @ u / 0.01
    J_one = np.eye(2) / 4.0 + np.outer(u[0], u[0]) / 0.01
    C_info = np.linalg.inv(0.5 * (J_all + J_one))
    C_bound = 0.5 * (np.linalg.inv(J_all) + np.linalg.inv(J_one))
    np.testing.assert_allclose(pcrlb(scs, P0).cov[0], C_info, rtol=1e-10)
    res_b = pcrlb(scs, P0, average="bound")
    np.testing.assert_allclose(res_b.cov[0], C_bound, rtol=1e-10)
    assert res_b.bounds["p"][0] > 1.5 * pcrlb(scs, P0).bounds["p"][0]
    # each scenario's own mean-square bound, in order: the closed-form traces
    np.testing.assert_allclose(
        res_b.per_scenario["p"][:, 0],
        [np.trace(np.linalg.inv(J_all)), np.trace(np.linalg.inv(J_one))],
        rtol=1e-10,
    )
    assert pcrlb(scs, P0).per_scenario is None  # averaged information: no per-run bounds
    # identical scenarios: both averages coincide
    same = [scs[0], scs[0]]
    np.testing.assert_allclose(
        pcrlb(same, P0, average="bound").cov, pcrlb(same, P0).cov, rtol=1e-12
    )
    with pytest.raises(ValidationError, match="average"):
        pcrlb(scs, P0, average="mean")


def test_pcrlb_validation():
    with pytest.raises(ValidationError, match="scenarios"):
        pcrlb([], np.eye(2)[None])
    with pytest.raises(ValidationError):
        pcrlb_recursion(np.eye(2), np.eye(3), np.eye(3), np.zeros((1, 3, 3)))


def test_one_range_per_pair_halves_a_pair_measured_both_ways_closed_form():
    """Two agents on a line with one anchor each side, static model: a pair measured both
    ways adds 2/σ² along the line to the joint information, one range per pair 1/σ²; anchor
    ranges are untouched; one-way pairs are kept once whichever agent measured them."""
    model = RangeModel("static", 2, sigma_r=0.1)
    anchors = np.array([[-5.0, 0.0], [15.0, 0.0]])
    x = np.array([[0.0, 0.0], [10.0, 0.0]])
    z = np.full((1, 2, 4), np.nan)
    z[0, 0, [1, 2]] = 1.0  # agent 0: agent 1 and anchor 0
    z[0, 1, [0, 3]] = 1.0  # agent 1: agent 0 and anchor 1
    sc = RangeScenario(model, anchors, x[None], x[None], z)
    P0 = np.eye(2)[None].repeat(2, axis=0)
    e = np.array([1.0, 0.0])
    uu = np.outer(e, e) / 0.01

    def joint(w):  # prior + anchors + w agent-agent ranges
        J = np.eye(4)
        J[:2, :2] += uu
        J[2:, 2:] += uu
        J[:2, :2] += w * uu
        J[2:, 2:] += w * uu
        J[:2, 2:] -= w * uu
        J[2:, :2] -= w * uu
        return J

    np.testing.assert_allclose(pcrlb([sc], P0).cov[0], np.linalg.inv(joint(2)), rtol=1e-10)
    one = pcrlb([sc], P0, pairs="one")
    np.testing.assert_allclose(one.cov[0], np.linalg.inv(joint(1)), rtol=1e-10)
    assert one.bounds["p"][0] > pcrlb([sc], P0).bounds["p"][0]
    m = np.isfinite(z[0])
    kept = one_range_per_pair(m)
    assert kept[0, 1] and not kept[1, 0] and kept[0, 2] and kept[1, 3]
    m1 = m.copy()
    m1[0, 1] = False  # only agent 1 measured the pair: still kept once, as (0, 1)
    kept1 = one_range_per_pair(m1)
    assert kept1[0, 1] and not kept1[1, 0]
    with pytest.raises(ValidationError, match="pairs"):
        pcrlb([sc], P0, pairs="two")
