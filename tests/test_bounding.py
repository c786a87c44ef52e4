"""Distributed bounding of feasible sets (phyloc.localization.static.bounding): the S-procedure
discs of the ellipse baseline POA-NBP cites.

References: closed forms (the pencil disc of two equal circles and of a disc cut by a line),
brute force (the optimum against SLSQP from several starts on the primal
``min_{h <= 0} max_i (‖x − a_i‖² − r_i²)``, and against random feasible multipliers), Monte
Carlo samples of the exact feasible set (containment), the minimum-area ellipse of the exact
set from inside (phyloc's Löwner–John kernel on boundary points of the set) and phyloc's exact
ellipse baseline (area bounds both ways), invariances, and the truth of simulated networks
with non-negative ranging errors.
"""

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from phyloc.errors import ValidationError
from phyloc.evaluation.static_scenarios import paper_static_scenario
from phyloc.localization import METHODS
from phyloc.localization.static import _polygon_kernels as K
from phyloc.localization.static.bounding import bounding_disc, feasible_set_bounding
from phyloc.localization.static.ellipses import ellipse_outer_approximation
from phyloc.localization.static.static_ranges import StaticPrior, range_error_model

BOX = (0.0, 0.0, 100.0, 100.0)
BOX_A = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
BOX_C = np.array([100.0, 100.0, 0.0, 0.0])


def _random_set(rng):
    """Discs and halfspaces around a common point ``x0`` (so the set is not empty)."""
    m = int(rng.integers(1, 8))
    x0 = rng.uniform(20.0, 80.0, 2)
    a = x0 + rng.uniform(-20.0, 20.0, (m, 2))
    r = np.linalg.norm(a - x0, axis=1) + rng.exponential(2.0, m)
    p = int(rng.integers(0, 4))
    n = rng.normal(size=(p, 2))
    n /= np.linalg.norm(n, axis=1)[:, None]
    c = n @ x0 + rng.exponential(5.0, p)
    return x0, a, r, n, c


def _feasible(q, a, r, n, c):
    inside = np.all(np.linalg.norm(q[:, None] - a[None], axis=2) <= r, axis=1)
    return inside & np.all(q @ n.T <= c, axis=1) if n.size else inside


def _primal(a, r, n, c, x0, rng):
    """Brute force: ``min max_i f_i`` over the halfspaces by SLSQP on the epigraph from
    feasible starts near ``x0`` (a common point of the set), best of 6 that end feasible."""

    def f(x):
        return np.sum((x - a) ** 2, axis=1) - r * r

    cons = [{"type": "ineq", "fun": lambda z, k=k: c[k] - n[k] @ z[:2]} for k in range(len(c))]
    cons += [{"type": "ineq", "fun": lambda z, i=i: z[2] - f(z[:2])[i]} for i in range(len(r))]
    best = math.inf
    for k in range(6):
        x = x0 + (0.0 if k == 0 else 0.3) * rng.normal(size=2)
        if len(c) and np.any(n @ x > c):
            x = x0
        res = minimize(
            lambda z: z[2],
            np.r_[x, f(x).max() + 1.0],
            constraints=cons,
            method="SLSQP",
            options={"ftol": 1e-14, "maxiter": 1000},
        )
        z = res.x
        viol = max(np.max(f(z[:2]) - z[2]), np.max(n @ z[:2] - c, initial=-1.0))
        if viol < 1e-7:
            best = min(best, z[2])
    assert math.isfinite(best)
    return best


