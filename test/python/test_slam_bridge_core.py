"""The ROS-free core of slam_bridge: health, map anchoring, scale."""
import numpy as np
import pytest

from sparse_nav.slam_bridge import (LOST, NOT_INITIALIZED, OK, ORB_LOST, ORB_NOT_INITIALIZED,
                                    ORB_OK, BridgeConfig, DroneMoveScale, MapAnchors, MapScales,
                                    ScaleEstimator, StateTracker, odometry_camera_position)
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
    base, event = anchors.update(camera_in_slam(origin, origin, s), 1.0 / s)
    assert event == "first"
    np.testing.assert_allclose(base, np.eye(4), atol=1e-9)
    moved = origin @ planar(1.0, 0.5, 0.0, 0.3)
    base, event = anchors.update(camera_in_slam(origin, moved, s), 1.0 / s)
    assert event is None
    np.testing.assert_allclose(base[:3, 3], [1.0, 0.5, 0.0], atol=1e-9)
    assert yaw_of(base) == pytest.approx(0.3)


def test_new_map_continues_from_last_pose_and_merge_returns_to_old_anchor():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = planar(0.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, origin, 2.0), 0.5)
    last = planar(1.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, last, 2.0), 0.5)
    anchors.tracking_lost()
    anchors.expect_new_map()
    # A new SLAM map starts where the robot is, with another scale.
    new_origin = planar(1.2, 0.1, 0.0, 0.1)
    base, event = anchors.update(camera_in_slam(new_origin, new_origin, 5.0), 0.2)
    assert event == "new_map" and anchors.current.index == 1
    np.testing.assert_allclose(base[:3, 3], [1.0, 0.0, 0.0], atol=1e-9)
    # SLAM merges back: the pose jumps into the first map's frame and scale.
    back = planar(1.5, 0.2, 0.0, 0.2)
    base, event = anchors.update(camera_in_slam(origin, back, 2.0), 0.5)
    assert event == "switched" and anchors.current.index == 0
    np.testing.assert_allclose(base[:3, 3], [1.5, 0.2, 0.0], atol=1e-9)


def test_a_map_left_by_a_jump_while_tracking_is_never_picked_again():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = planar(0.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(origin, origin, 2.0), 0.5)
    anchors.update(camera_in_slam(origin, planar(1.0, 0.0, 0.0, 0.0), 2.0), 0.5)
    anchors.tracking_lost()
    anchors.expect_new_map()
    new_origin = planar(1.0, 0.0, 0.0, 0.0)
    anchors.update(camera_in_slam(new_origin, new_origin, 5.0), 0.2)
    anchors.update(camera_in_slam(new_origin, planar(3.0, 0.0, 0.0, 0.0), 5.0), 0.2)
    # While tracking, SLAM merges map 1 into map 0: the pose jumps into map 0's frame.
    _, event = anchors.update(camera_in_slam(origin, planar(3.0, 0.0, 0.0, 0.0), 2.0), 0.5)
    assert event == "switched" and anchors.current.index == 0
    assert anchors.anchors[1].retired and not anchors.anchors[0].retired
    # Lost, and back 0.6 m on in map 0's frame: map 1's anchor would read that pose 0.56 m
    # from the last one, nearer than map 0's own 0.6 m, yet it is map 0's.
    anchors.tracking_lost()
    base, event = anchors.update(camera_in_slam(origin, planar(3.6, 0.0, 0.0, 0.0), 2.0), 0.5)
    assert event == "relocalised" and anchors.current.index == 0
    np.testing.assert_allclose(base[:3, 3], [3.6, 0.0, 0.0], atol=1e-9)


def test_new_map_detected_without_hint_when_far_from_old_map():
    anchors = MapAnchors(BridgeConfig(relocalise_tolerance_m=1.0), MOUNT)
    origin = np.eye(4)
    anchors.update(camera_in_slam(origin, origin, 1.0), 1.0)
    for x in np.arange(0.2, 3.01, 0.2):
        _, event = anchors.update(camera_in_slam(origin, planar(x, 0, 0, 0), 1.0), 1.0)
        assert event is None
    anchors.tracking_lost()
    here = planar(3.1, 0, 0, 0)
    base, event = anchors.update(camera_in_slam(here, here, 4.0), 0.25)
    assert event == "new_map"
    np.testing.assert_allclose(base[:3, 3], [3.0, 0, 0], atol=1e-9)


def test_relocalisation_in_same_map_is_not_a_new_map():
    anchors = MapAnchors(BridgeConfig(), MOUNT)
    origin = np.eye(4)
    anchors.update(camera_in_slam(origin, origin, 1.0), 1.0)
    anchors.tracking_lost()
    _, event = anchors.update(camera_in_slam(origin, planar(0.2, 0, 0, 0), 1.0), 1.0)
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


def test_odometry_follows_the_camera_not_the_base():
    # Turning on the spot by 90 deg moves the camera 0.1 m ahead of the axis by 0.14 m, while
    # the base stays: SLAM sees the camera move, so the scale must compare camera positions.
    half = np.sqrt(0.5)
    before = odometry_camera_position((1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0), MOUNT)
    after = odometry_camera_position((1.0, 2.0, 0.0), (0.0, 0.0, half, half), MOUNT)
    assert before == pytest.approx([1.1, 2.0, 0.5])
    assert after == pytest.approx([1.0, 2.1, 0.5])
    assert np.linalg.norm(after - before) == pytest.approx(0.1 * np.sqrt(2.0))

