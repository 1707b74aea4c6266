#!/usr/bin/python3
"""rostest: when navigator/path stops coming, motion sends zero velocity and the robot stops."""
import os
import sys
import unittest

import numpy as np
import rospy
import rostest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from motion_harness import MotionHarness  # noqa: E402
from sparse_nav.msg import MotionStatus  # noqa: E402


class MotionStaleTest(unittest.TestCase):
    def test_stale_path_stops_the_robot(self):
        h = MotionHarness()
        h.wait_for_clock()
        self.assertTrue(h.initialise_slam(), "SLAM did not initialise with a measured scale")
        path_timeout_s = rospy.get_param("motion/path_timeout_s")
        path = h.relative_path(1.5, 0.0)
        moving_at = None
        deadline = rospy.Time.now().to_sec() + 60.0
        while rospy.Time.now().to_sec() < deadline and not rospy.is_shutdown():
            h.publish_path(path)
            rospy.sleep(0.5)
            if h.true_speed() > 0.1:
                moving_at = rospy.Time.now().to_sec()
                break
        self.assertIsNotNone(moving_at, "the robot never started along the path")
        status = h.latest_status()
        self.assertEqual(status.state, MotionStatus.FOLLOWING, status.reason)

        # The path stops coming; within its timeout (plus a control period) motion stops.
        last_path_s = h.last_path_s
        stopped = None
        while rospy.Time.now().to_sec() < last_path_s + path_timeout_s + 5.0:
            rospy.sleep(0.1)
            status = h.latest_status()
            if status.state == MotionStatus.STOPPED_STALE:
                stopped = rospy.Time.now().to_sec()
                break
        self.assertIsNotNone(stopped, f"no STOPPED_STALE: {status.state} {status.reason}")
        self.assertIn("path", status.reason)
        self.assertGreaterEqual(stopped - last_path_s, path_timeout_s - 0.2,
                                "stopped before the path was stale")
        rospy.sleep(1.0)
        with h.lock:
            last_cmd_s, last_cmd = h.cmd_vels[-1]
        self.assertEqual((last_cmd.linear.x, last_cmd.angular.z), (0.0, 0.0),
                         "motion's last cmd_vel is a stop")
        self.assertLessEqual(last_cmd_s, stopped + 0.5, "no command after the stop")
        here = h.true_xy()
        rospy.loginfo("motion_stale: STOPPED_STALE %.2f s after the last path (timeout %.2f s)",
                      stopped - last_path_s, path_timeout_s)
        rospy.sleep(3.0)
        self.assertLess(float(np.linalg.norm(h.true_xy() - here)), 0.01, "the robot stays put")
        self.assertLess(h.true_speed(), 0.01)
        self.assertEqual(h.latest_status().state, MotionStatus.STOPPED_STALE)


if __name__ == "__main__":
    rospy.init_node("test_motion_stale")
    rostest.rosrun("sparse_nav", "motion_stale", MotionStaleTest)