# -- the disc of one set ---------------------------------------------------------------------------
def test_closed_forms():
    # two circles of radius r at distance 2d: the disc through the lens tips, radius √(r² − d²)
    r, d = 5.0, 3.0
    c, r2, w, mu = bounding_disc([[-d, 1.0], [d, 1.0]], [r, r])
    np.testing.assert_allclose(c, [0.0, 1.0], atol=1e-12)
    assert r2 == pytest.approx(r * r - d * d, rel=1e-12)
    np.testing.assert_allclose(w, [0.5, 0.5], atol=1e-12)
    assert mu.size == 0
    # a unit disc cut by x <= −1/2: the disc through the chord's ends
    c, r2, w, mu = bounding_disc([[0.0, 0.0]], [1.0], [[1.0, 0.0]], [-0.5])
    np.testing.assert_allclose(c, [-0.5, 0.0], atol=1e-12)
    assert r2 == pytest.approx(0.75, rel=1e-12) and mu[0] == pytest.approx(1.0)
    # a half disc: the line through the centre does not help (the smallest enclosing disc)
    c, r2, _, mu = bounding_disc([[2.0, 3.0]], [1.0], [[0.0, 1.0]], [3.0])
    np.testing.assert_allclose(c, [2.0, 3.0], atol=1e-12)
    assert r2 == pytest.approx(1.0) and mu[0] == pytest.approx(0.0, abs=1e-12)
    # a disc inside another: the smaller one
    c, r2, w, _ = bounding_disc([[0.0, 0.0], [0.5, 0.0]], [3.0, 1.0])
    np.testing.assert_allclose(c, [0.5, 0.0], atol=1e-12)
    assert r2 == pytest.approx(1.0) and w[1] == pytest.approx(1.0)
    # disjoint discs: no common point, ρ² < 0
    assert bounding_disc([[0.0, 0.0], [5.0, 0.0]], [1.0, 1.0])[1] < 0


