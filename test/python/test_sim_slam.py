"""Emulated ORB-SLAM3 monocular behaviour: initialisation, scale, map points, loss, new maps,
merging, determinism and speed."""
import math
import time

import numpy as np
import pytest

from sparse_nav.sim import (SimConfig, Simulator, SlamOutput, TrackingState, load_world)
from sparse_nav.sim.world import segment_distances, world_from_dict

FRAME_S = 1.0 / 15.0
S = TrackingState


def _room(east_texture=80.0, start=(4.0, 2.0, 180.0)):
    """A 6 m x 5 m textured room; the east wall (x = 6) has its own texture density."""
    return world_from_dict({
        "ceiling_height_m": 2.5, "floor_texture_per_m2": 2, "ceiling_texture_per_m2": 1,
        "start": {"x": start[0], "y": start[1], "yaw_deg": start[2]},
        "walls": [{"points": [[0, 0], [6, 0], [6, 5], [0, 5]], "closed": True,
                   "texture_per_m2": 80, "segment_texture_per_m2": {1: east_texture}}],
        "exits": []}, source="test_room")


def _drive(sim, v, w, seconds, truth=None):
    """Hold a cmd_vel for a duration; returns the SlamOutput of every camera frame (and appends
    the true camera centre of each frame to ``truth`` when given)."""
    sim.set_cmd_vel(v, w)
    outs = []
    for _ in range(int(round(seconds / FRAME_S))):
        sim.step(FRAME_S)
        outs.append(sim.slam_output())
        if truth is not None:
            truth.append(sim.true_camera_pose()[:3, 3].copy())
    return outs


def _states(outs):
    return [o.state for o in outs]


def _surface_error(world, points_world):
    """Distance (m) of each world point to the nearest wall, box, floor or ceiling surface."""
    segs = world.obstacle_segments()[0]
    d_wall = np.array([segment_distances(p[:2], segs).min() for p in points_world])
    d_floor = np.abs(points_world[:, 2])
    d_ceiling = np.abs(points_world[:, 2] - world.ceiling_height_m)
    return np.minimum(d_wall, np.minimum(d_floor, d_ceiling))


def _assert_on_surfaces(world, points_world, camera_xyz):
    """Map points lie near true surfaces: a small median error, absolute and relative to
    their distance from the camera (monocular depth error grows with depth)."""
    err = _surface_error(world, points_world)
    dist = np.linalg.norm(points_world - camera_xyz, axis=1)
    assert np.median(err) < 0.25
    assert np.median(err / dist) < 0.06
    return err


def _slam_to_world_by_truth(sim, points_slam):
    """Undo the SLAM frame with the ground truth: p_w = T_world_slam * (p_slam * m_per_unit)."""
    t = sim.slam_map_origin_world()
    p = np.asarray(points_slam, dtype=float) * sim.true_slam_scale()
    return p @ t[:3, :3].T + t[:3, 3]


# -- initialisation -----------------------------------------------------------------------------

def test_output_is_none_until_the_first_frame_then_new_each_frame():
    sim = Simulator(load_world("one_room"), SimConfig())
    assert sim.slam_output() is None
    sim.step(0.03)
    assert sim.slam_output() is None
    sim.step(0.04)
    first = sim.slam_output()
    assert isinstance(first, SlamOutput) and first.state == S.NOT_INITIALIZED
    assert first.T_slam_camera is None and first.all_points.shape == (0, 3)
    sim.step(FRAME_S)
    assert sim.slam_output() is not first
    assert sim.slam_output().stamp_s == pytest.approx(2 * FRAME_S)


def test_pure_rotation_does_not_initialise():
    sim = Simulator(load_world("one_room"), SimConfig(seed=2))
    outs = _drive(sim, 0.0, 0.6, 2 * 2 * math.pi / 0.6)   # two full turns in place
    assert set(_states(outs)) == {S.NOT_INITIALIZED}
    assert all(len(o.all_points) == 0 for o in outs)
    assert math.isnan(sim.true_slam_scale()) and sim.slam_map_origin_world() is None


