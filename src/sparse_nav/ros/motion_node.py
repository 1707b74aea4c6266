"""motion: follows navigator/path with cmd_vel (ground robot) or Tello commands (drone).

Stops (zero velocity once, no further drone command) when SLAM is lost or when the pose, the map
alignment or the path is older than its timeout; go-to-wall on request.
"""
import math
import threading

import numpy as np
import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Twist
from nav_msgs.msg import Path
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger, TriggerResponse

from sparse_nav.motion import (FAILED, STATE_NAMES, STOPPED_LOST, STOPPED_STALE, MotionConfig,
                               MotionController)
from sparse_nav.msg import MotionStatus, SlamState
from sparse_nav.ros.conversions import transform_to_matrix
from sparse_nav.ros.robot_io import TelloClient
from sparse_nav.ros.params import read_fields

_TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException,
              tf2_ros.ExtrapolationException)


def _config_from_params():
    cfg = MotionConfig()
    read_fields(cfg, ("robot", "lookahead_m", "goal_tolerance_m", "max_linear_m_s",
                      "min_linear_m_s", "max_angular_rad_s", "angular_gain", "turn_in_place_deg", "slow_down_m",
                      "drone_goal_tolerance_m", "drone_max_step_cm", "drone_min_turn_deg",
                      "pose_timeout_s", "map_timeout_s", "path_timeout_s", "tracked_timeout_s",
                      "wall_min_tracked_points", "wall_max_fails", "wall_speed_m_s", "wall_step_cm",
                      "wall_back_off_m", "wall_max_distance_m", "stall_fraction",
                      "stall_timeout_s", "route_tolerance_m", "bump_max_tries",
                      "bump_back_off_m", "bump_shift_m", "bump_radius_m", "bump_speed_m_s"))
    cfg.validate()
    return cfg


def _move_distance_m(command):
    """Signed forward distance (m) of a Tello forward/back command, 0 for anything else."""
    parts = command.split()
    if len(parts) == 2 and parts[0] in ("forward", "back"):
        return int(parts[1]) / 100.0 * (1.0 if parts[0] == "forward" else -1.0)
    return 0.0


