"""The ROS-free core of slam_bridge: health, map anchoring, scale."""
import numpy as np
import pytest

from sparse_nav.slam_bridge import (LOST, NOT_INITIALIZED, OK, ORB_LOST, ORB_NOT_INITIALIZED,
                                    ORB_OK, ORB_RECENTLY_LOST, BridgeConfig, DroneMoveScale,
                                    MapAnchors, MapClouds, MapScales, ScaleEstimator,
                                    StateTracker, odometry_camera_position)
from sparse_nav.transforms import invert, make_transform, planar, yaw_of

# A forward-looking camera 0.5 m up: optical z = base x, optical x = -base y, optical y = -base z.
MOUNT = make_transform(np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float), [0.1, 0, 0.5])


def camera_in_slam(t_slamorigin_base, base_pose, units_per_metre):
    """Camera pose in a SLAM map whose origin is the camera at t_slamorigin_base (world frame)."""
    t_origin = t_slamorigin_base @ MOUNT
    t = invert(t_origin) @ base_pose @ MOUNT
    t[:3, 3] *= units_per_metre
    return t


def test_state_from_wrapper():
    tracker = StateTracker(BridgeConfig())
    assert not tracker.on_wrapper_state(ORB_NOT_INITIALIZED)
    assert tracker.evaluate(0.0)[0] == NOT_INITIALIZED
    tracker.on_wrapper_state(ORB_OK)
    assert tracker.evaluate(0.0)[0] == OK
    tracker.on_wrapper_state(ORB_LOST)
    state, reason = tracker.evaluate(0.0)
    assert state == LOST and "lost" in reason
    assert tracker.on_wrapper_state(ORB_NOT_INITIALIZED), "a new map after tracking worked"
    assert tracker.source == "wrapper"


def test_a_map_is_given_up_when_slam_is_lost_or_begins_another_not_while_recently_lost():
    tracker = StateTracker(BridgeConfig())
    tracker.on_wrapper_state(ORB_NOT_INITIALIZED)
    assert not tracker.map_given_up, "no map yet to give up"
    tracker.on_wrapper_state(ORB_OK)
    tracker.evaluate(0.0)
    assert not tracker.map_given_up
    tracker.on_wrapper_state(ORB_RECENTLY_LOST)
    assert tracker.evaluate(0.0)[0] == LOST and not tracker.map_given_up
    tracker.on_wrapper_state(ORB_LOST)
    assert tracker.map_given_up
    tracker.on_wrapper_state(ORB_NOT_INITIALIZED)
    assert tracker.map_given_up
    inferred = StateTracker(BridgeConfig(pose_timeout_s=0.5))
    inferred.on_pose(1.0)
    inferred.evaluate(1.0)
    assert inferred.evaluate(5.0)[0] == LOST and not inferred.map_given_up, "cannot tell"


def test_state_inferred_from_staleness_and_tracked_points():
    cfg = BridgeConfig(pose_timeout_s=0.5, min_tracked_points=10)
    tracker = StateTracker(cfg)
    assert tracker.evaluate(1.0)[0] == NOT_INITIALIZED
    tracker.on_pose(1.0)
    tracker.on_tracked_points(50)
    assert tracker.evaluate(1.2)[0] == OK
    state, reason = tracker.evaluate(2.0)
    assert state == LOST and "no camera pose" in reason
    tracker.on_pose(2.0)
    tracker.on_tracked_points(3)
    state, reason = tracker.evaluate(2.0)
    assert state == LOST and "3 tracked points" in reason
    assert tracker.source == "inferred"


def test_pose_gap_reveals_a_loss_nobody_saw():
    tracker = StateTracker(BridgeConfig(pose_timeout_s=0.5))
    assert tracker.on_pose(1.0) is None
    assert tracker.on_pose(1.1) is None
    assert tracker.on_pose(2.5) == pytest.approx(1.4)


def test_first_map_puts_base_at_origin_and_follows_motion():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = planar(2.0, 1.0, 0.0, 0.7)
    s = 3.0  # SLAM units per metre; the bridge is told 1/s metres per unit
    base, event = anchors.update(camera_in_slam(origin, origin, s), 1.0 / s, 1.0)
    assert event == "first"
    np.testing.assert_allclose(base, np.eye(4), atol=1e-9)
    moved = origin @ planar(1.0, 0.5, 0.0, 0.3)
    base, event = anchors.update(camera_in_slam(origin, moved, s), 1.0 / s, 2.0)
    assert event is None
    np.testing.assert_allclose(base[:3, 3], [1.0, 0.5, 0.0], atol=1e-9)
    assert yaw_of(base) == pytest.approx(0.3)


