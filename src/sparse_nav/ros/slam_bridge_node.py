"""slam_bridge: REP-105 TF, SLAM health and metric scale from an ORB-SLAM3 wrapper's topics."""
import threading

import numpy as np
import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Int32, String

from sparse_nav.msg import FloorEstimate, SlamScale, SlamState
from sparse_nav.ros.conversions import (CloudError, cloud_to_points, matrix_to_transform_stamped,
                                        points_to_cloud, pose_to_matrix, transform_to_matrix)
from sparse_nav.slam_bridge import (LOST, NEW_MAP, OK, STATE_NAMES, BridgeConfig, DroneMoveScale,
                                    MapAnchors, MapScales, StateTracker,
                                    odometry_camera_position)
from sparse_nav.transforms import invert
from sparse_nav.ros.params import locked, read_fields


def _config_from_params():
    cfg = BridgeConfig()
    read_fields(cfg, ("pose_timeout_s", "min_tracked_points", "relocalise_tolerance_m",
                      "jump_threshold_m", "merge_sample_points", "merge_match_tolerance",
                      "merge_min_share", "merge_scale_tolerance"))
    cfg.validate()
    return cfg


class SlamBridgeNode:
    """Glue between the wrapper's topics and the ROS-free bridge core."""

    def __init__(self):
        self.cfg = _config_from_params()
        self.map_frame = rospy.get_param("~map_frame", "map")
        self.odom_frame = rospy.get_param("~odom_frame", "odom")
        self.base_frame = rospy.get_param("~base_frame", "base_link")
        self.camera_frame = rospy.get_param("~camera_frame", "camera_optical")
        self.publish_odom_tf = rospy.get_param("~publish_odom_tf", True)
        self.scale_source = rospy.get_param("~scale_source", "parameter")
        if self.scale_source not in ("parameter", "odometry", "drone_commands", "camera_height"):
            raise ValueError(f"~scale_source must be parameter, odometry, drone_commands or "
                             f"camera_height, got {self.scale_source!r}")
        self.camera_height_m = float(rospy.get_param("~camera_height_m", 0.0))
        if self.scale_source == "camera_height" and not self.camera_height_m > 0:
            raise ValueError("~scale_source camera_height needs ~camera_height_m > 0")
        metres_per_unit = float(rospy.get_param("~metres_per_unit", 1.0))
        if not metres_per_unit > 0:
            raise ValueError(f"~metres_per_unit must be > 0, got {metres_per_unit}")
        self.rate_hz = float(rospy.get_param("~rate_hz", 20.0))

        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(10.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.tf_broadcaster = tf2_ros.TransformBroadcaster()
        self.t_base_cam = self._camera_mount()

        self.tracker = StateTracker(self.cfg)
        self.anchors = MapAnchors(self.cfg, self.t_base_cam)
        self.scales = MapScales(prior_metres_per_unit=metres_per_unit)
        self.drone_moves = DroneMoveScale()
        self.t_map_base = None
        self.t_map_odom = np.eye(4)
        self.last_slam_position = None
        self.last_odom_position = None
        self.state, self.reason = None, ""
        self.given_up_published = False
        self.new_map_pending = False
        self.n_poses = 0
        self.n_points = 0
        self.points_before_loss = 0
        self.reacquiring = False
        self.map_event = ""
        self.last_tf_stamp = None
        # Subscriber and timer callbacks run on their own threads and share the state below.
        self.lock = threading.RLock()
        self.bad_inputs = 0

        self.state_pub = rospy.Publisher("slam/state", SlamState, queue_size=10, latch=True)
        self.scale_pub = rospy.Publisher("slam/scale", SlamScale, queue_size=10, latch=True)
        self.points_pub = rospy.Publisher("slam/points", PointCloud2, queue_size=2)
        self.diag_pub = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=10)

        rospy.Subscriber("orb_slam3/camera_pose", PoseStamped, self._on_pose, queue_size=20)
        rospy.Subscriber("orb_slam3/tracked_points", PointCloud2, self._on_tracked, queue_size=5)
        rospy.Subscriber("orb_slam3/all_points", PointCloud2, self._on_all_points, queue_size=2)
        rospy.Subscriber("orb_slam3/tracking_state", Int32, self._on_wrapper_state, queue_size=20)
        if self.scale_source == "odometry":
            rospy.Subscriber("odom", Odometry, self._on_odom, queue_size=50)
        if self.scale_source == "camera_height":
            rospy.Subscriber("floor_plane", FloorEstimate, self._on_floor, queue_size=5)
        if self.scale_source == "drone_commands":
            rospy.Subscriber("tello/command", String, self._on_drone_command, queue_size=20)
            rospy.Subscriber("tello/response", String, self._on_drone_response, queue_size=20)

        self._publish_scale()
        rospy.Timer(rospy.Duration(1.0 / self.rate_hz), self._on_timer)
        rospy.Timer(rospy.Duration(1.0), self._on_diagnostics)

    def _camera_mount(self):
        """T_base_cameraOptical from TF (static publisher in the launch file), waiting for it."""
        deadline = rospy.Time.now() + rospy.Duration(30.0)
        while not rospy.is_shutdown():
            try:
                tf = self.tf_buffer.lookup_transform(self.base_frame, self.camera_frame,
                                                     rospy.Time(0), rospy.Duration(1.0))
                return transform_to_matrix(tf.transform)
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                    tf2_ros.ExtrapolationException):
                if rospy.Time.now() > deadline:
                    raise RuntimeError(f"no TF {self.base_frame} -> {self.camera_frame}: "
                                       "publish the camera mounting")
        raise rospy.ROSInterruptException("shutdown while waiting for the camera mounting")

    def _bad_input(self, what):
        self.bad_inputs += 1
        rospy.logerr_throttle(5.0, f"slam_bridge: ignoring {what}")

    def _on_wrapper_state(self, msg):
        with self.lock:
            if self.tracker.on_wrapper_state(msg.data):
                self.anchors.expect_new_map()
            self._update_state(rospy.Time.now())

    def _on_tracked(self, msg):
        self.tracker.on_tracked_points(msg.width * msg.height)

    def _on_pose(self, msg):
        try:
            t_slam_cam = pose_to_matrix(msg.pose)
        except ValueError as exc:
            self._bad_input(f"camera pose: {exc}")
            return
        with self.lock:
            gap = self.tracker.on_pose(msg.header.stamp.to_sec())
            if gap is not None and self.state == OK:
                # The timer may have slept through the whole loss on a loaded machine.
                self._publish_state(LOST, f"no camera pose for {gap:.2f} s", rospy.Time.now())
                self._lose_tracking()
                self.state = LOST
            self._use_pose(msg, t_slam_cam)

    def _use_pose(self, msg, t_slam_cam):
        state, _ = self.tracker.evaluate(rospy.Time.now().to_sec())
        if state != OK:
            return
        self.n_poses += 1
        metres_per_unit, _, _ = self.scales.current.estimate()
        t_map_base, event = self.anchors.update(t_slam_cam, metres_per_unit,
                                                msg.header.stamp.to_sec())
        self.reacquiring = False
        self._on_map_event(event)
        self.t_map_base = t_map_base
        self.last_slam_position = t_slam_cam[:3, 3].copy()
        sample = self.drone_moves.on_pose(self.last_slam_position)
        if sample is not None and self.scales.current.add(*sample):
            self._apply_scale()
        if not self.publish_odom_tf:
            self._update_map_odom(msg.header.stamp)

    def _on_map_event(self, event):
        self.scales.on_map_event(self.anchors.current.index, event)
        if event == "reframed":
            rospy.logwarn("slam_bridge: the pose jumped while tracking in map %d and no earlier "
                          "map explains it: re-anchored where the robot was",
                          self.anchors.current.index)
        if event in ("new_map", "switched", "reframed"):
            self._forget_scale_pairs()
        if event in ("new_map", "switched"):
            self.new_map_pending = True
            self.map_event = (f"SLAM started a new map (index {self.anchors.current.index})"
                              if event == "new_map" else
                              f"SLAM merged back into map {self.anchors.current.index}")
            self._publish_scale()  # the new map's own scale, or the prior it starts from

    def _forget_scale_pairs(self):
        """The SLAM frame changed: a scale sample across it would pair positions in two."""
        self.drone_moves.invalidate()
        self.last_slam_position = None
        self.last_odom_position = None

    def _update_map_odom(self, stamp):
        try:
            tf = self.tf_buffer.lookup_transform(self.odom_frame, self.base_frame, stamp,
                                                 rospy.Duration(0.1))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException) as exc:
            rospy.logwarn_throttle(5.0, f"slam_bridge: no {self.odom_frame} -> "
                                        f"{self.base_frame} at the pose time: {exc}")
            return
        except rospy.ROSInterruptException:
            return  # shut down while waiting for the transform: the last map -> odom stays
        self.t_map_odom = self.t_map_base @ invert(transform_to_matrix(tf.transform))

    @locked
    def _on_all_points(self, msg):
        try:
            points = cloud_to_points(msg)
        except CloudError as exc:
            self._bad_input(f"orb_slam3/all_points: {exc}")
            return
        points = points[np.all(np.isfinite(points), axis=1)]
        anchor = self.anchors.current
        if self.reacquiring:
            # ORB-SLAM3 publishes only the active map: a collapsed count means a new map.
            if self.points_before_loss and len(points) < 0.5 * self.points_before_loss:
                self.anchors.expect_new_map()
                self.points_before_loss = 0
            return
        if anchor is None or self.state != OK:
            return
        if self.anchors.is_late(msg.header.stamp.to_sec()):
            return  # the map before the current one: it would read as a merge into it
        if self.anchors.on_cloud(points) is not None:
            self._on_map_event("switched")
            anchor = self.anchors.current
        self.points_before_loss = len(points)
        merge = self.anchors.merge
        source = None if merge is None else self.scales.on_merge(merge)
        moved = merge is not None and merge.left == merge.into
        if moved or source is not None:
            value, _, n = self.scales.current.estimate()
            self.anchors.rescale(value)
            self._publish_scale()
            carried = ("no ratio of units measured: its scale samples dropped" if source is None
                       else f"the cloud holds map {source}'s points at "
                            f"{merge.units_ratios[source]:.3f} of its units to one: their scale "
                            f"samples carried over ({value:.3f} m per unit from {n})")
            if moved:
                self._forget_scale_pairs()
                rospy.logwarn("slam_bridge: map %d's points moved and no known map's points are "
                              "in its cloud (SLAM merged it into a map whose points it moved "
                              "too); %s; the map re-anchored where the robot is",
                              merge.into, carried)
            else:
                rospy.loginfo("slam_bridge: SLAM merged map %d into map %d; %s; the map "
                              "re-anchored where the robot is", merge.left, merge.into, carried)
            return  # in the map's old frame or scale; the next pose re-anchors it
        metric = points * anchor.metres_per_unit
        metric = metric @ anchor.t_map_slam[:3, :3].T + anchor.t_map_slam[:3, 3]
        self.n_points = len(metric)
        header = msg.header
        header.frame_id = self.map_frame
        self.points_pub.publish(points_to_cloud(metric, header))

    @locked
    def _on_odom(self, msg):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        odom_position = odometry_camera_position((p.x, p.y, p.z), (q.x, q.y, q.z, q.w),
                                                 self.t_base_cam)
        if self.state != OK or self.last_slam_position is None:
            self.last_odom_position = None
            return
        if self.last_odom_position is None:
            self.last_odom_position = odom_position
            self._odom_slam_start = self.last_slam_position.copy()
            return
        metric = float(np.linalg.norm(odom_position - self.last_odom_position))
        if metric >= 0.3:
            slam = float(np.linalg.norm(self.last_slam_position - self._odom_slam_start))
            if self.scales.current.add(slam, metric):
                self._apply_scale()
            self.last_odom_position = odom_position
            self._odom_slam_start = self.last_slam_position.copy()

    @locked
    def _on_floor(self, msg):
        """The camera's measured height above the floor against its known height gives the scale."""
        anchor = self.anchors.current
        if self.state != OK or anchor is None or not np.isfinite(msg.camera_height):
            return
        if msg.header.frame_id != self.map_frame:
            self._bad_input(f"floor_plane in frame {msg.header.frame_id!r}, expected "
                            f"{self.map_frame!r}")
            return
        if self.scales.current.add(msg.camera_height / anchor.metres_per_unit, self.camera_height_m):
            self._apply_scale()

    def _current_slam_position(self):
        return self.last_slam_position if self.state == OK else None

    @locked
    def _on_drone_command(self, msg):
        self.drone_moves.on_command(msg.data, self._current_slam_position())

    @locked
    def _on_drone_response(self, msg):
        self.drone_moves.on_response(msg.data, self._current_slam_position())

    def _apply_scale(self):
        self.anchors.set_scale(self.scales.current.estimate()[0])
        self._publish_scale()

    def _publish_scale(self):
        value, confidence, n = self.scales.current.estimate()
        msg = SlamScale()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.map_frame
        msg.metres_per_unit = value
        msg.confidence = confidence
        msg.n_samples = n
        msg.source = self.scale_source if n else "parameter"
        msg.map_index = self.anchors.current.index if self.anchors.current else 0
        self.scale_pub.publish(msg)

    def _lose_tracking(self):
        self.reacquiring = True
        self.anchors.tracking_lost()
        self.drone_moves.invalidate()
        self.last_odom_position = None

    def _on_timer(self, _event):
        now = rospy.Time.now()
        with self.lock:
            self._update_state(now)
            self._publish_tf(now)

    def _update_state(self, now):
        state, reason = self.tracker.evaluate(now.to_sec())
        if state != OK and self.state == OK:
            self._lose_tracking()
        if state == OK and self.reacquiring:
            return  # the next pose tells whether this is the old map, an earlier one or a new one
        published = state
        if state == OK and self.new_map_pending:
            published, reason = NEW_MAP, self.map_event
            self.new_map_pending = False
        given_up = published == LOST and self.tracker.map_given_up
        if published != self.state or published == NEW_MAP or given_up != self.given_up_published:
            self._publish_state(published, reason, now)
        self.state = OK if published == NEW_MAP else state
        self.reason = reason

    def _publish_state(self, state, reason, stamp):
        msg = SlamState()
        msg.header.stamp = stamp
        msg.header.frame_id = self.map_frame
        msg.state = state
        msg.map_index = self.anchors.current.index if self.anchors.current else 0
        msg.n_tracked_points = self.tracker.n_tracked
        msg.map_given_up = self.given_up_published = state == LOST and self.tracker.map_given_up
        msg.source = self.tracker.source
        msg.reason = reason
        self.state_pub.publish(msg)
        log = rospy.logwarn if state in (LOST, NEW_MAP) else rospy.loginfo
        log("slam_bridge: %s (%s)", STATE_NAMES[state], reason)

    def _publish_tf(self, stamp):
        # Under /clock the timer can fire twice at one sim time; tf2 rejects repeated stamps.
        if self.t_map_base is None or stamp == self.last_tf_stamp:
            return
        self.last_tf_stamp = stamp
        transforms = []
        if self.publish_odom_tf:
            transforms.append(matrix_to_transform_stamped(np.eye(4), stamp, self.map_frame,
                                                          self.odom_frame))
            transforms.append(matrix_to_transform_stamped(self.t_map_base, stamp,
                                                          self.odom_frame, self.base_frame))
        else:
            transforms.append(matrix_to_transform_stamped(self.t_map_odom, stamp, self.map_frame,
                                                          self.odom_frame))
        self.tf_broadcaster.sendTransform(transforms)

    def _on_diagnostics(self, _event):
        value, confidence, n = self.scales.current.estimate()
        status = DiagnosticStatus()
        status.name = "slam_bridge"
        status.hardware_id = "slam"
        status.level = DiagnosticStatus.OK if self.state == OK else DiagnosticStatus.WARN
        status.message = f"{STATE_NAMES.get(self.state, 'starting')}: {self.reason}"
        status.values = [KeyValue(k, str(v)) for k, v in (
            ("tracking_source", self.tracker.source), ("tracked_points", self.tracker.n_tracked),
            ("map_points", self.n_points), ("poses_used", self.n_poses),
            ("maps", len(self.anchors.anchors)), ("metres_per_unit", f"{value:.4f}"),
            ("scale_confidence", f"{confidence:.2f}"), ("scale_samples", n),
            ("bad_inputs", self.bad_inputs))]
        msg = DiagnosticArray()
        msg.header.stamp = rospy.Time.now()
        msg.status = [status]
        self.diag_pub.publish(msg)


def main():
    rospy.init_node("slam_bridge")
    try:
        SlamBridgeNode()
    except (ValueError, RuntimeError) as exc:
        rospy.logfatal(f"slam_bridge: {exc}")
        raise SystemExit(1)
    rospy.spin()