def test_drone_rotation_after_loss_does_not_initialise_a_new_map():
    sim = Simulator(load_world("one_room"), SimConfig(robot="drone", seed=1,
                                                      force_loss_at_s=[4.0]))
    sim.drone_command("takeoff")
    sim.step(4.2)
    assert sim.slam_output().map_id == 1          # the takeoff climb initialised map 0
    for _ in range(4):
        sim.drone_command("cw 90")
    outs = []
    for _ in range(int(6.0 / FRAME_S)):
        sim.step(FRAME_S)
        outs.append(sim.slam_output())
    assert [r for _, r in sim.pop_drone_responses()] == ["ok"] * 5
    assert set(_states(outs)) == {S.NOT_INITIALIZED}
    assert {o.map_id for o in outs} == {1}


def test_translation_initialises_with_a_pose_and_points():
    sim = Simulator(_room(), SimConfig(seed=0))
    outs = _drive(sim, -0.3, 0.0, 2.0)
    assert outs[0].state == S.NOT_INITIALIZED
    ok = [o for o in outs if o.state == S.OK]
    assert ok, "backing up 0.6 m gives the baseline to initialise"
    first = ok[0]
    assert first.map_id == 0 and first.T_slam_camera.shape == (4, 4)
    # The SLAM world is the reference camera's optical frame: the pose starts near identity.
    assert np.allclose(first.T_slam_camera[:3, :3], np.eye(3), atol=0.02)
    last = outs[-1]
    assert last.all_points.dtype == np.float32 and last.all_points.shape[1] == 3
    assert len(last.all_points) > 300
    assert last.n_tracked == len(last.tracked_points) > 100
    assert not last.all_points.flags.writeable


# -- scale and map quality ----------------------------------------------------------------------

def test_scale_is_not_one_and_differs_per_run():
    scales = []
    for seed in range(4):
        sim = Simulator(_room(), SimConfig(seed=seed))
        _drive(sim, -0.3, 0.0, 2.0)
        scales.append(sim.true_slam_scale())
    assert all(0.2 <= s <= 5.0 for s in scales)
    assert len({round(s, 6) for s in scales}) == 4
    assert sum(abs(math.log(s)) > 0.05 for s in scales) >= 3


def test_slam_positions_and_points_scale_with_the_true_scale():
    world = _room()
    sim = Simulator(world, SimConfig(seed=4))
    truth = []
    outs = _drive(sim, -0.3, 0.0, 3.6, truth)
    i0 = next(i for i, o in enumerate(outs) if o.state == S.OK)
    first, last = outs[i0], outs[-1]
    assert last.state == S.OK
    m_per_unit = sim.true_slam_scale()
    assert abs(math.log(m_per_unit)) > 0.05
    slam_dist = np.linalg.norm(last.T_slam_camera[:3, 3] - first.T_slam_camera[:3, 3])
    true_dist = np.linalg.norm(truth[-1] - truth[i0])
    assert true_dist > 0.5
    assert slam_dist * m_per_unit == pytest.approx(true_dist, rel=0.05)
    # Map points, brought back to the world with the true origin and scale, lie on surfaces.
    err = _assert_on_surfaces(world, _slam_to_world_by_truth(sim, last.all_points), truth[-1])
    # With the scale ignored they would not: the scale is real.
    t = sim.slam_map_origin_world()
    unscaled = last.all_points.astype(float) @ t[:3, :3].T + t[:3, 3]
    assert np.median(_surface_error(world, unscaled)) > 3 * np.median(err)
    # A few spurious points (outliers) exist, but few.
    assert 0.002 < np.mean(err > 1.0) < 0.08


def test_scale_drifts_with_distance_travelled():
    sim = Simulator(_room(start=(4.5, 2.5, 180.0)), SimConfig(seed=3))
    _drive(sim, -0.3, 0.0, 1.5)
    assert sim.slam_output().state == S.OK
    s0 = sim.true_slam_scale()
    for _ in range(5):                                   # 5 x 2 x 1.6 m = 16 m
        assert S.OK in _states(_drive(sim, 0.8, 0.0, 2.0))
        _drive(sim, -0.8, 0.0, 2.0)
    assert sim.slam_output().state == S.OK and sim.slam_output().map_id == 0
    change = abs(math.log(sim.true_slam_scale() / s0))
    assert 0.002 < change < 0.3


# -- tracking loss, new maps, merging -----------------------------------------------------------

