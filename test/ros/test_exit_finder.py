#!/usr/bin/python3
"""rostest: after the seed 000 initial scan of one_room, the exit finder finds its door."""
import threading
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PointStamped
from std_msgs.msg import Float64

from drone_driver import DroneDriver
from sparse_nav.msg import ExitCandidates, SlamScale
from sparse_nav.ros.conversions import transform_to_matrix
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
        self.drone = DroneDriver()
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
            self.drone.command(command)
            if rospy.Time.now().to_sec() > self.limit_s:
                break
        rospy.sleep(3.0)

    def _to_truth(self, xy, scale_ratio):
        """A map point (x, y) in sim_world, with the bridge's scale error taken out: the map is
        metric only up to the scale estimate, and the test judges the finder, not the scale."""
        t = transform_to_matrix(self.tf_buffer.lookup_transform(
            "sim_world", "map", rospy.Time(0), rospy.Duration(5.0)).transform)
        return t[:2, :2] @ (scale_ratio * np.asarray(xy)) + t[:2, 3]

    def test_exit_at_the_door(self):
        while rospy.Time.now().is_zero() and not rospy.is_shutdown():
            rospy.sleep(0.05)
        rospy.wait_for_service("exit_finder/find_exit", 60.0)
        find = rospy.ServiceProxy("exit_finder/find_exit", FindExit)
        before = find(method="")
        self.assertFalse(before.success, "no exit before any scan")
        self.assertIn(before.candidates.status, (ExitCandidates.STATUS_NO_CLOUD,
                                                 ExitCandidates.STATUS_TOO_FEW_POINTS))
        self.assertEqual(len(before.candidates.exits), 0)

        rospy.sleep(1.0)
        self._fly(["command", "takeoff"] + to_tello_commands(initial_scan()))
        answer = find(method="")
        if answer.candidates.status == ExitCandidates.STATUS_NO_EXIT:
            # From the start one_room's recess can show as a slit one bearing wide, which the
            # finder misses in about one run in four; the mission then scans again, and so
            # does the test.
            self._fly(to_tello_commands(initial_scan()))
            answer = find(method="")
        cand = answer.candidates
        self.assertTrue(answer.success, f"an exit is found ({cand.status}: {cand.reason})")
        self.assertEqual(cand.header.frame_id, "map")
        self.assertEqual(len(cand.exits), len(cand.scores))
        self.assertTrue(all(a >= b for a, b in zip(cand.scores, cand.scores[1:])),
                        "candidates best first")
        self.assertGreaterEqual(len(cand.room_outline), 3, "a room outline")

        deadline = rospy.Time.now() + rospy.Duration(10.0)
        while rospy.Time.now() < deadline:
            with self.lock:
                if self.exits:
                    break
            rospy.sleep(0.1)
        with self.lock:
            exits = list(self.exits)
            estimated_scale, true_scale = self.estimated_scale, self.true_scale
        self.assertTrue(exits, "the best exit is published on exit")
        best = exits[-1]
        self.assertEqual(best.header.frame_id, "map")
        self.assertAlmostEqual(best.point.x, cand.exits[0].x, places=6)
        self.assertAlmostEqual(best.point.y, cand.exits[0].y, places=6)

        self.assertIsNotNone(estimated_scale, "the bridge publishes its scale estimate")
        self.assertIsNotNone(true_scale, "the simulator publishes the true scale")
        scale_ratio = true_scale / estimated_scale
        door = self.world.exits[0]
        errors = []
        for p in cand.exits[:TOP_K]:
            found = self._to_truth([p.x, p.y], scale_ratio)
            errors.append(float(np.hypot(found[0] - door["x"], found[1] - door["y"])))
        # On this room the door wins in most runs; in the others a gap between the two boxes
        # along the west wall (the wall seen behind it) scores a little higher. The monocular
        # map differs from run to run with the timing, so the test asks for the door among the
        # two best, and the bench (bench/bench_exit_finder.py) measures the best alone.
        self.assertLess(min(errors), door["width_m"] / 2.0 + HIT_MARGIN_M,
                        f"one of the {TOP_K} best exits is at the door ({door['x']}, "
                        f"{door['y']}): errors {', '.join(f'{e:.2f}' for e in errors)} m")


if __name__ == "__main__":
    rospy.init_node("test_exit_finder")
    rostest.rosrun("sparse_nav", "exit_finder_sim", ExitFinderTest)
