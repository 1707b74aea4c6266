"""demo: records the escape mission on the simulator and summarises it in output_dir.

The conductor runs the mission; this node only watches. It ends when the conductor is done or
gave up (or at sim_time_limit_s) and writes report.json, cloud.csv (the SLAM map points in the
wrapper's frame, as users save them), summary.png (top view: SLAM points, true walls, tracks, the
exit found and the room lines next to it, the last path), map.png, run.mp4 (top view over time)
and run.bag, then exits so that a launch file with required="true" ends.
"""
import collections
import json
import os
import threading

import numpy as np
import rosbag
import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from map_msgs.msg import OccupancyGridUpdate
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64, Int32, String
from tf2_msgs.msg import TFMessage

from sparse_nav.mission_report import (LookArounds, MapAlignments, ScaleByMap, evaluate,
                                       mission_end_s, tracking_losses)
from sparse_nav.msg import ConductorState, ExitCandidates, FloorEstimate, SlamScale, SlamState
from sparse_nav.pointfiles import write_points_csv
from sparse_nav.ros.conversions import cloud_to_points, pose_to_matrix, transform_to_matrix
from sparse_nav.ros.sim_node import load_ros_world
from sparse_nav.summary import plot_grid, plot_summary
from sparse_nav.transforms import apply_planar
from sparse_nav.video import TopViewVideo

