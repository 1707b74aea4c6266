#!/usr/bin/python3
"""rostest: the escape mission end to end, judged against the simulator's ground truth."""
import threading
import unittest

import rospy
import rostest
from nav_msgs.msg import Odometry

from sparse_nav.mission_report import evaluate
from sparse_nav.msg import ConductorState, SlamState
from sparse_nav.ros.sim_node import load_ros_world


class MissionTest(unittest.TestCase):
    def setUp(self):
        self.world = load_ros_world(rospy.get_param("~world"))
        self.limit_s = float(rospy.get_param("~sim_time_limit_s"))
        self.lock = threading.Lock()
        self.states, self.track, self.slam_states = [], [], []
        rospy.Subscriber("conductor/state", ConductorState, self._on_state, queue_size=50)
        rospy.Subscriber("ground_truth/odom", Odometry, self._on_truth, queue_size=50)
        rospy.Subscriber("slam/state", SlamState, self._on_slam, queue_size=50)

    def _on_state(self, msg):
        with self.lock:
            self.states.append(msg)

    def _on_truth(self, msg):
        with self.lock:
            self.track.append((msg.pose.pose.position.x, msg.pose.pose.position.y))

    def _on_slam(self, msg):
        with self.lock:
            self.slam_states.append(msg.state)

    def _phase(self):
        with self.lock:
            return self.states[-1].phase if self.states else ""

    def test_the_robot_leaves_the_room_through_its_exit(self):
        while rospy.Time.now().is_zero() and not rospy.is_shutdown():
            rospy.sleep(0.05)
        while (self._phase() not in ("done", "gave_up") and not rospy.is_shutdown()
               and rospy.Time.now().to_sec() < self.limit_s):
            rospy.sleep(0.5)
        rospy.sleep(2.0)
        with self.lock:
            states, track = list(self.states), list(self.track)
            losses = self.slam_states.count(SlamState.LOST)
        trail = [(s.state, s.phase, s.reason) for s in states]
        self.assertTrue(states, "the conductor publishes its state")
        self.assertEqual(states[-1].phase, "done", f"the mission ends done: {trail}")
        self.assertGreaterEqual(losses, 1, "the forced SLAM loss happened")
        result = evaluate(self.world, states[-1].phase, track, None)
        self.assertTrue(result["left_the_room"], f"the robot is truly outside: {track[-1]}")
        self.assertTrue(result["success"])


if __name__ == "__main__":
    rospy.init_node("test_mission")
    rostest.rosrun("sparse_nav", "mission_drone", MissionTest)
