#!/usr/bin/python3
"""rostest: go-to-wall drives the simulated ground robot to the obstacle ahead and backs off."""
import os
import sys
import unittest

import numpy as np
import rospy
import rostest
from std_srvs.srv import Trigger

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from motion_harness import MotionHarness  # noqa: E402
from sparse_nav.msg import MotionStatus  # noqa: E402
from sparse_nav.sim import load_world  # noqa: E402
from sparse_nav.sim.world import segment_distances  # noqa: E402


class MotionWallTest(unittest.TestCase):
    def test_goes_to_the_wall_and_backs_off(self):
        h = MotionHarness()
        h.wait_for_clock()
        self.assertTrue(h.initialise_slam(), "SLAM did not initialise")
        segments, _ = load_world("one_room").obstacle_segments()
        start = h.true_xy()
        rospy.wait_for_service("motion/go_to_wall", timeout=60.0)
        answer = rospy.ServiceProxy("motion/go_to_wall", Trigger)()
        self.assertTrue(answer.success, answer.message)
        closest = np.inf
        deadline = rospy.Time.now().to_sec() + 120.0
        status = None
        while rospy.Time.now().to_sec() < deadline and not rospy.is_shutdown():
            rospy.sleep(0.2)
            closest = min(closest, float(np.min(segment_distances(h.true_xy(), segments))))
            status = h.latest_status()
            if status.state in (MotionStatus.WALL_REACHED, MotionStatus.FAILED):
                break
        self.assertEqual(status.state, MotionStatus.WALL_REACHED, status.reason)
        rospy.sleep(1.0)
        end = h.true_xy()
        final = float(np.min(segment_distances(end, segments)))
        rospy.loginfo("motion_wall: %s; closest %.2f m, final %.2f m from an obstacle, "
                      "travelled %.2f m", status.reason, closest, final,
                      float(np.linalg.norm(end - start)))
        self.assertLess(closest, 0.9, "the robot did not come close to an obstacle")
        self.assertGreater(final - closest, 0.15, "the robot did not back off")
        self.assertLess(h.true_speed(), 0.01)
        with h.lock:
            last_cmd = h.cmd_vels[-1][1]
        self.assertEqual((last_cmd.linear.x, last_cmd.angular.z), (0.0, 0.0))


if __name__ == "__main__":
    rospy.init_node("test_motion_wall")
    rostest.rosrun("sparse_nav", "motion_wall", MotionWallTest)
