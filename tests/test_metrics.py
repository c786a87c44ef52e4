"""Metrics: DiPNet eq. (4) and eq. (1), rigid alignment, error CDF, outage, per-snapshot RMSE."""

import math

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.evaluation.metrics import (
    error_cdf,
    framework_distance_errors,
    framework_distance_rmse,
    outage_probability,
    rigid_align,
    rmse_per_snapshot,
    shape_difference,
)


def random_orthogonal(rng, dim, proper=True):
    """A random rotation (det +1) or rotation-reflection (det −1)."""
    q, r = np.linalg.qr(rng.normal(size=(dim, dim)))
    q = q * np.sign(np.diag(r))
    if (np.linalg.det(q) > 0) != proper:
        q[:, 0] = -q[:, 0]
    return q


def brute_eq4(est, true, is_anchor):
    """DiPNet eq. (4) as written: u over agents, v over all other nodes, one term at a time."""
    n = len(true)
    total, count = 0.0, 0
    for u in range(n):
        if is_anchor[u]:
            continue
        for v in range(n):
            if v == u:
                continue
            d_hat = math.dist(est[u], est[v])
            d = math.dist(true[u], true[v])
            total += (d_hat - d) ** 2
            count += 1
    n_agents = n - sum(is_anchor)
    assert count == n_agents * (n - 1)
    return math.sqrt(total / (n_agents * (n - 1)))


def brute_shape_2d(est, true, agents, fix_point=None, n_angles=20_000):
    """min over angles θ, mirror ∈ {no, yes} and translation of the agent RMS error (2-D).

    With ``fix_point`` the transform is a rotation/mirror about that (anchor) point.
    """
    best = np.inf
    th = np.linspace(0, 2 * np.pi, n_angles, endpoint=False)
    c, s = np.cos(th), np.sin(th)
    for mirror in (1.0, -1.0):
        q = est[agents] * [1.0, mirror]
        p = true[agents]
        if fix_point is None:
            q = q - q.mean(axis=0)
            p = p - p.mean(axis=0)
        else:
            q = q - fix_point * [1.0, mirror]
            p = p - fix_point
        rx = c[:, None] * q[None, :, 0] - s[:, None] * q[None, :, 1]
        ry = s[:, None] * q[None, :, 0] + c[:, None] * q[None, :, 1]
        err = np.mean((rx - p[:, 0]) ** 2 + (ry - p[:, 1]) ** 2, axis=1)
        best = min(best, float(np.sqrt(err.min())))
    return best


# -- framework distance RMSE (eq. (4)) ------------------------------------------------------


