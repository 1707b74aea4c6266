"""demo: the seed 000 initial scan on the simulator, recorded, then summarised in output_dir.

Writes report.json, cloud.csv (the SLAM map points in the wrapper's frame, as users save them),
summary.png (top view: SLAM points, true walls, trajectories) and run.bag, then exits so that a
launch file with required="true" ends.
"""
import json
import os
import threading

import numpy as np
import rosbag
import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from map_msgs.msg import OccupancyGridUpdate
from nav_msgs.msg import OccupancyGrid, Odometry
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64, Int32, String
from tf2_msgs.msg import TFMessage

from sparse_nav.msg import FloorEstimate, SlamScale, SlamState
from sparse_nav.pointfiles import write_points_csv
from sparse_nav.ros.conversions import cloud_to_points, transform_to_matrix
from sparse_nav.ros.sim_node import load_ros_world
from sparse_nav.ros.robot_io import StepExecutor, TelloClient
from sparse_nav.scanning import initial_scan
from sparse_nav.summary import plot_grid, plot_summary

RECORDED = [
    ("orb_slam3/camera_pose", PoseStamped), ("orb_slam3/tracked_points", PointCloud2),
    ("orb_slam3/all_points", PointCloud2), ("orb_slam3/tracking_state", Int32),
    ("slam/state", SlamState), ("slam/scale", SlamScale), ("slam/points", PointCloud2),
    ("ground_truth/odom", Odometry), ("ground_truth/slam_scale", Float64), ("odom", Odometry),
    ("cmd_vel", Twist), ("tello/command", String), ("tello/response", String),
    ("map", OccupancyGrid), ("map_updates", OccupancyGridUpdate), ("floor_plane", FloorEstimate),
    ("cloud/obstacles", PointCloud2),
    ("/tf", TFMessage), ("/tf_static", TFMessage),
]


def grid_to_array(grid):
    """(height, width) int8 array of a nav_msgs/OccupancyGrid, row 0 at the lowest y."""
    return np.asarray(grid.data, dtype=np.int8).reshape(grid.info.height, grid.info.width)


def grid_stats(grid):
    """Size and cell counts of the occupancy grid, or None when none was received."""
    if grid is None:
        return None
    cells = grid_to_array(grid)
    return {"width": grid.info.width, "height": grid.info.height,
            "resolution_m": round(grid.info.resolution, 4),
            "occupied_cells": int(np.count_nonzero(cells == 100)),
            "free_cells": int(np.count_nonzero(cells == 0)),
            "unknown_cells": int(np.count_nonzero(cells < 0))}


