"""navigator: rospy glue around the ROS-free Navigator core (seed 004's D* Lite navigator)."""
import math
import threading

import actionlib
import numpy as np
import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped, Quaternion
from map_msgs.msg import OccupancyGridUpdate
from move_base_msgs.msg import MoveBaseAction, MoveBaseFeedback, MoveBaseResult
from nav_msgs.msg import OccupancyGrid, Path
from nav_msgs.srv import GetPlan, GetPlanResponse

from sparse_nav.msg import NavigatorStatus, SlamState
from sparse_nav.navigation.maps import GridGeometry
from sparse_nav.navigation.navigator import (NO_PATH, REACHED, REJECTED, Navigator,
                                             NavigatorConfig, NavigatorInputError, Status)
from sparse_nav.ros.conversions import pose_to_matrix, transform_to_matrix
from sparse_nav.ros.params import locked, read_fields

TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException,
             tf2_ros.ExtrapolationException, tf2_ros.InvalidArgumentException)


def _config_from_params():
    cfg = NavigatorConfig()
    read_fields(cfg, ("robot_radius_m", "squeeze_radius_m", "unknown_policy", "unknown_cost",
                      "occupied_threshold", "viewing_range_m", "goal_tolerance_m", "goal_search_radius_m",
                      "replan_improvement_m", "max_deviation_m", "smooth_path", "max_cells"))
    cfg.validate()
    return cfg


