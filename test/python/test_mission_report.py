"""Mission judgement against ground truth."""
import numpy as np
import pytest

from sparse_nav.mission_report import (LookArounds, MapAlignments, ScaleByMap, evaluate,
                                       exit_error_m, left_the_room, path_length_m,
                                       mission_end_s, planar_alignment, tally_look_arounds,
                                       tracking_losses)
from sparse_nav.sim.world import load_world
from sparse_nav.slam_bridge import LOST, NEW_MAP, OK
from sparse_nav.transforms import make_transform, planar, quaternion_to_matrix


def test_success_needs_done_and_the_robot_outside():
    world = load_world("one_room")  # 6 x 5 m room, exit at (5.5, 5.8) at the end of a recess
    inside = [(3.0, 2.5), (5.5, 5.0)]
    outside = inside + [(5.5, 6.6)]
    assert left_the_room(world, (5.5, 6.6)) and not left_the_room(world, (5.5, 5.5))
    assert evaluate(world, "done", outside, (5.4, 5.8))["success"]
    assert not evaluate(world, "done", inside, (5.4, 5.8))["success"]
    assert not evaluate(world, "gave_up", outside, None)["success"]
    report = evaluate(world, "done", outside, (5.4, 5.8))
    assert report["path_length_m"] == pytest.approx(path_length_m(outside), abs=1e-3)
    assert report["exit_error_m"] == pytest.approx(0.1)
    assert evaluate(world, "done", [], None) == {"success": False, "left_the_room": False,
                                                 "path_length_m": 0.0, "exit_error_m": None}


def test_each_look_around_is_kept_with_its_verdict_and_where_the_robot_truly_stood():
    looks = LookArounds(load_world("one_room"))
    looks.observe(10.0, "pass_through", "at the exit: pass through", (5.5, 5.5))
    looks.observe(12.0, "look_around", "passed through the exit: look around", (5.5, 6.6))
    # A loss while looking keeps the phase: no verdict yet.
    looks.observe(13.0, "look_around", "SLAM tracking lost: the scan retries", (5.5, 6.6))
    looks.observe(20.0, "find_exit", "another room beyond the exit", (5.5, 6.6))
    looks.observe(30.0, "look_around", "passed through the exit: look around", (5.5, 5.5))
    looks.observe(31.0, "done", "passed through the exit", (5.5, 5.5))
    looks.observe(32.0, "look_around", "look around", (5.5, 6.6))
    looks.observe(33.0, "done", "no pose", None)
    looks.observe(34.0, "look_around", "look around", (5.5, 5.5))
    looks.observe(35.0, "step_out", "passed through the exit: step out", (5.5, 5.5))
    assert [(r["sim_time_s"], r["then"], r["truly_outside"]) for r in looks.records] == [
        (20.0, "find_exit", True), (31.0, "done", False), (35.0, "step_out", False)]
    assert looks.records[0]["reason"] == "another room beyond the exit"
    assert looks.records[0]["true_xy"] == [5.5, 6.6]
    # Stepping out follows a look that said out.
    assert tally_look_arounds(looks.records + [{"then": "done", "truly_outside": True}]) == {
        "out_truly_outside": 1, "out_truly_inside": 2, "inside_truly_outside": 1,
        "inside_truly_inside": 0}


def test_lengths_and_errors():
    assert path_length_m([(0, 0), (3, 4), (3, 5)]) == pytest.approx(6.0)
    assert path_length_m([(1, 1)]) == 0.0
    assert exit_error_m(load_world("one_room"), None) is None


def test_the_true_scale_is_the_one_of_the_map_tracked_in_not_of_one_begun_while_lost():
    scales = ScaleByMap()
    scales.on_truth(2.0)  # before any tracking: no map the bridge estimates for
    scales.on_estimate(0, 1.0, 0.0, 0, "parameter")
    assert scales.figures(0)["true_metres_per_unit"] is None
    scales.on_state(True, 0)
    scales.on_truth(0.48)
    scales.on_estimate(0, 0.5, 0.9, 40, "odometry")
    scales.on_state(False, 0)
    scales.on_truth(2.7)  # a new map the simulator began while the bridge was lost (a landing)
    final = scales.figures(scales.last_map)
    assert final["true_metres_per_unit"] == 0.48
    assert final["relative_error"] == pytest.approx(0.02 / 0.48)
    scales.on_state(True, 1)  # the bridge names the new map: its truth counts from now on
    scales.on_truth(2.7)
    scales.on_truth(float("nan"))
    assert scales.figures(1)["true_metres_per_unit"] == 2.7
    assert scales.figures(0)["true_metres_per_unit"] == 0.48