def test_new_map_continues_from_last_pose_and_merge_returns_to_old_anchor():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = planar(0.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, origin, 2.0), 0.5, 1.0)
    last = planar(1.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, last, 2.0), 0.5, 2.0)
    anchors.tracking_lost()
    anchors.expect_new_map()
    # A new SLAM map starts where the robot is, with another scale.
    new_origin = planar(1.2, 0.1, 0.0, 0.1)
    base, event = anchors.update(camera_in_slam(new_origin, new_origin, 5.0), 0.2, 3.0)
    assert event == "new_map" and anchors.current.index == 1
    np.testing.assert_allclose(base[:3, 3], [1.0, 0.0, 0.0], atol=1e-9)
    # SLAM merges back: the pose jumps into the first map's frame and scale.
    back = planar(1.5, 0.2, 0.0, 0.2)
    base, event = anchors.update(camera_in_slam(origin, back, 2.0), 0.5, 4.0)
    assert event == "switched" and anchors.current.index == 0
    np.testing.assert_allclose(base[:3, 3], [1.5, 0.2, 0.0], atol=1e-9)


def test_a_map_left_by_a_jump_while_tracking_is_never_picked_again():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = planar(0.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, origin, 2.0), 0.5, 1.0)
    anchors.update(camera_in_slam(origin, planar(1.0, 0.0, 0.0, 0.0), 2.0), 0.5, 2.0)
    anchors.tracking_lost()
    anchors.expect_new_map()
    new_origin = planar(1.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(new_origin, new_origin, 5.0), 0.2, 3.0)
    anchors.update(camera_in_slam(new_origin, planar(3.0, 0.0, 0.0, 0.0), 5.0), 0.2, 4.0)
    # While tracking, SLAM merges map 1 into map 0: the pose jumps into map 0's frame.
    _, event = anchors.update(camera_in_slam(origin, planar(3.0, 0.0, 0.0, 0.0), 2.0), 0.5, 5.0)
    assert event == "switched" and anchors.current.index == 0
    assert anchors.anchors[1].retired and not anchors.anchors[0].retired
    # Lost, and back 0.6 m on in map 0's frame: map 1's anchor would read that pose 0.56 m
    # from the last one, nearer than map 0's own 0.6 m, yet it is map 0's.
    anchors.tracking_lost()
    base, event = anchors.update(camera_in_slam(origin, planar(3.6, 0.0, 0.0, 0.0), 2.0), 0.5, 6.0)
    assert event == "relocalised" and anchors.current.index == 0
    np.testing.assert_allclose(base[:3, 3], [3.6, 0.0, 0.0], atol=1e-9)


def test_new_map_detected_without_hint_when_far_from_old_map():
    anchors = MapAnchors(BridgeConfig(relocalise_tolerance_m=1.0), MOUNT)
    origin = np.eye(4)
    anchors.update(camera_in_slam(origin, origin, 1.0), 1.0, 1.0)
    for x in np.arange(0.2, 3.01, 0.2):
        _, event = anchors.update(camera_in_slam(origin, planar(x, 0, 0, 0), 1.0), 1.0, 1.0 + x)
        assert event is None
    anchors.tracking_lost()
    here = planar(3.1, 0, 0, 0)
    base, event = anchors.update(camera_in_slam(here, here, 4.0), 0.25, 5.0)
    assert event == "new_map"
    np.testing.assert_allclose(base[:3, 3], [3.0, 0, 0], atol=1e-9)


def test_relocalisation_in_same_map_is_not_a_new_map():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = np.eye(4)
    anchors.update(camera_in_slam(origin, origin, 1.0), 1.0, 1.0)
    anchors.tracking_lost()
    _, event = anchors.update(camera_in_slam(origin, planar(0.2, 0, 0, 0), 1.0), 1.0, 2.0)
    assert event == "relocalised" and len(anchors.anchors) == 1


