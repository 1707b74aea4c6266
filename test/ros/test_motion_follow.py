#!/usr/bin/python3
"""rostest: the simulated ground robot follows a hand-given L-shaped path and stops at its end."""
import math
import os
import sys
import unittest

import numpy as np
import rospy
import rostest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from motion_harness import MotionHarness  # noqa: E402
from sparse_nav.msg import MotionStatus  # noqa: E402


class MotionFollowTest(unittest.TestCase):
    def test_follows_path_to_its_end(self):
        h = MotionHarness()
        h.wait_for_clock()
        self.assertTrue(h.initialise_slam(), "SLAM did not initialise with a measured scale")
        path = h.relative_path(1.0, 0.6)
        start_truth = h.true_xy()

        # Bad paths are refused: the robot stays, the node keeps running.
        nan_path = [p.copy() for p in path]
        nan_path[2][0] = float("nan")
        for _ in range(3):
            h.publish_path(nan_path)
            h.publish_path(path, frame="odom")
            rospy.sleep(0.5)
        self.assertEqual(h.latest_status().state, MotionStatus.IDLE, h.latest_status().reason)
        self.assertLess(float(np.linalg.norm(h.true_xy() - start_truth)), 0.02)
        deadline = rospy.Time.now().to_sec() + 120.0
        status = None
        while rospy.Time.now().to_sec() < deadline and not rospy.is_shutdown():
            h.publish_path(path)               # like the navigator, at 2 Hz
            rospy.sleep(0.5)
            status = h.latest_status()
            if status is not None and status.state == MotionStatus.REACHED:
                break
        self.assertIsNotNone(status)
        self.assertEqual(status.state, MotionStatus.REACHED,
                         f"{status.state}: {status.reason}")
        states = {s.state for _, s in h.statuses}
        self.assertIn(MotionStatus.FOLLOWING, states)
        rospy.sleep(1.0)
        x, y, _ = h.pose()
        end = path[-1]
        error = math.hypot(x - end[0], y - end[1])
        rospy.loginfo("motion_follow: ended %.3f m from the path's end (map frame)", error)
        self.assertLess(error, 0.3, f"ended {error:.2f} m from the end")
        moved = float(np.linalg.norm(h.true_xy() - start_truth))
        self.assertGreater(moved, 0.6, f"the robot moved only {moved:.2f} m (ground truth)")
        with h.lock:
            last_cmd = h.cmd_vels[-1][1]
        self.assertEqual((last_cmd.linear.x, last_cmd.angular.z), (0.0, 0.0))
        self.assertLess(h.true_speed(), 0.02)


if __name__ == "__main__":
    rospy.init_node("test_motion_follow")
    rostest.rosrun("sparse_nav", "motion_follow", MotionFollowTest)
