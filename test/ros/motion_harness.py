"""Shared steps of the motion rostests: initialise SLAM on the simulated ground robot, read the
pose in the map frame, publish a hand-given path, watch motion/status and cmd_vel."""
import math
import threading

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import Odometry, Path

from sparse_nav.msg import MotionStatus, SlamScale, SlamState
from sparse_nav.ros.conversions import transform_to_matrix
from sparse_nav.scanning import initial_scan, to_velocity_segments


class MotionHarness:
    def __init__(self):
        self.lock = threading.Lock()
        self.statuses = []
        self.cmd_vels = []
        self.truth = None
        self.slam_state = None
        self.scale = None
        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        rospy.Subscriber("motion/status", MotionStatus, self._keep, callback_args="statuses")
        rospy.Subscriber("cmd_vel", Twist, self._keep, callback_args="cmd_vels")
        self.truth_track = []
        rospy.Subscriber("ground_truth/odom", Odometry, self._on_truth)
        rospy.Subscriber("slam/state", SlamState, self._set, callback_args="slam_state")
        rospy.Subscriber("slam/scale", SlamScale, self._set, callback_args="scale")
        self.cmd_pub = rospy.Publisher("cmd_vel", Twist, queue_size=10)
        self.path_pub = rospy.Publisher("navigator/path", Path, queue_size=5)

    def _keep(self, msg, name):
        with self.lock:
            getattr(self, name).append((rospy.Time.now().to_sec(), msg))

    def _on_truth(self, msg):
        with self.lock:
            self.truth = msg
            p = msg.pose.pose.position
            self.truth_track.append((rospy.Time.now().to_sec(), p.x, p.y))
            del self.truth_track[:-100]

    def _set(self, msg, name):
        with self.lock:
            setattr(self, name, msg)

    def wait_for_clock(self):
        while rospy.Time.now().is_zero() and not rospy.is_shutdown():
            rospy.sleep(0.05)
        rospy.sleep(1.0)

    def initialise_slam(self, limit_s=200.0):
        """Drives the seed 000 initial scan until SLAM tracks with a measured scale."""
        end = rospy.Time.now().to_sec() + limit_s
        rate = rospy.Rate(20)
        turned = 0.0

        def drive(v, w, duration):
            stop = rospy.Time.now() + rospy.Duration(duration)
            while rospy.Time.now() < stop and not rospy.is_shutdown():
                cmd = Twist()
                cmd.linear.x, cmd.angular.z = v, w
                self.cmd_pub.publish(cmd)
                rate.sleep()

        for v, w, duration in to_velocity_segments(initial_scan()):
            drive(v, w, duration)
            with self.lock:
                ready = (self.slam_state is not None and self.slam_state.state == SlamState.OK
                         and self.scale is not None and self.scale.n_samples >= 3)
            if v == 0.05:
                turned += w * duration      # the iteration's turn, back where it began
                if ready:
                    break
            if rospy.Time.now().to_sec() > end:
                break
        if turned:
            # Face the start heading again: the first iteration mapped what lies ahead of it.
            drive(0.05, -math.copysign(0.5, turned), abs(turned) / 0.5)
        self.cmd_pub.publish(Twist())
        rospy.sleep(1.0)
        return ready

    def pose(self):
        """(x, y, yaw) of base_link in map."""
        tf = self.tf_buffer.lookup_transform("map", "base_link", rospy.Time(0),
                                             rospy.Duration(5.0))
        t = transform_to_matrix(tf.transform)
        return t[0, 3], t[1, 3], math.atan2(t[1, 0], t[0, 0])

    def true_xy(self):
        with self.lock:
            p = self.truth.pose.pose.position
        return np.array([p.x, p.y])

    def true_speed(self, window_s=0.5):
        """Ground-truth speed (m/s) over the last window_s of sim time."""
        with self.lock:
            track = list(self.truth_track)
        t1, x1, y1 = track[-1]
        older = [p for p in track if p[0] <= t1 - window_s]
        if not older:
            return float("nan")
        t0, x0, y0 = older[-1]
        return math.hypot(x1 - x0, y1 - y0) / (t1 - t0)

    def publish_path(self, points, frame="map"):
        msg = Path()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = frame
        for x, y in points:
            pose = PoseStamped()
            pose.header = msg.header
            pose.pose.position.x, pose.pose.position.y = x, y
            pose.pose.orientation.w = 1.0
            msg.poses.append(pose)
        self.path_pub.publish(msg)
        self.last_path_s = msg.header.stamp.to_sec()

    def relative_path(self, forward_m, left_m):
        """A path from the robot: forward_m ahead, then left_m to its left (map frame)."""
        x, y, yaw = self.pose()
        h = np.array([math.cos(yaw), math.sin(yaw)])
        n = np.array([-h[1], h[0]])
        start = np.array([x, y])
        corner = start + forward_m * h
        return [start, start + 0.5 * forward_m * h, corner, corner + left_m * n]

    def latest_status(self):
        with self.lock:
            return self.statuses[-1][1] if self.statuses else None
