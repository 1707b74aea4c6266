"""sim: the built-in ORB-SLAM3 + robot simulator, publishing what an ORB-SLAM3 wrapper publishes."""
import os
import time

import numpy as np
import rospkg
import rospy
import tf2_ros
from geometry_msgs.msg import Point, PoseStamped, Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import ColorRGBA, Float64, Header, Int32, String
from visualization_msgs.msg import Marker, MarkerArray

from sparse_nav.ros.conversions import matrix_to_pose, matrix_to_transform_stamped, points_to_cloud
from sparse_nav.sim import DroneCommandError, SimConfig, Simulator, TrackingState, load_world
from sparse_nav.transforms import invert, planar


def load_ros_world(name_or_path):
    """A world by name from this package's share directory (source or install space), or a path."""
    shipped = os.path.join(rospkg.RosPack().get_path("sparse_nav"), "worlds", f"{name_or_path}.yaml")
    return load_world(shipped if os.path.isfile(shipped) else name_or_path)


class SimNode:
    """Steps the ROS-free simulator on its own clock and publishes its outputs."""

    def __init__(self):
        world_name = rospy.get_param("~world", "one_room")
        self.world = load_ros_world(world_name)
        cfg = SimConfig()
        cfg.robot = rospy.get_param("~robot", cfg.robot)
        cfg.seed = int(rospy.get_param("~seed", cfg.seed))
        cfg.force_loss_at_s = [float(t) for t in rospy.get_param("~force_loss_at_s",
                                                                 list(cfg.force_loss_at_s))]
        cfg.force_loss_duration_s = float(rospy.get_param("~force_loss_duration_s",
                                                          cfg.force_loss_duration_s))
        if cfg.robot not in ("ground", "drone"):
            raise ValueError(f"~robot must be 'ground' or 'drone', got {cfg.robot!r}")
        self.sim = Simulator(self.world, cfg)
        self.robot = cfg.robot
        self.rate_factor = float(rospy.get_param("~rate_factor", 1.0))
        # A lossy link between the SLAM process and the rest (benches): whole SLAM outputs vanish.
        self.drop_fraction = float(rospy.get_param("~slam_message_drop_fraction", 0.0))
        if not 0.0 <= self.drop_fraction < 1.0:
            raise ValueError(f"slam_message_drop_fraction must be in [0, 1): {self.drop_fraction}")
        self.drop_rng = np.random.default_rng(cfg.seed + 1)
        self.physics_rate_hz = float(rospy.get_param("~physics_rate_hz", 50.0))
        self.all_points_rate_hz = float(rospy.get_param("~all_points_rate_hz", 2.0))
        self.odom_rate_hz = float(rospy.get_param("~odom_rate_hz", 20.0))
        self.cmd_vel_timeout_s = float(rospy.get_param("~cmd_vel_timeout_s", 0.5))
        self.publish_tracking_state = bool(rospy.get_param("~publish_tracking_state", True))
        self.publish_odom_tf = bool(rospy.get_param("~publish_odom_tf", self.robot == "ground"))
        self.publish_ground_truth_tf = bool(rospy.get_param("~publish_ground_truth_tf", True))
        self.slam_frame = rospy.get_param("~slam_frame", "world")
        self.slam_camera_frame = rospy.get_param("~slam_camera_frame", "camera")
        self.truth_frame = rospy.get_param("~truth_frame", "sim_world")
        self.map_frame = rospy.get_param("~map_frame", "map")
        self.odom_frame = rospy.get_param("~odom_frame", "odom")
        self.base_frame = rospy.get_param("~base_frame", "base_link")
        self.camera_frame = rospy.get_param("~camera_frame", "camera_optical")
        if self.physics_rate_hz <= 0 or self.all_points_rate_hz <= 0 or self.odom_rate_hz <= 0:
            raise ValueError("rates must be > 0")

        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=10)
        self.pose_pub = rospy.Publisher("orb_slam3/camera_pose", PoseStamped, queue_size=10)
        self.all_pub = rospy.Publisher("orb_slam3/all_points", PointCloud2, queue_size=2)
        self.tracked_pub = rospy.Publisher("orb_slam3/tracked_points", PointCloud2, queue_size=5)
        self.state_pub = rospy.Publisher("orb_slam3/tracking_state", Int32, queue_size=10)
        self.truth_pub = rospy.Publisher("ground_truth/odom", Odometry, queue_size=10)
        self.truth_scale_pub = rospy.Publisher("ground_truth/slam_scale", Float64, queue_size=10)
        self.world_pub = rospy.Publisher("ground_truth/world", MarkerArray, queue_size=1, latch=True)
        self.odom_pub = rospy.Publisher("odom", Odometry, queue_size=20)
        self.response_pub = rospy.Publisher("tello/response", String, queue_size=20)
        self.tf_broadcaster = tf2_ros.TransformBroadcaster()
        self.static_broadcaster = tf2_ros.StaticTransformBroadcaster()

        self.static_transforms = []
        self._send_static(self.sim.camera_mount(), self.base_frame, self.camera_frame)
        self.last_cmd_vel_s = None
        self.next_all_points_s = 0.0
        self.next_odom_s = 0.0
        self.truth_tf_sent = False
        if self.robot == "ground":
            rospy.Subscriber("cmd_vel", Twist, self._on_cmd_vel, queue_size=10)
        else:
            rospy.Subscriber("tello/command", String, self._on_drone_command, queue_size=20)
        self.world_pub.publish(self._world_markers())
        rospy.loginfo("sim: world %s, robot %s, %d walls, %d exits, rate factor %.1f",
                      self.world.name, self.robot, len(self.world.wall_segments()),
                      len(self.world.exits), self.rate_factor)

    def _stamp(self):
        return rospy.Time.from_sec(self.sim.time_s)

    def _on_cmd_vel(self, msg):
        v, w = msg.linear.x, msg.angular.z
        if not (np.isfinite(v) and np.isfinite(w)):
            rospy.logerr_throttle(5.0, "sim: ignoring cmd_vel with non-finite values")
            return
        self.sim.set_cmd_vel(v, w)
        self.last_cmd_vel_s = self.sim.time_s

    def _on_drone_command(self, msg):
        try:
            self.sim.drone_command(msg.data)
        except DroneCommandError as exc:
            rospy.logwarn("sim: drone command refused: %s", exc)
            self.response_pub.publish(String(data=f"error: {exc}"))

    def run(self):
        dt = 1.0 / self.physics_rate_hz
        wall_start = time.monotonic()
        sim_start = self.sim.time_s
        last_output = None
        losses = 0
        while not rospy.is_shutdown():
            if (self.robot == "ground" and self.last_cmd_vel_s is not None
                    and self.sim.time_s - self.last_cmd_vel_s > self.cmd_vel_timeout_s):
                self.sim.set_cmd_vel(0.0, 0.0)  # a base stops when its driver goes quiet
                self.last_cmd_vel_s = None
            self.sim.step(dt)
            self.clock_pub.publish(Clock(clock=self._stamp()))
            output = self.sim.slam_output()
            if output is not None and output is not last_output:
                self._publish_slam(output)
                last_output = output
            if self.sim.tracking_losses != losses:
                losses = self.sim.tracking_losses
                rospy.loginfo("sim: SLAM tracking lost (%d so far): %s", losses,
                              self.sim.last_loss_cause)
            for command, response in self.sim.pop_drone_responses():
                self.response_pub.publish(String(data=response))
            if self.sim.time_s >= self.next_odom_s:
                self._publish_odometry()
                self.next_odom_s = self.sim.time_s + 1.0 / self.odom_rate_hz
            if self.rate_factor > 0:
                ahead = (self.sim.time_s - sim_start) / self.rate_factor - (time.monotonic()
                                                                            - wall_start)
                if ahead > 0:
                    time.sleep(ahead)

    def _publish_slam(self, out):
        if self.drop_fraction and self.drop_rng.random() < self.drop_fraction:
            return
        stamp = rospy.Time.from_sec(out.stamp_s)
        header = Header(stamp=stamp, frame_id=self.slam_frame)
        if self.publish_tracking_state:
            self.state_pub.publish(Int32(data=int(out.state)))
        if out.state == TrackingState.OK and out.T_slam_camera is not None:
            if not self.truth_tf_sent and self.publish_ground_truth_tf:
                self._send_truth_alignment()
            self.pose_pub.publish(PoseStamped(header=header, pose=matrix_to_pose(out.T_slam_camera)))
            self.tf_broadcaster.sendTransform(matrix_to_transform_stamped(
                out.T_slam_camera, stamp, self.slam_frame, self.slam_camera_frame))
            self.tracked_pub.publish(points_to_cloud(out.tracked_points, header))
        if out.stamp_s >= self.next_all_points_s and len(out.all_points):
            self.all_pub.publish(points_to_cloud(out.all_points, header))
            self.next_all_points_s = out.stamp_s + 1.0 / self.all_points_rate_hz
        true_scale = self.sim.true_slam_scale()
        if np.isfinite(true_scale):  # no SLAM map, no scale
            self.truth_scale_pub.publish(Float64(data=float(true_scale)))

    def _send_truth_alignment(self):
        """map -> sim_world, so rviz can draw the true walls under the estimate.

        slam_bridge puts base_link at the map origin on the first tracked frame; the true base pose
        of that frame therefore relates the two. This is a display aid, not used for estimation.
        """
        x, y, _, yaw = self.sim.true_base_pose()
        self._send_static(invert(planar(x, y, 0.0, yaw)), self.map_frame, self.truth_frame)
        self.truth_tf_sent = True

    def _send_static(self, t, parent, child):
        # One latched /tf_static message carries all of this node's static transforms.
        self.static_transforms.append(matrix_to_transform_stamped(t, self._stamp(), parent, child))
        self.static_broadcaster.sendTransform(self.static_transforms)

    def _publish_odometry(self):
        stamp = self._stamp()
        x, y, z, yaw = self.sim.true_base_pose()
        truth = Odometry()
        truth.header = Header(stamp=stamp, frame_id=self.truth_frame)
        truth.child_frame_id = self.base_frame
        truth.pose.pose = matrix_to_pose(planar(x, y, z, yaw))
        self.truth_pub.publish(truth)
        odometry = self.sim.odometry()
        if odometry is None:
            return
        t_odom_base = planar(odometry[0], odometry[1], 0.0, odometry[2])
        odom = Odometry()
        odom.header = Header(stamp=stamp, frame_id=self.odom_frame)
        odom.child_frame_id = self.base_frame
        odom.pose.pose = matrix_to_pose(t_odom_base)
        self.odom_pub.publish(odom)
        if self.publish_odom_tf:
            self.tf_broadcaster.sendTransform(matrix_to_transform_stamped(
                t_odom_base, stamp, self.odom_frame, self.base_frame))

    def _world_markers(self):
        stamp = rospy.Time(0)
        walls = Marker(header=Header(stamp=stamp, frame_id=self.truth_frame), ns="walls", id=0,
                       type=Marker.LINE_LIST, action=Marker.ADD)
        walls.scale.x = 0.08
        walls.color = ColorRGBA(0.85, 0.85, 0.85, 1.0)
        walls.pose.orientation.w = 1.0
        for x1, y1, x2, y2 in self.world.wall_segments():
            walls.points += [Point(x1, y1, 0.0), Point(x2, y2, 0.0)]
        markers = [walls]
        for i, exit_ in enumerate(self.world.exits):
            m = Marker(header=Header(stamp=stamp, frame_id=self.truth_frame), ns="exits", id=i,
                       type=Marker.CYLINDER, action=Marker.ADD)
            m.pose.position = Point(exit_["x"], exit_["y"], 0.05)
            m.pose.orientation.w = 1.0
            m.scale.x = m.scale.y = float(exit_.get("width_m", 1.0))
            m.scale.z = 0.1
            m.color = ColorRGBA(0.0, 0.8, 0.0, 0.6)
            markers.append(m)
        return MarkerArray(markers=markers)


def main():
    rospy.init_node("sim")
    try:
        node = SimNode()
    except Exception as exc:  # noqa: BLE001 - world and parameter errors end the node with a reason
        rospy.logfatal(f"sim: {exc}")
        raise SystemExit(1)
    try:
        node.run()
    except rospy.ROSInterruptException:
        pass