def test_scale_estimator_is_robust_and_confident_with_samples():
    est = ScaleEstimator(prior_metres_per_unit=1.0)
    assert est.estimate() == (1.0, 0.0, 0)
    assert not est.add(1.0, 0.01), "too short a motion is not used"
    assert not est.add(float("nan"), 1.0)
    rng = np.random.default_rng(0)
    for _ in range(20):
        est.add(1.0, 0.4 * (1 + 0.02 * rng.standard_normal()))
    est.add(1.0, 9.0)  # an outlier
    value, confidence, n = est.estimate()
    assert value == pytest.approx(0.4, rel=0.02)
    assert 0.5 < confidence <= 1.0 and n == 21
    assert est.fresh().estimate() == (pytest.approx(0.4, rel=0.02), 0.0, 0)


def test_each_slam_map_keeps_its_scale_samples_across_merges():
    scales = MapScales(prior_metres_per_unit=1.0)
    scales.on_map_event(0, "first")
    for _ in range(5):
        scales.current.add(1.0, 3.0)
    scales.on_map_event(0, None)
    assert scales.current.estimate()[2] == 5
    # A new map starts without samples, from the last map's value.
    scales.on_map_event(1, "new_map")
    assert scales.current.estimate() == (3.0, 0.0, 0)
    scales.current.add(1.0, 0.5)
    # SLAM merges back into map 0: its five samples and its scale are back.
    scales.on_map_event(0, "switched")
    assert scales.current.estimate()[:1] == (3.0,) and scales.current.estimate()[2] == 5
    scales.on_map_event(1, "switched")
    assert scales.current.estimate() == (0.5, pytest.approx(0.25), 1)


def test_a_second_sample_read_short_does_not_blow_the_scale_up():
    est = ScaleEstimator(prior_metres_per_unit=1.0)
    est.add(0.1, 0.3)    # 3 m per unit
    est.add(0.01, 0.3)   # the same move read with a stale end pose: 30 m per unit
    assert est.estimate()[0] == pytest.approx(3.0)  # not their mean, 16.5


def test_drone_moves_pair_with_responses_in_order_and_end_at_the_next_pose():
    moves = DroneMoveScale()
    moves.on_command("forward 100", np.zeros(3))
    moves.on_command("cw 90", None)
    assert moves.on_pose(np.array([0.0, 0.0, 1.0])) is None  # still moving, not answered
    moves.on_response("ok", np.array([0.0, 0.0, 2.0]))  # the pose at hand lags the drone
    assert moves.on_pose(np.array([0.0, 0.0, 2.5])) == (2.5, 1.0)
    assert moves.on_pose(np.array([0.0, 0.0, 2.5])) is None  # one sample per move
    moves.on_response("ok", np.array([0.0, 0.0, 2.5]))
    assert moves.on_pose(np.array([0.0, 0.0, 2.5])) is None  # a turn has no length
    moves.on_command("left 50", np.zeros(3))
    moves.on_response("error: obstacle", np.ones(3))
    assert moves.on_pose(np.ones(3)) is None
    moves.on_command("back 50", np.zeros(3))
    moves.invalidate()
    moves.on_response("ok", np.ones(3))
    assert moves.on_pose(np.ones(3)) is None


def test_an_answer_that_overtakes_its_command_does_not_shift_the_pairing():
    moves = DroneMoveScale()
    moves.on_response("ok", np.zeros(3))        # the answer to "cw 90" arrives first
    moves.on_command("cw 90", np.zeros(3))      # ... then the command: already answered
    moves.on_command("right 50", np.zeros(3))
    moves.on_response("ok", np.zeros(3))
    assert moves.on_pose(np.array([2.0, 0.0, 0.0])) == (2.0, 0.5)  # paired with its own command
    moves.on_command("cw 90", np.array([2.0, 0.0, 0.0]))
    moves.on_response("ok", np.array([2.0, 0.0, 0.0]))
    assert moves.on_pose(np.array([2.0, 0.1, 0.0])) is None  # a turn, not a 0.1-unit move