def _arc_to_face_east(sim):
    """Initialise facing west, then an arc (translation + turn) to face east, 1.5 m from x=6."""
    _drive(sim, -0.3, 0.0, 1.5)
    assert sim.slam_output().state == S.OK
    return _drive(sim, 0.15, 0.4, math.pi / 0.4)


def test_facing_a_blank_wall_loses_tracking():
    textured = Simulator(_room(east_texture=80.0, start=(4.0, 2.5, 180.0)), SimConfig(seed=3))
    outs = _arc_to_face_east(textured)
    assert set(_states(outs)) == {S.OK}
    assert textured.tracking_losses == 0

    blank = Simulator(_room(east_texture=0.0, start=(4.0, 2.5, 180.0)), SimConfig(seed=3))
    outs = _arc_to_face_east(blank) + _drive(blank, 0.0, 0.0, 4.0)
    states = _states(outs)
    assert S.RECENTLY_LOST in states and S.LOST in states
    assert blank.tracking_losses == 1
    assert blank.last_loss_cause.endswith("features in view")
    first_recent = states.index(S.RECENTLY_LOST)
    first_lost = states.index(S.LOST)
    lost_after_s = outs[first_lost].stamp_s - outs[first_recent].stamp_s
    assert 2.9 <= lost_after_s <= 3.2                     # RECENTLY_LOST for ~3 s
    assert all(o.T_slam_camera is None for o in outs[first_recent:])
    # The atlas then starts a new, empty map, waiting for baseline.
    assert outs[-1].state == S.NOT_INITIALIZED and outs[-1].map_id == 1
    assert len(outs[-1].all_points) == 0


def test_fast_turn_loses_tracking_and_relocalises_in_the_same_map():
    sim = Simulator(_room(), SimConfig(seed=5, slam_max_turn_rate_rad_s=0.8))
    _drive(sim, -0.3, 0.0, 1.5)
    _drive(sim, 0.0, 0.0, 3.0)   # past slam_young_map_s: a loss may relocalise
    assert sim.slam_output().state == S.OK
    fast = _drive(sim, 0.0, 1.2, 0.2)
    assert S.RECENTLY_LOST in _states(fast)
    assert sim.last_loss_cause.startswith("turn at")
    calm = _drive(sim, 0.0, 0.0, 0.5)
    assert calm[-1].state == S.OK and calm[-1].map_id == 0
    assert sim.tracking_losses == 1


def test_a_young_map_is_lost_outright():
    sim = Simulator(_room(), SimConfig(seed=5, slam_max_turn_rate_rad_s=0.8))
    outs = _drive(sim, -0.3, 0.0, 1.5)
    assert outs[-1].state == S.OK
    initialised_s = next(o.stamp_s for o in outs if o.state == S.OK)
    assert outs[-1].stamp_s - initialised_s < SimConfig().slam_young_map_s
    fast = _drive(sim, 0.0, 1.2, 0.2)
    assert S.RECENTLY_LOST not in _states(fast) and S.LOST in _states(fast)
    assert sim.tracking_losses == 1 and sim.last_loss_cause.startswith("turn at")
    assert sim.slam_output().map_id == 1


@pytest.mark.parametrize("pose_min_tracked, first_state", [(10, S.RECENTLY_LOST), (1000, S.LOST)])
def test_a_young_map_whose_pose_is_still_found_is_only_recently_lost(pose_min_tracked,
                                                                      first_state):
    # Every frame after initialisation tracks too few points for slam_min_tracked; the pose is
    # found (10 or more) in one case and not in the other.
    sim = Simulator(_room(), SimConfig(seed=5, slam_min_tracked=1000,
                                       slam_pose_min_tracked=pose_min_tracked))
    outs = _drive(sim, -0.3, 0.0, 1.5)
    after = [o.state for o in outs if o.state != S.NOT_INITIALIZED][1:]
    assert after and after[0] == first_state


def test_force_loss_at_s():
    sim = Simulator(_room(), SimConfig(seed=1, force_loss_at_s=[2.5]))
    outs = _drive(sim, -0.3, 0.0, 3.0)
    lost = [o for o in outs if o.state == S.LOST]
    assert len(lost) == 1 and 2.5 <= lost[0].stamp_s < 2.5 + FRAME_S + 1e-9
    before = [o for o in outs if o.stamp_s < 2.5]
    assert before[-1].state == S.OK
    assert sim.tracking_losses == 1 and sim.last_loss_cause == "forced"
    after = [o for o in outs if o.stamp_s > lost[0].stamp_s]
    assert after[0].state == S.NOT_INITIALIZED and after[0].map_id == 1