@pytest.mark.parametrize("seed", range(3))
def test_optimum_against_brute_force_and_random_multipliers(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        x0, a, r, n, c = _random_set(rng)
        centre, r2, w, mu = bounding_disc(a, r, n, c)
        # strong duality: ρ*² = −min_{h <= 0} max_i f_i
        assert r2 == pytest.approx(-_primal(a, r, n, c, x0, rng), rel=1e-7, abs=1e-7)
        # the multipliers reproduce the disc (eq. (B2)) and are feasible
        assert np.all(w >= 0) and np.all(mu >= 0) and w.sum() == pytest.approx(1.0)
        abar = w @ a - 0.5 * mu @ n
        np.testing.assert_allclose(centre, abar, atol=1e-9)
        rho2 = abar @ abar - w @ (np.sum(a * a, axis=1) - r * r) + mu @ c
        assert rho2 == pytest.approx(r2, rel=1e-9, abs=1e-9)
        # every other feasible multiplier set gives a disc at least as large
        for _ in range(20):
            wr = rng.dirichlet(np.ones(len(r)))
            mr = rng.exponential(1.0, len(c))
            ar = wr @ a - 0.5 * mr @ n
            assert ar @ ar - wr @ (np.sum(a * a, axis=1) - r * r) + mr @ c >= r2 - 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_disc_contains_the_feasible_set_and_is_no_smaller_than_its_min_area_ellipse(seed):
    """Both ways: every sampled point of the exact set lies in the disc, and the disc is no
    smaller than the minimum-area ellipse of boundary points of the set (which lies inside the
    Löwner–John ellipse of the set)."""
    rng = np.random.default_rng(10 + seed)
    for _ in range(15):
        x0, a, r, n, c = _random_set(rng)
        centre, r2, _, _ = bounding_disc(a, r, n, c)
        q = x0 + rng.uniform(-45.0, 45.0, (40_000, 2))
        inner = q[_feasible(q, a, r, n, c)]
        assert inner.shape[0] > 0
        assert np.all(np.sum((inner - centre) ** 2, axis=1) <= r2 * (1 + 1e-12) + 1e-9)
        # boundary points of the set: the disc circles and lines, kept where feasible
        t = np.linspace(0.0, 2.0 * np.pi, 2000, endpoint=False)
        pts = [a[i] + r[i] * np.column_stack([np.cos(t), np.sin(t)]) for i in range(len(r))]
        for k in range(len(c)):
            foot = n[k] * c[k]
            along = np.array([-n[k, 1], n[k, 0]])
            pts.append(foot + np.linspace(-200.0, 200.0, 4000)[:, None] * along)
        pts = np.vstack(pts)
        pts = pts[_feasible(pts, a, r * (1 + 1e-12), n, c + 1e-9)]
        if pts.shape[0] < 3:
            continue
        _, S, _ = K.mvee_kernel(pts, 1e-7, 100_000)
        assert math.pi * r2 >= math.pi * math.sqrt(np.linalg.det(S)) * (1 - 1e-6)


def test_invariances():
    rng = np.random.default_rng(7)
    _, a, r, n, c = _random_set(rng)
    c0, r0, _, _ = bounding_disc(a, r, n, c)
    shift = np.array([123.0, -45.0])
    c1, r1, _, _ = bounding_disc(a + shift, r, n, c + n @ shift)
    np.testing.assert_allclose(c1, c0 + shift, atol=1e-9)
    assert r1 == pytest.approx(r0, rel=1e-9)
    perm = rng.permutation(len(r))
    c2, r2, _, _ = bounding_disc(a[perm], r[perm], n[::-1], c[::-1])
    np.testing.assert_allclose(c2, c0, atol=1e-9)
    assert r2 == pytest.approx(r0, rel=1e-9)
    with pytest.raises(ValidationError):
        bounding_disc(np.empty((0, 2)), [])


# -- the network iteration ------------------------------------------------------------------------
def _scenario(seed, n_agents=40):
    sc = paper_static_scenario(
        np.random.default_rng(seed),
        n_agents=n_agents,
        side_m=100.0,
        comm_range_m=20.0,
        error_model=range_error_model("exponential", mean_m=0.38),
    )
    return sc, sc.measurements()


@pytest.mark.parametrize("seed", range(2))
def test_network_discs_contain_their_agents_and_never_grow(seed):
    sc, m = _scenario(seed)
    assert sc.region == BOX
    b = feasible_set_bounding(m.positions, m.ranges, m.is_anchor, n_iterations=4, region=BOX)
    truth = sc.agent_positions
    assert b.area_history.shape == (4, truth.shape[0]) and b.bounded.all()
    for a in range(truth.shape[0]):
        assert b.contains(a, truth[a : a + 1])[0]
    H = b.area_history
    assert np.all(np.isfinite(H)) and np.all(np.diff(H, axis=0) <= 1e-9 * H[:-1])
    assert b.dropped.shape == (0, 2)
    np.testing.assert_allclose(H[-1], math.pi * b.radii**2)
    np.testing.assert_allclose(b.shapes, b.radii[:, None, None] ** 2 * np.eye(2))


@pytest.mark.parametrize("seed", range(2))
def test_iteration_one_bounds_the_exact_set_both_ways(seed):
    """Iteration 1 (region ∩ anchor discs): each disc contains the Monte Carlo points of the
    exact set, and is no smaller than phyloc's exact minimum-area ellipse of it, less the
    inflation of that baseline's tangent polygon (each anchor disc is replaced by its
    circumscribed 64-gon, radius at most r/cos(π/64): the pencil disc of the inflated set is
    larger by at most r_max² tan²(π/64))."""
    _, m = _scenario(seed)
    b = feasible_set_bounding(m.positions, m.ranges, m.is_anchor, n_iterations=1, region=BOX)
    e = ellipse_outer_approximation(m.positions, m.ranges, m.is_anchor, n_iterations=1, region=BOX)
    anchors = np.flatnonzero(m.is_anchor)
    q = np.random.default_rng(seed).uniform(0.0, 100.0, (40_000, 2))
    for a, j in enumerate(b.agents):
        heard = anchors[np.isfinite(m.ranges[j, anchors])]
        z = m.ranges[j, heard]
        inner = q[_feasible(q, m.positions[heard], z, BOX_A, BOX_C)]
        assert b.contains(a, inner, tol=1e-9).all()
        slack = math.pi * float(np.max(z, initial=0.0)) ** 2 * math.tan(math.pi / 64) ** 2
        assert b.area_history[0, a] >= e.area_history[0, a] * (1 - 1e-6) - slack


def test_without_region_an_agent_without_anchors_is_unbounded_at_first():
    pos = np.array([[0.0, 0.0], [20.0, 0.0], [10.0, 5.0], [10.0, 15.0]])
    z = np.full((4, 4), np.nan)
    z[2, :2] = [11.2, 11.2]
    z[3, 2] = 10.5  # agent 3 hears only agent 2
    b = feasible_set_bounding(pos, z, [0, 1], n_iterations=2)
    assert math.isinf(b.area_history[0, 1]) and math.isfinite(b.area_history[1, 1])
    # iteration 2: agent 3's disc is agent 2's grown by the range (one constraint: exact)
    assert b.radii[1] == pytest.approx(b.radii[0] + 10.5)
    np.testing.assert_allclose(b.centers[1], b.centers[0])
    with pytest.raises(ValidationError, match="n_iterations"):
        feasible_set_bounding(pos, z, [0, 1], n_iterations=0)


def test_contradicting_measurements_are_dropped_in_order():
    """Discs without a common point (negative errors): as in POA, the later anchor that
    empties the set is dropped, for good; the own disc of the previous iteration wins over
    a contradicting agent neighbour."""
    pos = np.array([[0.0, 0.0], [20.0, 0.0], [40.0, 0.0], [9.0, 0.0], [30.0, 0.0]])
    z = np.full((5, 5), np.nan)
    z[3, :3] = [9.5, 11.5, 29.0]  # anchor 2 is 1 m short: no common point with anchor 0
    z[4, 2] = 10.5
    z[3, 4] = 1.0  # agents 3 and 4 are 21 m apart
    b = feasible_set_bounding(pos, z, [0, 1, 2], n_iterations=2)
    # (the link 3–4 serves both agents: each drops the other's disc)
    np.testing.assert_array_equal(b.dropped, [[2, 3], [4, 3], [3, 4]])
    np.testing.assert_array_equal(b.dropped_iteration, [1, 2, 2])
    # agent 3 keeps the lens of anchors 0 and 1: the disc through its tips, centre on x = 9.75
    c, r2, _, _ = bounding_disc(pos[:2], [9.5, 11.5])
    np.testing.assert_allclose(b.centers[0], c, atol=1e-9)
    assert b.radii[0] ** 2 == pytest.approx(r2)


def test_negative_ranges_are_dropped():
    pos = np.array([[0.0, 0.0], [20.0, 0.0], [10.0, 5.0]])
    z = np.full((3, 3), np.nan)
    z[2, :2] = [11.2, -1.0]
    b = feasible_set_bounding(pos, z, [0, 1], n_iterations=2)
    np.testing.assert_array_equal(b.dropped, [[1, 2]])
    assert b.radii[0] == pytest.approx(11.2)


# -- NBP in the discs (nbp_bounding, the paper's 'NBP ell.') --------------------------------------
def test_nbp_bounding_samples_inside_its_discs():
    sc, m = _scenario(3, n_agents=25)
    M = METHODS["nbp_bounding"]
    opts = M.make_options({"n_samples": 60, "n_iterations": 2, "jacobian_weights": False})
    res = M.run(m, StaticPrior(sc.region), np.random.default_rng(2), opts)
    assert res.diagnostics["support"] == "bounding"
    assert res.diagnostics["support_floats_per_link_iteration"] == 3.0
    b = feasible_set_bounding(m.positions, m.ranges, m.is_anchor, n_iterations=2, region=sc.region)
    np.testing.assert_array_equal(res.diagnostics["bounding_area_m2"], b.area_history)
    for a, E in enumerate(b.regions()):
        live = np.exp(res.log_weights[a]) > 0
        assert E.contains(res.particles[a][live]).all()
    with pytest.raises(ValidationError, match="proposal"):
        M.run(m, StaticPrior(sc.region), None, M.make_options({"proposal": "mixture"}))