def test_an_answer_to_a_command_never_heard_does_not_shift_the_pairing_for_good():
    moves = DroneMoveScale()
    moves.on_response("ok", np.zeros(3))        # "command" was sent before the bridge listened
    moves.on_command("takeoff", np.zeros(3))    # taken as answered by that "ok" ...
    moves.on_response("ok", np.zeros(3))        # ... until its own answer comes
    moves.on_command("forward 30", np.zeros(3))
    moves.on_response("ok", np.array([0.1, 0.0, 0.0]))
    assert moves.on_pose(np.array([0.1, 0.0, 0.0])) == (pytest.approx(0.1), 0.3)
    for step in range(2, 5):
        moves.on_command("forward 30", np.array([0.1 * (step - 1), 0.0, 0.0]))
        moves.on_response("ok", np.array([0.1 * step, 0.0, 0.0]))
        assert moves.on_pose(np.array([0.1 * step, 0.0, 0.0])) == (pytest.approx(0.1), 0.3)


def test_config_validation():
    with pytest.raises(ValueError, match="pose_timeout_s"):
        BridgeConfig(pose_timeout_s=0).validate()
    with pytest.raises(ValueError, match="merge_min_share"):
        BridgeConfig(merge_min_share=0).validate()
    with pytest.raises(ValueError, match="merge_sample_points"):
        BridgeConfig(merge_sample_points=0).validate()
    with pytest.raises(ValueError, match="merge_scale_tolerance"):
        BridgeConfig(merge_scale_tolerance=0).validate()


def room_points(seed=0, n=3000):
    """Features on the walls of a 6 m x 5 m room, 2.5 m high (world frame, m)."""
    rng = np.random.default_rng(seed)
    u, z = rng.uniform(0, 1, n), rng.uniform(0, 2.5, n)
    wall = rng.integers(0, 4, n)
    x = np.select([wall == 0, wall == 1, wall == 2], [u * 6, 6.0, u * 6], 0.0)
    y = np.select([wall == 0, wall == 1, wall == 2], [0.0, u * 5, 5.0], u * 5)
    return np.column_stack([x - 3.0, y - 2.5, z])


def in_slam(t_slamorigin_base, world_points, units_per_metre):
    """World points in the SLAM frame of a map begun with the base at t_slamorigin_base."""
    t = invert(t_slamorigin_base @ MOUNT)
    return (world_points @ t[:3, :3].T + t[:3, 3]) * units_per_metre


def test_a_merge_of_a_robot_scanning_in_place_is_seen_in_the_cloud():
    # The robot turns on the spot; a loss begins map 1 there, 60 deg on, at another scale.
    # When SLAM merges map 1 back into map 0, the pose read through map 1's anchor barely moves
    # (both maps begin at the robot) but map 0's points reappear at their own coordinates.
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    world = room_points()
    origin, s0 = planar(0.0, 0.0, 0.0, 0.0), 2.0
    anchors.update(camera_in_slam(origin, origin, s0), 1.0 / s0, 1.0)
    seen0 = world[world[:, 0] > 0]
    assert anchors.on_cloud(in_slam(origin, seen0, s0)) is None
    anchors.tracking_lost()
    anchors.expect_new_map()
    turned, s1 = planar(0.0, 0.0, 0.0, np.radians(60)), 0.7
    _, event = anchors.update(camera_in_slam(turned, turned, s1), 1.0 / s0, 2.0)
    assert event == "new_map" and anchors.current.index == 1
    seen1 = world[world[:, 1] > 0]
    assert anchors.on_cloud(in_slam(turned, seen1, s1)) is None, "a new map is no merge"
    # Merged: one cloud in map 0's frame; the pose is in map 0's frame too, a small step.
    more = planar(0.0, 0.0, 0.0, np.radians(70))
    _, event = anchors.update(camera_in_slam(origin, more, s0), 1.0 / s0, 3.0)
    assert event is None and anchors.current.index == 1, "the pose alone does not tell"
    merged = in_slam(origin, np.vstack([seen0, seen1]), s0)
    assert anchors.on_cloud(merged) == 0
    assert anchors.current.index == 0 and anchors.anchors[1].retired
    later = planar(0.0, 0.0, 0.0, np.radians(80))
    base, event = anchors.update(camera_in_slam(origin, later, s0), 1.0 / s0, 4.0)
    assert event is None
    assert yaw_of(base) == pytest.approx(np.radians(80))
    # The same map goes on: no further merge.
    assert anchors.on_cloud(merged) is None and anchors.current.index == 0


