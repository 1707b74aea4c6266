"""Seed 000 scan patterns and their Tello / cmd_vel forms."""
import math

import numpy as np
import pytest

from sparse_nav.scanning import (GROUND_TURN_RATE_RAD_S, InitialScanConfig, RelocaliseConfig, Step,
                                 WallScanConfig, circular_scan, initial_scan, random_scan,
                                 pose_after, relocalise, steps_to_pose, sway, to_tello_commands,
                                 to_velocity_segments, wall_scan)
from sparse_nav.sim import SimConfig, load_world
from sparse_nav.sim.simulator import Simulator
from sparse_nav.sim.slam import TrackingState


def test_initial_scan_turns_a_full_circle_and_returns_each_iteration():
    steps = initial_scan()
    assert sum(s.ccw_deg for s in steps) == pytest.approx(-360.0)
    # Translation sums to zero: the scan stays where it started.
    assert sum(s.forward_m for s in steps) == pytest.approx(0.0)
    assert sum(s.left_m for s in steps) == pytest.approx(0.0)
    assert all(s.forward_m or s.left_m or s.ccw_deg for s in steps)


def test_tello_commands_within_limits():
    commands = to_tello_commands(initial_scan())
    assert commands[:5] == ["back 30", "right 30", "cw 20", "ccw 20", "left 30"]
    for c in commands:
        verb, value = c.split()
        assert verb in {"forward", "back", "left", "right", "cw", "ccw"}
        assert (1 <= int(value) <= 360) if verb in {"cw", "ccw"} else (20 <= int(value) <= 500)
    with pytest.raises(ValueError, match="outside"):
        to_tello_commands([Step(forward_m=0.1)])


def test_velocity_segments_reproduce_the_steps_on_a_unicycle():
    x = y = th = 0.0
    for v, w, duration in to_velocity_segments(initial_scan(InitialScanConfig(turn_deg=90))):
        n = 200
        for _ in range(n):
            x += v * math.cos(th) * duration / n
            y += v * math.sin(th) * duration / n
            th += w * duration / n
    assert np.hypot(x, y) < 0.02
    assert math.remainder(th, 2 * math.pi) == pytest.approx(0.0, abs=1e-6)


def _drive(segments, x=0.0, y=0.0, th=0.0, n=200):
    for v, w, duration in segments:
        for _ in range(n):
            x += v * math.cos(th) * duration / n
            y += v * math.sin(th) * duration / n
            th += w * duration / n
    return x, y, th


@pytest.mark.parametrize("left_m, ccw_deg", [(0.3, 20.0), (-0.3, -20.0), (0.25, -10.0)])
def test_a_sideways_step_moves_the_unicycle_sideways_and_its_undo_retraces_it(left_m, ccw_deg):
    step = Step(left_m=left_m, ccw_deg=ccw_deg)
    x, y, th = _drive(to_velocity_segments([step]), n=10)
    # Sideways by the step's length, as a drone moves (an arc gave ~5 cm); straight drives and
    # turns on the spot integrate exactly.
    assert (x, y) == pytest.approx((0.0, left_m), abs=1e-3)
    assert th == pytest.approx(math.radians(ccw_deg), abs=1e-9)
    x, y, th = _drive(to_velocity_segments([step.undo()]), x, y, th, n=10)
    assert (x, y, th) == pytest.approx((0.0, 0.0, 0.0), abs=1e-3)


def test_sideways_faces_the_side_by_the_angle_given():
    segments = to_velocity_segments([Step(left_m=0.3)], side_face_deg=60.0)
    turns = [w * duration for v, w, duration in segments if v == 0.0]
    assert turns == pytest.approx([math.radians(60.0), -math.radians(60.0)])
    for bad in (0.0, -10.0, 95.0):
        with pytest.raises(ValueError, match="side_face_deg"):
            to_velocity_segments([Step(left_m=0.3)], side_face_deg=bad)


def test_bad_config():
    with pytest.raises(ValueError):
        initial_scan(InitialScanConfig(turn_deg=0))


def test_circular_scan_turns_once_round_in_place():
    steps = circular_scan(WallScanConfig(circle_turn_deg=45.0, circle_sway_m=0.2))
    assert sum(s.ccw_deg for s in steps) == pytest.approx(-360.0)
    assert sum(s.forward_m for s in steps) == pytest.approx(0.0)
    assert sum(1 for s in steps if s.ccw_deg) == 8
    to_tello_commands(steps)  # every move is a valid Tello command


def test_wall_scan_visits_each_wall_it_has_room_for_and_comes_back():
    cfg = WallScanConfig(standoff_m=0.5, min_move_m=0.2, max_move_m=2.0)
    steps = wall_scan([(0.0, 1.5), (90.0, 0.6), (180.0, 9.0), (float("nan"), 3.0)], cfg)
    forwards = [s.forward_m for s in steps if s.forward_m > 0.25]
    # 1.5 - 0.5 = 1.0 m; the 0.6 m wall leaves too little room; the far wall is capped at 2 m.
    assert forwards == [pytest.approx(1.0), pytest.approx(2.0)]
    assert sum(s.forward_m for s in steps) == pytest.approx(0.0)
    assert sum(s.ccw_deg for s in steps) == pytest.approx(-720.0)  # two circles, turns undone
    to_tello_commands(steps)


def test_random_scan_is_seeded_and_respects_the_free_distance():
    free = lambda bearing: 2.0  # noqa: E731
    a = random_scan(np.random.default_rng(3), free)
    b = random_scan(np.random.default_rng(3), free)
    assert a == b
    assert 0.2 <= a[1].forward_m <= 1.4 + 1e-9 and a[0].ccw_deg != 0.0
    boxed_in = random_scan(np.random.default_rng(3), lambda bearing: 0.5)
    assert boxed_in == circular_scan()  # no room to move: only the circle
    with pytest.raises(ValueError):
        circular_scan(WallScanConfig(circle_turn_deg=0.0))