@pytest.mark.parametrize(("dim", "n_anchors"), [(2, 0), (2, 3), (3, 4), (3, 0)])
def test_eq4_equals_double_loop(dim, n_anchors, rng):
    n = 9
    true = rng.uniform(0, 50, size=(n, dim))
    est = true + rng.normal(0, 2.0, size=(n, dim))
    anchor = np.zeros(n, bool)
    anchor[n - n_anchors :] = True
    est[anchor] = true[anchor]
    errors, pairs = framework_distance_errors(est, true, anchor, return_pairs=True)
    n_agents = n - n_anchors
    assert errors.shape == (n_agents * (n - 1),)
    # agent–agent pairs twice, agent–anchor pairs once, anchor–anchor never
    assert all(not anchor[u] for u, _ in pairs)
    got = framework_distance_rmse(est, true, anchor if n_anchors else None)
    assert got == pytest.approx(brute_eq4(est, true, anchor), rel=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("proper", [True, False])
def test_metrics_invariant_to_rigid_motion_of_the_estimates(dim, proper, rng):
    n = 10
    true = rng.uniform(0, 30, size=(n, dim))
    est = true + rng.normal(0, 1.5, size=(n, dim))
    R = random_orthogonal(rng, dim, proper)
    moved = est @ R.T + rng.uniform(-100, 100, size=dim)
    assert framework_distance_rmse(moved, true) == pytest.approx(
        framework_distance_rmse(est, true), rel=1e-10
    )
    assert shape_difference(moved, true) == pytest.approx(shape_difference(est, true), rel=1e-9)
    # with anchors: the whole estimated framework (anchors included) moved rigidly
    anchor = np.zeros(n, bool)
    anchor[: dim + 1] = True
    assert shape_difference(moved, true, anchor) == pytest.approx(
        shape_difference(est, true, anchor), rel=1e-9
    )
    assert framework_distance_rmse(moved, true, anchor) == pytest.approx(
        framework_distance_rmse(est, true, anchor), rel=1e-10
    )
    if not proper:  # a mirror cannot be undone by a rotation alone
        assert shape_difference(moved, true, reflection=False) > shape_difference(est, true) + 1


# -- rigid alignment --------------------------------------------------------------------------


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("proper", [True, False])
@pytest.mark.parametrize("n_anchors", [0, 1, 2, 4])
def test_rigid_align_recovers_known_transform(dim, proper, n_anchors, rng):
    n = 8
    true = rng.uniform(0, 20, size=(n, dim))
    R = random_orthogonal(rng, dim, proper)
    t = rng.uniform(-50, 50, size=dim)
    est = (true - t) @ R  # T(est) = R est + t = true
    anchor = np.zeros(n, bool)
    anchor[n - n_anchors :] = True
    R_hat, t_hat, aligned = rigid_align(est, true, is_anchor=anchor)
    np.testing.assert_allclose(R_hat, R, atol=1e-10)
    np.testing.assert_allclose(t_hat, t, atol=1e-8)
    np.testing.assert_allclose(aligned, true, atol=1e-8)
    assert shape_difference(est, true, anchor) == pytest.approx(0.0, abs=1e-8)
    R_p, _, _ = rigid_align(est, true, is_anchor=anchor, reflection=False)
    assert np.linalg.det(R_p) == pytest.approx(1.0)
    if proper:
        np.testing.assert_allclose(R_p, R, atol=1e-10)


def test_rigid_align_is_optimal_against_brute_force_2d(rng):
    n = 7
    true = rng.uniform(0, 20, size=(n, 2))
    est = (true + rng.normal(0, 2.0, size=(n, 2))) @ random_orthogonal(rng, 2, False).T + 5.0
    agents = np.ones(n, bool)
    brute = brute_shape_2d(est, true, agents)
    got = shape_difference(est, true)
    assert brute - 1e-6 <= got <= brute + 1e-6


def test_one_anchor_fixes_a_point_brute_force_2d(rng):
    n = 7
    true = rng.uniform(0, 20, size=(n, 2))
    est = true + rng.normal(0, 2.0, size=(n, 2))
    anchor = np.zeros(n, bool)
    anchor[-1] = True
    est[-1] = true[-1]
    _R, _t, aligned = rigid_align(est, true, is_anchor=anchor)
    np.testing.assert_allclose(aligned[-1], true[-1], atol=1e-10)  # the anchor stays put
    brute = brute_shape_2d(est, true, ~anchor, fix_point=true[-1])
    assert shape_difference(est, true, anchor) == pytest.approx(brute, abs=1e-6)
    # fixing a point can only cost: the free fit over the same agents is at least as good
    free = shape_difference(est[~anchor], true[~anchor])
    assert free < shape_difference(est, true, anchor)


def test_two_anchors_in_2d_allow_only_identity_or_mirror(rng):
    n = 6
    true = rng.uniform(0, 20, size=(n, 2))
    anchor = np.array([False] * 4 + [True] * 2)
    a, b = true[4], true[5]
    axis = (b - a) / np.linalg.norm(b - a)
    mirror = 2 * np.outer(axis, axis) - np.eye(2)  # reflection across the anchors' line
    est = true.copy()
    est[:4] = (true[:4] - a) @ mirror.T + a + rng.normal(0, 0.1, size=(4, 2))
    plain = np.sqrt(np.mean(np.sum((est[:4] - true[:4]) ** 2, axis=1)))
    flipped = np.sqrt(np.mean(np.sum(((est[:4] - a) @ mirror.T + a - true[:4]) ** 2, axis=1)))
    assert shape_difference(est, true, anchor) == pytest.approx(min(plain, flipped), rel=1e-9)
    assert shape_difference(est, true, anchor, reflection=False) == pytest.approx(plain, rel=1e-9)
    _, _, aligned = rigid_align(est, true, is_anchor=anchor)
    np.testing.assert_allclose(aligned[4:], true[4:], atol=1e-10)


def test_enough_anchors_mean_no_transform(rng):
    for dim in (2, 3):
        n = 9
        true = rng.uniform(0, 20, size=(n, dim))
        anchor = np.zeros(n, bool)
        anchor[: dim + 1] = True
        est = true + np.where(anchor[:, None], 0.0, rng.normal(0, 1.0, size=(n, dim)))
        R, t, _ = rigid_align(est, true, is_anchor=anchor)
        np.testing.assert_allclose(R, np.eye(dim), atol=1e-12)
        np.testing.assert_allclose(t, 0.0, atol=1e-10)
        plain = np.sqrt(np.mean(np.sum((est[~anchor] - true[~anchor]) ** 2, axis=1)))
        assert shape_difference(est, true, anchor) == pytest.approx(plain, rel=1e-10)


def test_collinear_anchors_in_3d_keep_their_line(rng):
    true = rng.uniform(0, 20, size=(8, 3))
    true[5:] = true[5] + np.outer([0.0, 1.0, 2.5], [1.0, 2.0, -1.0])  # 3 anchors on a line
    anchor = np.array([False] * 5 + [True] * 3)
    axis = np.array([1.0, 2.0, -1.0]) / math.sqrt(6)
    # a rotation by 40° about the anchors' line: fixes the anchors, moves the agents
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + math.sin(0.7) * k + (1 - math.cos(0.7)) * k @ k
    est = (true - true[5]) @ rot + true[5]  # rot⁻¹ applied
    R, _t, aligned = rigid_align(est, true, is_anchor=anchor)
    np.testing.assert_allclose(aligned, true, atol=1e-8)
    np.testing.assert_allclose(R, rot, atol=1e-10)


# -- degenerate inputs ------------------------------------------------------------------------


def test_two_nodes_closed_form():
    true = np.array([[0.0, 0.0], [2.0, 0.0]])
    est = np.array([[5.0, 5.0], [5.0, 8.0]])
    assert framework_distance_rmse(est, true) == pytest.approx(1.0)
    assert shape_difference(est, true) == pytest.approx(0.5)  # |3 − 2| / 2 at each end
    R, _t, aligned = rigid_align(est, true)
    assert np.all(np.isfinite(R)) and np.all(np.isfinite(aligned))
    np.testing.assert_allclose(aligned.mean(axis=0), true.mean(axis=0), atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_collinear_nodes_closed_form(dim, rng):
    direction = random_orthogonal(rng, dim)[:, 0]
    s_true = np.array([0.0, 1.0, 3.0, 7.0])
    s_est = np.array([0.2, 0.9, 3.5, 6.0])
    true = s_true[:, None] * direction + 4.0
    other = random_orthogonal(rng, dim)[:, 0]
    est = s_est[:, None] * other - 2.0
    # 1-D Procrustes: centre, then best sign
    a, b = s_est - s_est.mean(), s_true - s_true.mean()
    expected = min(np.sqrt(np.mean((a - b) ** 2)), np.sqrt(np.mean((a + b) ** 2)))
    got = shape_difference(est, true)
    assert np.isfinite(got) and got == pytest.approx(expected, rel=1e-9)
    assert framework_distance_rmse(est, true) == pytest.approx(
        brute_eq4(est, true, [False] * 4), rel=1e-12
    )


def test_single_agent_and_coincident_estimates():
    true = np.array([[1.0, 2.0]])
    with pytest.raises(ValidationError, match="at least 2 nodes"):
        framework_distance_rmse(true + 1, true)
    assert shape_difference(true + 1, true) == 0.0
    true = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])
    est = np.zeros((3, 2))  # all estimates at one point: finite, equal to the centred spread
    expected = np.sqrt(np.mean(np.sum((true - true.mean(axis=0)) ** 2, axis=1)))
    assert shape_difference(est, true) == pytest.approx(expected)