def test_a_jump_while_tracking_that_no_anchor_explains_keeps_the_map_until_its_cloud_tells():
    anchors = MapAnchors(BridgeConfig(relocalise_tolerance_m=1.0), MOUNT)
    world = room_points(seed=1)
    origin, s0 = planar(0.0, 0.0, 0.0, 0.0), 1.0
    anchors.update(camera_in_slam(origin, origin, s0), 1.0 / s0, 1.0)
    anchors.on_cloud(in_slam(origin, world, s0))
    anchors.tracking_lost()
    anchors.expect_new_map()
    here, s1 = planar(0.5, 0.0, 0.0, 0.0), 3.0
    anchors.update(camera_in_slam(here, here, s1), 1.0 / s0, 2.0)
    anchors.on_cloud(in_slam(here, world[:1000], s1))
    # Map 1's scale is read 3 times too large until measured: its anchor puts the robot 3 m
    # off when SLAM merges it into map 0, 2 m on; no anchor explains the jump.
    there = planar(2.5, 0.0, 0.0, 0.0)
    base_before = anchors.last_base.copy()
    base, event = anchors.update(camera_in_slam(origin, there, s0), 1.0, 3.0)
    assert event == "reframed" and anchors.current.index == 1 and len(anchors.anchors) == 2
    np.testing.assert_allclose(base, base_before, atol=1e-9)
    assert anchors.on_cloud(in_slam(origin, world, s0)) == 0
    base, event = anchors.update(camera_in_slam(origin, there, s0), 1.0 / s0, 4.0)
    assert event is None and anchors.current.index == 0
    np.testing.assert_allclose(base[:3, 3], [2.5, 0.0, 0.0], atol=1e-9)


def test_a_new_scale_for_a_young_map_is_no_jump_back_to_the_earlier_map():
    # sim_bridge_ground: a new map begun where the robot scans in place, read at the earlier
    # map's scale until the odometry's first samples made it several times larger. The robot
    # then moved by a metre at once, and map 0's anchor, whose origin is as near, explained the
    # pose: a switch back to map 0 a second before SLAM merged.
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = planar(0.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, origin, 1.0), 1.0, 1.0)
    anchors.tracking_lost()
    anchors.expect_new_map()
    turned, s1 = planar(0.0, 0.0, 0.0, np.radians(60)), 0.2
    anchors.update(camera_in_slam(turned, turned, s1), 1.0, 2.0)
    on = turned @ planar(1.0, 0.0, 0.0, 0.0)
    base, event = anchors.update(camera_in_slam(turned, on, s1), 1.0, 3.0)
    assert event is None and np.linalg.norm(base[:3, 3]) == pytest.approx(0.2)
    anchors.set_scale(1.0 / s1)
    further = turned @ planar(1.1, 0.0, 0.0, 0.0)
    base, event = anchors.update(camera_in_slam(turned, further, s1), 1.0 / s1, 4.0)
    assert event is None and anchors.current.index == 1
    np.testing.assert_allclose(base[:3, 3], [1.1, 0.0, 0.0], atol=1e-9)

def _double_loss_then_merge(anchors, world):
    """Map 0 from the origin; the robot drives 1.5 m on and loses tracking twice there: map 1
    holds a handful of points, map 2, begun at nearly the same pose, holds the wall ahead. Then
    SLAM merges map 2 into map 0 and the pose, read in map 0, tells (stamp 4 s). Returns map 2's
    last cloud, stamped 3.5 s."""
    origin, s0 = planar(0.0, 0.0, 0.0, 0.0), 2.0
    anchors.update(camera_in_slam(origin, origin, s0), 1.0 / s0, 1.0)
    anchors.on_cloud(in_slam(origin, world[world[:, 0] > 0], s0))
    here = planar(1.5, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, here, s0), 1.0 / s0, 1.5)
    ahead = world[world[:, 0] > 2.0]
    for index, (start, units, n, stamp) in enumerate(
            [(here, 0.7, 6, 2.0), (planar(1.52, 0.0, 0.0, 0.02), 0.72, len(ahead), 3.0)], 1):
        anchors.tracking_lost()
        anchors.expect_new_map()
        _, event = anchors.update(camera_in_slam(start, start, units), 1.0 / s0, stamp)
        assert event == "new_map" and anchors.current.index == index
        cloud = in_slam(start, ahead[:n], units)
        assert not anchors.is_late(stamp + 0.5)
        assert anchors.on_cloud(cloud) is None
    _, event = anchors.update(camera_in_slam(origin, here, s0), 1.0 / s0, 4.0)
    assert event == "switched" and anchors.current.index == 0
    return cloud