def test_sway_is_the_initial_scan_iteration_without_its_turn():
    steps = sway()
    assert steps == initial_scan()[:6]
    assert sum(s.forward_m for s in steps) == pytest.approx(0.0)
    assert sum(s.ccw_deg for s in steps) == pytest.approx(0.0)


def test_the_drone_relocalises_with_the_sway_and_a_turn():
    assert relocalise("drone") == sway() + [Step(ccw_deg=RelocaliseConfig().turn_deg)]
    assert relocalise("drone", config=RelocaliseConfig(turn_deg=-45.0))[-1] == Step(ccw_deg=-45.0)


def test_the_ground_robot_relocalises_straight_into_the_side_with_room():
    # No sideways step: a unicycle would turn to face the side, and the view with it.
    out_back = relocalise("ground")
    assert out_back == [Step(forward_m=0.6), Step(forward_m=-0.6), Step(ccw_deg=60.0)]
    assert all(s.left_m == 0.0 for s in out_back)
    wall_ahead = relocalise("ground", lambda bearing: 0.5 if bearing == 0.0 else 3.0)
    assert wall_ahead[:2] == [Step(forward_m=-0.6), Step(forward_m=0.6)]
    cramped = relocalise("ground", lambda bearing: 0.8 if bearing == 0.0 else 0.3)
    assert cramped[:2] == [Step(forward_m=0.4), Step(forward_m=-0.4)]  # 0.8 - standoff
    boxed_in = relocalise("ground", lambda bearing: 0.1)
    assert boxed_in[0] == Step(forward_m=0.2)  # min_baseline_m: a try moves all the same
    with pytest.raises(ValueError, match="min_baseline_m"):
        relocalise("ground", config=RelocaliseConfig(baseline_m=0.1))


def test_relocalising_starts_a_new_map_after_a_forced_loss_in_the_simulator():
    """The ground robot, lost in its first sway, stops; standing still, SLAM cannot start a new
    map (no baseline); the relocalising motion gets it one."""
    sim = Simulator(load_world("one_room"), SimConfig(robot="ground", seed=1,
                                                      force_loss_at_s=[6.0]))
    for v, w, duration in to_velocity_segments(sway()):
        sim.set_cmd_vel(v, w)
        end = sim.time_s + duration
        while sim.time_s < end - 1e-9 and not sim.tracking_losses:
            sim.step(0.05)
    assert sim.tracking_losses == 1
    sim.set_cmd_vel(0.0, 0.0)
    sim.step(5.0)
    assert sim.slam_output().state == TrackingState.NOT_INITIALIZED
    lost_map = sim.slam_output().map_id
    for v, w, duration in to_velocity_segments(relocalise("ground")):
        sim.set_cmd_vel(v, w)
        sim.step(duration)
    assert sim.slam_output().state == TrackingState.OK
    # The new map started at the loss saw the first map's points and merged back into it.
    assert lost_map == 1 and sim.slam_output().map_id == 0


def test_default_ground_scan_turns_within_what_the_robot_and_tracking_allow():
    # Faster than the simulated ground robot turns, the scan would drift from its steps; faster
    # than the simulated tracking survives, every turn would lose it.
    limits = SimConfig(robot="ground")
    segments = to_velocity_segments(initial_scan())
    fastest = max(abs(w) for _, w, _ in segments)
    assert fastest == pytest.approx(GROUND_TURN_RATE_RAD_S)
    assert fastest < min(limits.ground_max_angular_rad_s, limits.slam_max_turn_rate_rad_s)
    assert max(abs(v) for v, _, _ in segments) <= limits.ground_max_linear_m_s


@pytest.mark.parametrize("start, target", [
    ((0.0, 0.0, 0.0), (1.0, 0.5, 0.3)),        # ahead: forward
    ((0.0, 0.0, 0.0), (-0.8, 0.2, -2.5)),      # behind: backed into
    ((1.0, -1.0, 3.0), (0.4, -0.7, -3.0)),     # headings across +-180 deg
    ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),        # on the spot: only the turn
])
def test_steps_to_pose_bring_the_unicycle_there(start, target):
    steps = steps_to_pose(start, target)
    x, y, th = pose_after(start, steps)
    assert (x, y) == pytest.approx(target[:2], abs=1e-9)
    assert math.remainder(th - target[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-6)
    assert all(not s.left_m and not s.reverse and abs(s.ccw_deg) <= 180.0 for s in steps)
    assert sum(1 for s in steps if s.ccw_deg and abs(s.ccw_deg) > 90.0) <= 1


def test_steps_to_pose_back_into_a_target_behind_without_turning_round():
    assert steps_to_pose((0.0, 0.0, 0.0), (-0.6, 0.0, 0.0)) == [Step(forward_m=-0.6)]
    assert steps_to_pose((0.2, 0.1, 0.5), (0.2, 0.1, 0.5)) == []


def test_pose_after_follows_the_unicycle_and_an_undo_comes_back():
    steps = [Step(forward_m=0.3), Step(left_m=0.3, ccw_deg=20.0), Step(ccw_deg=-60.0)]
    x, y, th = _drive(to_velocity_segments(steps, turn_rate_rad_s=1e6), n=10)
    # turns so fast that their 5 cm/s creep moves nothing: straight lines and turns on the spot
    assert pose_after((0.0, 0.0, 0.0), steps) == pytest.approx((x, y, th), abs=1e-3)
    back = [s.undo() for s in reversed(steps)]
    assert pose_after((1.0, 2.0, 0.5), steps + back) == pytest.approx((1.0, 2.0, 0.5), abs=1e-9)
