"""Waypoint trajectories (``model = "waypoints"``): exact arc length, corners, loops, stops.

Expected positions are computed here from the leg geometry directly (leg start + elapsed time ·
speed · leg direction; arc centres from the angle bisector), not from the module's pieces.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.network import (
    MotionSpec,
    NetworkSpec,
    make_network,
    pentagon,
    simulate_motion,
    waypoint_trajectory,
)


def _distance_to_polyline(p, wp):
    """Distance of point p to the closed segments of the polyline wp (brute force)."""
    best = math.inf
    for a, b in itertools.pairwise(wp):
        ab = b - a
        t = min(1.0, max(0.0, float((p - a) @ ab / (ab @ ab))))
        best = min(best, float(np.linalg.norm(p - (a + t * ab))))
    return best


def _sharp_reference(wp, speeds, t):
    """Position and velocity on the polyline at time t, leg by leg (no loop)."""
    for a, b, s in zip(wp[:-1], wp[1:], speeds, strict=True):
        length = np.linalg.norm(b - a)
        duration = length / s
        if t < duration:
            u = (b - a) / length
            return a + t * s * u, s * u
        t -= duration
    return wp[-1], np.zeros(wp.shape[1])


@pytest.mark.parametrize("dim", [2, 3])
def test_sharp_corners_follow_the_polyline_at_the_leg_speeds(dim):
    rng = np.random.default_rng(5)
    wp = rng.uniform(0.0, 50.0, (6, dim))
    speeds = rng.uniform(0.5, 3.0, 5)
    K, dt = 400, 0.37
    pos, vel = waypoint_trajectory(wp, speeds, K, dt)
    assert pos.shape == vel.shape == (K, dim)
    np.testing.assert_array_equal(pos[0], wp[0])
    for k in range(K):
        ref_p, ref_v = _sharp_reference(wp, speeds, k * dt)
        np.testing.assert_allclose(pos[k], ref_p, atol=1e-9)
        np.testing.assert_allclose(vel[k], ref_v, atol=1e-12)
        assert _distance_to_polyline(pos[k], wp) < 1e-9
    # within a leg the step length is exactly speed·dt
    bounds = np.concatenate(
        ([0.0], np.cumsum(np.linalg.norm(np.diff(wp, axis=0), axis=1) / speeds))
    )
    t = np.arange(K) * dt
    leg = np.searchsorted(bounds, t, side="right") - 1
    same = (leg[:-1] == leg[1:]) & (leg[1:] < len(speeds))
    assert same.sum() > 100
    step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    np.testing.assert_allclose(step[same] / dt, speeds[leg[:-1][same]], rtol=1e-9)


def test_rounded_right_angle_is_a_quarter_circle_of_the_radius():
    wp = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    r, speed, dt = 2.0, 1.0, 0.05
    pos, vel = waypoint_trajectory(wp, speed, 500, dt, corner_radius_m=r)
    centre = np.array([8.0, 2.0])  # r from both legs
    t = np.arange(500) * dt
    on_arc = (t > 8.0 + 1e-9) & (t < 8.0 + r * math.pi / 2 - 1e-9)  # arc from s = 10 − r
    assert on_arc.sum() > 50
    np.testing.assert_allclose(np.linalg.norm(pos[on_arc] - centre, axis=1), r, rtol=1e-12)
    np.testing.assert_allclose(
        np.einsum("kd,kd->k", vel[on_arc], pos[on_arc] - centre), 0.0, atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.norm(vel[: t.size], axis=1)[t < 16.0], speed, rtol=1e-12)
    # straight parts are on the legs; total length 8 + π + 8
    before, after = t <= 8.0, (t >= 8.0 + math.pi) & (t < 16.0 + math.pi)
    np.testing.assert_allclose(pos[before, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(pos[after, 0], 10.0, atol=1e-12)
    np.testing.assert_allclose(pos[after, 1], 2.0 + (t[after] - 8.0 - math.pi), atol=1e-9)
    assert np.all(pos[t >= 16.0 + math.pi] == wp[-1])


@pytest.mark.parametrize(("radius", "clipped"), [(1.5, False), (50.0, True)])
def test_arc_radius_in_3d_from_the_bisector(radius, clipped):
    wp = np.array(
        [[0.0, 0.0, 0.0], [6.0, 0.0, 0.0], [6.0 + 4.0 * math.cos(1.0), 4.0 * math.sin(1.0), 3.0]]
    )
    u_in = (wp[1] - wp[0]) / np.linalg.norm(wp[1] - wp[0])
    u_out = (wp[2] - wp[1]) / np.linalg.norm(wp[2] - wp[1])
    theta = math.acos(u_in @ u_out)  # turning angle
    t_len = radius * math.tan(theta / 2)
    if clipped:  # limited to half the shorter leg
        t_len = 0.5 * min(6.0, np.linalg.norm(wp[2] - wp[1]))
    r_eff = t_len / math.tan(theta / 2)
    assert (r_eff < radius) == clipped
    bis = (u_out - u_in) / np.linalg.norm(u_out - u_in)
    centre = wp[1] + r_eff / math.cos(theta / 2) * bis  # interior half-angle (π − θ)/2
    speed, dt = 0.8, 0.01
    pos, vel = waypoint_trajectory(wp, speed, 2000, dt, corner_radius_m=radius)
    s = np.arange(2000) * dt * speed
    a0 = 6.0 - t_len
    on_arc = (s > a0 + 1e-9) & (s < a0 + r_eff * theta - 1e-9)
    assert on_arc.sum() > 20
    np.testing.assert_allclose(np.linalg.norm(pos[on_arc] - centre, axis=1), r_eff, rtol=1e-10)
    # the arc is in the plane of the two legs
    normal = np.cross(u_in, u_out)
    np.testing.assert_allclose((pos[on_arc] - wp[1]) @ normal, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(vel[on_arc], axis=1), speed, rtol=1e-12)
    # the path is C¹: consecutive velocities turn by at most speed·dt / r_eff
    cosang = np.einsum("kd,kd->k", vel[:-1], vel[1:]) / speed**2
    moving = np.linalg.norm(vel[1:], axis=1) > 0
    assert np.all(np.arccos(np.clip(cosang[moving], -1, 1)) <= speed * dt / r_eff + 1e-9)


def test_arc_halves_take_the_speeds_of_their_legs():
    wp = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    r, s1, s2, dt = 2.0, 1.0, 3.0, 0.01
    pos, vel = waypoint_trajectory(wp, [s1, s2], 2000, dt, corner_radius_m=r)
    half = r * math.pi / 4
    t = np.arange(2000) * dt
    t_mid = (8.0 + half) / s1
    first = (t > 8.0 / s1) & (t < t_mid - 1e-9)
    second = (t > t_mid + 1e-9) & (t < t_mid + half / s2)
    np.testing.assert_allclose(np.linalg.norm(vel[first], axis=1), s1)
    np.testing.assert_allclose(np.linalg.norm(vel[second], axis=1), s2)
    # end of the path: 8 m and half the arc at s1, the rest at s2
    t_end = t_mid + (half + 8.0) / s2
    assert np.all(pos[t >= t_end] == wp[-1]) and np.all(vel[t >= t_end] == 0)
    assert not np.allclose(pos[t < t_end - dt][-1], wp[-1])


@pytest.mark.parametrize("radius", [0.0, 1.0])
def test_loop_is_periodic_with_the_course_time(radius):
    wp = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    speed = 2.0
    # corners 1, 2, 3 rounded (90° each: 2r of leg replaced by πr/2); waypoint 0 sharp
    length = 40.0 - 3 * (2 * radius - math.pi * radius / 2)
    period = length / speed
    n = 64
    pos, vel = waypoint_trajectory(
        wp, speed, 3 * n + 1, period / n, loop=True, corner_radius_m=radius
    )
    np.testing.assert_allclose(pos[n:], pos[:-n], atol=1e-9)
    np.testing.assert_allclose(pos[[0, n, 2 * n, 3 * n]], np.zeros((4, 2)), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(vel, axis=1), speed, rtol=1e-12)
    if radius == 0.0:  # on the closed polyline
        closed = np.vstack([wp, wp[:1]])
        assert max(_distance_to_polyline(p, closed) for p in pos) < 1e-9


def test_loop_closing_leg_speed_and_one_speed_per_leg():
    wp = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])  # closing leg length 5
    pos, vel = waypoint_trajectory(wp, [1.0, 1.0, 5.0], 9, 1.0, loop=True)
    # t = 7 → on the closing leg for 0 s (it starts at t = 7): at (4, 3) heading home at 5 m/s
    np.testing.assert_allclose(pos[7], [4.0, 3.0])
    np.testing.assert_allclose(vel[7], [-4.0, -3.0])
    np.testing.assert_allclose(pos[8], [0.0, 0.0], atol=1e-12)  # period 4 + 3 + 1 = 8 s


def test_stops_at_the_last_waypoint_without_loop():
    wp = np.array([[1.0, 1.0], [4.0, 5.0]])
    pos, vel = waypoint_trajectory(wp, 0.5, 30, 1.0)  # 5 m at 0.5 m/s: 10 s
    np.testing.assert_allclose(pos[:11, 0], 1.0 + 0.3 * np.arange(11), atol=1e-12)
    assert np.all(pos[10:] == wp[-1]) and np.all(vel[10:] == 0.0)
    np.testing.assert_allclose(vel[:10], np.tile([0.3, 0.4], (10, 1)), atol=1e-15)


@pytest.mark.parametrize(
    ("kwargs", "field", "text"),
    [
        ({"waypoints_m": [[0.0, 0.0]]}, "waypoints_m", ">= 2 points"),
        ({"waypoints_m": [[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]]}, "waypoints_m", "differ"),
        ({"waypoints_m": [[0.0, 0.0], [1.0, math.nan]]}, "waypoints_m", "finite"),
        ({"waypoints_m": [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]}, "waypoints_m", "2 or 3"),
        ({"waypoints_m": [[0, 0], [1, 0], [0, 0]], "loop": True}, "waypoints_m", "implicit"),
        ({"speeds_m_s": [1.0, 2.0]}, "speeds_m_s", "3 speeds"),
        ({"speeds_m_s": 0.0}, "speeds_m_s", "> 0"),
        ({"corner_radius_m": -1.0}, "corner_radius_m", ">= 0"),
        ({"n_snapshots": 0}, "n_snapshots", ">= 1"),
    ],
)
def test_waypoint_trajectory_input_errors(kwargs, field, text):
    args = {
        "waypoints_m": [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [2.0, 2.0]],
        "speeds_m_s": 1.0,
        "n_snapshots": 5,
        "dt_s": 1.0,
    }
    args.update(kwargs)
    with pytest.raises(ValidationError, match=text) as err:
        waypoint_trajectory(**args)
    assert err.value.field == field


# -- MotionSpec / make_network ----------------------------------------------------------------

ROVER = {
    "model": "waypoints",
    "movers": [5],
    "waypoints_m": [[5.0, 5.0], [45.0, 5.0], [45.0, 75.0], [5.0, 75.0]],
    "speeds_m_s": [1.0, 2.0, 1.5, 2.5],
    "loop": True,
    "corner_radius_m": 3.0,
    "n_snapshots": 120,
    "dt_s": 1.0,
}


def test_rover_network_static_pentagon_and_a_mover():
    agents = np.vstack([pentagon(15.0, [25.0, 40.0]), [[0.0, 0.0]]])
    spec = NetworkSpec.from_dict(
        {"n_agents": 6, "region_m": [50.0, 80.0], "agents_m": agents.tolist(), "motion": ROVER}
    )
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    net = make_network(spec, rng)
    assert rng.bit_generator.state == state  # nothing drawn: explicit agents, no anchors
    assert net.positions.shape == net.velocities.shape == (120, 6, 2)
    assert net.accelerations is None and net.dt_s == 1.0
    np.testing.assert_array_equal(net.positions[:, :5], np.broadcast_to(agents[:5], (120, 5, 2)))
    np.testing.assert_array_equal(net.velocities[:, :5], 0.0)
    path, vel = waypoint_trajectory(
        ROVER["waypoints_m"], ROVER["speeds_m_s"], 120, 1.0, loop=True, corner_radius_m=3.0
    )
    np.testing.assert_array_equal(net.positions[:, 5], path)
    np.testing.assert_array_equal(net.velocities[:, 5], vel)
    np.testing.assert_array_equal(net.positions[0, 5], ROVER["waypoints_m"][0])
    assert spec.motion.tracks_velocity and not spec.motion.tracks_acceleration
    assert NetworkSpec.from_dict(spec.to_dict()) == spec


@pytest.mark.parametrize("dim", [2, 3])
def test_simulate_motion_waypoints_consumes_no_randomness(dim):
    wp = np.eye(dim)[:2] * 7.0
    spec = MotionSpec(
        model="waypoints", movers=[0, 2], waypoints_m=wp, speeds_m_s=1.0, n_snapshots=9
    )
    p0 = np.arange(4 * dim, dtype=float).reshape(4, dim)
    rng = np.random.default_rng(0)
    pos, vel, acc = simulate_motion(spec, p0, rng)
    assert rng.random() == np.random.default_rng(0).random()
    assert acc is None and pos.shape == (9, 4, dim)
    np.testing.assert_array_equal(pos[:, 1], np.broadcast_to(p0[1], (9, dim)))
    np.testing.assert_array_equal(pos[:, 0], pos[:, 2])
    np.testing.assert_array_equal(vel[:, [1, 3]], 0.0)
    np.testing.assert_allclose(
        vel[:, 0], np.broadcast_to((wp[1] - wp[0]) / (7.0 * math.sqrt(2)), (9, dim))
    )
    np.testing.assert_allclose(np.linalg.norm(pos[-1, 0] - wp[0]), 0.8, atol=1e-12)


def test_motion_spec_round_trip_and_other_models_unchanged():
    spec = MotionSpec.from_dict(ROVER)
    assert spec.waypoints_m[1] == (45.0, 5.0) and spec.speeds_m_s == (1.0, 2.0, 1.5, 2.5)
    d = spec.to_dict()
    assert d["waypoints_m"] == ROVER["waypoints_m"] and d["movers"] == [5]
    assert MotionSpec.from_dict(d) == spec
    one_speed = MotionSpec.from_dict({**ROVER, "speeds_m_s": 2})
    assert one_speed.speeds_m_s == 2.0 and MotionSpec.from_dict(one_speed.to_dict()) == one_speed
    # the recipe form of the other models has exactly the keys it had before
    ca = MotionSpec(model="constant_acceleration").to_dict()
    assert list(ca) == [
        "model",
        "n_snapshots",
        "dt_s",
        "accel_std",
        "step_std_m",
        "initial_velocity",
        "initial_speed_std",
        "initial_speed_m_s",
        "initial_accel_std",
    ]


@pytest.mark.parametrize(
    ("changes", "field", "text"),
    [
        ({"movers": None}, "network.motion.movers", "required"),
        ({"movers": []}, "network.motion.movers", "at least one"),
        ({"movers": [1, 1]}, "network.motion.movers", "distinct"),
        ({"movers": [6]}, "network.motion.movers", r"\[0, 6\)"),
        ({"movers": [-1]}, "network.motion.movers", ">= 0"),
        ({"waypoints_m": None}, "network.motion.waypoints_m", "required"),
        (
            {"waypoints_m": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 1]]},
            "network.motion.waypoints_m",
            "2-D",
        ),
        ({"speeds_m_s": [1.0, 2.0, 3.0]}, "network.motion.speeds_m_s", "4 speeds"),
        ({"speeds_m_s": [1.0, 2.0, -3.0, 1.0]}, "network.motion.speeds_m_s", "> 0"),
        ({"loop": "yes"}, "network.motion.loop", "true or false"),
        ({"corner_radius_m": -0.5}, "network.motion.corner_radius_m", ">= 0"),
    ],
)
def test_waypoint_spec_errors_name_the_key(changes, field, text):
    with pytest.raises(ValidationError, match=text) as err:
        NetworkSpec.from_dict({"n_agents": 6, "motion": {**ROVER, **changes}})
    assert err.value.field == field


@pytest.mark.parametrize("key", ["movers", "waypoints_m", "speeds_m_s", "loop", "corner_radius_m"])
def test_waypoint_keys_rejected_by_other_models(key):
    with pytest.raises(ValidationError, match="only used by model = 'waypoints'") as err:
        MotionSpec.from_dict({"model": "constant_velocity", key: ROVER[key]})
    assert err.value.field == f"network.motion.{key}"