def _yaw(q):
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _quaternion(yaw):
    return Quaternion(0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


class NavigatorNode:
    """Owns one Navigator; feeds it maps, TF poses, goals and SLAM state; publishes its output."""

    def __init__(self):
        self.cfg = _config_from_params()
        self.map_frame = rospy.get_param("~map_frame", "map")
        self.base_frame = rospy.get_param("~base_frame", "base_link")
        self.rate_hz = float(rospy.get_param("~rate_hz", 5.0))
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"~rate_hz must be > 0, got {self.rate_hz}")
        self.nav = Navigator(self.cfg)
        self.lock = threading.RLock()
        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(10.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.slam_state = None
        self.slam_map_index = None
        self.last_status = None
        self.last_published = None
        self.input_error = ""
        self.counts = dict(maps=0, map_updates=0, goals=0, bad_inputs=0)
        self.action_goal = None
        self.served_goal = None  # the action goal the core follows
        self.action_preempted = False

        self.path_pub = rospy.Publisher("navigator/path", Path, queue_size=2)
        self.status_pub = rospy.Publisher("navigator/status", NavigatorStatus, queue_size=10,
                                          latch=True)
        self.diag_pub = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=10)
        self.action = actionlib.SimpleActionServer("move_base", MoveBaseAction, auto_start=False)
        self.action.register_goal_callback(self._on_action_goal)
        self.action.register_preempt_callback(self._on_action_preempt)
        rospy.Subscriber("map", OccupancyGrid, self._on_map, queue_size=2)
        rospy.Subscriber("map_updates", OccupancyGridUpdate, self._on_map_update, queue_size=20)
        rospy.Subscriber("move_base_simple/goal", PoseStamped, self._on_simple_goal, queue_size=5)
        rospy.Subscriber("slam/state", SlamState, self._on_slam_state, queue_size=20)
        rospy.Service("~make_plan", GetPlan, self._on_make_plan)
        self.action.start()
        self._publish(Status("idle", "no goal"))
        rospy.Timer(rospy.Duration(1.0 / self.rate_hz), self._on_timer)
        rospy.Timer(rospy.Duration(1.0), self._on_diagnostics)

    def _refuse(self, what):
        """A refused input: a REJECTED status with the reason, a throttled error, no crash."""
        self.counts["bad_inputs"] += 1
        self.input_error = what
        rospy.logerr_throttle(2.0, f"navigator: {what}")
        self._publish(Status(REJECTED, what))

    @locked
    def _on_map(self, msg):
        try:
            if msg.header.frame_id not in ("", self.map_frame):
                raise NavigatorInputError(f"map refused: frame {msg.header.frame_id!r}, expected "
                                          f"{self.map_frame!r}")
            o = msg.info.origin
            values = (o.position.x, o.position.y, o.orientation.x, o.orientation.y,
                      o.orientation.z, o.orientation.w, msg.info.resolution)
            if not all(math.isfinite(v) for v in values):
                raise NavigatorInputError("map refused: origin or resolution not finite")
            geometry = GridGeometry(msg.info.width, msg.info.height, float(msg.info.resolution),
                                    (o.position.x, o.position.y, _yaw(o.orientation)))
            self.nav.set_map(geometry, np.asarray(msg.data, dtype=np.int8))
        except NavigatorInputError as exc:
            self._refuse(str(exc))
            return
        self.counts["maps"] += 1
        self.input_error = ""
        self._step()

    @locked
    def _on_map_update(self, msg):
        if self.nav.geometry is None:
            # Before the first map (or right after a new SLAM map) an update has nothing to patch;
            # the latched map that follows carries it anyway.
            rospy.logwarn_throttle(5.0, "navigator: map update before a map, ignored")
            return
        try:
            if msg.header.frame_id not in ("", self.map_frame):
                raise NavigatorInputError(f"map update refused: frame {msg.header.frame_id!r}")
            self.nav.update_map(msg.x, msg.y, msg.width, msg.height,
                                np.asarray(msg.data, dtype=np.int8))
        except NavigatorInputError as exc:
            self._refuse(str(exc))
            return
        self.counts["map_updates"] += 1
        self._step()

    def _to_map(self, pose_stamped):
        """(x, y) of a pose in the map frame; raises NavigatorInputError when impossible."""
        frame = pose_stamped.header.frame_id or self.map_frame
        p = pose_stamped.pose.position
        q = pose_stamped.pose.orientation
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z, q.x, q.y, q.z, q.w)):
            raise NavigatorInputError(f"goal refused: position ({p.x}, {p.y}, {p.z}) or "
                                      "orientation is not finite")
        if frame == self.map_frame:
            return p.x, p.y
        try:
            tf = self.tf_buffer.lookup_transform(self.map_frame, frame, rospy.Time(0),
                                                 rospy.Duration(0.2))
        except TF_ERRORS as exc:
            raise NavigatorInputError(f"goal refused: no transform from {frame!r} to "
                                      f"{self.map_frame!r}: {exc}") from None
        t = transform_to_matrix(tf.transform) @ pose_to_matrix(pose_stamped.pose)
        return float(t[0, 3]), float(t[1, 3])

    def _new_goal(self, pose_stamped):
        self.counts["goals"] += 1
        try:
            x, y = self._to_map(pose_stamped)
            self.nav.set_goal(x, y)
        except NavigatorInputError as exc:
            self.nav.cancel()
            self._refuse(str(exc))
            return False
        self.input_error = ""
        self._step()
        return True

    @locked
    def _on_simple_goal(self, msg):
        if self.action.is_active():
            self.action.set_preempted(MoveBaseResult(), "replaced by move_base_simple/goal")
        self._new_goal(msg)

    def _on_action_goal(self):
        # actionlib calls this holding its own locks; taking the node's lock here could deadlock
        # against _step, which holds the node's lock while it reports to the action server.
        self.action_goal = self.action.accept_new_goal()

    def _on_action_preempt(self):
        self.action_preempted = True

    def _action_inputs(self):
        """Goals and cancellations the action server received since the last step."""
        goal, self.action_goal = self.action_goal, None
        preempted, self.action_preempted = self.action_preempted, False
        if goal is not None:
            self.served_goal = goal
            if not self._new_goal(goal.target_pose) and self.action.is_active():
                self.action.set_aborted(MoveBaseResult(), self.input_error)
        elif preempted and self.action.is_active():
            self.nav.cancel()
            self.action.set_preempted(MoveBaseResult(), "cancelled")

    @locked
    def _on_slam_state(self, msg):
        index_changed = self.slam_map_index is not None and msg.map_index != self.slam_map_index
        previous = self.slam_state
        self.slam_state, self.slam_map_index = msg.state, msg.map_index
        if msg.state == SlamState.LOST and previous != SlamState.LOST:
            self.nav.on_slam_lost()
        elif msg.state == SlamState.NEW_MAP or (msg.state == SlamState.OK and index_changed
                                                 and previous == SlamState.LOST):
            self.nav.on_slam_new_map()
        elif msg.state == SlamState.OK:
            self.nav.on_slam_ok()
        self._step()

    def _update_pose(self):
        if self.slam_state == SlamState.LOST:
            return  # the last pose before the loss anchors the goal
        try:
            tf = self.tf_buffer.lookup_transform(self.map_frame, self.base_frame, rospy.Time(0))
        except TF_ERRORS:
            return
        t = tf.transform
        try:
            self.nav.set_pose(t.translation.x, t.translation.y, _yaw(t.rotation))
        except NavigatorInputError as exc:
            rospy.logerr_throttle(5.0, f"navigator: {exc}")

    @locked
    def _on_timer(self, _event):
        self._action_inputs()
        self._step()

    def _step(self):
        self._update_pose()
        status = self.nav.update()
        self._publish(status)
        # A goal accepted by actionlib reaches the core at the next timer step; until then the
        # core's status belongs to the previous goal and must not end the new one.
        if self.action.is_active() and self.action.current_goal.get_goal() is self.served_goal:
            if status.state == REACHED:
                self.action.set_succeeded(MoveBaseResult(), status.reason)
            elif status.state in (NO_PATH, REJECTED):
                self.nav.cancel()
                self.action.set_aborted(MoveBaseResult(), status.reason)
            elif self.nav.pose is not None:
                feedback = MoveBaseFeedback()
                feedback.base_position.header.frame_id = self.map_frame
                feedback.base_position.header.stamp = rospy.Time.now()
                feedback.base_position.pose.position = Point(*self.nav.pose[:2], 0.0)
                feedback.base_position.pose.orientation = _quaternion(self.nav.pose[2])
                self.action.publish_feedback(feedback)

    def _publish(self, status):
        stamp = rospy.Time.now()
        if stamp.is_zero():
            # Simulated time before the first /clock: a zero stamp means "no time" to consumers;
            # the next step, with the clock running, publishes this status.
            return
        path = Path()
        path.header.frame_id = self.map_frame
        path.header.stamp = stamp
        path.poses = self._poses(status.path, stamp)
        self.path_pub.publish(path)
        reason = status.reason
        if self.input_error and status.state != REJECTED:
            reason += f" (last refused input: {self.input_error})"
        key = (status.state, reason)
        self.last_status = status
        if key == self.last_published:
            return
        self.last_published = key
        msg = NavigatorStatus()
        msg.header.frame_id = self.map_frame
        msg.header.stamp = stamp
        msg.state = getattr(NavigatorStatus, status.state.upper())
        msg.reason = reason
        msg.has_goal = status.goal is not None
        if msg.has_goal:
            msg.goal = Point(status.goal[0], status.goal[1], 0.0)
        msg.has_target = status.target is not None
        if msg.has_target:
            msg.target = Point(status.target[0], status.target[1], 0.0)
        msg.path_length_m = status.path_length_m
        msg.plan_ms = status.plan_ms
        self.status_pub.publish(msg)
        rospy.loginfo(f"navigator: {status.state}: {reason}")

    def _poses(self, points, stamp):
        poses = []
        for i, (x, y) in enumerate(points):
            nxt = points[i + 1] if i + 1 < len(points) else None
            prv = points[i - 1] if i > 0 else None
            a, b = ((x, y), nxt) if nxt is not None else (prv, (x, y))
            yaw = math.atan2(b[1] - a[1], b[0] - a[0]) if a is not None and b is not None else 0.0
            p = PoseStamped()
            p.header.frame_id = self.map_frame
            p.header.stamp = stamp
            p.pose.position = Point(x, y, 0.0)
            p.pose.orientation = _quaternion(yaw)
            poses.append(p)
        return poses

    @locked
    def _on_make_plan(self, req):
        response = GetPlanResponse()
        response.plan.header.frame_id = self.map_frame
        response.plan.header.stamp = rospy.Time.now()
        try:
            goal = self._to_map(req.goal)
            if req.start.header.frame_id:
                start = self._to_map(req.start)
            elif self.nav.pose is not None:
                start = self.nav.pose[:2]
            else:
                raise NavigatorInputError("make_plan: no start given and no robot pose")
        except NavigatorInputError as exc:
            rospy.logerr_throttle(2.0, f"navigator: {exc}")
            return response
        tolerance = float(req.tolerance) if math.isfinite(req.tolerance) else 0.0
        points, reason = self.nav.make_plan(start, goal, tolerance)
        if reason:
            rospy.logwarn_throttle(2.0, f"navigator: make_plan: {reason}")
        response.plan.poses = self._poses(points, response.plan.header.stamp)
        return response

    @locked
    def _on_diagnostics(self, _event):
        status = self.last_status
        diag = DiagnosticStatus()
        diag.name = "navigator"
        diag.hardware_id = "navigator"
        state = status.state if status else "starting"
        diag.level = DiagnosticStatus.OK if state in ("idle", "following", "reached", "planning") \
            else DiagnosticStatus.WARN
        diag.message = f"{state}: {status.reason if status else ''}"
        g = self.nav.geometry
        values = dict(self.counts)
        values.update(map_size=f"{g.width}x{g.height}" if g else "none",
                      pending_cells=int(self.nav.pending.sum()) if g else 0,
                      plan_ms=f"{status.plan_ms:.2f}" if status else "0",
                      path_length_m=f"{status.path_length_m:.2f}" if status else "0",
                      replans=self.nav.n_replans, slam_state=self.slam_state)
        diag.values = [KeyValue(k, str(v)) for k, v in values.items()]
        array = DiagnosticArray()
        array.header.stamp = rospy.Time.now()
        array.status = [diag]
        self.diag_pub.publish(array)


def main():
    rospy.init_node("navigator")
    try:
        NavigatorNode()
    except ValueError as exc:
        rospy.logfatal(f"navigator: {exc}")
        raise SystemExit(1)
    rospy.spin()