def test_a_loss_forced_before_the_map_initialises_waits_for_tracking():
    sim = Simulator(_room(), SimConfig(seed=1, force_loss_at_s=[0.05]))
    outs = _drive(sim, -0.3, 0.0, 3.0)
    first_ok = next(o for o in outs if o.state == S.OK)
    assert first_ok.stamp_s > 0.05 + FRAME_S  # not initialised at the forced time
    lost = [o for o in outs if o.state == S.LOST]
    assert lost and lost[0].stamp_s <= first_ok.stamp_s + 2 * FRAME_S
    assert sim.tracking_losses == 1


def test_loss_starts_a_new_map_that_merges_back_on_revisit():
    world = _room(start=(4.0, 2.0, 180.0))
    sim = Simulator(world, SimConfig(seed=0, force_loss_at_s=[2.0]))
    outs = _drive(sim, -0.3, 0.0, 1.9)                   # map 0 facing west
    assert outs[-1].state == S.OK and outs[-1].map_id == 0
    map0_scale = sim.true_slam_scale()
    map0_origin = sim.slam_map_origin_world()
    outs += _drive(sim, -0.3, 0.0, 0.3)                  # forced loss at 2 s
    assert outs[-1].map_id == 1 and outs[-1].state == S.NOT_INITIALIZED
    map0_points = max(len(o.all_points) for o in outs if o.map_id == 0)
    outs = _drive(sim, 0.0, -0.5, math.pi / 2 / 0.5)     # turn in place to face north
    assert set(_states(outs)) == {S.NOT_INITIALIZED}
    outs = _drive(sim, 0.3, 0.0, 1.5)                    # baseline: a new map, facing north
    new = [o for o in outs if o.state == S.OK]
    assert new and all(o.map_id == 1 for o in new)
    new_scale = sim.true_slam_scale()
    new_origin = sim.slam_map_origin_world()
    # The new map's origin is its own reference camera: turned towards north, away from map 0's.
    assert new_origin[1, 2] > 0.8 and np.dot(new_origin[:3, 2], map0_origin[:3, 2]) < 0.5
    outs = _drive(sim, 0.0, 0.0, 2.0) + _drive(sim, 0.15, 0.4, math.pi / 2 / 0.4) \
        + _drive(sim, 0.0, 0.0, 1.0)                     # wait, then arc back to face west
    merged = [o for o in outs if o.merged]
    assert len(merged) == 1
    assert merged[0].map_id == 0 and merged[0].state == S.OK
    assert all(o.map_id == 0 for o in outs if o.stamp_s >= merged[0].stamp_s)
    assert len(outs[-1].all_points) > map0_points
    merged_scale = sim.true_slam_scale()
    assert abs(math.log(new_scale / map0_scale)) > 0.05   # the new map had its own scale
    assert merged_scale == pytest.approx(map0_scale, rel=0.05)   # map 0's scale is back
    np.testing.assert_allclose(sim.slam_map_origin_world(), map0_origin)
    # After the merge the map is expressed in map 0's frame: points lie on the walls again.
    _assert_on_surfaces(world, sim.slam_to_world(outs[-1].all_points),
                        sim.true_camera_pose()[:3, 3])
    assert sim.tracking_losses == 1


# -- determinism and speed ----------------------------------------------------------------------

def _scripted_run(seed):
    sim = Simulator(load_world("one_room"), SimConfig(seed=seed))
    _drive(sim, 0.3, 0.2, 3.0)
    out = sim.slam_output()
    return out.state, out.map_id, out.all_points.copy(), sim.true_base_pose()


def test_same_seed_same_run_different_seed_different_run():
    a, b, c = _scripted_run(11), _scripted_run(11), _scripted_run(12)
    assert a[0] == b[0] == S.OK and a[1] == b[1]
    np.testing.assert_array_equal(a[2], b[2])
    assert a[3] == b[3]
    assert a[2].shape != c[2].shape or not np.array_equal(a[2], c[2])