def test_a_late_cloud_of_the_map_slam_merged_is_ignored():
    # cartographer_sim, once: a cloud of map 2 handled 0.1 s after the pose that showed the
    # merge into map 0 read as a merge of map 0 into map 1, the tiny map begun at the same pose.
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    world = room_points(seed=2)
    late = _double_loss_then_merge(anchors, world)
    assert anchors.is_late(3.5)
    merged = in_slam(planar(0.0, 0.0, 0.0, 0.0), world[world[:, 0] > 0], 2.0)
    assert not anchors.is_late(4.5)
    assert anchors.on_cloud(merged) is None
    assert anchors.current.index == 0 and not anchors.anchors[0].retired
    assert anchors.merge is not None and (anchors.merge.left, anchors.merge.into) == (2, 0)
    # Taken as on time, the late cloud reads as a merge of map 0 into map 2 (or into map 1,
    # whose handful of points it holds too), and map 0 is retired.
    replayed = MapAnchors(BridgeConfig(), MOUNT)
    _double_loss_then_merge(replayed, world)
    assert replayed.on_cloud(late) in (1, 2) and replayed.anchors[0].retired

def test_map_clouds_recognise_a_map_whose_points_were_refined():
    cfg = BridgeConfig()
    clouds = MapClouds(cfg)
    rng = np.random.default_rng(2)
    a = room_points(seed=3) * 0.8
    assert clouds.observe(0, a) is None and clouds.last_index == 0
    b = room_points(seed=4) * 2.0 + [0.3, -0.2, 1.0]
    assert clouds.observe(1, b) is None and clouds.last_index == 1
    # Bundle adjustment moved 40 % of map 0's points by more than the tolerance.
    refined = a.copy()
    moved = rng.random(len(a)) < 0.4
    refined[moved] += rng.normal(0.0, 0.2, (moved.sum(), 3))
    merged = np.vstack([refined, b * 0.4 + [1.0, 0.0, 0.0]])
    assert clouds.observe(1, merged) == 0 and clouds.last_index == 0
    # A map whose points moved more than that is not recognised.
    assert clouds.observe(1, a + rng.normal(0.0, 0.2, a.shape)) is None
    assert clouds.observe(0, np.zeros((0, 3))) is None


def test_odometry_follows_the_camera_not_the_base():
    # Turning on the spot by 90 deg moves the camera 0.1 m ahead of the axis by 0.14 m, while
    # the base stays: SLAM sees the camera move, so the scale must compare camera positions.
    half = np.sqrt(0.5)
    before = odometry_camera_position((1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0), MOUNT)
    after = odometry_camera_position((1.0, 2.0, 0.0), (0.0, 0.0, half, half), MOUNT)
    assert before == pytest.approx([1.1, 2.0, 0.5])
    assert after == pytest.approx([1.0, 2.1, 0.5])
    assert np.linalg.norm(after - before) == pytest.approx(0.1 * np.sqrt(2.0))




def _measured_map_then_young_maps(clouds, world, s0, young):
    """Map 0's cloud (the whole room at s0 units per metre), then each young map's (a corner of
    it, in its own frame and units); returns MapScales with five samples of map 0 and none of
    the young maps."""
    scales = MapScales()
    scales.on_map_event(0, "first")
    for _ in range(5):
        scales.current.add(1.0, 1.0 / s0)
    clouds.observe(0, in_slam(planar(0.0, 0.0, 0.0, 0.0), world, s0))
    for index, (origin, units) in enumerate(young, start=1):
        scales.on_map_event(index, "new_map")
        clouds.observe(index, in_slam(origin, world[:200], units))
    return scales