def test_each_map_keeps_its_own_scale_and_the_most_measured_one_is_reported():
    scales = ScaleByMap()
    assert scales.most_measured() is None
    scales.on_state(True, 0)
    scales.on_truth(0.5)
    scales.on_estimate(0, 0.52, 0.9, 50, "odometry")
    # A new map's prior can arrive before the state that names it: it names its own map.
    scales.on_estimate(1, 0.52, 0.0, 0, "parameter")
    assert scales.figures(0)["samples"] == 50
    scales.on_state(True, 1)
    scales.on_truth(0.05)  # begun outside after a loss, at a tenth of the room map's unit
    final = scales.figures(scales.last_map)
    assert (final["map_index"], final["samples"]) == (1, 0)
    assert final["relative_error"] == pytest.approx(9.4)
    best = scales.most_measured()
    assert (best["map_index"], best["samples"]) == (0, 50)
    assert best["relative_error"] == pytest.approx(0.04)
    assert set(scales.by_map()) == {"0", "1"}
    scales.on_estimate(1, 0.05, 0.9, 50, "odometry")  # as measured as map 0: the final wins
    assert scales.most_measured()["map_index"] == 1


def test_the_planar_alignment_puts_the_estimate_on_the_truth_and_ignores_tilt():
    truth = planar(4.0, -2.0, 1.1, 0.3)
    tilt = make_transform(quaternion_to_matrix([np.sin(0.05), 0.0, 0.0, np.cos(0.05)]), [0, 0, 0])
    estimate = planar(1.0, 1.0, 0.9, -0.4) @ tilt
    t = planar_alignment(truth, estimate)
    assert np.allclose(t[:2, :2] @ [1.0, 1.0] + t[:2, 3], [4.0, -2.0])
    assert np.arctan2(t[1, 0], t[0, 0]) == pytest.approx(0.7)
    assert np.allclose(t[2], [0, 0, 1, 0])


def test_each_slam_map_keeps_its_own_alignment_and_a_switch_settles_first():
    alignments = MapAlignments(settle_s=1.0)
    truth = planar(2.0, 1.0, 0.0, 0.5)
    assert alignments.get(0) is None
    alignments.add(0.0, True, 0, truth, planar(0.0, 0.0, 0.0, 0.0))
    assert alignments.get(0) is None  # the first second of a map is not sampled
    alignments.add(1.5, True, 0, truth, planar(0.0, 0.0, 0.0, 0.0))
    first = alignments.get(0)
    assert np.allclose(first, truth)
    alignments.add(2.0, False, 0, None, None)
    alignments.add(3.0, True, 1, truth, planar(1.0, 0.0, 0.0, 0.5))  # a new map, anchored anew
    assert alignments.get(1) is first  # not yet settled: the newest of any map
    alignments.add(4.5, True, 1, truth, planar(1.0, 0.0, 0.0, 0.5))
    assert np.allclose(alignments.get(1), planar(1.0, 1.0, 0.0, 0.0))  # same heading, 1 m off
    assert alignments.get(0) is first  # merged back into map 0: its own alignment again


def test_the_biggest_slam_map_with_its_own_alignment_is_the_one_drawn():
    alignments = MapAlignments(settle_s=0.0)
    assert alignments.biggest_aligned({0: 5000}) is None
    alignments.add(0.0, True, 0, planar(2.0, 1.0, 0.0, 0.5), planar(0.0, 0.0, 0.0, 0.0))
    alignments.add(1.0, True, 1, planar(2.0, 1.0, 0.0, 0.5), planar(1.0, 0.0, 0.0, 0.5))
    assert alignments.biggest_aligned({0: 5000, 1: 218}) == 0  # the room's, not outside's
    assert alignments.biggest_aligned({0: 100, 1: 218}) == 1
    assert alignments.biggest_aligned({2: 9000, 1: 218}) == 1  # map 2 never aligned
    assert alignments.biggest_aligned({}) is None


def test_a_loss_counts_once_however_often_lost_is_said():
    # LOST, then LOST again once SLAM gives up its map, then a new map: one loss.
    assert tracking_losses([OK, LOST, LOST, NEW_MAP, OK, LOST, OK]) == 2
    assert tracking_losses([LOST]) == 1 and tracking_losses([]) == 0


def test_a_mission_ends_when_it_first_reaches_done_and_only_counts_within_the_time_limit():
    world = load_world("one_room")
    outside = [(3.0, 2.5), (5.5, 5.0), (5.5, 6.6)]
    phases = [(1.0, "initial_scan"), (590.0, "look_around"), (601.5, "done"), (603.0, "done")]
    assert mission_end_s(phases) == 601.5
    assert mission_end_s(phases[:2]) is None, "still running at the limit"
    assert mission_end_s([]) is None
    assert not evaluate(world, "done", outside, None, 601.5, 600.0)["success"]
    assert evaluate(world, "done", outside, None, 600.0, 600.0)["success"]
    assert not evaluate(world, "done", outside, None, None, 600.0)["success"], "never done"
    assert evaluate(world, "done", outside, None)["success"], "no limit given"