class MotionNode:
    """Glue between the path, TF, SLAM health and the ROS-free MotionController."""

    def __init__(self):
        self.ctl = MotionController(_config_from_params())
        self.robot = self.ctl.cfg.robot
        self.map_frame = rospy.get_param("~map_frame", "map")
        self.odom_frame = rospy.get_param("~odom_frame", "odom")
        self.base_frame = rospy.get_param("~base_frame", "base_link")
        self.rate_hz = float(rospy.get_param("~rate_hz", 10.0))
        self.settle_s = float(rospy.get_param("~settle_s", 0.3))
        response_timeout_s = float(rospy.get_param("~response_timeout_s", 15.0))
        self.max_command_failures = int(rospy.get_param("~max_command_failures", 3))
        if not self.rate_hz > 0 or self.settle_s < 0 or not response_timeout_s > 0 \
                or self.max_command_failures < 1:
            raise ValueError("rate_hz and response_timeout_s must be > 0, settle_s >= 0, "
                             "max_command_failures >= 1")
        self.lock = threading.RLock()
        self.bad_inputs = 0
        self.last_problem = ""
        self.last_decision = None
        self.was_moving = False
        self.last_twist = (0.0, 0.0)
        self.last_tick_s = None
        self.last_command = ""
        self.last_answer = ""
        self.in_flight = False
        self.answered_at_s = -math.inf
        self.failures = 0
        self.odom_pose = None          # (x, y, yaw) of base in odom: the wheel odometry
        self.prev_odom_pose = None     # at the last control step

        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(10.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.status_pub = rospy.Publisher("motion/status", MotionStatus, queue_size=10,
                                          latch=True)
        self.diag_pub = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=10)
        self.cmd_pub = None
        self.tello = None
        if self.robot == "ground":
            self.cmd_pub = rospy.Publisher("cmd_vel", Twist, queue_size=10)
        else:
            self.tello = TelloClient(timeout_s=response_timeout_s)
        rospy.Subscriber("navigator/path", Path, self._on_path, queue_size=5)
        rospy.Subscriber("slam/state", SlamState, self._on_slam_state, queue_size=20)
        rospy.Subscriber("orb_slam3/tracked_points", PointCloud2, self._on_tracked, queue_size=5)
        rospy.Service("~go_to_wall", Trigger, self._on_go_to_wall)
        rospy.Service("~stop", Trigger, self._on_stop)
        rospy.Timer(rospy.Duration(1.0 / self.rate_hz), self._on_timer)
        rospy.Timer(rospy.Duration(1.0), self._on_diagnostics)

    def _bad_input(self, what):
        self.bad_inputs += 1
        self.last_problem = what
        rospy.logerr_throttle(5.0, f"motion: ignoring {what}")

    def _on_path(self, msg):
        now = rospy.Time.now().to_sec()
        frame = msg.header.frame_id.lstrip("/")
        if msg.poses and frame != self.map_frame:
            self._bad_input(f"navigator/path in frame {frame!r}, expected {self.map_frame!r}")
            return
        points = np.array([[p.pose.position.x, p.pose.position.y] for p in msg.poses],
                          dtype=float).reshape(-1, 2)
        stamp = msg.header.stamp.to_sec() or now
        with self.lock:
            try:
                self.ctl.set_path(points, stamp, now)
            except ValueError as exc:
                self._bad_input(f"navigator/path: {exc}")

    def _on_slam_state(self, msg):
        with self.lock:
            if msg.state in (SlamState.OK, SlamState.NEW_MAP):
                self.ctl.set_slam_state(False, msg.map_index, msg.header.stamp.to_sec())
            else:
                why = "not initialised" if msg.state == SlamState.NOT_INITIALIZED else msg.reason
                self.ctl.set_slam_state(True, msg.map_index, msg.header.stamp.to_sec(), why)

    def _on_tracked(self, msg):
        with self.lock:
            self.ctl.set_tracked(msg.width * msg.height, rospy.Time.now().to_sec())

    def _on_go_to_wall(self, _req):
        with self.lock:
            if self.ctl.lost:
                return TriggerResponse(success=False, message="SLAM is lost")
            self.ctl.start_wall()
            self.prev_odom_pose = None
        return TriggerResponse(success=True, message="going to the wall ahead")

    def _on_stop(self, _req):
        with self.lock:
            self.ctl.stop()
        return TriggerResponse(success=True, message="stopped")

    def _lookup(self, target, source, now_s):
        """(4x4 transform, stamp in s) of source in target; a static one counts as fresh."""
        tf = self.tf_buffer.lookup_transform(target, source, rospy.Time(0))
        stamp = tf.header.stamp.to_sec() or now_s
        return transform_to_matrix(tf.transform), stamp

    def _update_pose(self, now_s):
        try:
            t_map_odom, map_stamp = self._lookup(self.map_frame, self.odom_frame, now_s)
            t_odom_base, pose_stamp = self._lookup(self.odom_frame, self.base_frame, now_s)
        except _TF_ERRORS:
            return
        self.odom_pose = (float(t_odom_base[0, 3]), float(t_odom_base[1, 3]),
                          math.atan2(t_odom_base[1, 0], t_odom_base[0, 0]))
        t = t_map_odom @ t_odom_base
        yaw = math.atan2(t[1, 0], t[0, 0])
        try:
            self.ctl.set_pose(float(t[0, 3]), float(t[1, 3]), yaw, pose_stamp, map_stamp)
        except ValueError as exc:
            self._bad_input(f"TF pose: {exc}")

    def _on_timer(self, _event):
        now = rospy.Time.now().to_sec()
        with self.lock:
            self._update_pose(now)
            if self.robot == "ground":
                decision = self._ground_step(now)
            else:
                decision = self._drone_step(now)
            if decision is not None:
                try:
                    self._publish_status(decision)
                except rospy.ROSException:
                    if not rospy.is_shutdown():
                        raise  # a tick racing the shutdown finds its topics closed: harmless
            self.last_tick_s = now

    def _ground_step(self, now):
        if self.last_tick_s is not None:
            commanded = self.last_twist[0] * (now - self.last_tick_s)
            if self.ctl.mode == "wall":
                self.ctl.wall_moved(commanded, self._odom_advance())
            else:
                self.ctl.follow_moved(commanded, self._odom_advance(), now)
        self.prev_odom_pose = self.odom_pose
        decision = self.ctl.step(now)
        if decision.moving:
            self._send_twist(decision.linear_m_s, decision.angular_rad_s)
            self.was_moving = True
        elif self.was_moving:
            # Once: a silent motion layer leaves cmd_vel to others (the conductor's scans).
            self._send_twist(0.0, 0.0)
            self.was_moving = False
        else:
            self.last_twist = (0.0, 0.0)
        return decision

    def _odom_advance(self):
        """Distance (m) the wheel odometry advanced along the heading since the last tick."""
        if self.odom_pose is None or self.prev_odom_pose is None:
            return None
        (x0, y0, yaw0), (x1, y1, _) = self.prev_odom_pose, self.odom_pose
        return (x1 - x0) * math.cos(yaw0) + (y1 - y0) * math.sin(yaw0)

    def _send_twist(self, v, w):
        cmd = Twist()
        cmd.linear.x, cmd.angular.z = v, w
        self.cmd_pub.publish(cmd)
        self.last_twist = (v, w)

    def _drone_step(self, now):
        if self.in_flight:
            return None
        if now - self.answered_at_s < self.settle_s:
            return None   # let SLAM report the pose at the end of the last move first
        decision = self.ctl.step(now)
        if decision.moving and decision.command:
            self.in_flight = True
            self.last_command = decision.command
            threading.Thread(target=self._send_tello, args=(decision.command,),
                             daemon=True).start()
        return decision

    def _send_tello(self, command):
        answer = self.tello.send(command)
        with self.lock:
            self.in_flight = False
            self.answered_at_s = rospy.Time.now().to_sec()
            self.last_answer = answer
            if self.ctl.mode == "wall":
                if answer == "ok":
                    self.ctl.wall_moved(_move_distance_m(command))
                elif answer.startswith("error: obstacle"):
                    self.ctl.wall_blocked()
            elif answer.startswith("error: obstacle"):
                # Pushing on, the Tello repeated the move against a door jamb without end.
                self.ctl.path_blocked(f"Tello answered {answer!r} to {command!r}")
            if answer == "ok":
                self.failures = 0
                return
            rospy.logwarn("motion: Tello answered %r to %r", answer, command)
            self.failures += 1
            self.last_problem = f"Tello answered {answer!r} to {command!r}"
            if self.failures >= self.max_command_failures:
                # The drone cannot carry the commands out (not flying, no link): stop sending.
                self.ctl.stop(f"gave up after {self.failures} failed Tello commands; last: "
                              f"{self.last_problem}")
                self.failures = 0
            self._publish_status_raw(FAILED, self.last_problem)

    def _publish_status(self, decision):
        previous = self.last_decision
        if decision.reason.startswith("blocked") and (previous is None
                                                      or previous.reason != decision.reason):
            rospy.logwarn("motion: %s", decision.reason)
        self.last_decision = decision
        msg = MotionStatus()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.map_frame
        msg.state = decision.state
        msg.reason = decision.reason
        msg.distance_to_goal_m = decision.distance_to_goal_m
        msg.heading_error_deg = decision.heading_error_deg
        msg.linear_m_s = decision.linear_m_s if self.robot == "ground" else 0.0
        msg.angular_rad_s = decision.angular_rad_s if self.robot == "ground" else 0.0
        msg.last_command = self.last_command
        self.status_pub.publish(msg)

    def _publish_status_raw(self, state, reason):
        msg = MotionStatus(state=state, reason=reason, last_command=self.last_command,
                           distance_to_goal_m=float("nan"), heading_error_deg=float("nan"))
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.map_frame
        self.status_pub.publish(msg)

    def _on_diagnostics(self, _event):
        with self.lock:
            decision = self.last_decision
            status = DiagnosticStatus()
            status.name = "motion"
            status.hardware_id = self.robot
            state = decision.state if decision else None
            problems = (STOPPED_STALE, STOPPED_LOST, FAILED)
            status.level = DiagnosticStatus.WARN if state in problems else DiagnosticStatus.OK
            status.message = (f"{STATE_NAMES[state]}: {decision.reason}" if decision
                              else "starting")
            status.values = [KeyValue(k, str(v)) for k, v in (
                ("robot", self.robot), ("mode", self.ctl.mode),
                ("last_command", self.last_command), ("last_answer", self.last_answer),
                ("bad_inputs", self.bad_inputs), ("last_problem", self.last_problem))]
        msg = DiagnosticArray()
        msg.header.stamp = rospy.Time.now()
        msg.status = [status]
        self.diag_pub.publish(msg)


def main():
    rospy.init_node("motion")
    try:
        MotionNode()
    except ValueError as exc:
        rospy.logfatal(f"motion: {exc}")
        raise SystemExit(1)
    rospy.spin()
