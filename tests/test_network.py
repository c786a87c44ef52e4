"""Networks: deployments, anchors, links, isolated nodes, motion (PF-BP eqs. (1)–(3))."""

import itertools
import math
import warnings

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.network import (
    IsolatedNodesWarning,
    MotionSpec,
    Network,
    NetworkSpec,
    anchor_positions,
    make_network,
    noise_gain_matrix,
    pentagon,
    simulate_motion,
    transition_matrices,
)


def brute_links(positions, is_anchor, comm_range):
    """Every ordered pair (u, v), u != v, not both anchors, within range — one pair at a time."""
    out = []
    n = positions.shape[0]
    for u in range(n):
        for w in range(n):
            if u == w or (is_anchor[u] and is_anchor[w]):
                continue
            d = math.dist(positions[u], positions[w])
            if comm_range is None or d <= comm_range:
                out.append((u, w))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


# -- deployments and anchors ------------------------------------------------------------------


def test_same_seed_same_network_different_seed_different():
    spec = NetworkSpec(
        n_agents=12,
        dim=3,
        region_m=(20.0, 30.0, 10.0),
        anchors=5,
        anchor_layout="uniform",
        comm_range_m=25.0,
        on_isolated="allow",
        motion=MotionSpec(model="constant_acceleration", n_snapshots=6, initial_accel_std=0.5),
    )
    a = make_network(spec, np.random.default_rng(7))
    b = make_network(spec, np.random.default_rng(7))
    c = make_network(spec, np.random.default_rng(8))
    for name in ("positions", "velocities", "accelerations", "is_anchor"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    for k in range(spec.motion.n_snapshots):
        np.testing.assert_array_equal(a.links_at(k), b.links_at(k))
    assert not np.array_equal(a.positions, c.positions)


def test_deployment_does_not_depend_on_motion_settings():
    base = NetworkSpec(n_agents=8, anchors=4)
    moving = base.replace(motion=MotionSpec(model="random_walk", n_snapshots=5))
    a = make_network(base, np.random.default_rng(3))
    b = make_network(moving, np.random.default_rng(3))
    np.testing.assert_array_equal(a.positions[0], b.positions[0])


@pytest.mark.parametrize("dim", [2, 3])
def test_agents_uniform_in_region_and_ordered_first(dim):
    side = (10.0, 40.0, 5.0)[:dim]
    spec = NetworkSpec(n_agents=4000, dim=dim, region_m=side, anchors=2)
    net = make_network(spec, np.random.default_rng(1))
    ag = net.positions[0, : spec.n_agents]
    assert net.is_anchor.tolist() == [False] * 4000 + [True] * 2
    np.testing.assert_array_equal(net.agent_index, np.arange(4000))
    np.testing.assert_array_equal(net.anchor_index, [4000, 4001])
    assert np.all(ag >= 0) and np.all(ag <= np.array(side))
    # uniform on [0, L]: mean L/2, std L/sqrt(12); 4000 draws → standard error ≈ 0.5 % of L
    np.testing.assert_allclose(ag.mean(axis=0), np.array(side) / 2, rtol=0.04)
    np.testing.assert_allclose(ag.std(axis=0), np.array(side) / math.sqrt(12), rtol=0.04)


def test_anchor_layouts_closed_form():
    np.testing.assert_array_equal(
        anchor_positions("corners", 4, (10.0, 20.0)), [[0, 0], [10, 0], [0, 20], [10, 20]]
    )
    three = anchor_positions("corners", 4, (1.0, 1.0, 1.0))  # never a coplanar 4-set
    assert abs(np.linalg.det(three[1:] - three[0])) == pytest.approx(1.0)
    cube = anchor_positions("corners_center", 9, (20.0, 20.0, 20.0))  # PF-BP Scenario I
    expected = {tuple(c) for c in itertools.product((0.0, 20.0), repeat=3)} | {(10.0, 10.0, 10.0)}
    assert {tuple(r) for r in cube} == expected and tuple(cube[-1]) == (10.0, 10.0, 10.0)
    np.testing.assert_array_equal(
        anchor_positions("grid", 4, (8.0, 4.0)), [[2, 1], [6, 1], [2, 3], [6, 3]]
    )
    assert anchor_positions("grid", 27, (3.0, 3.0, 3.0)).min() == 0.5
    for layout, n, dim in [("corners", 5, 2), ("corners_center", 10, 3), ("grid", 5, 2)]:
        with pytest.raises(ValidationError, match=r"network\.anchors"):
            NetworkSpec(n_agents=3, dim=dim, anchors=n, anchor_layout=layout)


def test_explicit_anchors_kept_last_and_static():
    spec = NetworkSpec(
        n_agents=3,
        anchors=[[0.0, 0.0], [5.0, -7.0]],
        motion={"model": "random_walk", "n_snapshots": 4},
    )
    net = make_network(spec, np.random.default_rng(0))
    np.testing.assert_array_equal(
        net.positions[:, 3:], np.broadcast_to([[0, 0], [5, -7]], (4, 2, 2))
    )
    assert net.n_anchors == 2 and net.n_agents == 3 and net.n_nodes == 5 and net.dim == 2


# -- links ----------------------------------------------------------------------------------


@pytest.mark.parametrize("dim", [2, 3])
def test_links_match_brute_force_both_directions(dim):
    spec = NetworkSpec(
        n_agents=15,
        dim=dim,
        region_m=(50.0,) * dim,
        anchors=4,
        comm_range_m=30.0,
        on_isolated="allow",
    )
    net = make_network(spec, np.random.default_rng(11))
    links = net.links
    np.testing.assert_array_equal(links, brute_links(net.positions[0], net.is_anchor, 30.0))
    assert links.dtype == np.int64
    assert {tuple(x) for x in links} == {(w, u) for u, w in links}  # both directions
    assert np.all(np.diff(links[:, 0] * net.n_nodes + links[:, 1]) > 0)  # sorted by (u, v)
    d = net.distances()
    np.testing.assert_allclose(d, [math.dist(*net.positions[0, [u, w]]) for u, w in links])
    assert np.all(d <= 30.0)
    for u in range(net.n_nodes):
        np.testing.assert_array_equal(net.neighbors(u), links[links[:, 0] == u, 1])


def test_fully_meshed_link_count():
    net = make_network(NetworkSpec(n_agents=6, anchors=3), np.random.default_rng(2))
    n, na = 9, 3
    assert len(net.links) == n * (n - 1) - na * (na - 1)


def test_range_is_inclusive():
    net = Network(
        positions=np.array([[[0.0, 0.0], [3.0, 4.0], [6.0, 8.0]]]),
        is_anchor=np.array([False, False, True]),
        comm_range_m=5.0,
    )
    np.testing.assert_array_equal(net.links, [[0, 1], [1, 0], [1, 2], [2, 1]])


def test_links_follow_motion():
    spec = NetworkSpec(
        n_agents=10,
        anchors=4,
        comm_range_m=40.0,
        on_isolated="allow",
        motion=MotionSpec(model="random_walk", n_snapshots=6, step_std_m=15.0),
    )
    net = make_network(spec, np.random.default_rng(5))
    sets = []
    for k in range(net.n_snapshots):
        np.testing.assert_array_equal(
            net.links_at(k), brute_links(net.positions[k], net.is_anchor, 40.0)
        )
        sets.append({tuple(x) for x in net.links_at(k)})
    assert len({frozenset(s) for s in sets}) > 1  # connectivity changed with motion


# -- isolated nodes ---------------------------------------------------------------------------


def test_isolated_anchor_is_reported_with_node_and_range():
    # agents in a 100 m box are within 142 m of each other; the explicit anchor is 10 km away
    spec = NetworkSpec(n_agents=3, anchors=[[1e4, 1e4]], comm_range_m=200.0)
    with pytest.raises(ValidationError, match=r"comm_range_m = 200.0 m.*anchor node 3"):
        make_network(spec, np.random.default_rng(0))
    with pytest.warns(IsolatedNodesWarning, match="anchor node 3"):
        make_network(spec.replace(on_isolated="warn"), np.random.default_rng(0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        net = make_network(spec.replace(on_isolated="allow"), np.random.default_rng(0))
    np.testing.assert_array_equal(net.isolated_nodes(), [3])


def test_isolation_at_a_later_snapshot_is_reported():
    # one agent flying away from an anchor at the centre: linked at snapshot 0, lost later
    spec = NetworkSpec(
        n_agents=1,
        anchors=[[50.0, 50.0]],
        comm_range_m=150.0,
        motion=MotionSpec(
            model="constant_velocity",
            n_snapshots=20,
            dt_s=1.0,
            accel_std=0.0,
            initial_speed_std=100.0,
        ),
    )
    with pytest.raises(ValidationError, match=r"agent node 0.* at snapshot [1-9]"):
        make_network(spec, np.random.default_rng(4))
    net = make_network(spec.replace(on_isolated="allow"), np.random.default_rng(4))
    assert net.isolated_nodes(0).size == 0
    np.testing.assert_array_equal(net.isolated_nodes(-1), [0, 1])


def test_single_node_network_rejected():
    with pytest.raises(ValidationError, match="n_agents"):
        NetworkSpec(n_agents=1)
    NetworkSpec(n_agents=1, anchors=1)  # one agent and one anchor is a network


# -- motion ---------------------------------------------------------------------------------


def test_transition_matrices_closed_form():
    dt, sa = 0.2, 0.3
    F, Q = transition_matrices("constant_acceleration", 3, dt, sa)
    assert F.shape == Q.shape == (9, 9)
    for i in range(3):  # position i, velocity 3+i, acceleration 6+i
        assert F[i, i] == 1 and F[i, 3 + i] == dt and F[i, 6 + i] == dt**2 / 2
        assert F[3 + i, 6 + i] == dt and F[6 + i, 6 + i] == 1
        assert Q[i, i] == pytest.approx(sa**2 * dt**4 / 4)
        assert Q[i, 3 + i] == pytest.approx(sa**2 * dt**3 / 2)
        assert Q[i, 6 + i] == pytest.approx(sa**2 * dt**2 / 2)
        assert Q[3 + i, 3 + i] == pytest.approx(sa**2 * dt**2)
        assert Q[6 + i, 6 + i] == pytest.approx(sa**2)
    assert np.count_nonzero(F) == 3 * 6 and np.count_nonzero(Q) == 3 * 9  # no cross-axis terms
    assert np.linalg.matrix_rank(Q) == 3
    G = noise_gain_matrix("constant_acceleration", 3, dt)
    np.testing.assert_allclose(Q, sa**2 * G @ G.T)  # PF-BP eq. (48)
    F2, Q2 = transition_matrices("constant_velocity", 2, dt, sa)
    np.testing.assert_array_equal(F2, [[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]])
    np.testing.assert_allclose(Q2[0, [0, 2]], [sa**2 * dt**4 / 4, sa**2 * dt**3 / 2])
    with pytest.raises(ValidationError, match="model"):
        transition_matrices("random_walk", 2, dt, sa)


@pytest.mark.parametrize("dim", [2, 3])
def test_noise_free_kinematics_exact(dim, rng):
    p0 = rng.uniform(0, 10, size=(5, dim))
    spec = MotionSpec(
        model="constant_acceleration",
        n_snapshots=11,
        dt_s=0.25,
        accel_std=0.0,
        initial_accel_std=2.0,
    )
    p, vel, acc = simulate_motion(spec, p0, rng)
    t = 0.25 * np.arange(11)[:, None, None]
    v0, a0 = vel[0], acc[0]
    assert np.all(a0 != 0)
    np.testing.assert_allclose(p, p0 + v0 * t + 0.5 * a0 * t**2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(vel, v0 + a0 * t, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(acc, np.broadcast_to(a0, acc.shape))
    cv = MotionSpec(model="constant_velocity", n_snapshots=11, dt_s=0.25, accel_std=0.0)
    p, vel, acc = simulate_motion(cv, p0, rng)
    assert acc is None
    np.testing.assert_allclose(p, p0 + vel[0] * t, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("model", "dim"), [("constant_acceleration", 3), ("constant_velocity", 2)])
def test_one_step_increments_have_covariance_q(model, dim, rng):
    dt, sa, n, K = 0.5, 0.3, 3000, 21
    spec = MotionSpec(model=model, n_snapshots=K, dt_s=dt, accel_std=sa, initial_accel_std=1.0)
    p, vel, acc = simulate_motion(spec, rng.uniform(0, 100, size=(n, dim)), rng)
    parts = [p, vel] + ([acc] if acc is not None else [])
    x = np.concatenate(parts, axis=2)  # [K, n, order·dim], layout [p; v; a]
    F, Q = transition_matrices(model, dim, dt, sa)
    w = (x[1:] - x[:-1] @ F.T).reshape(-1, F.shape[0])
    # exact structure: w = G u, so the residual is G times its last dim components / G's tail
    G = noise_gain_matrix(model, dim, dt)
    u = w[:, -dim:] / G[-1, -1]
    np.testing.assert_allclose(w, u @ G.T, atol=1e-9)
    # statistics: 60 000 draws, standard error of a variance ≈ 0.6 %
    C = np.cov(w.T)
    scale = np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    np.testing.assert_allclose(C / scale, Q / scale, atol=0.03)
    np.testing.assert_allclose(np.diag(C), np.diag(Q), rtol=0.03)
    assert np.abs(u.mean(axis=0)).max() < 4 * sa / math.sqrt(u.shape[0])


def test_random_walk_and_static(rng):
    p0 = rng.uniform(0, 10, size=(2000, 2))
    p, vel, acc = simulate_motion(
        MotionSpec(model="random_walk", n_snapshots=6, step_std_m=2.0), p0, rng
    )
    assert vel is None and acc is None
    steps = np.diff(p, axis=0)
    np.testing.assert_allclose(steps.std(), 2.0, rtol=0.02)
    np.testing.assert_array_equal(p[0], p0)
    p, vel, acc = simulate_motion(MotionSpec(n_snapshots=3), p0, rng)
    np.testing.assert_array_equal(p, np.broadcast_to(p0, (3, *p0.shape)))
    assert vel is None and acc is None


def test_toward_center_initial_velocity():
    spec = NetworkSpec(
        n_agents=30,
        dim=3,
        region_m=(20.0, 20.0, 20.0),
        anchors=9,
        anchor_layout="corners_center",
        on_isolated="allow",
        motion=MotionSpec(
            model="constant_acceleration",
            n_snapshots=2,
            initial_velocity="toward_center",
            initial_speed_m_s=1.0,
        ),
    )
    net = make_network(spec, np.random.default_rng(9))
    v0 = net.velocities[0, :30]
    to_c = 10.0 - net.positions[0, :30]
    np.testing.assert_allclose(np.linalg.norm(v0, axis=1), 1.0)
    np.testing.assert_allclose(v0, to_c / np.linalg.norm(to_c, axis=1, keepdims=True))
    np.testing.assert_array_equal(net.velocities[:, 30:], 0.0)
    np.testing.assert_array_equal(net.accelerations[0, :30], 0.0)  # PF-BP: a(0) = 0


# -- specs and validation ---------------------------------------------------------------------


def test_spec_round_trip_and_unknown_keys():
    d = {
        "n_agents": 20,
        "dim": 3,
        "region_m": [20, 20, 20],
        "anchors": 9,
        "anchor_layout": "corners_center",
        "comm_range_m": 18.0,
        "motion": {"model": "constant_acceleration", "n_snapshots": 50},
    }
    spec = NetworkSpec.from_dict(d)
    assert spec.region_m == (20.0, 20.0, 20.0) and spec.motion.accel_std == 0.15
    assert NetworkSpec.from_dict(spec.to_dict()) == spec
    explicit = NetworkSpec(n_agents=2, anchors=[[1, 2], [3, 4]])
    assert NetworkSpec.from_dict(explicit.to_dict()) == explicit
    with pytest.raises(ValidationError, match=r"network\.comm_rang_m.*did you mean 'comm_range_m'"):
        NetworkSpec.from_dict({"n_agents": 3, "comm_rang_m": 5.0})
    with pytest.raises(ValidationError, match=r"network\.motion\.dt.*did you mean 'dt_s'"):
        NetworkSpec.from_dict({"n_agents": 3, "motion": {"dt": 0.1}})
    with pytest.raises(ValidationError, match=r"network\.n_agents"):
        NetworkSpec.from_dict({"anchors": 3})


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"dim": 4}, "network.dim"),
        ({"dim": 3, "region_m": (10.0, 10.0)}, "network.region_m"),
        ({"region_m": (10.0, -1.0)}, "network.region_m"),
        ({"comm_range_m": 0.0}, "network.comm_range_m"),
        ({"anchors": [[0.0, 0.0, 0.0]]}, "network.anchors"),
        ({"anchors": -1}, "network.anchors"),
        ({"anchor_layout": "circle"}, "network.anchor_layout"),
        ({"on_isolated": "ignore"}, "network.on_isolated"),
        ({"motion": {"model": "brownian"}}, "network.motion.model"),
        ({"motion": {"n_snapshots": 0}}, "network.motion.n_snapshots"),
        ({"motion": {"accel_std": -0.1}}, "network.motion.accel_std"),
    ],
)
def test_spec_validation_names_the_key(kwargs, field):
    with pytest.raises(ValidationError) as err:
        NetworkSpec(n_agents=3, **kwargs)
    assert err.value.field == field


def test_network_rejects_moving_anchors_and_is_read_only():
    pos = np.zeros((2, 2, 2))
    pos[1, 1] = 1.0
    with pytest.raises(ValidationError, match="static"):
        Network(positions=pos, is_anchor=np.array([False, True]))
    net = Network(positions=pos[:1], is_anchor=np.array([False, True]))
    with pytest.raises(ValueError, match="read-only"):
        net.positions[0, 0, 0] = 5.0
    with pytest.raises(ValidationError, match="snapshot"):
        net.links_at(1)


# -- explicit agents, pentagon, unchanged draws -----------------------------------------------


@pytest.mark.parametrize(("diameter", "rotation"), [(15.0, 90.0), (30.0, 17.0)])
def test_pentagon_is_regular_with_the_circumscribed_diameter(diameter, rotation):
    centre = np.array([25.0, 40.0])
    pts = pentagon(diameter, centre, rotation_deg=rotation)
    assert pts.shape == (5, 2)
    np.testing.assert_allclose(np.linalg.norm(pts - centre, axis=1), diameter / 2, rtol=1e-14)
    sides = np.linalg.norm(pts - np.roll(pts, -1, axis=0), axis=1)
    np.testing.assert_allclose(sides, diameter * math.sin(math.radians(36.0)), rtol=1e-14)
    np.testing.assert_allclose(pts.mean(axis=0), centre, atol=1e-12)
    first = math.radians(rotation)
    np.testing.assert_allclose(
        pts[0], centre + diameter / 2 * np.array([math.cos(first), math.sin(first)])
    )
    # counter-clockwise: positive signed area (shoelace) = (5/8) D² sin 72°
    x, y = pts[:, 0], pts[:, 1]
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    np.testing.assert_allclose(area, 5 / 8 * diameter**2 * math.sin(math.radians(72.0)))
    with pytest.raises(ValidationError) as err:
        pentagon(0.0, centre)
    assert err.value.field == "diameter_m"
    with pytest.raises(ValidationError) as err:
        pentagon(1.0, [0.0, 0.0, 0.0])
    assert err.value.field == "center"


def test_explicit_agents_draw_nothing_for_them():
    agents = [[1.0, 2.0], [-3.0, 4.0], [150.0, 7.5]]  # outside the region is allowed
    spec = NetworkSpec(n_agents=3, anchors=2, anchor_layout="uniform", agents_m=agents)
    net = make_network(spec, np.random.default_rng(11))
    np.testing.assert_array_equal(net.positions[0, :3], agents)
    # the anchors are the first draws of the generator
    ref = np.random.default_rng(11).uniform(0.0, np.array([100.0, 100.0]), size=(2, 2))
    np.testing.assert_array_equal(net.positions[0, 3:], ref)
    assert NetworkSpec.from_dict(spec.to_dict()) == spec
    assert spec.to_dict()["agents_m"] == agents


def test_without_agents_m_the_draws_are_unchanged():
    spec = NetworkSpec(
        n_agents=4,
        region_m=(30.0, 20.0),
        anchors=3,
        anchor_layout="uniform",
        motion=MotionSpec(model="constant_acceleration", n_snapshots=3, initial_accel_std=0.5),
    )
    net = make_network(spec, np.random.default_rng(2024))
    rng = np.random.default_rng(2024)
    np.testing.assert_array_equal(net.positions[0, :4], rng.uniform(0.0, [30.0, 20.0], (4, 2)))
    np.testing.assert_array_equal(net.positions[0, 4:], rng.uniform(0.0, [30.0, 20.0], (3, 2)))
    # snapshot 2 and recipe form as computed by the code before agents_m and waypoints existed
    before = [
        [20.28046054519369, 4.45135001222389],
        [9.001975758667097, 15.903456430135568],
        [29.610061348084354, 2.6977552416524064],
        [2.5359842958627956, 3.320792541956584],
    ]
    np.testing.assert_allclose(net.positions[-1, :4], before, rtol=1e-13)
    assert spec.to_dict() == {
        "n_agents": 4,
        "dim": 2,
        "region_m": [30.0, 20.0],
        "anchors": 3,
        "anchor_layout": "uniform",
        "on_isolated": "error",
        "motion": {
            "model": "constant_acceleration",
            "n_snapshots": 3,
            "dt_s": 0.1,
            "accel_std": 0.15,
            "step_std_m": 1.0,
            "initial_velocity": "gaussian",
            "initial_speed_std": 1.0,
            "initial_speed_m_s": 1.0,
            "initial_accel_std": 0.5,
        },
    }


@pytest.mark.parametrize(
    ("agents", "text"),
    [
        ([[0.0, 0.0], [1.0, 1.0]], "exactly n_agents = 3"),
        ([[0.0, 0.0, 0.0]] * 3, "2-D coordinates"),
        ([[0.0, 0.0], [1.0, math.inf], [2.0, 2.0]], "finite"),
        ([0.0, 1.0, 2.0], "2-D coordinates"),
    ],
)
def test_agents_m_validation_names_the_key(agents, text):
    with pytest.raises(ValidationError, match=text) as err:
        NetworkSpec.from_dict({"n_agents": 3, "agents_m": agents})
    assert err.value.field == "network.agents_m"


@pytest.mark.parametrize("n", [30, 120, 1000])
def test_constant_density_region_holds_n_agents_at_the_density(n):
    spec = NetworkSpec.from_dict({"n_agents": n, "density_per_km2": 3000.0})
    side = spec.region_m[0]
    assert spec.region_m == (side, side)
    assert n / (side * side / 1e6) == pytest.approx(3000.0, rel=1e-12)
    net = make_network(spec.replace(on_isolated="allow"), np.random.default_rng(3))
    assert np.all((net.positions >= 0) & (net.positions <= side))


def test_constant_density_keeps_the_mean_neighbour_count():
    """At fixed density and range the interior neighbour count is ρπR² whatever N (the
    border lowers the mean less as the network grows)."""
    rng = np.random.default_rng(11)
    means = []
    for n in (300, 1200):
        spec = NetworkSpec.from_dict(
            {"n_agents": n, "density_per_km2": 3000.0, "comm_range_m": 50.0}
        )
        net = make_network(spec, rng)
        side = spec.region_m[0]
        p = net.positions[0]
        inner = np.all((p > 50.0) & (p < side - 50.0), axis=1)
        deg = np.bincount(net.links[:, 0], minlength=n)
        means.append(deg[inner].mean())
    expected = 3000e-6 * math.pi * 50.0**2  # 23.6
    for m in means:
        assert m == pytest.approx(expected, rel=0.12)


def test_density_excludes_region_and_3d_and_round_trips():
    with pytest.raises(ValidationError, match=r"network\.region_m"):
        NetworkSpec.from_dict({"n_agents": 5, "density_per_km2": 10.0, "region_m": [9, 9]})
    with pytest.raises(ValidationError, match=r"density_per_km2"):
        NetworkSpec.from_dict({"n_agents": 5, "dim": 3, "density_per_km2": 10.0})
    with pytest.raises(ValidationError, match=r"density_per_km2"):
        NetworkSpec.from_dict({"n_agents": 5, "density_per_km2": 0.0})
    spec = NetworkSpec.from_dict({"n_agents": 50, "density_per_km2": 3000.0})
    assert "region_m" not in spec.to_dict()
    assert NetworkSpec.from_dict(spec.to_dict()) == spec
    bigger = spec.replace(n_agents=200)  # the region follows the size
    assert bigger.region_m[0] == pytest.approx(2 * spec.region_m[0])


def test_range_limited_neighbours_and_isolated_nodes_match_the_matrix():
    spec = NetworkSpec.from_dict(
        {"n_agents": 60, "anchors": 4, "comm_range_m": 22.0, "on_isolated": "allow"}
    )
    net = make_network(spec, np.random.default_rng(5))
    D = net.distance_matrix()
    adj = (D <= 22.0) & ~np.eye(net.n_nodes, dtype=bool)
    adj &= ~(net.is_anchor[:, None] & net.is_anchor[None, :])
    assert np.array_equal(net.adjacency(), adj)
    for u in (0, 17, 61):
        assert net.neighbors(u).tolist() == np.flatnonzero(adj[u]).tolist()
    assert net.isolated_nodes().tolist() == np.flatnonzero(~adj.any(axis=1)).tolist()
