#!/usr/bin/python3
"""rostest: bad inputs (an empty map, a NaN goal, a goal in a frame without TF, a start inside a
wall, a map update outside the map, a map in another frame) give a status with the reason and no
path; the navigator keeps running and plans again from good input."""
import math
import unittest

import numpy as np
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from map_msgs.msg import OccupancyGridUpdate

from navigator_harness import NavWorld, occupancy_grid, start_clock

RES = 0.1


class NavigatorBadInput(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.world = NavWorld()
        assert cls.world.wait_for_node(), "the navigator publishes status and path"

    def assert_refused(self, since, state, reason):
        status = self.world.wait_status(since, (state,), reason=reason, timeout_s=30.0)
        self.assertIsNotNone(status, f"a {state} status mentioning {reason!r}")
        self.assertEqual(self.world.wait_path(lambda p: p == [], timeout_s=5.0), [])
        return status

    def test_bad_inputs(self):
        w = self.world
        w.set_pose(1.0, 1.0)
        w.publish_update(0, 0, np.zeros((2, 2), dtype=np.int8))  # before any map: ignored
        since = w.mark()
        w.map_pub.publish(occupancy_grid(np.zeros((0, 0), dtype=np.int8), RES))
        self.assert_refused(since, "rejected", "empty grid")
        since = w.mark()
        w.send_goal(3.0, 1.0)
        self.assert_refused(since, "planning", "waiting for a map")

        data = np.zeros((40, 60), dtype=np.int8)
        data[20:30, 20:30] = 100
        since = w.mark()
        w.publish_map(data)
        self.assertIsNotNone(w.wait_status(since, ("following",)))
        self.assertIsNotNone(w.wait_path(lambda p: len(p) >= 2))

        since = w.mark()
        w.send_goal(math.nan, 2.0)
        self.assert_refused(since, "rejected", "not finite")
        since = w.mark()
        w.send_goal(2.0, 2.0, frame="nowhere")
        self.assert_refused(since, "rejected", "no transform")

        # A map in another frame and an update outside the map are refused; the map stays.
        since = w.mark()
        w.publish_map(np.full((40, 60), 100, dtype=np.int8), frame="odom")
        self.assert_refused(since, "rejected", "frame 'odom'")
        since = w.mark()
        update = OccupancyGridUpdate()
        update.header.frame_id = "map"
        update.x, update.y, update.width, update.height = 55, 0, 10, 1
        update.data = [100] * 10
        w.update_pub.publish(update)
        self.assert_refused(since, "rejected", "outside")

        since = w.mark()
        w.set_pose(2.5, 2.5)  # inside the block
        w.send_goal(5.0, 3.5)
        self.assert_refused(since, "no_path", "inside an obstacle")

        # Still running: a good pose and goal give a path again, around the block.
        since = w.mark()
        w.set_pose(1.0, 1.0)
        w.send_goal(5.0, 3.5)
        self.assertIsNotNone(w.wait_status(since, ("following",)))
        path = w.wait_path(lambda p: len(p) >= 2 and math.dist(p[-1], (5.05, 3.55)) < 0.2)
        self.assertIsNotNone(path)
        self.assertEqual(w.unstamped_paths, 0)
        diag = rospy.wait_for_message("/diagnostics", DiagnosticArray, timeout=30.0)
        while not any(s.name == "navigator" for s in diag.status):
            diag = rospy.wait_for_message("/diagnostics", DiagnosticArray, timeout=30.0)
        values = {v.key: v.value for s in diag.status if s.name == "navigator" for v in s.values}
        self.assertEqual(int(values["bad_inputs"]), 5)  # map, 2 goals, frame, update (not the early one)
        self.assertEqual(values["map_size"], "60x40")


if __name__ == "__main__":
    rospy.init_node("navigator_bad_input")
    start_clock()
    rostest.rosrun("sparse_nav", "navigator_bad_input", NavigatorBadInput)