class DemoNode:
    """Drives the scripted scan and records what the stack publishes."""

    def __init__(self):
        self.world_name = rospy.get_param("~world", "one_room")
        self.robot = rospy.get_param("~robot", "drone")
        self.output_dir = os.path.abspath(rospy.get_param("~output_dir", "demo_output"))
        self.response_timeout_s = float(rospy.get_param("~response_timeout_s", 30.0))
        os.makedirs(self.output_dir, exist_ok=True)
        self.lock = threading.Lock()
        self.bag = rosbag.Bag(os.path.join(self.output_dir, "run.bag"), "w")
        self.latest = {}
        self.responses = []
        self.states = []
        self.true_path, self.estimated_path = [], []
        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        for topic, msg_type in RECORDED:
            rospy.Subscriber(topic, msg_type, self._record, callback_args=topic, queue_size=50)

    def _record(self, msg, topic):
        with self.lock:
            if self.bag is not None:
                # Record at sim time: rosbag would otherwise stamp with wall time, and a replay
                # with --clock would then run on a clock unrelated to the message stamps.
                self.bag.write(topic, msg, rospy.Time.now())
            self.latest[topic] = msg
            if topic == "tello/response":
                self.responses.append(msg.data)
            elif topic == "slam/state":
                self.states.append(msg)
            elif topic == "ground_truth/odom":
                p = msg.pose.pose.position
                self.true_path.append((p.x, p.y))

    def _wait_for_clock(self):
        while not rospy.is_shutdown() and rospy.Time.now().is_zero():
            rospy.sleep(0.05)

    def _sample_estimate(self):
        try:
            tf = self.tf_buffer.lookup_transform("sim_world", "base_link", rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException):
            return
        t = tf.transform.translation
        self.estimated_path.append((t.x, t.y))

    def run_scan(self):
        self._wait_for_clock()
        rospy.sleep(1.0)  # let every node subscribe before the first motion
        tello = (TelloClient(self.response_timeout_s, on_wait=self._sample_estimate)
                 if self.robot == "drone" else None)
        executor = StepExecutor(self.robot, tello=tello, on_wait=self._sample_estimate)
        if tello is not None:
            for command in ("command", "takeoff"):
                rospy.loginfo("demo: %s -> %s", command, tello.send(command))
        for step in initial_scan():
            if not executor.execute(step):
                rospy.logwarn("demo: step %s was not carried out completely", step)
        if tello is not None:
            rospy.loginfo("demo: land -> %s", tello.send("land"))
        rospy.sleep(1.0)

    def write_outputs(self):
        with self.lock:
            bag, self.bag = self.bag, None
            latest = dict(self.latest)
            states = list(self.states)
        bag.close()
        raw = latest.get("orb_slam3/all_points")
        raw_points = cloud_to_points(raw) if raw is not None else np.empty((0, 3))
        write_points_csv(os.path.join(self.output_dir, "cloud.csv"), raw_points)

        world = load_ros_world(self.world_name)
        map_points = np.empty((0, 3))
        t_truth_map = None
        try:
            tf = self.tf_buffer.lookup_transform("sim_world", "map", rospy.Time(0))
            t_truth_map = transform_to_matrix(tf.transform)
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException) as exc:
            rospy.logwarn("demo: no map -> sim_world alignment, map not drawn: %s", exc)
        if "slam/points" in latest and t_truth_map is not None:
            map_points = cloud_to_points(latest["slam/points"])
            map_points = map_points @ t_truth_map[:3, :3].T + t_truth_map[:3, 3]
        grid = latest.get("map")
        if grid is not None and t_truth_map is not None:
            plot_grid(os.path.join(self.output_dir, "map.png"), world, grid_to_array(grid),
                      grid.info.resolution, (grid.info.origin.position.x, grid.info.origin.position.y),
                      t_truth_map, title=f"{world.name}: occupancy grid (sim_world frame)")
        plot_summary(os.path.join(self.output_dir, "summary.png"), world, map_points,
                     self.true_path, self.estimated_path,
                     title=f"{world.name}, {self.robot}: {len(raw_points)} SLAM points")

        scale = latest.get("slam/scale")
        true_scale = latest.get("ground_truth/slam_scale")
        estimated = scale.metres_per_unit if scale else None
        truth = true_scale.data if true_scale else None
        report = {
            "world": world.name,
            "robot": self.robot,
            "sim_time_s": round(rospy.Time.now().to_sec(), 2),
            "slam_points": int(len(raw_points)),
            "tracking_losses": sum(1 for s in states if s.state == SlamState.LOST),
            "slam_maps": len({s.map_index for s in states}),
            "final_slam_state": states[-1].reason if states else "no state received",
            "scale": {
                "estimated_metres_per_unit": estimated,
                "confidence": scale.confidence if scale else 0.0,
                "source": scale.source if scale else None,
                "samples": scale.n_samples if scale else 0,
                "true_metres_per_unit": truth,
                "relative_error": (abs(estimated - truth) / truth) if estimated and truth else None,
            },
            "map": grid_stats(grid),
            "drone_responses": {"ok": self.responses.count("ok"),
                                "error": sum(1 for r in self.responses if r.startswith("error"))},
        }
        path = os.path.join(self.output_dir, "report.json")
        with open(path + ".tmp", "w") as f:
            json.dump(report, f, indent=1)
        os.replace(path + ".tmp", path)
        rospy.loginfo("demo: wrote %s", self.output_dir)


def main():
    rospy.init_node("demo")
    node = DemoNode()
    try:
        node.run_scan()
    except rospy.ROSInterruptException:
        return
    node.write_outputs()