def test_a_measured_map_merged_into_a_young_one_gives_it_its_scale():
    # SLAM merges the map it tracks into an earlier young map it recognises, which keeps its
    # frame and its scale, never measured: the measured map's samples carry over, converted.
    world = room_points(seed=5)
    s0, young = 2.0, (planar(0.3, 0.2, 0.0, np.radians(60)), 0.7)
    clouds = MapClouds(BridgeConfig())
    scales = _measured_map_then_young_maps(clouds, world, s0, [young])
    scales.on_map_event(0, "switched")
    assert clouds.observe(0, in_slam(*young[:1], world, young[1])) == 1
    assert clouds.merge.left == 0 and clouds.merge.into == 1
    assert clouds.merge.units_ratios == {0: pytest.approx(young[1] / s0, rel=0.02)}
    scales.on_map_event(1, "switched")
    assert scales.on_merge(clouds.merge) == 0
    value, _, n = scales.current.estimate()
    assert value == pytest.approx(1.0 / young[1], rel=0.02) and n == 5


def test_a_map_merged_on_the_way_gives_its_scale_too():
    # SLAM merged young map 2 into map 0, then map 0 into young map 1, within one frame: the pose
    # went from map 2 to map 1, and map 0's points are in map 1's cloud.
    world = room_points(seed=6)
    s0 = 2.0
    young = [(planar(0.3, 0.2, 0.0, np.radians(60)), 0.7), (planar(0.0, 0.4, 0.0, 1.0), 4.0)]
    clouds = MapClouds(BridgeConfig())
    scales = _measured_map_then_young_maps(clouds, world, s0, young)
    scales.on_map_event(1, "switched")
    clouds.merged_from = 2
    assert clouds.observe(1, in_slam(young[0][0], world, young[0][1])) is None
    assert clouds.merge == (2, 1, {0: pytest.approx(0.7 / s0, rel=0.02)})
    assert scales.on_merge(clouds.merge) == 0
    assert scales.current.estimate()[0] == pytest.approx(1.0 / 0.7, rel=0.02)


def test_a_young_map_merged_into_a_measured_one_keeps_the_measured_scale():
    world = room_points(seed=7)
    s0, young = 2.0, (planar(0.3, 0.2, 0.0, np.radians(60)), 0.7)
    clouds = MapClouds(BridgeConfig())
    scales = _measured_map_then_young_maps(clouds, world, s0, [young])
    # Map 1 merged into map 0, whose cloud had more points: no ratio is measured.
    assert clouds.observe(1, in_slam(planar(0.0, 0.0, 0.0, 0.0), world, s0)) == 0
    assert clouds.merge == (1, 0, {})
    scales.on_map_event(0, "switched")
    assert scales.on_merge(clouds.merge) is None
    assert scales.current.estimate() == (pytest.approx(0.5), pytest.approx(0.625), 5)


def test_a_merged_cloud_unlike_the_maps_last_one_gives_no_scale():
    # Map 0 had seen half the room; the merged cloud holds all of it: the distances between
    # points disagree at the quantiles, whatever scale is tried.
    world = room_points(seed=8)
    clouds = MapClouds(BridgeConfig())
    clouds.observe(0, world[world[:, 0] > 0] * 2.0)
    clouds.observe(1, world[:200] * 0.7 + 5.0)
    assert clouds.observe(0, world * 0.7 + 5.0) == 1
    assert clouds.merge == (0, 1, {})


def test_a_sparse_map_of_the_room_is_not_taken_to_hold_the_measured_one():
    # Maps 1 and 2 began after map 0 and hold a third of the room's points between them; a
    # random third of a room has the distances of the whole room. Map 2 merging into map 1 must
    # not carry map 0's samples over at the ratio of the two maps' sizes (random:27, stressed
    # ground: the scale ended 4.7 times off).
    world = room_points(seed=9)
    sparse = world[np.random.default_rng(3).random(len(world)) < 0.35]
    clouds = MapClouds(BridgeConfig())
    clouds.observe(0, world * 2.0)
    clouds.observe(1, sparse[:100] * 0.7 + 5.0)
    clouds.observe(2, sparse[100:] * 3.0 - 2.0)
    assert clouds.observe(2, sparse * 0.7 + 5.0) == 1
    assert clouds.merge == (2, 1, {2: pytest.approx(0.7 / 3.0, rel=0.05)})


