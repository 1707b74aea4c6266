#!/usr/bin/python3
"""rostest: the simulator and slam_bridge together publish the wrapper's topics, TF and states."""
import threading
import unittest

import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64, Int32

from sparse_nav.msg import SlamScale, SlamState
from sparse_nav.ros.robot_io import TelloClient
from sparse_nav.scanning import initial_scan, to_tello_commands, to_velocity_segments

TOPICS = [("/clock", Clock), ("orb_slam3/camera_pose", PoseStamped),
          ("orb_slam3/tracked_points", PointCloud2), ("orb_slam3/all_points", PointCloud2),
          ("orb_slam3/tracking_state", Int32), ("slam/state", SlamState),
          ("slam/scale", SlamScale), ("slam/points", PointCloud2),
          ("ground_truth/slam_scale", Float64)]


class SimBridgeTest(unittest.TestCase):
    def setUp(self):
        self.robot = rospy.get_param("~robot")
        self.expect_source = rospy.get_param("~expect_state_source")
        self.forced_loss_s = float(rospy.get_param("~forced_loss_at_s"))
        self.lock = threading.Lock()
        self.stamps = {topic: [] for topic, _ in TOPICS}
        self.latest = {}
        for topic, msg_type in TOPICS:
            rospy.Subscriber(topic, msg_type, self._on_msg, callback_args=topic, queue_size=100)
        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(60.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.cmd_pub = rospy.Publisher("cmd_vel", Twist, queue_size=10)
        self.drone = TelloClient()

    def _on_msg(self, msg, topic):
        with self.lock:
            self.stamps[topic].append(rospy.Time.now().to_sec())
            if topic == "slam/state":
                self.latest.setdefault("states", []).append(msg)
            self.latest[topic] = msg

    def _wait_sim(self, seconds):
        end = rospy.Time.now() + rospy.Duration(seconds)
        while not rospy.is_shutdown() and rospy.Time.now() < end:
            rospy.sleep(0.1)

    def _drive_until(self, until_s):
        steps = initial_scan() * 3
        if self.robot == "ground":
            rate = rospy.Rate(20)
            for v, w, duration in to_velocity_segments(steps):
                end = rospy.Time.now() + rospy.Duration(duration)
                while rospy.Time.now() < end and not rospy.is_shutdown():
                    cmd = Twist()
                    cmd.linear.x, cmd.angular.z = v, w
                    self.cmd_pub.publish(cmd)
                    rate.sleep()
                if rospy.Time.now().to_sec() > until_s:
                    break
            self.cmd_pub.publish(Twist())
        else:
            for command in ["command", "takeoff"] + to_tello_commands(steps):
                self.drone.send(command)
                if rospy.Time.now().to_sec() > until_s:
                    break

    def test_topics_tf_and_states(self):
        while rospy.Time.now().is_zero() and not rospy.is_shutdown():
            rospy.sleep(0.05)
        rospy.sleep(1.0)
        # Long enough after the loss for the new map to collect several scale samples: the ground
        # scan turns on the spot before each sideways drive, so its moves come slowly.
        self._drive_until(self.forced_loss_s + 45.0)
        self._wait_sim(2.0)
        with self.lock:
            stamps = {k: list(v) for k, v in self.stamps.items()}
            states = list(self.latest.get("states", []))
            latest = dict(self.latest)

        clock = stamps["/clock"]
        self.assertGreater(len(clock), 100, "the simulator publishes /clock")
        self.assertTrue(all(b >= a for a, b in zip(clock, clock[1:])), "/clock never goes back")

        poses = stamps["orb_slam3/camera_pose"]
        self.assertGreater(len(poses), 50, "camera poses are published once tracking works")
        duration = poses[-1] - poses[0]
        self.assertGreater(len(poses) / duration, 4.0, "camera pose rate (sim time)")
        self.assertGreater(len(stamps["orb_slam3/tracked_points"]), 50)
        all_points = stamps["orb_slam3/all_points"]
        self.assertGreater(len(all_points), 5)
        self.assertGreater(len(stamps["slam/points"]), 3, "the bridge republishes the map points")
        if self.expect_source == "wrapper":
            self.assertGreater(len(stamps["orb_slam3/tracking_state"]), 50)
        else:
            self.assertEqual(stamps["orb_slam3/tracking_state"], [],
                             "tracking_state is switched off")

        names = [s.state for s in states]
        self.assertIn(SlamState.OK, names, f"tracking reaches OK: {[s.reason for s in states]}")
        first_ok = names.index(SlamState.OK)
        self.assertIn(SlamState.LOST, names[first_ok:], "the forced loss is reported as LOST")
        after_loss = names[names.index(SlamState.LOST, first_ok):]
        self.assertTrue(SlamState.NEW_MAP in after_loss or SlamState.OK in after_loss,
                        f"tracking recovers after the loss: {[s.reason for s in states]}")
        # The bridge infers the state until the wrapper's first tracking_state message arrives;
        # on a loaded machine a fresh pose can beat it, so only the states from the first one
        # of the expected source on must all come from it, and the forced loss must be among them.
        sources = [s.source for s in states]
        self.assertIn(self.expect_source, sources)
        first_expected = sources.index(self.expect_source)
        self.assertTrue(all(s == self.expect_source for s in sources[first_expected:]),
                        f"the source never falls back once set: {sources}")
        self.assertIn(SlamState.LOST, names[max(first_ok, first_expected):],
                      f"the {self.expect_source} state reports the forced loss")
        # The forced loss makes the simulated SLAM begin a new map: only its wrapper state says so.
        given_up = [s.map_given_up for s in states[first_ok:] if s.state == SlamState.LOST]
        self.assertEqual(any(given_up), self.expect_source == "wrapper",
                         f"map_given_up at the losses: {given_up}")

        for parent, child in (("map", "base_link"), ("map", "odom"), ("odom", "base_link"),
                              ("base_link", "camera_optical"), ("map", "sim_world")):
            self.assertTrue(self.tf_buffer.can_transform(parent, child, rospy.Time(0),
                                                         rospy.Duration(5.0)),
                            f"TF {parent} -> {child}")

        scale = latest["slam/scale"]
        truth = latest["ground_truth/slam_scale"].data
        self.assertGreater(scale.n_samples, 0, "scale measured from known motions")
        self.assertEqual(scale.map_index, states[-1].map_index, "the scale names its SLAM map")
        self.assertGreater(scale.confidence, 0.0)
        self.assertLess(abs(scale.metres_per_unit - truth) / truth, 0.5,
                        f"scale {scale.metres_per_unit:.3f} m/unit vs true {truth:.3f}")


if __name__ == "__main__":
    rospy.init_node("test_sim_bridge")
    rostest.rosrun("sparse_nav", "sim_bridge", SimBridgeTest)
