#!/usr/bin/python3
"""rostest: the simulated Tello flies a hand-given path on the motion node's Tello commands."""
import math
import os
import sys
import threading
import unittest

import numpy as np
import rospy
import rostest
from std_msgs.msg import String

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from motion_harness import MotionHarness  # noqa: E402
from sparse_nav.msg import MotionStatus, SlamState  # noqa: E402
from sparse_nav.ros.robot_io import TelloClient  # noqa: E402
from sparse_nav.scanning import initial_scan, to_tello_commands  # noqa: E402
from sparse_nav.sim.robots import TelloDrone  # noqa: E402


class MotionDroneTest(unittest.TestCase):
    def test_flies_path_to_its_end(self):
        h = MotionHarness()
        driver = TelloClient(timeout_s=30.0)
        commands, lock = [], threading.Lock()

        def on_command(msg):
            with lock:
                commands.append(msg.data)
        rospy.Subscriber("tello/command", String, on_command)
        h.wait_for_clock()
        self.assertEqual(driver.send("command"), "ok")
        self.assertEqual(driver.send("takeoff"), "ok")
        ready = False
        # The path is flown once SLAM tracks with a measured scale. Now and then (1 run in 25
        # here) SLAM is not there yet when the scan ends: scan once more rather than fail.
        for command in to_tello_commands(initial_scan()) * 2:
            driver.send(command)
            with h.lock:
                ready = (h.slam_state is not None and h.slam_state.state == SlamState.OK
                         and h.scale is not None and h.scale.n_samples >= 3)
            if ready and command.startswith("cw"):
                break
        self.assertTrue(ready, "SLAM did not initialise with a measured scale in two scans")
        rospy.sleep(1.0)
        with lock:
            before = len(commands)
        path = h.relative_path(1.2, 0.8)
        start_truth = h.true_xy()
        status = None
        deadline = rospy.Time.now().to_sec() + 150.0
        while rospy.Time.now().to_sec() < deadline and not rospy.is_shutdown():
            h.publish_path(path)
            rospy.sleep(0.5)
            status = h.latest_status()
            if status is not None and status.state == MotionStatus.REACHED:
                break
        self.assertIsNotNone(status)
        with lock:
            sent = commands[before:]
        self.assertEqual(status.state, MotionStatus.REACHED,
                         f"{status.state}: {status.reason}, {status.distance_to_goal_m:.2f} m "
                         f"to go, heading error {status.heading_error_deg:.1f} deg, pose "
                         f"{h.pose()}, path {[list(p) for p in path]}, commands {sent}")
        rospy.loginfo("motion_drone: commands %s", sent)
        self.assertTrue(any(c.startswith("forward") for c in sent), sent)
        self.assertTrue(any(c.startswith(("cw", "ccw")) for c in sent), sent)
        for command in sent:
            TelloDrone.parse(command)   # the simulator's Tello limits; raises if outside
        x, y, _ = h.pose()
        error = math.hypot(x - path[-1][0], y - path[-1][1])
        rospy.loginfo("motion_drone: ended %.3f m from the path's end after %d commands",
                      error, len(sent))
        self.assertLess(error, 0.45, f"ended {error:.2f} m from the end")
        moved = float(np.linalg.norm(h.true_xy() - start_truth))
        self.assertGreater(moved, 0.8, f"the drone moved only {moved:.2f} m (ground truth)")
        rospy.sleep(2.0)
        with lock:
            self.assertEqual(commands[before:], sent, "no command after REACHED")
        driver.send("land")


if __name__ == "__main__":
    rospy.init_node("test_motion_drone")
    rostest.rosrun("sparse_nav", "motion_drone", MotionDroneTest)