def test_a_map_merged_into_a_frame_no_cloud_showed_goes_on_in_it_at_its_scale():
    # random:16 replayed, a ground robot scanning in place: young map 1 had a few points when
    # tracking came back to map 0; then SLAM merged map 0 into map 1, whose points it had
    # refined since. The cloud holds no known map's points where they were: the bridge read it
    # as map 0's, its scale 14 times off, and carried that on at the next merges.
    world = room_points(seed=10)
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    scales = MapScales()
    origin, s0 = planar(0.0, 0.0, 0.0, 0.0), 2.0
    scales.on_map_event(0, anchors.update(camera_in_slam(origin, origin, s0), 1.0 / s0, 1.0)[1])
    for _ in range(5):
        scales.current.add(1.0, 1.0 / s0)
    assert anchors.on_cloud(in_slam(origin, world, s0)) is None
    anchors.tracking_lost()
    anchors.expect_new_map()
    turned, s1 = planar(0.0, 0.0, 0.0, np.radians(60)), 0.7
    _, event = anchors.update(camera_in_slam(turned, turned, s1), 1.0 / s0, 2.0)
    scales.on_map_event(anchors.current.index, event)
    assert event == "new_map"
    young = world[:80]
    anchors.on_cloud(in_slam(turned, young, s1))
    anchors.tracking_lost()
    _, event = anchors.update(camera_in_slam(origin, origin, s0), 1.0 / s0, 3.0)
    scales.on_map_event(anchors.current.index, event)
    assert event == "switched" and anchors.current.index == 0
    assert anchors.on_cloud(in_slam(origin, world, s0)) is None
    # Merged into map 1: the pose, near the origin of both maps, barely moves.
    _, event = anchors.update(camera_in_slam(turned, turned, s1), 1.0 / s0, 4.0)
    assert event is None and anchors.current.index == 0
    refined = in_slam(turned, world, s1)
    refined[:80] += 0.05 * s1
    assert anchors.on_cloud(refined) is None
    assert anchors.merge == (0, 0, {0: pytest.approx(s1 / s0, rel=0.02)})
    assert scales.on_merge(anchors.merge) == 0
    value, _, n = scales.current.estimate()
    assert value == pytest.approx(1.0 / s1, rel=0.02) and n == 5
    # The map goes on where the robot is, at its new scale.
    anchors.rescale(value)
    base_before = anchors.last_base.copy()
    base, _ = anchors.update(camera_in_slam(turned, turned, s1), 1.0, 5.0)
    np.testing.assert_allclose(base, base_before, atol=1e-9)
    for k in range(1, 11):
        on = turned @ planar(0.1 * k, 0.0, 0.0, 0.0)
        base, event = anchors.update(camera_in_slam(turned, on, s1), 1.0, 5.0 + 0.1 * k)
        assert event is None and anchors.current.index == 0
    assert np.linalg.norm(base[:3, 3] - base_before[:3, 3]) == pytest.approx(1.0, rel=0.03)
    assert anchors.on_cloud(refined) is None and anchors.merge is None


def test_a_young_map_whose_points_slam_refined_is_no_merge():
    world = room_points(seed=11)
    clouds = MapClouds(BridgeConfig())
    clouds.observe(0, world * 2.0)
    young = world[:300] * 0.7 + 5.0
    clouds.observe(1, young)
    # Four in five of its points moved by 5 % of the map's size; more points triangulated.
    rng = np.random.default_rng(4)
    refined = young + (rng.random(len(young)) < 0.8)[:, None] * 0.05 * np.ptp(young, axis=0)
    assert clouds.observe(1, np.vstack([refined, world[300:400] * 0.7 + 5.0])) is None
    assert clouds.merge is None


def test_a_rescaled_map_is_reanchored_where_the_robot_is():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin, s = planar(0.0, 0.0, 0.0, 0.0), 2.0
    anchors.update(camera_in_slam(origin, origin, s), 1.0, 1.0)
    here = planar(1.0, 0.5, 0.0, 0.3)
    base_before, _ = anchors.update(camera_in_slam(origin, here, s), 1.0, 2.0)
    # The map is read at 1 m per unit, twice its true scale; set right, it stays under the robot.
    anchors.rescale(1.0 / s)
    base, event = anchors.update(camera_in_slam(origin, here, s), 1.0 / s, 3.0)
    assert event is None
    np.testing.assert_allclose(base, base_before, atol=1e-9)
    on = planar(2.0, 0.5, 0.0, 0.3)
    base, event = anchors.update(camera_in_slam(origin, on, s), 1.0 / s, 4.0)
    assert event is None and np.linalg.norm(base[:3, 3] - base_before[:3, 3]) == pytest.approx(1.0)
