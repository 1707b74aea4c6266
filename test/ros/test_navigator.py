#!/usr/bin/python3
"""rostest: the four navigation scenarios of seed 004 against the navigator node, with a synthetic
map, TF and SLAM state in simulated time (the robot follows navigator/path kinematically)."""
import math
import unittest

import actionlib
import numpy as np
import rospy
import rostest
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from actionlib_msgs.msg import GoalStatus
from nav_msgs.srv import GetPlan
from geometry_msgs.msg import PoseStamped

from navigator_harness import NavWorld, crosses, start_clock
from sparse_nav.msg import SlamState

RES = 0.1


def free(width_m, height_m):
    return np.zeros((int(round(height_m / RES)), int(round(width_m / RES))), dtype=np.int8)


class NavigatorScenarios(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.world = NavWorld()
        assert cls.world.wait_for_node(), "the navigator publishes status and path"

    def setUp(self):
        self.world.follow = False

    def test_1_clear_path_with_the_action_server(self):
        w = self.world
        data = free(10.0, 6.0)
        data[15:45, 40:60] = 100  # a 2 m x 3 m block between start and goal
        w.set_pose(1.0, 3.0)
        w.publish_map(data)
        client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
        self.assertTrue(client.wait_for_server(rospy.Duration(60.0)))
        since = w.mark()
        goal = MoveBaseGoal()
        goal.target_pose.header.frame_id = "map"
        goal.target_pose.pose.position.x, goal.target_pose.pose.position.y = 8.5, 3.0
        goal.target_pose.pose.orientation.w = 1.0
        client.send_goal(goal)
        status = w.wait_status(since, ("following",))
        self.assertIsNotNone(status, "following a path")
        self.assertTrue(status.has_goal)
        self.assertAlmostEqual(status.goal.x, 8.5, places=6)
        path = w.wait_path(lambda p: len(p) >= 2 and math.dist(p[-1], (8.5, 3.0)) < RES)
        self.assertIsNotNone(path)
        self.assertFalse(crosses(path, data, RES), f"path through the block: {path}")
        self.assertGreater(sum(math.dist(a, b) for a, b in zip(path, path[1:])), 7.5)
        w.follow = True
        self.assertTrue(client.wait_for_result(rospy.Duration(90.0)))
        self.assertEqual(client.get_state(), GoalStatus.SUCCEEDED)
        self.assertIsNotNone(w.wait_status(since, ("reached",), timeout_s=5.0))
        self.assertLess(math.dist(w.pose[:2], (8.5, 3.0)), 0.3)
        self.assertEqual(w.wait_path(lambda p: p == [], timeout_s=5.0), [])
        self.assertEqual(w.unstamped_paths, 0)

    def test_2_goal_out_of_bounds(self):
        w = self.world
        # Away from the earlier scenarios' maps, whose cells the navigator would otherwise keep
        # believing beyond its viewing range.
        data = free(6.0, 4.0)
        w.set_pose(21.0, 2.0)
        w.publish_map(data, origin=(20.0, 0.0))
        rospy.sleep(0.5)
        since = w.mark()
        w.send_goal(32.0, 2.0)
        status = w.wait_status(since, ("goal_off_map",))
        self.assertIsNotNone(status, "goal off map")
        self.assertTrue(status.has_target)
        self.assertGreater(status.target.x, 25.7)  # the known cell nearest the goal: the edge
        self.assertLess(abs(status.target.y - 2.0), 0.06)  # the centre of a cell next to y = 2
        path = w.wait_path(lambda p: len(p) >= 2 and p[-1][0] > 25.7)
        self.assertIsNotNone(path, "a path to the edge of the known map")
        # The map grows: the path now reaches the goal itself.
        since = w.mark()
        w.publish_map(free(14.0, 4.0), origin=(20.0, 0.0))
        self.assertIsNotNone(w.wait_status(since, ("following",)))
        self.assertIsNotNone(w.wait_path(lambda p: math.dist(p[-1], (32.0, 2.0)) < RES))

    def test_3_obstacle_beyond_the_viewing_range(self):
        w = self.world
        data = free(12.0, 6.0)
        w.set_pose(41.0, 3.0)
        w.publish_map(data, origin=(40.0, 0.0))
        rospy.sleep(0.5)
        since = w.mark()
        w.send_goal(50.0, 3.0)
        self.assertIsNotNone(w.wait_status(since, ("following",)))
        # A closed wall at x = 7 m cuts the goal off; it is 6 m away, beyond viewing_range_m = 2.
        walled = data.copy()
        walled[:, 70] = 100
        w.publish_update(0, 0, walled)
        rospy.sleep(2.0)
        path = w.current_path()
        self.assertEqual(w.last_state(), "following")
        self.assertTrue(crosses(path, walled, RES, origin=(40.0, 0.0)),
                        "the far wall is not planned around yet")
        since = w.mark()
        w.follow = True
        status = w.wait_status(since, ("no_path",), timeout_s=90.0)
        w.follow = False
        self.assertIsNotNone(status, "no path once the wall is in range")
        self.assertGreater(w.pose[0], 47.0 - 2.0 - 1.5)  # it got close before giving up
        self.assertEqual(w.wait_path(lambda p: p == [], timeout_s=5.0), [])
        # ~make_plan plans on the newest map: no way to the goal either.
        rospy.wait_for_service("navigator/make_plan", 30.0)
        goal = PoseStamped()
        goal.header.frame_id = "map"
        goal.pose.position.x, goal.pose.position.y = 50.0, 3.0
        goal.pose.orientation.w = 1.0
        plan = rospy.ServiceProxy("navigator/make_plan", GetPlan)(PoseStamped(), goal, 0.0)
        self.assertEqual(plan.plan.poses, [])
        goal.pose.position.x = 46.0
        plan = rospy.ServiceProxy("navigator/make_plan", GetPlan)(PoseStamped(), goal, 0.0)
        self.assertGreater(len(plan.plan.poses), 1)

    def test_4_slam_lost_goal_kept_relative_and_reanchored(self):
        w = self.world
        w.slam(SlamState.OK, 0)
        w.set_pose(62.0, 2.0, 0.0)
        w.publish_map(free(10.0, 8.0), origin=(60.0, 0.0))
        rospy.sleep(0.5)
        since = w.mark()
        w.send_goal(65.0, 3.0)  # 3 m ahead, 1 m left of the robot
        self.assertIsNotNone(w.wait_status(since, ("following",)))
        since = w.mark()
        w.slam(SlamState.LOST, 0)
        self.assertIsNotNone(w.wait_status(since, ("lost",)))
        self.assertEqual(w.wait_path(lambda p: p == [], timeout_s=5.0), [])
        # A new SLAM map: the robot now sits at (4, 1) facing +y in a map with another origin.
        w.set_pose(4.0, 1.0, math.pi / 2)
        since = w.mark()
        w.slam(SlamState.NEW_MAP, 1)
        rospy.sleep(1.0)
        self.assertEqual(w.last_state(), "lost")  # waiting for the new map
        w.publish_map(free(10.0, 8.0), origin=(-2.0, -1.0))
        status = w.wait_status(since, ("following",))
        self.assertIsNotNone(status, "following again after the new map")
        self.assertAlmostEqual(status.goal.x, 4.0 - 1.0, places=3)
        self.assertAlmostEqual(status.goal.y, 1.0 + 3.0, places=3)
        path = w.wait_path(lambda p: len(p) >= 2 and math.dist(p[-1], (3.0, 4.0)) < RES)
        self.assertIsNotNone(path)
        w.slam(SlamState.OK, 1)


if __name__ == "__main__":
    rospy.init_node("navigator_scenarios")
    start_clock()
    rostest.rosrun("sparse_nav", "navigator_scenarios", NavigatorScenarios)
