"""Motion core: seed 000's primitive, the look-ahead follower, Tello commands within the SDK's
limits, go-to-wall with its fail counter, and the staleness guard."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparse_nav.motion import (FAILED, FOLLOWING, IDLE, REACHED, STOPPED_LOST, STOPPED_STALE,
                               WALL_REACHED, WALL_SEEKING, MotionConfig, MotionController,
                               PathFollower, StalenessGuard, signed_angle, tello_command)
from sparse_nav.sim import SimConfig, load_world
from sparse_nav.sim.robots import GroundRobot, TelloDrone


@pytest.mark.parametrize("a, b, expected_deg", [
    ((1, 0), (1, 0), 0.0), ((1, 0), (0, 1), 90.0), ((1, 0), (0, -1), -90.0),
    ((1, 0), (-1, 1), 135.0), ((1, 0), (-1, -1), -135.0), ((0, 1), (1, 0), -90.0),
    ((2, 0), (-3, 0), 180.0), ((1, 1), (1, 1.0001), 0.0)])
def test_signed_angle_cases(a, b, expected_deg):
    assert math.degrees(signed_angle(a, b)) == pytest.approx(expected_deg, abs=0.01)


@settings(max_examples=300, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-math.pi, math.pi), st.floats(0.01, 100),
       st.floats(0.01, 100))
def test_dot_and_cross_agree_with_seed_001_atan2(yaw, bearing, na, nb):
    a = (na * math.cos(yaw), na * math.sin(yaw))
    b = (nb * math.cos(bearing), nb * math.sin(bearing))
    expected = math.atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1])
    got = signed_angle(a, b)
    diff = (got - expected + math.pi) % (2 * math.pi) - math.pi
    assert abs(diff) < 1e-5


def test_signed_angle_refuses_zero_vectors():
    with pytest.raises(ValueError):
        signed_angle((0, 0), (1, 0))


def test_lookahead_point_lies_ahead_on_the_path():
    f = PathFollower(lookahead_m=0.5, goal_tolerance_m=0.1)
    f.set_path([[0, 0], [2, 0], [2, 2]])
    t = f.target(0.0, 0.1, 0.0)
    np.testing.assert_allclose(t.point, [0.5, 0.0], atol=1e-9)
    assert t.heading_error == pytest.approx(-math.atan2(0.1, 0.5), abs=1e-9)   # turn cw
    for x in np.arange(0.0, 1.9, 0.1):
        f.target(x, 0.0, 0.0)
    t = f.target(1.9, 0.0, 0.0)
    np.testing.assert_allclose(t.point, [2.0, 0.4], atol=1e-9)
    assert t.heading_error > 0                                                 # turn ccw
    assert t.remaining_m == pytest.approx(2.1)
    assert not t.reached
    for y in np.arange(0.0, 1.8, 0.1):
        assert not f.target(2.0, y, math.pi / 2).reached
    assert f.target(2.0, 1.95, math.pi / 2).reached


def test_progress_does_not_jump_back_on_a_path_that_returns():
    f = PathFollower(lookahead_m=0.3, goal_tolerance_m=0.1)
    f.set_path([[0, 0], [3, 0], [3, 0.2], [0, 0.2]])     # out and back, 0.2 m apart
    for x in np.arange(0.0, 3.0, 0.1):
        f.target(x, 0.0, 0.0)
    f.target(3.0, 0.1, math.pi / 2)
    for x in np.arange(2.9, 2.0, -0.1):
        f.target(x, 0.15, math.pi)
    t = f.target(2.0, 0.15, math.pi)                      # on the way back, near the outbound leg
    np.testing.assert_allclose(t.point, [1.7, 0.2], atol=1e-9)


def test_malformed_paths_are_refused_and_the_old_one_kept():
    c = MotionController()
    c.set_path([[0, 0], [1, 0]], 0.0, 0.0)
    for bad in ([[0, np.nan]], [[0, 0, 0]], [[np.inf, 1], [2, 2]]):
        with pytest.raises(ValueError):
            c.set_path(np.array(bad, dtype=float), 0.0, 0.0)
    np.testing.assert_array_equal(c.follower.points, [[0, 0], [1, 0]])


def fresh(c, now, x=0.0, y=0.0, yaw=0.0):
    c.set_pose(x, y, yaw, now, now)


def test_velocity_turns_toward_the_path_within_limits():
    c = MotionController(MotionConfig(max_linear_m_s=0.3, max_angular_rad_s=0.8))
    c.set_path([[0, 0], [0, 2]], 0.0, 0.0)                # straight ahead is +y
    fresh(c, 0.1)
    d = c.step(0.1)
    assert d.state == FOLLOWING and d.moving
    assert d.angular_rad_s == pytest.approx(0.8)          # 90 deg left: saturated ccw
    assert d.linear_m_s == pytest.approx(c.cfg.min_linear_m_s)   # turning, creeping forward
    fresh(c, 0.2, yaw=math.pi)                            # facing -x: the path is to the right
    assert c.step(0.2).angular_rad_s == pytest.approx(-0.8)
    fresh(c, 0.3, yaw=math.pi / 2)
    d = c.step(0.3)
    assert d.angular_rad_s == pytest.approx(0.0, abs=1e-9)
    assert d.linear_m_s == pytest.approx(0.3)


def test_slows_down_and_stops_at_the_end():
    c = MotionController()
    c.set_path([[0, 0], [1, 0]], 0.0, 0.0)
    fresh(c, 0.0, x=0.75)
    d = c.step(0.0)
    assert 0 < d.linear_m_s < c.cfg.max_linear_m_s
    fresh(c, 0.0, x=0.9)
    d = c.step(0.0)
    assert d.state == REACHED and not d.moving and d.linear_m_s == 0 and d.angular_rad_s == 0


def test_ground_robot_follows_an_l_shaped_path_in_one_room():
    world = load_world("one_room")
    robot = GroundRobot(world, SimConfig(), np.random.default_rng(0))
    c = MotionController()
    # World frame; the robot starts at (3, 2.5) facing +x; the path avoids both boxes.
    path = np.array([[3.0, 2.5], [4.5, 2.5], [4.5, 4.0], [2.5, 4.0]])
    c.set_path(path, 0.0, 0.0)
    t, dt, states = 0.0, 0.02, []
    max_dev = 0.0
    while t < 60.0:
        x, y, _, yaw = robot.pose()
        c.set_pose(x, y, yaw, t, t)
        c.guard.mark("path", t)                       # as if the navigator republished it
        d = c.step(t)
        states.append(d.state)
        if d.state == REACHED:
            break
        robot.set_cmd_vel(d.linear_m_s, d.angular_rad_s)
        robot.step(dt)
        t += dt
        seg = [abs((b - a)[0] * (y - a[1]) - (b - a)[1] * (x - a[0])) / np.linalg.norm(b - a)
               for a, b in zip(path[:-1], path[1:])]
        max_dev = max(max_dev, min(seg))
    x, y, _, _ = robot.pose()
    assert states[-1] == REACHED
    assert math.hypot(x - 2.5, y - 4.0) <= c.cfg.goal_tolerance_m + 1e-6
    assert robot.collisions == 0
    assert max_dev < 0.3


def test_drone_commands_stay_within_tello_limits():
    for heading in np.radians(np.arange(-180, 181, 1)):
        for distance in (0.0, 0.05, 0.2, 0.49, 1.0, 7.3, 80.0):
            text = tello_command(heading, distance, min_turn_deg=8, max_step_cm=100)
            name, value = TelloDrone.parse(text)      # the simulator's Tello limits
            if abs(round(math.degrees(heading))) >= 8:
                assert name == ("ccw" if heading > 0 else "cw")
                assert value == abs(round(math.degrees(heading)))
            else:
                assert name == "forward" and 20 <= value <= 100


def test_drone_flies_a_path_with_discrete_commands():
    world = load_world("one_room")
    cfg = SimConfig(robot="drone")
    drone = TelloDrone(world, cfg, np.random.default_rng(3))
    c = MotionController(MotionConfig(robot="drone"))
    path = np.array([[3.0, 2.5], [3.0, 4.0], [5.0, 4.0]])
    c.set_path(path, 0.0, 0.0)
    now, commands = 0.0, []
    drone.command("takeoff", now)
    for _ in range(200):
        while drone._task is not None or drone._queue:
            now += 0.05
            drone.step(0.05, now)
        responses = drone.pop_responses()
        assert all(r == "ok" for _, r in responses), responses
        x, y, _, yaw = drone.pose()
        c.set_pose(x, y, yaw, now, now)
        c.guard.mark("path", now)
        d = c.step(now)
        if d.state == REACHED:
            break
        assert d.command is not None
        commands.append(d.command)
        drone.command(d.command, now)
    x, y, _, _ = drone.pose()
    assert math.hypot(x - 5.0, y - 4.0) <= c.cfg.drone_goal_tolerance_m
    assert drone.collisions == 0
    assert commands[0] == "ccw 90" and any(cmd.startswith("cw") for cmd in commands)


def test_stale_pose_map_or_path_stops_the_robot():
    c = MotionController(MotionConfig(pose_timeout_s=0.25, map_timeout_s=0.25,
                                      path_timeout_s=2.0))
    assert c.step(0.0).state == IDLE
    c.set_path([[0, 0], [3, 0]], 0.0, 0.0)
    d = c.step(0.0)
    assert d.state == STOPPED_STALE and "pose never received" in d.reason and not d.moving
    c.set_pose(0, 0, 0, 0.0, 0.0)
    assert c.step(0.2).state == FOLLOWING
    d = c.step(0.3)                                   # pose and map 0.3 s old
    assert d.state == STOPPED_STALE and "pose 0.30 s old" in d.reason and "map" in d.reason
    assert d.linear_m_s == 0 and d.angular_rad_s == 0 and d.command is None
    c.set_pose(0, 0, 0, 0.3, 0.0)                     # odometry fresh, map alignment old
    d = c.step(0.35)
    assert d.state == STOPPED_STALE and "map 0.35 s old" in d.reason and "pose" not in d.reason
    c.set_pose(0, 0, 0, 2.1, 2.1)
    d = c.step(2.2)                                   # the path stopped coming at t = 0
    assert d.state == STOPPED_STALE and "path 2.20 s old" in d.reason
    c.set_path([[0, 0], [3, 0]], 2.2, 2.2)
    assert c.step(2.2).state == FOLLOWING


def test_stale_drone_inputs_give_no_command():
    c = MotionController(MotionConfig(robot="drone"))
    c.set_path([[0, 0], [3, 0]], 0.0, 0.0)
    c.set_pose(0, 0, 0, 0.0, 0.0)
    assert c.step(0.1).command == "forward 50"
    d = c.step(1.0)
    assert d.state == STOPPED_STALE and d.command is None


def test_slam_loss_and_map_switch_stop_the_robot():
    c = MotionController()
    c.set_slam_state(False, 1, 0.0)
    c.set_path([[0, 0], [3, 0]], 0.0, 0.0)
    c.set_pose(0, 0, 0, 0.0, 0.0)
    assert c.step(0.0).state == FOLLOWING
    c.set_slam_state(True, 1, 0.1, "no camera pose")
    d = c.step(0.1)
    assert d.state == STOPPED_LOST and not d.moving and "no camera pose" in d.reason
    c.set_slam_state(False, 2, 1.0)                   # a new SLAM map: old coordinates
    assert c.step(1.0).state == IDLE
    with pytest.raises(ValueError, match="before the SLAM map switch"):
        c.set_path([[0, 0], [3, 0]], 0.5, 1.1)
    c.set_path([[0, 0], [3, 0]], 1.05, 1.1)
    c.set_pose(0, 0, 0, 1.1, 1.1)
    assert c.step(1.1).state == FOLLOWING


def test_empty_path_stops():
    c = MotionController()
    c.set_path([[0, 0], [3, 0]], 0.0, 0.0)
    c.set_pose(0, 0, 0, 0.0, 0.0)
    c.set_path(np.empty((0, 2)), 0.1, 0.1)
    d = c.step(0.1)
    assert d.state == IDLE and not d.moving and "empty path" in d.reason


def test_guard_reports_each_input():
    g = StalenessGuard({"a": 1.0, "b": 0.5})
    assert g.stale(0.0) == [("a", None), ("b", None)]
    g.mark("a", 0.0)
    g.mark("b", 0.0)
    assert g.stale(0.5) == []
    assert g.stale(0.75) == [("b", 0.75)]


def wall_run(c, tracked, blocked_at=None, dt=0.1):
    """Ground go-to-wall with a tracked-point count per step; returns the decisions."""
    c.start_wall()
    decisions = []
    for i, n in enumerate(tracked):
        c.set_tracked(n, i * dt)
        if blocked_at == i:
            c.wall_blocked()
        d = c.step(i * dt)
        decisions.append(d)
        c.wall_moved(d.linear_m_s * dt)
        if not d.moving:
            break
    return decisions


def test_go_to_wall_ignores_momentary_misses():
    c = MotionController(MotionConfig(wall_max_fails=3, wall_min_tracked_points=40,
                                      wall_back_off_m=0.3, wall_speed_m_s=0.15))
    tracked = [100, 10, 10, 100, 10, 10, 100, 100] + [10] * 3 + [10] * 30
    decisions = wall_run(c, tracked)
    seeking = [d for d in decisions if d.linear_m_s > 0]
    assert len(seeking) == 10                     # the three misses in a row end it at step 11
    backing = [d for d in decisions if d.linear_m_s < 0]
    assert sum(-d.linear_m_s * 0.1 for d in backing) == pytest.approx(0.3, abs=0.016)
    assert decisions[-1].state == WALL_REACHED and "features lost" in decisions[-1].reason
    assert c.step(10.0).state == WALL_REACHED     # the outcome stays for the conductor


def test_go_to_wall_blocked_and_give_up():
    c = MotionController(MotionConfig(wall_back_off_m=0.0))
    decisions = wall_run(c, [100] * 10, blocked_at=4)
    assert decisions[-1].state == WALL_REACHED and "blocked" in decisions[-1].reason
    c = MotionController(MotionConfig(wall_max_distance_m=1.0, wall_speed_m_s=0.5))
    decisions = wall_run(c, [100] * 50)
    assert decisions[-1].state == FAILED and "no wall within 1.0 m" in decisions[-1].reason


def test_go_to_wall_drone_commands():
    c = MotionController(MotionConfig(robot="drone", wall_step_cm=30, wall_back_off_m=0.3,
                                      wall_max_fails=2))
    c.start_wall()
    c.set_tracked(100, 0.0)
    assert c.step(0.0).command == "forward 30"
    c.wall_moved(0.3)
    c.set_tracked(5, 1.0)
    assert c.step(1.0).command == "forward 30"
    c.wall_moved(0.3)
    d = c.step(5.0)                                   # no recent tracked points: second miss
    assert d.state == WALL_SEEKING and d.command == "back 30"
    c.wall_moved(-0.3)
    assert c.step(6.0).state == WALL_REACHED


@pytest.mark.parametrize("kwargs", [
    {"robot": "boat"}, {"lookahead_m": 0.0}, {"drone_max_step_cm": 10},
    {"drone_max_step_cm": 600}, {"drone_goal_tolerance_m": 0.1}, {"min_linear_m_s": 2.0},
    {"pose_timeout_s": -1.0}, {"wall_max_fails": 0}, {"turn_in_place_deg": 200.0}])
def test_config_is_validated(kwargs):
    with pytest.raises(ValueError):
        MotionController(MotionConfig(**kwargs))


def test_republished_path_keeps_progress_and_a_new_one_is_projected_whole():
    f = PathFollower(lookahead_m=0.5, goal_tolerance_m=0.3)
    path = [[0, 0], [0.6, 0], [1.2, 0], [1.2, 0.8]]
    f.set_path(path)
    for x in np.arange(0.0, 1.25, 0.05):
        f.target(x, 0.0, 0.0)
    for y in np.arange(0.0, 1.0, 0.1):
        f.set_path(path)                   # the navigator republishes the same path
        t = f.target(1.25, y, math.pi / 2)
    assert t.reached
    f.set_path([[-2.0, 0.0], [1.2, 0.0], [1.2, 1.0]])   # a replan, starting far behind
    t = f.target(1.2, 0.9, math.pi / 2)
    assert t.remaining_m == pytest.approx(0.1)
    assert t.reached


def test_go_to_wall_notices_a_stall_with_the_fail_counter():
    c = MotionController(MotionConfig(wall_max_fails=3, stall_fraction=0.3,
                                      wall_back_off_m=0.0))
    c.start_wall()
    dt, advances = 0.1, [0.015, 0.0, 0.015, 0.001, 0.0, 0.0, 0.0, 0.0]
    states = []
    for i, advance in enumerate(advances):
        c.set_tracked(200, i * dt)                   # the camera still sees plenty
        d = c.step(i * dt)
        states.append(d.state)
        if not d.moving:
            break
        c.wall_moved(d.linear_m_s * dt, advance)
    # One stalled step, a good one, then three stalled ones in a row.
    assert states == [WALL_SEEKING] * 6 + [WALL_REACHED]
    assert "stalled" in c.step(1.0).reason
    assert c.wall.travelled_m == pytest.approx(0.031)


def test_blocked_robot_stops_until_a_different_path():
    c = MotionController(MotionConfig(stall_timeout_s=3.0, stall_fraction=0.3, bump_max_tries=0))
    path = [[0, 0], [3, 0]]
    c.set_path(path, 0.0, 0.0)
    t, dt, x = 0.0, 0.1, 0.0
    states = []
    while t < 10.0:
        c.set_pose(x, 0.0, 0.0, t, t)
        c.set_path(path, t, t)                     # republished unchanged
        d = c.step(t)
        states.append(d.state)
        advance = d.linear_m_s * dt if t < 2.0 else 0.0   # hits something at t = 2 s
        x += advance
        t += dt
        c.follow_moved(d.linear_m_s * dt, advance, t)
    assert states[0] == FOLLOWING and states[-1] == FAILED
    blocked_at = states.index(FAILED) * dt
    # Over the last 3 s it advanced less than 30% of the command: 2.1 s after the hit.
    assert 3.9 < blocked_at < 4.3
    assert "blocked" in c.step(t).reason and not c.step(t).moving
    c.set_path([[x, 0.0], [x, 1.0]], t, t)        # a replan around the obstacle
    assert c.step(t).state == FOLLOWING


def test_blocked_robot_ignores_a_republished_path_that_starts_at_its_jittering_pose():
    c = MotionController(MotionConfig(stall_timeout_s=3.0, stall_fraction=0.3, bump_max_tries=0))
    rng = np.random.default_rng(3)
    t, dt = 0.0, 0.1
    states = []
    while t < 8.0:
        # Blocked from the start; the navigator republishes the path from the robot's pose,
        # which SLAM jitters by millimetres.
        x, y = rng.normal(0.0, 0.005, 2)
        c.set_pose(x, y, 0.0, t, t)
        c.set_path([[x, y], [1.0, 0.5], [3.0, 0.5]], t, t)
        d = c.step(t)
        states.append(d.state)
        t += dt
        c.follow_moved(d.linear_m_s * dt, 0.0, t)
    assert states[0] == FOLLOWING and states[-1] == FAILED
    assert states[states.index(FAILED):] == [FAILED] * (len(states) - states.index(FAILED))
    c.set_path([[0.0, 0.0], [1.0, -0.5], [3.0, 0.5]], t, t)   # another route: it tries again
    assert c.step(t).state == FOLLOWING


def test_a_drone_meeting_an_obstacle_on_its_path_stops_until_another_route():
    c = MotionController(MotionConfig(robot="drone", bump_max_tries=0))
    c.set_pose(0.0, 0.0, 0.0, 0.0, 0.0)
    c.set_path([[0.0, 0.0], [2.0, 0.0]], 0.0, 0.0)
    assert c.step(0.0).state == FOLLOWING
    c.path_blocked("Tello answered 'error: obstacle' to 'forward 100'")
    c.set_path([[0.003, -0.002], [2.0, 0.0]], 0.1, 0.1)    # republished from the robot's pose
    d = c.step(0.1)
    assert d.state == FAILED and "obstacle" in d.reason and d.command is None
    c.set_path([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]], 0.2, 0.2)
    assert c.step(0.2).state == FOLLOWING


def test_turning_creep_against_a_wall_is_not_a_stall():
    c = MotionController(MotionConfig(stall_timeout_s=1.0))
    c.set_path([[0, 0], [-2, 0]], 0.0, 0.0)         # behind the robot: it turns with the creep
    for i in range(40):
        t = i * 0.1
        c.set_pose(0.0, 0.0, 0.0, t, t)
        c.set_path([[0, 0], [-2, 0]], t, t)
        d = c.step(t)
        c.follow_moved(d.linear_m_s * 0.1, 0.0, t + 0.1)
        assert d.state == FOLLOWING


def _drive_through_one_rooms_door(config, path):
    """The simulated ground robot follows ``path`` in one_room; wheel odometry reports its
    advance. Returns the states, the robot and the controller."""
    world = load_world("one_room")
    robot = GroundRobot(world, SimConfig(), np.random.default_rng(0))
    c = MotionController(config)
    t, dt, states = 0.0, 0.05, []
    while t < 120.0:
        x, y, _, yaw = robot.pose()
        c.set_pose(x, y, yaw, t, t)
        c.set_path(path, t, t)                        # the navigator republishes it
        d = c.step(t)
        states.append(d.state)
        if d.state in (REACHED, FAILED):
            break
        robot.set_cmd_vel(d.linear_m_s, d.angular_rad_s)
        robot.step(dt)
        t += dt
        x1, y1, _, _ = robot.pose()
        c.follow_moved(d.linear_m_s * dt, (x1 - x) * math.cos(yaw) + (y1 - y) * math.sin(yaw), t)
    return states, robot, c


# one_room's exit is a 0.9 m door at the end of a 1 m wide recess (x 5-6, y 5-5.8). This path
# turns into the recess 0.2 m from its west wall, closer than the robot's 0.25 m radius, as a
# squeezed path through a thickly mapped door does; cutting the turn takes the robot closer still.
_TOO_CLOSE_TO_THE_JAMB = [[3.0, 2.5], [5.2, 4.2], [5.2, 6.6]]


def test_a_robot_blocked_at_a_door_jamb_stops_without_tries():
    states, robot, c = _drive_through_one_rooms_door(MotionConfig(bump_max_tries=0),
                                                     _TOO_CLOSE_TO_THE_JAMB)
    assert states[-1] == FAILED and robot.collisions >= 1
    assert "blocked" in c.blocked and "tries" not in c.blocked
    assert robot.pose()[1] < 5.8                       # still inside


def test_a_robot_blocked_at_a_door_jamb_backs_off_and_passes_beside_the_path():
    states, robot, c = _drive_through_one_rooms_door(MotionConfig(), _TOO_CLOSE_TO_THE_JAMB)
    x, y, _, _ = robot.pose()
    assert states[-1] == REACHED and y > 6.3, (x, y)
    assert robot.collisions >= 1                       # it was blocked, and got through
    assert FAILED not in states
    assert c._bump is None                             # the tries ended once it was through


def _pushing_on_walls(c, walls_x, until_s=60.0):
    """A robot following y = 0 toward x = 3 that the first wall in walls_x beyond it stops (the
    map shows none); the wall it is stopped by is taken away once it stopped there a second time.
    Returns each new reason of the controller and the time at the end."""
    path = [[0.0, 0.0], [3.0, 0.0]]
    walls = list(walls_x)
    t, dt, x, stops = 0.0, 0.1, 0.0, 0
    reasons = []
    while t < until_s and not c.blocked:
        c.set_pose(x, 0.0, 0.0, t, t)
        c.set_path(path, t, t)
        d = c.step(t)
        if not reasons or reasons[-1] != d.reason:
            reasons.append(d.reason)
            if "try 2 of" in d.reason and len(walls) > 1:
                walls.pop(0)
        limit = walls[0] if walls else 10.0
        advance = min(d.linear_m_s * dt, limit - x)
        x += advance
        t += dt
        c.follow_moved(d.linear_m_s * dt, advance, t)
    return reasons, t


def test_each_try_takes_the_other_side_with_a_growing_shift_and_then_the_robot_stops():
    c = MotionController(MotionConfig(bump_max_tries=4, bump_back_off_m=0.3, bump_shift_m=0.15))
    reasons, t = _pushing_on_walls(c, [1.0])
    tries = [r for r in reasons if "backing off" in r]
    assert [("left" if "left" in r else "right", r.split("then ")[1][:4]) for r in tries] == [
        ("left", "0.15"), ("right", "0.15"), ("left", "0.30"), ("right", "0.30")]
    assert [f"try {k} of 4" in r for k, r in enumerate(tries, 1)] == [True] * 4
    assert c.step(t).state == FAILED and "4 shifted tries failed" in c.blocked
    c.set_path([[1.0, 0.0], [1.0, 2.0]], t, t)          # another route: tries of its own
    assert c.step(t).state == FOLLOWING and c._bump is None


def test_blocked_again_past_the_spot_is_a_new_spot_tried_first_on_the_side_that_worked():
    c = MotionController(MotionConfig(bump_max_tries=2, bump_back_off_m=0.3))
    # Stopped at x = 1 (left, then right: that wall goes), then again at x = 2.
    reasons, _ = _pushing_on_walls(c, [1.0, 2.0])
    tries = [r for r in reasons if "backing off" in r]
    assert ["left" in r for r in tries] == [True, False, False, True]
    assert ["try 1 of 2" in r for r in tries] == [True, False, True, False]
    assert "2 shifted tries failed" in c.blocked


def test_a_drone_meeting_an_obstacle_backs_off_once_and_aims_beside_the_path():
    c = MotionController(MotionConfig(robot="drone", bump_back_off_m=0.3, bump_shift_m=0.15))
    c.set_pose(0.0, 0.0, 0.0, 0.0, 0.0)
    c.set_path([[0.0, 0.0], [1.0, 1.0], [1.0, 3.0]], 0.0, 0.0)   # bends left
    c.step(0.0)
    c.set_pose(0.75, 0.85, math.pi / 4, 0.1, 0.1)  # cutting the corner: strayed to the left
    c.step(0.1)
    c.path_blocked("Tello answered 'error: obstacle' to 'forward 100'")
    d = c.step(0.2)
    assert d.state == FOLLOWING and d.command == "back 30" and "right" in d.reason
    assert c.step(0.3).command != "back 30"            # one command carries the whole move
    shifted = c.follower.target(*c.pose)
    c.follower.shift(None, 0.0, 0.0)
    plain = c.follower.target(*c.pose)
    # The look-ahead point lies on the part heading +y, whose right is +x.
    assert plain.point[0] == pytest.approx(1.0)
    assert shifted.point == pytest.approx(plain.point + [0.15, 0.0])
