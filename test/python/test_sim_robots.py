"""Simulated robots: the ground robot on cmd_vel (motion, limits, collisions, odometry) and the
Tello drone on SDK text commands (limits, takeoff, moves, turns, obstacles, auto-land)."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparse_nav.sim import DroneCommandError, SimConfig, Simulator, load_world
from sparse_nav.sim.robots import TelloDrone


def _drone(seed=0, **cfg):
    return Simulator(load_world("one_room"), SimConfig(robot="drone", seed=seed, **cfg))


def _ground(seed=0, **cfg):
    return Simulator(load_world("one_room"), SimConfig(robot="ground", seed=seed, **cfg))


def _until_answered(sim, n=1, timeout_s=20.0, dt=0.05):
    """Step until n drone responses arrived; returns them."""
    got = []
    t_end = sim.time_s + timeout_s
    while len(got) < n and sim.time_s < t_end:
        sim.step(dt)
        got += sim.pop_drone_responses()
    return got


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


# -- drone: command validation ------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("forward 600", "forward 600': distance must be 20-500 cm, got 600"),
    ("back 10", "distance must be 20-500 cm, got 10"),
    ("up 501", "distance must be 20-500 cm"),
    ("cw 0", "angle must be 1-360 deg, got 0"),
    ("ccw 400", "angle must be 1-360 deg, got 400"),
    ("speed 5", "speed must be 10-100 cm/s"),
    ("forward", "needs one integer distance in cm (20-500)"),
    ("forward 1.5", "distance must be an integer 20-500 cm, got '1.5'"),
    ("left many", "must be an integer"),
    ("takeoff 3", "'takeoff' takes no argument"),
    ("flip l", "unknown command 'flip'; known: command, takeoff, land"),
    ("", "empty command"),
])
def test_out_of_limit_or_unknown_commands_raise(text, message):
    sim = _drone()
    with pytest.raises(DroneCommandError) as err:
        sim.drone_command(text)
    assert message in str(err.value)
    assert isinstance(err.value, ValueError)
    assert sim.pop_drone_responses() == []      # nothing was queued


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(["forward", "back", "left", "right", "up", "down", "cw", "ccw"]),
       st.integers(min_value=-100, max_value=1000))
def test_limits_are_exactly_the_tellos(name, value):
    lo, hi = (1, 360) if name in ("cw", "ccw") else (20, 500)
    if lo <= value <= hi:
        assert TelloDrone.parse(f"{name} {value}") == (name, value)
    else:
        with pytest.raises(DroneCommandError):
            TelloDrone.parse(f"{name} {value}")


def test_robot_kind_is_checked():
    with pytest.raises(ValueError, match="drone"):
        _drone().set_cmd_vel(0.1, 0.0)
    with pytest.raises(ValueError, match="ground robot"):
        _ground().drone_command("takeoff")
    assert _ground().pop_drone_responses() == []


# -- drone: flight ------------------------------------------------------------------------------

def test_drone_starts_landed_and_must_take_off():
    sim = _drone()
    assert sim.true_base_pose()[2] == 0.0 and not sim.drone_flying
    sim.drone_command("command")
    sim.drone_command("forward 100")
    sim.drone_command("cw 90")
    assert _until_answered(sim, 3) == [("command", "ok"), ("forward 100", "error: not flying"),
                                       ("cw 90", "error: not flying")]
    assert sim.true_base_pose()[:2] == pytest.approx(load_world("one_room").start[:2])


def test_takeoff_then_forward_100_moves_about_a_metre():
    sim = _drone(seed=3)
    x0, y0, _, yaw0 = sim.true_base_pose()
    sim.drone_command("takeoff")
    assert _until_answered(sim) == [("takeoff", "ok")]
    assert sim.drone_flying and sim.true_base_pose()[2] == pytest.approx(1.0)
    sim.drone_command("forward 100")
    assert _until_answered(sim) == [("forward 100", "ok")]
    x, y, z, yaw = sim.true_base_pose()
    moved = math.hypot(x - x0, y - y0)
    assert moved == pytest.approx(1.0, abs=0.12)             # ~3 % error
    heading = math.atan2(y - y0, x - x0)
    assert abs(_wrap(heading - yaw0)) < math.radians(8)      # ~2 deg error
    assert z == pytest.approx(1.0)


def test_moves_take_time_at_the_set_speed():
    sim = _drone()
    sim.drone_command("takeoff")
    _until_answered(sim)
    sim.drone_command("speed 50")
    sim.drone_command("right 100")
    t0 = sim.time_s
    got = _until_answered(sim, 2, dt=0.01)
    assert got == [("speed 50", "ok"), ("right 100", "ok")]
    assert sim.time_s - t0 == pytest.approx(2.0, rel=0.1)


def test_cw_90_turns_about_90_degrees_and_ccw_back():
    sim = _drone(seed=5)
    sim.drone_command("takeoff")
    _until_answered(sim)
    yaw0 = sim.true_base_pose()[3]
    sim.drone_command("cw 90")
    assert _until_answered(sim) == [("cw 90", "ok")]
    yaw1 = sim.true_base_pose()[3]
    assert math.degrees(_wrap(yaw1 - yaw0)) == pytest.approx(-90.0, abs=6.0)  # clockwise
    sim.drone_command("ccw 90")
    _until_answered(sim)
    assert math.degrees(_wrap(sim.true_base_pose()[3] - yaw0)) == pytest.approx(0.0, abs=8.0)


def test_commands_queue_and_answer_in_order():
    sim = _drone()
    for text in ("takeoff", "up 30", "cw 45", "left 50", "land"):
        sim.drone_command(text)
    got = _until_answered(sim, 5, timeout_s=30.0)
    assert got == [(t, "ok") for t in ("takeoff", "up 30", "cw 45", "left 50", "land")]
    assert not sim.drone_flying and sim.true_base_pose()[2] == 0.0


def test_obstacle_stops_a_move_early():
    sim = _drone()
    sim.drone_command("takeoff")
    _until_answered(sim)
    sim.drone_command("forward 500")     # the east wall is 3 m ahead of the start
    assert _until_answered(sim) == [("forward 500", "error: obstacle")]
    x, y, _, _ = sim.true_base_pose()
    assert 5.4 < x < 6.0 - 0.15 + 1e-6
    assert sim.collisions == 1
    sim.drone_command("up 200")          # the ceiling is 2.5 m high
    assert _until_answered(sim) == [("up 200", "error: obstacle")]
    assert sim.true_base_pose()[2] < 2.5


def test_stop_cancels_the_running_move_and_the_queue():
    sim = _drone()
    sim.drone_command("takeoff")
    _until_answered(sim)
    sim.drone_command("back 200")
    sim.drone_command("cw 90")
    sim.step(0.5)
    sim.drone_command("stop")
    assert sim.pop_drone_responses() == [("back 200", "error: stopped"),
                                         ("cw 90", "error: stopped"), ("stop", "ok")]
    x = sim.true_base_pose()[0]
    sim.step(2.0)
    assert sim.true_base_pose()[0] == x and sim.drone_flying


def test_auto_land_after_15_s_without_commands():
    sim = _drone()
    sim.drone_command("takeoff")
    _until_answered(sim)
    t_last = sim.time_s
    sim.step(14.0)
    assert sim.drone_flying and sim.true_base_pose()[2] == pytest.approx(1.0)
    sim.step(1.0 + 1.0 / 0.5 + 0.2)      # the 15 s limit, then the descent at 0.5 m/s
    assert not sim.drone_flying and sim.true_base_pose()[2] == 0.0
    assert sim.time_s - t_last < 18.5
    assert sim.pop_drone_responses() == []
    sim.drone_command("forward 50")
    assert _until_answered(sim) == [("forward 50", "error: not flying")]


def test_a_command_resets_the_auto_land_timer():
    sim = _drone()
    sim.drone_command("takeoff")
    _until_answered(sim)
    for _ in range(3):
        sim.step(10.0)
        sim.drone_command("cw 10")
    sim.step(5.0)
    assert sim.drone_flying


def test_drone_execution_error_is_seeded():
    def run(seed):
        sim = _drone(seed=seed)
        for text in ("takeoff", "forward 100", "ccw 90", "forward 100"):
            sim.drone_command(text)
        _until_answered(sim, 4)
        return sim.true_base_pose()
    assert run(4) == run(4)
    assert run(4) != run(5)


def test_drone_camera_is_level_at_the_nose():
    sim = _drone()
    mount = sim.camera_mount()
    assert mount[:3, 3] == pytest.approx([0.05, 0.0, 0.0])
    assert sim.odometry() is None


# -- ground robot -------------------------------------------------------------------------------

def test_cmd_vel_moves_the_ground_robot():
    sim = _ground()
    x0, y0, _, yaw0 = sim.true_base_pose()
    sim.set_cmd_vel(0.5, 0.0)
    sim.step(2.0)
    x, y, z, yaw = sim.true_base_pose()
    assert (x - x0, y - y0, z, yaw) == pytest.approx((1.0, 0.0, 0.0, yaw0), abs=1e-6)
    sim.set_cmd_vel(0.0, 0.5)
    sim.step(math.pi / 0.5)
    assert abs(_wrap(sim.true_base_pose()[3] - yaw0 - math.pi)) < 1e-6
    assert sim.collisions == 0


def test_cmd_vel_is_clamped_to_the_limits():
    sim = _ground()
    x0 = sim.true_base_pose()[0]
    sim.set_cmd_vel(5.0, 0.0)
    sim.step(1.0)
    assert sim.true_base_pose()[0] - x0 == pytest.approx(1.0, abs=1e-6)
    sim.set_cmd_vel(0.0, -9.0)
    yaw0 = sim.true_base_pose()[3]
    sim.step(1.0)
    assert _wrap(sim.true_base_pose()[3] - yaw0) == pytest.approx(-1.5, abs=1e-6)
    with pytest.raises(ValueError, match="finite"):
        sim.set_cmd_vel(float("nan"), 0.0)


def test_a_wall_stops_the_ground_robot_and_counts_one_collision():
    sim = _ground()
    sim.set_cmd_vel(1.0, 0.0)           # east wall at x = 6, robot radius 0.25
    sim.step(6.0)
    x = sim.true_base_pose()[0]
    assert 6.0 - 0.25 - 0.01 < x < 6.0 - 0.25 + 1e-9
    assert sim.collisions == 1
    sim.set_cmd_vel(0.0, 1.0)           # turning in contact is allowed
    sim.step(math.pi / 2)
    assert sim.true_base_pose()[0] == pytest.approx(x)
    sim.set_cmd_vel(0.5, 0.0)           # now facing north: slides free along the wall
    sim.step(1.0)
    assert sim.collisions == 1
    sim.set_cmd_vel(0.0, 1.0)
    sim.step(math.pi / 2)               # facing west, away from the wall
    sim.set_cmd_vel(0.5, 0.0)
    sim.step(1.0)
    assert sim.true_base_pose()[0] < x - 0.4
    sim.set_cmd_vel(-1.0, 0.0)          # reversing into the wall is a second collision
    sim.step(2.0)
    assert sim.collisions == 2


def test_boxes_stop_the_ground_robot():
    sim = _ground()
    sim.set_cmd_vel(1.0, 0.0)
    sim.step(0.01)
    sim.set_cmd_vel(0.0, -1.0)
    sim.step(math.atan2(2.5 - 1.0, 3.0 - 1.2) + math.pi / 2 - 0.01)  # face the table
    sim.set_cmd_vel(0.5, 0.0)
    sim.step(8.0)
    x, y, _, _ = sim.true_base_pose()
    assert sim.collisions == 1
    # Stopped at the table (1.4 m x 0.8 m centred at (1.2, 1.0)), not at a wall.
    assert 0.5 < x < 2.4 and 1.4 < y < 1.8


def test_odometry_drifts_a_little():
    sim = _ground(seed=7)
    assert sim.odometry() == (0.0, 0.0, 0.0)
    sim.set_cmd_vel(0.5, 0.0)
    sim.step(4.0)                       # 2 m east
    ox, oy, oyaw = sim.odometry()
    assert math.hypot(ox, oy) == pytest.approx(2.0, rel=0.06)
    assert math.hypot(ox, oy) != pytest.approx(2.0, abs=1e-6)
    assert abs(oyaw) < 0.05


def test_ground_camera_mount_and_pose():
    sim = _ground()
    mount = sim.camera_mount()
    assert mount[:3, 3] == pytest.approx([0.1, 0.0, 0.5])
    # Optical axes in the base frame: z forward (+x), x right (-y), y down (-z).
    np.testing.assert_allclose(mount[:3, 2], [1, 0, 0])
    np.testing.assert_allclose(mount[:3, 0], [0, -1, 0])
    np.testing.assert_allclose(mount[:3, 1], [0, 0, -1])
    x, y, _, yaw = sim.true_base_pose()
    cam = sim.true_camera_pose()
    np.testing.assert_allclose(cam[:3, 3], [x + 0.1 * math.cos(yaw), y + 0.1 * math.sin(yaw),
                                            0.5], atol=1e-12)
    np.testing.assert_allclose(cam[:3, 2], [math.cos(yaw), math.sin(yaw), 0.0], atol=1e-12)


def test_step_rejects_bad_durations_and_config_is_validated():
    sim = _ground()
    for bad in (0.0, -1.0, float("inf")):
        with pytest.raises(ValueError, match="dt_s"):
            sim.step(bad)
    with pytest.raises(ValueError, match="robot"):
        Simulator(load_world("one_room"), SimConfig(robot="boat"))
    with pytest.raises(ValueError, match="camera_rate_hz"):
        Simulator(load_world("one_room"), SimConfig(camera_rate_hz=0))


def test_config_defaults_are_the_documented_ones():
    cfg = SimConfig()
    assert (cfg.robot, cfg.seed) == ("ground", 0)
    assert (cfg.camera_hfov_deg, cfg.camera_vfov_deg) == (82.0, 52.0)
    assert (cfg.camera_min_range_m, cfg.camera_max_range_m, cfg.camera_rate_hz) == (0.3, 8.0, 15.0)
    assert (cfg.ground_max_linear_m_s, cfg.ground_max_angular_rad_s, cfg.ground_radius_m) == \
        (1.0, 1.5, 0.25)
    assert cfg.ground_camera_height_m == 0.5 and cfg.drone_flight_height_m == 1.0
    assert (cfg.drone_speed_m_s, cfg.drone_turn_rate_deg_s, cfg.drone_auto_land_s) == \
        (1.0, 90.0, 15.0)
    assert cfg.force_loss_at_s == [] and SimConfig().force_loss_at_s is not cfg.force_loss_at_s
    cfg.validate()


def test_emergency_drops_the_drone():
    sim = _drone()
    sim.drone_command("takeoff")
    _until_answered(sim)
    sim.drone_command("forward 300")
    sim.step(0.5)
    sim.drone_command("emergency")
    assert sim.pop_drone_responses() == [("forward 300", "error: emergency"), ("emergency", "ok")]
    assert not sim.drone_flying and sim.true_base_pose()[2] == 0.0
