#!/usr/bin/python3
"""rostest: the navigator on the map the perception chain builds from the simulator's SLAM cloud.
The ground robot drives a slow circle until the map has enough free space, stops, and asks for a
free cell 1-2.5 m away: the path must reach it without crossing an occupied cell."""
import math
import threading
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import OccupancyGrid, Path

from navigator_harness import STATE_NAMES, crosses
from sparse_nav.msg import NavigatorStatus

MIN_FREE_CELLS = 1000


class NavigatorOnSimMap(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.map = None
        self.path = None
        self.statuses = []
        rospy.Subscriber("map", OccupancyGrid, self._on_map, queue_size=2)
        rospy.Subscriber("navigator/path", Path, self._on_path, queue_size=2)
        rospy.Subscriber("navigator/status", NavigatorStatus, self._on_status, queue_size=50)
        self.cmd = rospy.Publisher("cmd_vel", Twist, queue_size=2)
        self.goal = rospy.Publisher("move_base_simple/goal", PoseStamped, queue_size=2)
        self.tf = tf2_ros.Buffer()
        tf2_ros.TransformListener(self.tf)

    def _on_map(self, msg):
        with self.lock:
            self.map = msg

    def _on_path(self, msg):
        with self.lock:
            self.path = [(p.pose.position.x, p.pose.position.y) for p in msg.poses]

    def _on_status(self, msg):
        with self.lock:
            self.statuses.append(msg)

    def _free_cells(self):
        with self.lock:
            m = self.map
        if m is None:
            return 0
        return int(np.count_nonzero(np.asarray(m.data, dtype=np.int8) == 0))

    def _goal_candidate(self):
        """The farthest free cell 1-2.5 m from the robot whose 0.5 m square is free, with the map
        and pose it was chosen on (goal_xy, robot, data, res, origin), or None."""
        with self.lock:
            m = self.map
        if m is None:
            return None
        try:
            tf = self.tf.lookup_transform("map", "base_link", rospy.Time(0), rospy.Duration(1.0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException):
            return None
        robot = (tf.transform.translation.x, tf.transform.translation.y)
        res = m.info.resolution
        origin = (m.info.origin.position.x, m.info.origin.position.y)
        data = np.asarray(m.data, dtype=np.int8).reshape(m.info.height, m.info.width)
        free = data == 0
        k = int(round(0.25 / res))
        clear = free.copy()
        for dy in range(-k, k + 1):
            for dx in range(-k, k + 1):
                clear &= np.roll(np.roll(free, dy, 0), dx, 1)
        ys, xs = np.nonzero(clear)
        wx, wy = origin[0] + (xs + 0.5) * res, origin[1] + (ys + 0.5) * res
        d = np.hypot(wx - robot[0], wy - robot[1])
        ok = (d > 1.0) & (d < 2.5)
        if not ok.any():
            return None
        best = int(np.argmax(np.where(ok, d, -1.0)))
        return (float(wx[best]), float(wy[best])), robot, data, res, origin

    def test_path_on_the_perception_map(self):
        while rospy.Time.now().is_zero():
            rospy.sleep(0.05)
        # Drive a slow circle until the map has free space to plan in (and then a little more).
        deadline = rospy.Time.now() + rospy.Duration(300.0)
        drive = Twist()
        drive.linear.x, drive.angular.z = 0.15, 0.25
        while ((self._free_cells() < MIN_FREE_CELLS or self._goal_candidate() is None)
               and rospy.Time.now() < deadline):
            self.cmd.publish(drive)
            rospy.sleep(0.1)
        for _ in range(10):
            self.cmd.publish(Twist())
            rospy.sleep(0.1)
        self.assertGreaterEqual(self._free_cells(), MIN_FREE_CELLS, "a map with free space")
        rospy.sleep(3.0)  # the last clouds settle into the map
        candidate = self._goal_candidate()
        self.assertIsNotNone(candidate, "a clear free cell 1-2.5 m from the robot")
        goal_xy, robot, data, res, origin = candidate
        since = len(self.statuses)
        goal = PoseStamped()
        goal.header.frame_id = "map"
        goal.header.stamp = rospy.Time.now()
        goal.pose.position.x, goal.pose.position.y = goal_xy
        goal.pose.orientation.w = 1.0
        self.goal.publish(goal)
        deadline = rospy.Time.now() + rospy.Duration(60.0)
        path = None
        while rospy.Time.now() < deadline:
            with self.lock:
                states = [STATE_NAMES[s.state] for s in self.statuses[since:]]
                path = self.path
            if "following" in states and path and len(path) >= 2 \
                    and math.dist(path[-1], goal_xy) < res:
                break
            rospy.sleep(0.1)
        self.assertIn("following", states, f"statuses after the goal: {states}")
        self.assertLess(math.dist(path[-1], goal_xy), res)
        self.assertLess(math.dist(path[0], robot), 0.3)
        self.assertFalse(crosses(path, data, res, origin), f"path {path} crosses an obstacle")


if __name__ == "__main__":
    rospy.init_node("navigator_on_sim_map")
    rostest.rosrun("sparse_nav", "navigator_on_sim_map", NavigatorOnSimMap)
