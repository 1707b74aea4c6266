#!/usr/bin/python3
"""rostest: after the seed 000 initial scan of one_room, the exit finder answers on the live cloud.

It checks the node's contract on the simulator's cloud (status, ranking, the latched exit, the room
outline against the true room) and logs how far the best candidates are from the door. Whether the
door wins is a rate, not a property of one run (one_room's recess shows as a slit about one
bearing wide; the live finder put it among the two best in 3 of 8 runs on an idle machine), so
it is measured over 200 rooms by bench/bench_exit_finder.py rather than asserted here.
"""
import threading
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PointStamped
from std_msgs.msg import Float64

from sparse_nav.msg import ExitCandidates, SlamScale
from sparse_nav.ros.conversions import transform_to_matrix
from sparse_nav.ros.robot_io import TelloClient
from sparse_nav.ros.sim_node import load_ros_world
from sparse_nav.scanning import initial_scan, to_tello_commands
from sparse_nav.srv import FindExit

HIT_MARGIN_M = 0.3   # the bench's hit rule: within half the door width plus this
TOP_K = 2


class ExitFinderTest(unittest.TestCase):
    def setUp(self):
        self.world = load_ros_world(rospy.get_param("~world"))
        self.limit_s = float(rospy.get_param("~sim_time_limit_s"))
        self.lock = threading.Lock()
        self.exits = []
        self.estimated_scale = None
        self.true_scale = None
        rospy.Subscriber("exit", PointStamped, self._on_exit, queue_size=5)
        rospy.Subscriber("slam/scale", SlamScale, self._on_scale, queue_size=1)
        rospy.Subscriber("ground_truth/slam_scale", Float64, self._on_true_scale, queue_size=1)
        self.drone = TelloClient()
        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(60.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)

    def _on_exit(self, msg):
        with self.lock:
            self.exits.append(msg)

    def _on_scale(self, msg):
        with self.lock:
            self.estimated_scale = msg.metres_per_unit

    def _on_true_scale(self, msg):
        with self.lock:
            self.true_scale = msg.data

    def _fly(self, commands):
        for command in commands:
            self.drone.send(command)
            if rospy.Time.now().to_sec() > self.limit_s:
                break
        rospy.sleep(3.0)

    def _to_truth(self, xy, scale_ratio):
        """A map point (x, y) in sim_world, with the bridge's scale error taken out: the map is
        metric only up to the scale estimate, and the test judges the finder, not the scale."""
        t = transform_to_matrix(self.tf_buffer.lookup_transform(
            "sim_world", "map", rospy.Time(0), rospy.Duration(5.0)).transform)
        return t[:2, :2] @ (scale_ratio * np.asarray(xy)) + t[:2, 3]

    def _check_from_the_robot(self, find):
        """Asked to look from the robot, which stands in the same room after the scan, the finder
        answers on that room (called last: its answer is published on exit too)."""
        from_robot = find(method="", viewpoint="robot").candidates
        self.assertIn(from_robot.status, (ExitCandidates.STATUS_OK, ExitCandidates.STATUS_NO_EXIT),
                      f"{from_robot.status}: {from_robot.reason}")
        self.assertGreaterEqual(len(from_robot.room_outline), 3)

    def _check_any_probability(self, find):
        """The conductor's last attempt: however unlikely the model rates them, the candidates of
        a scanned room are reported (the room has walls with gaps, so there are some)."""
        guess = find(method="", any_probability=True).candidates
        self.assertEqual(guess.status, ExitCandidates.STATUS_OK, guess.reason)
        self.assertGreaterEqual(len(guess.exits), 2, "more than the one likely candidate")
        self.assertTrue(all(a >= b for a, b in zip(guess.scores, guess.scores[1:])))

    def test_answer_on_the_scanned_room(self):
        while rospy.Time.now().is_zero() and not rospy.is_shutdown():
            rospy.sleep(0.05)
        rospy.wait_for_service("exit_finder/find_exit", 60.0)
        find = rospy.ServiceProxy("exit_finder/find_exit", FindExit)
        before = find(method="")
        self.assertFalse(before.success, "no exit before any scan")
        self.assertIn(before.candidates.status, (ExitCandidates.STATUS_NO_CLOUD,
                                                 ExitCandidates.STATUS_TOO_FEW_POINTS))
        self.assertEqual(len(before.candidates.exits), 0)
        unknown = find(method="", viewpoint="nowhere")
        self.assertFalse(unknown.success)
        self.assertEqual(unknown.candidates.status, ExitCandidates.STATUS_BAD_INPUT)
        self.assertIn("unknown viewpoint 'nowhere'", unknown.candidates.reason)

        rospy.sleep(1.0)
        self._fly(["command", "takeoff"] + to_tello_commands(initial_scan()))
        answer = find(method="")
        cand = answer.candidates
        self.assertIn(cand.status, (ExitCandidates.STATUS_OK, ExitCandidates.STATUS_NO_EXIT),
                      f"a room is found in the scanned cloud ({cand.status}: {cand.reason})")
        self.assertEqual(answer.success, cand.status == ExitCandidates.STATUS_OK)
        self.assertEqual(answer.success, len(cand.exits) > 0, "candidates exactly when ok")
        self.assertEqual(cand.header.frame_id, "map")
        self.assertEqual(len(cand.exits), len(cand.scores))
        self.assertTrue(all(a >= b for a, b in zip(cand.scores, cand.scores[1:])),
                        "candidates best first")
        self.assertGreaterEqual(len(cand.room_outline), 3, "a room outline")

        with self.lock:
            estimated_scale, true_scale = self.estimated_scale, self.true_scale
        self.assertIsNotNone(estimated_scale, "the bridge publishes its scale estimate")
        self.assertIsNotNone(true_scale, "the simulator publishes the true scale")
        scale_ratio = true_scale / estimated_scale

        # The outline is the finder's room: it must be one_room's main room (0..6 m x 0..5 m).
        outline = np.array([self._to_truth([p.x, p.y], scale_ratio) for p in cand.room_outline])
        # The area centroid: the outline's vertices crowd along jagged walls, so their mean can
        # sit a metre or more off the room's centre (0.3-1.7 m in recorded runs).
        x, y = outline[:, 0], outline[:, 1]
        x1, y1 = np.roll(x, -1), np.roll(y, -1)
        cross = x * y1 - x1 * y
        signed_area = 0.5 * cross.sum()
        area = abs(signed_area)
        centre = np.array([np.dot(x + x1, cross), np.dot(y + y1, cross)]) / (6.0 * signed_area)
        rospy.loginfo("exit finder test: %s, outline area %.1f m2 centred at (%.2f, %.2f)",
                      cand.status, area, centre[0], centre[1])
        self.assertLess(np.hypot(centre[0] - 3.0, centre[1] - 2.5), 1.0,
                        f"the outline is centred in the room ({centre[0]:.2f}, {centre[1]:.2f})")
        self.assertTrue(15.0 < area < 45.0, f"the outline has the room's size ({area:.1f} m2)")

        if not answer.success:
            self._check_any_probability(find)
            self._check_from_the_robot(find)
            return
        deadline = rospy.Time.now() + rospy.Duration(10.0)
        while rospy.Time.now() < deadline:
            with self.lock:
                if self.exits:
                    break
            rospy.sleep(0.1)
        with self.lock:
            exits = list(self.exits)
        self.assertTrue(exits, "the best exit is published on exit")
        best = exits[-1]
        self.assertEqual(best.header.frame_id, "map")
        self.assertAlmostEqual(best.point.x, cand.exits[0].x, places=6)
        self.assertAlmostEqual(best.point.y, cand.exits[0].y, places=6)
        door = self.world.exits[0]
        errors = [float(np.hypot(*(self._to_truth([p.x, p.y], scale_ratio)
                                   - (door["x"], door["y"]))))
                  for p in cand.exits[:TOP_K]]
        hit = min(errors) < door["width_m"] / 2.0 + HIT_MARGIN_M
        rospy.loginfo("exit finder test: the %d best exits are %s m from the door (%s)", TOP_K,
                      ", ".join(f"{e:.2f}" for e in errors), "hit" if hit else "miss")
        self._check_any_probability(find)
        self._check_from_the_robot(find)


if __name__ == "__main__":
    rospy.init_node("test_exit_finder")
    rostest.rosrun("sparse_nav", "exit_finder_sim", ExitFinderTest)