def test_camera_frame_is_fast_in_the_large_hall():
    sim = Simulator(load_world("large_hall"), SimConfig(seed=0))
    assert len(sim.features) > 10000
    sim.set_cmd_vel(0.3, 0.1)
    sim.step(0.5)
    start = time.perf_counter()
    n = 0
    while n < 30:
        sim.step(FRAME_S)
        n += 1
    per_frame = (time.perf_counter() - start) / n
    assert per_frame < 0.03, f"{per_frame * 1000:.1f} ms per camera frame"


# -- a seed 000 scan, end to end ----------------------------------------------------------------

def _cloud_statistics(points):
    """Scale-free statistics of a cloud seen from its SLAM origin (as shared/tools/cloud_stats.py
    computes them; ORB convention, up = -y): far_frac, outlier_frac, wall_sharpness."""
    flat = points[:, [0, 2]].astype(float)
    r = np.hypot(flat[:, 0], flat[:, 1])
    rr = r / np.median(r)
    sector = (np.degrees(np.arctan2(flat[:, 0], flat[:, 1])) % 360 // 10).astype(int)
    sharp = []
    for k in range(36):
        s = rr[sector == k]
        if len(s) > 20:
            q1, q2, q3 = np.percentile(s, [25, 50, 75])
            sharp.append((q3 - q1) / q2)
    return float(np.mean(rr > 2)), float(np.mean(rr > 5)), float(np.median(sharp))


def test_seed_000_initial_scan_maps_the_room_like_a_real_cloud():
    world = load_world("one_room")
    sim = Simulator(world, SimConfig(robot="drone", seed=0))
    script = ["command", "takeoff"] + 12 * ["back 30", "right 30", "cw 20", "ccw 20", "left 30",
                                            "forward 30", "cw 30"]
    for text in script:
        sim.drone_command(text)
    answers = []
    while len(answers) < len(script) and sim.time_s < 120.0:
        sim.step(0.1)
        answers += sim.pop_drone_responses()
    assert [r for _, r in answers] == ["ok"] * len(script)
    out = sim.slam_output()
    assert out.state == S.OK and out.map_id == 0 and sim.tracking_losses == 0
    assert 2500 < len(out.all_points) < 12000          # real clouds: 2.8k-11.7k (10-90 %)
    pts = sim.slam_to_world(out.all_points)
    _assert_on_surfaces(world, pts, sim.true_camera_pose()[:3, 3])
    # Every wall of the room carries map points: a full turn was scanned.
    for x1, y1, x2, y2 in ([0, 0, 6, 0], [6, 0, 6, 5], [0, 5, 5, 5], [0, 0, 0, 5]):
        d = _segment_distances_many(pts[:, :2], np.array([x1, y1, x2, y2], dtype=float))
        assert np.count_nonzero(d < 0.3) > 100
    # The real clouds' 10-90 % band (data/orbslam_rooms, shared/tools/cloud_stats.py).
    far_frac, outlier_frac, sharpness = _cloud_statistics(out.all_points)
    assert 0.0007 <= far_frac <= 0.19
    assert outlier_frac <= 0.024
    assert 0.098 <= sharpness <= 0.47


def _segment_distances_many(points, seg):
    """Distances (N,) in metres from 2D points (N, 2) to one segment (4,)."""
    a, b = seg[:2], seg[2:]
    t = np.clip((points - a) @ (b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * (b - a)), axis=1)


def test_forced_loss_blinds_the_camera_for_its_duration():
    """With force_loss_duration_s the loss lasts: no relocalisation or new map while blind."""
    from sparse_nav.sim import SimConfig, Simulator, load_world
    sim = Simulator(load_world("one_room"), SimConfig(robot="drone", force_loss_at_s=[6.0],
                                                      force_loss_duration_s=2.0))
    for command in ["takeoff", "back 50", "forward 50", "back 50", "forward 50"]:
        sim.drone_command(command)
    states = []
    while sim.time_s < 10.0:
        sim.step(0.02)
        out = sim.slam_output()
        if out is not None and (not states or states[-1][0] != out.stamp_s):
            states.append((out.stamp_s, out.state))
    blind = [state for stamp, state in states if 6.05 < stamp < 7.95]
    assert blind and all(state == 4 for state in blind), "LOST for the whole blind period"