def test_missing_estimates_error_or_exclude(rng):
    n = 8
    true = rng.uniform(0, 20, size=(n, 2))
    est = true + rng.normal(0, 1.0, size=(n, 2))
    anchor = np.zeros(n, bool)
    anchor[-2:] = True
    est[2, 1] = np.nan
    for fn in (framework_distance_rmse, shape_difference):
        with pytest.raises(ValidationError, match=r"NaN in agent rows \[2\].*missing='exclude'"):
            fn(est, true, anchor)
    keep = np.arange(n) != 2
    _errors, pairs = framework_distance_errors(
        est, true, anchor, missing="exclude", return_pairs=True
    )
    assert len(pairs) == 5 * (7 - 1) and not np.isin(pairs, 2).any()  # 5 agents, 7 nodes left
    assert framework_distance_rmse(est, true, anchor, missing="exclude") == pytest.approx(
        brute_eq4(est[keep], true[keep], anchor[keep])
    )
    assert shape_difference(est, true, anchor, missing="exclude") == pytest.approx(
        shape_difference(est[keep], true[keep], anchor[keep])
    )
    _, _, aligned = rigid_align(est, true, is_anchor=anchor, missing="exclude")
    assert np.isnan(aligned[2]).all() and np.isfinite(np.delete(aligned, 2, axis=0)).all()
    est[:6] = np.nan
    with pytest.raises(ValidationError, match="no agent has an estimate"):
        shape_difference(est, true, anchor, missing="exclude")
    with pytest.raises(ValidationError, match="finite or NaN"):
        framework_distance_rmse(np.full((n, 2), np.inf), true)