RECORDED = [
    ("orb_slam3/camera_pose", PoseStamped), ("orb_slam3/tracked_points", PointCloud2),
    ("orb_slam3/all_points", PointCloud2), ("orb_slam3/tracking_state", Int32),
    ("slam/state", SlamState), ("slam/scale", SlamScale), ("slam/points", PointCloud2),
    ("ground_truth/odom", Odometry), ("ground_truth/slam_scale", Float64), ("odom", Odometry),
    ("cmd_vel", Twist), ("tello/command", String), ("tello/response", String),
    ("map", OccupancyGrid), ("map_updates", OccupancyGridUpdate), ("floor_plane", FloorEstimate),
    ("cloud/obstacles", PointCloud2), ("conductor/state", ConductorState),
    ("navigator/path", Path), ("exit_candidates", ExitCandidates),
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
        self.sim_time_limit_s = float(rospy.get_param("~sim_time_limit_s", 900.0))
        self.frame_period_s = float(rospy.get_param("~video_frame_period_s", 1.0))
        self.world = load_ros_world(self.world_name)
        self.conductor_states = []
        self.look_arounds = LookArounds(self.world)
        self.scale_by_map = ScaleByMap()
        self.t_truth_map = None  # the simulator's map -> sim_world, for the first SLAM map
        self.alignments = MapAlignments()
        self.clouds = {}  # SLAM map index -> its newest slam/points
        self.truth_history = collections.deque(maxlen=200)  # ground_truth/odom, for alignment
        # Places in the map frame put in sim_world with the alignment of the moment they were
        # published: after a SLAM map switch the map frame's relation to the truth changes.
        self.exit_truth = {}
        self.outline_truth = None
        os.makedirs(self.output_dir, exist_ok=True)
        self.lock = threading.RLock()  # _record converts places with _truth_from_map, which locks
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
            elif topic == "slam/points" and self.states:
                self.clouds[self.states[-1].map_index] = msg
            elif topic == "slam/state":
                self.states.append(msg)
                self.scale_by_map.on_state(msg.state in (SlamState.OK, SlamState.NEW_MAP),
                                           msg.map_index)
            elif topic == "slam/scale":
                self.scale_by_map.on_estimate(msg.map_index, msg.metres_per_unit, msg.confidence,
                                              msg.n_samples, msg.source)
            elif topic == "ground_truth/slam_scale":
                self.scale_by_map.on_truth(msg.data)
            elif topic == "conductor/state":
                self.conductor_states.append(msg)
                self.look_arounds.observe(rospy.Time.now().to_sec(), msg.phase, msg.reason,
                                          self.true_path[-1] if self.true_path else None)
            elif topic == "ground_truth/odom":
                p = msg.pose.pose.position
                self.true_path.append((p.x, p.y))
                self.truth_history.append(msg)
            if topic == "conductor/state" and msg.has_exit:
                key = (msg.exit.x, msg.exit.y)
                truth = None if key in self.exit_truth else self._to_truth(key)
                if truth is not None:
                    self.exit_truth[key] = tuple(truth[0])
            elif topic == "exit_candidates" and len(msg.room_outline) >= 3:
                outline = self._to_truth([(p.x, p.y) for p in msg.room_outline])
                if outline is not None:
                    self.outline_truth = outline

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

    def _sample_alignment(self):
        """Samples map -> sim_world of the present SLAM map from the estimated and the true base
        pose of one instant.

        The simulator's alignment holds for the first SLAM map only: the bridge anchors each new
        map from a guessed pose (and re-anchors on a merge), and later maps drew rotated against
        the walls. A lost robot's estimate is the last one, not where it is: no sample then.
        """
        with self.lock:
            state = self.states[-1] if self.states else None
            truths = list(self.truth_history)
        if state is None or not truths:
            return
        tracking = state.state in (SlamState.OK, SlamState.NEW_MAP)
        now = rospy.Time.now().to_sec()
        if not tracking:
            self.alignments.add(now, False, state.map_index, None, None)
            return
        try:
            tf = self.tf_buffer.lookup_transform("map", "base_link", rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException):
            return
        stamp = tf.header.stamp.to_sec()
        truth = min(truths, key=lambda m: abs(m.header.stamp.to_sec() - stamp))
        if abs(truth.header.stamp.to_sec() - stamp) > 0.1:
            return
        try:
            t_truth_base = pose_to_matrix(truth.pose.pose)
        except ValueError:
            return
        self.alignments.add(stamp, True, state.map_index, t_truth_base,
                            transform_to_matrix(tf.transform))

    def _truth_from_map(self):
        """4x4 map -> sim_world of the present SLAM map, or None: its sampled alignment, else the
        newest of any map, else the simulator's."""
        with self.lock:
            map_index = self.states[-1].map_index if self.states else None
        sampled = self.alignments.get(map_index)
        if sampled is not None:
            return sampled
        if self.t_truth_map is None:
            try:
                tf = self.tf_buffer.lookup_transform("sim_world", "map", rospy.Time(0))
                self.t_truth_map = transform_to_matrix(tf.transform)
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                    tf2_ros.ExtrapolationException):
                return None
        return self.t_truth_map

    def _to_truth(self, xy):
        """(N, 2) map-frame points in sim_world with the present alignment, or None."""
        t = self._truth_from_map()
        return None if t is None else apply_planar(t, xy)

    def _found_exit(self):
        """The exit the conductor heads for, in the truth frame, or None."""
        with self.lock:
            last = self.conductor_states[-1] if self.conductor_states else None
            if last is None or not last.has_exit:
                return None
            return self.exit_truth.get((last.exit.x, last.exit.y))

    def _frame(self, video):
        with self.lock:
            grid = self.latest.get("map")
            path = self.latest.get("navigator/path")
            state = self.conductor_states[-1] if self.conductor_states else None
            true_track = list(self.true_path)
            estimated = list(self.estimated_path)
        cells_xy = None
        planned = []
        t_truth_map = self._truth_from_map()
        if t_truth_map is not None:
            if grid is not None:
                cells = grid_to_array(grid)
                res = grid.info.resolution
                o = grid.info.origin.position
                centres = []
                for value in (0, 100):
                    rows, cols = np.nonzero(cells == value)
                    centres.append(apply_planar(t_truth_map, np.stack(
                        [o.x + (cols + 0.5) * res, o.y + (rows + 0.5) * res], axis=1)))
                cells_xy = tuple(centres)
            if path is not None and path.poses:
                planned = apply_planar(t_truth_map, [(p.pose.position.x, p.pose.position.y)
                                                     for p in path.poses])
        text = f"t = {rospy.Time.now().to_sec():6.1f} s"
        if state is not None:
            text += f"  {state.state} / {state.phase}"
        video.add_frame(cells_xy, true_track, estimated, planned, self._found_exit(), text)

    def run_mission(self):
        """Watches until the conductor ends the mission (or the sim-time limit), filming it."""
        self._wait_for_clock()
        video = TopViewVideo(os.path.join(self.output_dir, "run.mp4"), self.world)
        next_frame = rospy.Time.now().to_sec()
        try:
            while not rospy.is_shutdown() and rospy.Time.now().to_sec() < self.sim_time_limit_s:
                self._sample_estimate()
                self._sample_alignment()
                now = rospy.Time.now().to_sec()
                if now >= next_frame:
                    self._frame(video)
                    next_frame = now + self.frame_period_s
                with self.lock:
                    phase = self.conductor_states[-1].phase if self.conductor_states else ""
                if phase in ("done", "gave_up"):
                    rospy.loginfo("demo: the conductor ended the mission: %s", phase)
                    break
                rospy.sleep(0.1)
            else:
                rospy.logwarn("demo: sim-time limit of %.0f s reached", self.sim_time_limit_s)
            # The drone lands; the last state and path arrive, and the present map's alignment
            # goes on being sampled (a map started in the last seconds is the one drawn).
            until = rospy.Time.now().to_sec() + 3.0
            while not rospy.is_shutdown() and rospy.Time.now().to_sec() < until:
                self._sample_alignment()
                rospy.sleep(0.1)
            self._frame(video)
        finally:
            video.close()

    def _exit_lines(self):
        """The room outline's two edges that meet nearest to the exit found (truth frame)."""
        with self.lock:
            outline = self.outline_truth
        found = self._found_exit()
        if outline is None or found is None:
            return []
        edges = [(outline[i], outline[(i + 1) % len(outline)]) for i in range(len(outline))]

        def distance(edge):
            a, b = edge
            t = np.clip(np.dot(found - a, b - a) / max(np.dot(b - a, b - a), 1e-12), 0, 1)
            return np.linalg.norm(found - (a + t * (b - a)))
        return sorted(edges, key=distance)[:2]

    def write_outputs(self):
        with self.lock:
            bag, self.bag = self.bag, None
            latest = dict(self.latest)
            states = list(self.states)
            clouds = dict(self.clouds)
            final_scale = self.scale_by_map.figures(self.scale_by_map.last_map)
            scales = {"scale_by_map": self.scale_by_map.by_map(),
                      "scale_most_measured": self.scale_by_map.most_measured()}
        bag.close()
        raw = latest.get("orb_slam3/all_points")
        raw_points = cloud_to_points(raw) if raw is not None else np.empty((0, 3))
        write_points_csv(os.path.join(self.output_dir, "cloud.csv"), raw_points)

        world = self.world
        map_points = np.empty((0, 3))
        t_truth_map = self._truth_from_map()
        if t_truth_map is None:
            rospy.logwarn("demo: no map -> sim_world alignment, map not drawn")
        drawn = self.alignments.biggest_aligned({k: c.width * c.height for k, c in clouds.items()})
        cloud, t_cloud = ((clouds[drawn], self.alignments.get(drawn)) if drawn is not None
                          else (latest.get("slam/points"), t_truth_map))
        if cloud is not None and t_cloud is not None:
            map_points = cloud_to_points(cloud) @ t_cloud[:3, :3].T + t_cloud[:3, 3]
        grid = latest.get("map")
        if grid is not None and t_truth_map is not None:
            plot_grid(os.path.join(self.output_dir, "map.png"), world, grid_to_array(grid),
                      grid.info.resolution, (grid.info.origin.position.x, grid.info.origin.position.y),
                      t_truth_map, title=f"{world.name}: occupancy grid (sim_world frame)")
        found_exit = self._found_exit()
        path_msg = latest.get("navigator/path")
        planned = (apply_planar(t_truth_map, [(p.pose.position.x, p.pose.position.y)
                                              for p in path_msg.poses])
                   if path_msg is not None and path_msg.poses and t_truth_map is not None else [])
        plot_summary(os.path.join(self.output_dir, "summary.png"), world, map_points,
                     self.true_path, self.estimated_path,
                     title=f"{world.name}, {self.robot}: {len(raw_points)} SLAM points",
                     found_exit=found_exit, exit_lines=self._exit_lines(), planned_path=planned)
        with self.lock:
            conductor_states = list(self.conductor_states)
            look_arounds = list(self.look_arounds.records)
        final_phase = conductor_states[-1].phase if conductor_states else "no conductor state"
        # The report is written seconds after the limit (the drone lands, the last messages
        # arrive): a mission that ends in those seconds ran out of time.
        ended_at_s = mission_end_s((c.header.stamp.to_sec(), c.phase) for c in conductor_states)
        judgement = evaluate(world, final_phase, self.true_path, found_exit, ended_at_s,
                             self.sim_time_limit_s)
        visited = []
        for c in conductor_states:
            if not visited or visited[-1] != [c.state, c.phase]:
                visited.append([c.state, c.phase])

        report = {
            "success": judgement["success"],
            "world": world.name,
            "robot": self.robot,
            "sim_time_s": round(rospy.Time.now().to_sec(), 2),
            "ended_at_s": None if ended_at_s is None else round(ended_at_s, 2),
            "sim_time_limit_s": self.sim_time_limit_s,
            "final_phase": final_phase,
            "final_reason": conductor_states[-1].reason if conductor_states else "",
            "left_the_room": judgement["left_the_room"],
            "path_length_m": judgement["path_length_m"],
            "exit_error_m": judgement["exit_error_m"],
            "exit_found_xy": None if found_exit is None else [round(v, 3) for v in found_exit],
            "states": visited,
            "look_arounds": look_arounds,
            "slam_points": int(len(raw_points)),
            "tracking_losses": tracking_losses([s.state for s in states]),
            "slam_maps": len({s.map_index for s in states}),
            "final_slam_state": states[-1].reason if states else "no state received",
            # The final map's (often one begun outside after a last loss) and each map's.
            "scale": final_scale,
            **scales,
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
        node.run_mission()
    except rospy.ROSInterruptException:
        return
    node.write_outputs()
