#!/usr/bin/python3
"""rostest: when navigator/path stops coming, or SLAM is lost, motion stops the robot."""
import os
import sys
import unittest

import numpy as np
import rospy
import rostest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from motion_harness import MotionHarness  # noqa: E402
from sparse_nav.msg import MotionStatus, SlamState  # noqa: E402


class MotionStaleTest(unittest.TestCase):
    def test_stale_path_stops_the_robot(self):
        h = MotionHarness()
        self.state_pub = rospy.Publisher("slam/state", SlamState, queue_size=5)
        h.wait_for_clock()
        self.assertTrue(h.initialise_slam(), "SLAM did not initialise with a measured scale")
        path_timeout_s = rospy.get_param("motion/path_timeout_s")
        path = h.relative_path(1.8, 0.0)
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

        # The path comes again: motion resumes. Then SLAM reports LOST: it stops although the
        # path keeps coming, and hands over (STOPPED_LOST).
        resumed = self._publish_until(h, path, lambda: h.true_speed() > 0.1)
        self.assertTrue(resumed, "motion did not resume with a fresh path")
        lost = SlamState(state=SlamState.LOST, map_index=h.slam_state.map_index,
                         source="test", reason="forced by the test")
        lost.header.stamp = rospy.Time.now()
        lost.header.frame_id = "map"
        self.state_pub.publish(lost)
        stopped = self._publish_until(
            h, path, lambda: h.latest_status().state == MotionStatus.STOPPED_LOST)
        self.assertTrue(stopped, f"no STOPPED_LOST: {h.latest_status().reason}")
        self.assertIn("forced by the test", h.latest_status().reason)
        self._publish_until(h, path, lambda: False, duration_s=2.0)
        with h.lock:
            last_cmd = h.cmd_vels[-1][1]
        self.assertEqual((last_cmd.linear.x, last_cmd.angular.z), (0.0, 0.0))
        self.assertLess(h.true_speed(), 0.01, "the robot stops when SLAM is lost")

    def _publish_until(self, h, path, condition, duration_s=20.0):
        """Publishes the path at 2 Hz until condition() holds (True) or duration_s passes."""
        end = rospy.Time.now().to_sec() + duration_s
        while rospy.Time.now().to_sec() < end and not rospy.is_shutdown():
            h.publish_path(path)
            rospy.sleep(0.5)
            if condition():
                return True
        return False


if __name__ == "__main__":
    rospy.init_node("test_motion_stale")
    rostest.rosrun("sparse_nav", "motion_stale", MotionStaleTest)