def test_nan_anchor_rows_mean_known_anchors(rng):
    true = rng.uniform(0, 20, size=(6, 2))
    anchor = np.array([False] * 3 + [True] * 3)
    est = true + rng.normal(0, 1.0, size=(6, 2))
    est[anchor] = true[anchor]
    blank = est.copy()
    blank[anchor] = np.nan
    assert framework_distance_rmse(blank, true, anchor) == framework_distance_rmse(
        est, true, anchor
    )
    assert shape_difference(blank, true, anchor) == shape_difference(est, true, anchor)
    with pytest.raises(ValidationError, match="at least one node must be an agent"):
        shape_difference(true, true, np.ones(6, bool))


# -- CDF, outage, RMSE per snapshot -----------------------------------------------------------


def test_error_cdf_and_outage_match_counting(rng):
    e = np.round(rng.exponential(1.0, size=500), 1)  # ties on purpose
    x, F = error_cdf(e)
    assert np.all(np.diff(x) > 0) and F[-1] == 1.0
    for xi, Fi in zip(x[::17], F[::17], strict=True):
        assert Fi == sum(1 for ei in e if ei <= xi) / 500
    grid = np.array([-1.0, 0.0, 0.5, 1.0, 3.0, 100.0])
    _, Fg = error_cdf(e, grid)
    P = outage_probability(e, grid)
    for g, fg, p in zip(grid, Fg, P, strict=True):
        assert fg == sum(1 for ei in e if ei <= g) / 500
        assert p == sum(1 for ei in e if ei > g) / 500  # strictly above the threshold
    assert outage_probability([1.0, 2.0], 1.0) == 0.5
    with pytest.raises(ValidationError, match="finite"):
        error_cdf([1.0, np.nan])
    with pytest.raises(ValidationError, match="empty"):
        outage_probability([], [1.0])


def test_rmse_per_snapshot_brute_force_mask_and_missing(rng):
    T, n, dim = 4, 6, 3
    true = rng.normal(size=(T, n, dim))
    est = true + rng.normal(0, 0.5, size=(T, n, dim))
    mask = np.array([True] * 4 + [False] * 2)
    got = rmse_per_snapshot(est, true, mask)
    for k in range(T):
        sq = [sum((est[k, u, i] - true[k, u, i]) ** 2 for i in range(dim)) for u in range(4)]
        assert got[k] == pytest.approx(math.sqrt(sum(sq) / 4), rel=1e-12)
    est[1, 5] = np.nan  # outside the mask: ignored
    np.testing.assert_array_equal(rmse_per_snapshot(est, true, mask), got)
    est[2, 0] = np.nan
    with pytest.raises(ValidationError, match="snapshot 2, node 0"):
        rmse_per_snapshot(est, true, mask)
    r, counts = rmse_per_snapshot(est, true, mask, missing="exclude", return_counts=True)
    np.testing.assert_array_equal(counts, [4, 4, 3, 4])
    assert r[2] == pytest.approx(
        np.sqrt(np.mean(np.sum((est[2, 1:4] - true[2, 1:4]) ** 2, axis=1)))
    )
    est[3, :4] = np.nan
    with pytest.raises(ValidationError, match=r"snapshots \[3\]"):
        rmse_per_snapshot(est, true, mask, missing="exclude")
